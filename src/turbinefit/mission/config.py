"""A simulated inspection mission's configuration (:class:`MissionConfig`): the turbine,
the camera, the GNSS, the loop's options, and how far the operator's typed-in turbine is
from the truth (:class:`InitialError`); the mission itself is :mod:`turbinefit.mission.loop`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.sim.gnss import gnss_model
from turbinefit.sim.turbines import PRESETS as TURBINE_PRESETS
from turbinefit.solver.config import PHOTO_FIT_DEFAULTS, FitConfig
from turbinefit.solver.tracker import (
    TrackerConfig,
)
from turbinefit.turbine.model import TurbineParams

#: The inspection camera of the benchmarks: 20 MP, a 50 mm lens on a full-frame sensor
#: (a DJI Zenmuse P1-like camera; 1.36 mm/px at 10 m).
MISSION_CAMERA = PinholeCamera(5280, 3956, 7350.0, 7350.0, 2639.5, 1977.5)
#: Kinds of heat-maps a mission reads (module docstring).
MAP_KINDS = ("photos", "ideal")
#: Where the pose graph's relative motions come from (module docstring).
ODOMETRY_KINDS = ("vio", "gnss")
#: Width [px] of the heat-maps (the shipped CNN's output for a 320 px photo).
MAP_WIDTH = 160
#: The width term's weight with :attr:`MissionConfig.width_term`.
WIDTH_WEIGHT = 1.0
@dataclass(frozen=True)
class InitialError:
    """How far the typed-in turbine is from the truth: each parameter off by a uniform
    draw within +- these (sizes as a fraction of the true ones), and the blades' parked
    pitch as the operator knows it (from the turbine's controller) off by up to
    ``blade_pitch_deg``."""

    heading_deg: float = 5.0
    blade_rotation_deg: float = 5.0
    base_m: float = 3.0
    size: float = 0.05
    blade_pitch_deg: float = 2.0

    def draw(self, truth: TurbineParams, rng: np.random.Generator) -> TurbineParams:
        """The typed-in turbine for ``truth``."""
        u = rng.uniform(-1.0, 1.0, size=7)
        return TurbineParams(
            truth.base_x + self.base_m * u[0], truth.base_y + self.base_m * u[1],
            truth.tower_height * (1.0 + self.size * u[2]),
            truth.heading + math.radians(self.heading_deg) * u[3],
            truth.nacelle_length * (1.0 + self.size * u[4]),
            truth.blade_rotation + math.radians(self.blade_rotation_deg) * u[5],
            truth.blade_length * (1.0 + self.size * u[6]))

    def draw_pitch(self, pitch: float, rng: np.random.Generator) -> float:
        """The blades' pitch [rad] as the operator knows it, for the true ``pitch``."""
        return pitch + math.radians(self.blade_pitch_deg) * float(rng.uniform(-1.0, 1.0))


@dataclass(frozen=True)
class MissionConfig:
    """Everything that defines a simulated mission (module docstring).

    Attributes:
        turbine: the turbine type (:data:`turbinefit.sim.turbines.PRESETS`).
        seed: random seed; the same configuration and seed give the same mission.
        standoff: the plan's stand-off [m].
        gsd_mm: the resolution each side must be seen at [mm/px].
        gnss: ``standard`` or ``rtk`` (:data:`turbinefit.sim.gnss.GNSS_MODELS`).
        camera: the inspection camera (coverage and resolution at its full size).
        photo_width: width [px] the photos are rendered at (the camera scaled).
        closed_loop: correct the navigation and replan from the tracker (else: fly the
            first plan on GNSS alone).
        defects: how many known defects are painted on the blades.
        maps: ``photos`` (the CNN on the rendered photos) or ``ideal`` (the simulator's).
        orbit_photos: photos of the approach orbit.
        initial_error: how far the typed-in turbine is from the truth.
        max_gimbal_up_deg: the gimbal's largest upward pitch [deg].
        odometry: ``vio``: the drone's visual-inertial odometry gives the relative motions
            between photos (body frame, :class:`~turbinefit.sim.noise.OdometrySensor`) and
            the GNSS fixes anchor the positions (``gauge="gps"``, the model's sigma);
            ``gnss``: the recorded GNSS poses give both.
        replan_m: replan when the turbine estimate's model points moved this far [m].
        replan_every: and at most once every this many photos.
        overlap: the share of a photo's footprint its neighbours along the part share.
        safety_sigmas: in closed loop, the plan keeps the stand-off plus this many times the
            tracker's standard deviation of the drone's position (its worst direction), as
            far as the camera still reaches the GSD, and widens the overlap by as much;
            and it keeps the tower clearance plus as many times the standard deviation of
            where the tower and the nacelle are (the turbine estimate's base and nacelle
            length with the drone's position; photos of blades alone leave them
            uncertain), that standard deviation never taken below
            ``structure_sigma_min`` [m] (the tracker's covariance of them is overconfident)
            (0: the stand-off, the overlap and the clearance alone).
        max_photos: end the mission after this many inspection photos (a short mission).
        speed_m_s: flight speed between waypoints [m/s]; photo_s: time per photo [s].
        tracker: the tracker's options (its cost: the defaults for photos).
        gps_sigma: the standard deviation [m] the tracker and the final fit give each GNSS
            fix (None: the GNSS model's horizontal one). The fixes' errors are correlated
            over minutes, so taken as independent they weigh more than they are worth; a
            larger value weighs them less (``benchmarks/bench_mission.py --gps-sigma``).
        fit_gps_sigma: the same for the final fit of the mission's photos alone (None: as
            :attr:`gps_sigma`). After the flight a batch fit has every photo of every side
            and can weigh the fixes less than a tracker in flight, whose causal estimate
            they keep from drifting (``bench_mission.py --fit-gps-sigma``).
        width_term: the width term (:mod:`turbinefit.costs.silhouette_width`) in the tracker
            and the final fit, weight :data:`WIDTH_WEIGHT`: the camera's distance from a
            blade from how wide it looks in the photo, the blades' sections taken at the
            pitch the operator knows (needs the photos: not with ideal maps and no
            defects). None (the default): with standard GNSS, where it holds the
            distance the fixes do not (every side covered on 95 % of 20 missions instead of
            90 %, the closest approach 0.85x instead of 0.80x), not with RTK, whose fixes
            already hold it and where it let one mission of 20 come to 0.78x
            (``benchmarks/bench_mission.py``).
    """

    turbine: str = "nrel5mw"
    seed: int = 0
    standoff: float = 10.0
    gsd_mm: float = 2.0
    gnss: str = "standard"
    camera: PinholeCamera = MISSION_CAMERA
    photo_width: int = 320
    closed_loop: bool = True
    defects: int = 12
    maps: Literal["photos", "ideal"] = "photos"
    orbit_photos: int = 24
    initial_error: InitialError = field(default_factory=InitialError)
    max_gimbal_up_deg: float = 90.0
    odometry: Literal["vio", "gnss"] = "vio"
    replan_m: float = 0.5
    replan_every: int = 3
    overlap: float = 0.3
    safety_sigmas: float = 2.0
    structure_sigma_min: float = 1.0
    max_photos: int = 100_000
    speed_m_s: float = 4.0
    photo_s: float = 2.0
    tracker: TrackerConfig = field(default_factory=lambda: TrackerConfig(
        fit=replace(FitConfig(), **PHOTO_FIT_DEFAULTS)))
    gps_sigma: float | None = None
    fit_gps_sigma: float | None = None
    width_term: bool | None = None

    def __post_init__(self) -> None:
        if self.turbine not in TURBINE_PRESETS:
            raise ValueError(f"unknown turbine type {self.turbine!r}; choose from "
                             f"{', '.join(TURBINE_PRESETS)}")
        if self.maps not in MAP_KINDS:
            raise ValueError(f"maps must be one of {', '.join(MAP_KINDS)}, got {self.maps!r}")
        if self.odometry not in ODOMETRY_KINDS:
            raise ValueError(f"odometry must be one of {', '.join(ODOMETRY_KINDS)}, "
                             f"got {self.odometry!r}")
        gnss_model(self.gnss)
        if self.orbit_photos < 8:
            raise ValueError(f"orbit_photos must be at least 8, got {self.orbit_photos}")
        for name in ("gps_sigma", "fit_gps_sigma"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v}")
        if not 32 <= self.photo_width <= self.camera.width:
            raise ValueError(f"photo_width must be between 32 and the camera's width "
                             f"({self.camera.width}), got {self.photo_width}")

    def fit_config(self, blade_pitch: float | None = None) -> FitConfig:
        """The cost and options of the tracker and the final fit: the tracker's, anchored
        to the GNSS fixes (``gauge="gps"`` at :attr:`gps_sigma`, by default the GNSS
        model's horizontal sigma: a compass yaw bias is then estimated, not held fixed at
        the first keyframe's); with :attr:`width_term`, the width term, its blades at
        ``blade_pitch`` [rad, the renderer's convention] (the pitch the operator knows)."""
        sigma = self.gps_sigma or max(float(gnss_model(self.gnss).horizontal_m), 0.01)
        cfg = replace(self.tracker.fit, gauge="gps", gps_sigma=sigma)
        if self.uses_width_term:
            cfg = replace(cfg, lambda_width=WIDTH_WEIGHT,
                          blade_pitch_deg=None if blade_pitch is None
                          else math.degrees(blade_pitch))
        return cfg

    @property
    def uses_width_term(self) -> bool:
        """Whether the tracker and the final fit use the width term: :attr:`width_term`,
        or if None (the default), with standard GNSS and not with RTK."""
        return self.gnss != "rtk" if self.width_term is None else bool(self.width_term)

    def final_fit_config(self, blade_pitch: float | None = None) -> FitConfig:
        """The final fit's: :meth:`fit_config` with :attr:`fit_gps_sigma` if given."""
        cfg = self.fit_config(blade_pitch)
        return cfg if self.fit_gps_sigma is None else replace(cfg, gps_sigma=self.fit_gps_sigma)

    def photo_camera(self) -> PinholeCamera:
        """The camera the photos are rendered with (:attr:`camera` scaled)."""
        h = max(24, round(self.camera.height * self.photo_width / self.camera.width))
        return self.camera.scaled_to(self.photo_width, h)

    def map_camera(self) -> PinholeCamera:
        """The heat-maps' camera (:attr:`camera` scaled to :data:`MAP_WIDTH` wide)."""
        h = max(24, round(self.camera.height * MAP_WIDTH / self.camera.width))
        return self.camera.scaled_to(MAP_WIDTH, h)
