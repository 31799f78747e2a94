"""A whole simulated flight: turbine, trajectory, heat-maps, drifting poses, noisy turbine.

World frame: metres, z up, ground z = 0; poses ``world_T_cam`` (camera-to-world), OpenCV
camera frame; angles in radians unless a name ends in ``_deg``.

:func:`simulate_flight` follows the paper's simulation (Sec. IV-A): ground-truth poses and
turbine, heat-maps rendered from the **ground truth**, then sequential (drifting) noise on
the poses and Gaussian noise on the turbine parameters as the initial estimates. It is
fully determined by :attr:`SimConfig.seed`: independent random streams are spawned from
``np.random.SeedSequence(seed)`` for the turbine, the trajectory, the second turbine, the
pose drift, the turbine noise, the heat-maps (one child per keyframe), the body-frame
odometry, the GNSS errors and the drawn defects (the last three appended after the others,
so that they changed no earlier flight), so changing one part of the configuration does
not reshuffle the others (e.g. the turbine and flight path do not change with the
heat-map noise, and the turbine does not change with N).

:func:`simulate` also flies a given path (:class:`FlightPath`: ground-truth poses and
timestamps, e.g. the keyframes ``plan`` wrote) instead of the simulator's own inspection,
records poses with a GNSS error model (:attr:`SimConfig.gnss`,
:mod:`turbinefit.sim.gnss`) instead of the default drift, and draws known defects on the
blades (:attr:`SimConfig.defects`, :mod:`turbinefit.sim.defects`) or takes them given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.sim.gnss import GNSS_MODELS, GnssPoses, gnss_model, gnss_poses
from turbinefit.sim.noise import (
    DEFAULT_TURBINE_SIGMA,
    body_odometry,
    drift_poses,
    perturb_turbine,
)
from turbinefit.sim.render import HeatmapNoise, RenderConfig, render_flight
from turbinefit.sim.trajectory import TrajectoryConfig, plan_inspection
from turbinefit.sim.turbines import PRESETS as TURBINE_PRESETS
from turbinefit.sim.turbines import neighbour_turbine, preset_turbine
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry, TurbineParams

if TYPE_CHECKING:
    from turbinefit.inspection.defects import Defect

#: Default largest heat-map width [px] (:attr:`SimConfig.heatmap_size`).
HEATMAP_WIDTH = 320

#: Stream indices of :func:`simulate_flight`'s spawned generators.
_STREAMS = ("turbine", "trajectory", "second_turbine", "drift", "turbine_noise", "heatmaps",
            "odometry", "gnss", "defects")
#: Kinds of pose measurements :func:`simulate_flight` simulates (``SimConfig.odometry``).
ODOMETRY_KINDS = ("gps", "vio")

#: Heat-map imperfections of the default scenario: a little of everything.
DEFAULT_HEATMAP_NOISE = HeatmapNoise(
    pixel_sigma=0.02, miss_prob=0.05, spurious_rate=0.3, amplitude_jitter=0.1
)


@dataclass(frozen=True)
class SimConfig:
    """Everything that defines a simulated flight (see :func:`simulate_flight`).

    Attributes:
        n_keyframes: number of keyframes N (>= 1).
        seed: random seed; the same configuration and seed give a bit-identical flight.
        width: camera (photo) width [px].
        height: camera (photo) height [px].
        heatmap_size: (width, height) [px] of the heat-maps, the camera's size scaled
            (:meth:`~turbinefit.geometry.camera.PinholeCamera.scaled_to`); None = the
            camera's size, scaled to :data:`HEATMAP_WIDTH` px wide if it is wider (320 x
            240 for any 4:3 camera), so files stay small whatever the camera.
        hfov_deg: horizontal field of view [deg]; fx = fy = (width / 2) / tan(hfov / 2)
            (70 deg at 320 px: 228.5 px, an inspection drone's wide camera).
        distortion: plumb_bob (k1, k2, p1, p2, k3); zeros for none.
        turbine: a preset of :data:`turbinefit.sim.turbines.PRESETS` (heading, blade
            rotation and base randomised) or ``"random"`` (every parameter sampled).
        geometry: shape details beyond the paper's model, used for the ground truth
            (default: the paper's model).
        heatmap_sigma: blob / ridge standard deviation [px] at 320 px width; scaled with
            the heat-maps' width ``/ 320`` (as are the false streaks' lengths of
            ``heatmap_noise``, and the block its pixel noise is drawn per).
        heatmap_noise: heat-map imperfections.
        drift_pos_m: RMS position drift of the initial poses at the last keyframe [m].
        drift_rot_deg: RMS orientation drift of the initial poses at the last keyframe
            [deg].
        turbine_sigma: standard deviation of the initial turbine's error per parameter
            (base x, base y, tower height [m], heading [rad], nacelle [m], blade rotation
            [rad], blade length [m]).
        second_turbine: add a neighbouring turbine 150-400 m away, drawn into the same
            heat-map channels (false responses); it is not part of the Flight's model.
        trajectory: shape of the inspection flight.
        t0: timestamp of keyframe 0 [s].
        dt: time between keyframes [s].
        odometry: the drone's pose measurements. ``gps``: GPS/IMU poses in the world
            frame, drifted as ``drift_pos_m`` / ``drift_rot_deg`` say; no odometry.txt.
            ``vio``: body-frame odometry (:func:`~turbinefit.sim.noise.body_odometry`:
            each relative motion measured in the camera's frame with per-edge noise,
            chained from the first ground-truth pose, so that its world frame drifts
            away), written to odometry.txt; keyframes.txt holds the same chained poses
            (what a drone flying on visual-inertial odometry alone has), and the drift
            fields are not used.
        odometry_noise: scale of the ``vio`` odometry's per-edge sigmas (1 = the defaults
            of :mod:`turbinefit.sim.noise`: 0.02 m + 1 % of the step, 0.05 deg per axis).
        intrinsics: (fx, fy, cx, cy, skew) [px] of the camera (a given ``camera.yaml``),
            or None: from ``hfov_deg``, the principal point at the image centre.
        gnss: the poses' error model, ``standard`` or ``rtk``
            (:data:`~turbinefit.sim.gnss.GNSS_MODELS`), instead of the drift of
            ``drift_pos_m`` / ``drift_rot_deg``; None: that drift. With ``vio`` odometry
            keyframes.txt holds the GNSS poses and odometry.txt the VIO.
        defects: number of known defects drawn on the blades
            (:func:`~turbinefit.sim.defects.draw_defects`).
        surface_detail: photos show the blades' and tower's surface as an inspection's
            close-ups do (:class:`~turbinefit.sim.photos.FlightPhotos`); always with
            defects.
    """

    n_keyframes: int = 200
    seed: int = 0
    width: int = 320
    height: int = 240
    heatmap_size: tuple[int, int] | None = None
    hfov_deg: float = 70.0
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    turbine: str = "nrel5mw"
    geometry: TurbineGeometry = PAPER_GEOMETRY
    heatmap_sigma: float = 2.0
    heatmap_noise: HeatmapNoise = DEFAULT_HEATMAP_NOISE
    drift_pos_m: float = 2.0
    drift_rot_deg: float = 2.0
    turbine_sigma: tuple[float, ...] = DEFAULT_TURBINE_SIGMA
    second_turbine: bool = False
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    t0: float = 0.0
    dt: float = 1.0
    odometry: str = "gps"
    odometry_noise: float = 1.0
    intrinsics: tuple[float, float, float, float, float] | None = None
    gnss: str | None = None
    defects: int = 0
    surface_detail: bool = False

    def __post_init__(self) -> None:
        if self.n_keyframes < 1:
            raise ValueError(f"n_keyframes must be at least 1, got {self.n_keyframes}")
        if not 1.0 < self.hfov_deg < 179.0:
            raise ValueError(f"hfov_deg must be in (1, 179), got {self.hfov_deg}")
        if self.turbine != "random" and self.turbine not in TURBINE_PRESETS:
            raise ValueError(f"unknown turbine {self.turbine!r}; choose from "
                             f"{', '.join([*TURBINE_PRESETS, 'random'])}")
        if len(self.turbine_sigma) != 7:
            raise ValueError("turbine_sigma needs 7 values")
        if not self.dt > 0:
            raise ValueError(f"dt must be positive, got {self.dt}")
        if self.odometry not in ODOMETRY_KINDS:
            raise ValueError(f"odometry must be {' or '.join(ODOMETRY_KINDS)}, "
                             f"got {self.odometry!r}")
        if not (isinstance(self.odometry_noise, int | float) and math.isfinite(self.odometry_noise)
                and self.odometry_noise >= 0):
            raise ValueError(f"odometry_noise must be a non-negative number, "
                             f"got {self.odometry_noise!r}")
        if self.gnss is not None and self.gnss not in GNSS_MODELS:
            raise ValueError(f"gnss must be one of {', '.join(GNSS_MODELS)}, got {self.gnss!r}")
        if not (isinstance(self.defects, int) and self.defects >= 0):
            raise ValueError(f"defects must be a whole number >= 0, got {self.defects!r}")
        if self.heatmap_size is not None:
            try:
                self.heatmap_camera()
            except ValueError as e:
                raise ValueError(f"heatmap_size: {e}") from None

    def camera(self) -> PinholeCamera:
        """The simulated camera: :attr:`intrinsics`, or the principal point at the image
        centre and the focal length of :attr:`hfov_deg`."""
        if self.intrinsics is not None:
            return PinholeCamera(self.width, self.height, *self.intrinsics, self.distortion)
        f = 0.5 * self.width / math.tan(math.radians(self.hfov_deg) / 2.0)
        return PinholeCamera(self.width, self.height, f, f, (self.width - 1) / 2.0,
                             (self.height - 1) / 2.0, 0.0, self.distortion)

    def heatmap_camera(self) -> PinholeCamera:
        """The camera of the heat-maps' pixel grid: :meth:`camera` scaled to
        :attr:`heatmap_size` (the camera itself at its own size)."""
        cam = self.camera()
        if self.heatmap_size is None:
            return cam.at_most(HEATMAP_WIDTH)
        return cam.scaled_to(*self.heatmap_size)

    def render_config(self) -> RenderConfig:
        """Heat-map rendering settings: blob and ridge sigma and the false streaks' lengths
        scaled to the heat-maps' width (``/ 320``), and above 320 px the pixel noise drawn
        per block of that many pixels, so that maps of one view at any size are the same
        picture at a different resolution."""
        k = self.heatmap_camera().width / 320.0
        noise = self.heatmap_noise
        if k != 1.0:
            lo, hi = noise.spurious_length_px
            noise = replace(noise, spurious_length_px=(lo * k, hi * k))
        return RenderConfig(sigma_px=self.heatmap_sigma * k, noise=noise,
                            noise_block=max(1, round(k)))


#: Named scenarios.
PRESETS: dict[str, SimConfig] = {
    # realistic defaults: NREL 5 MW, modest heat-map faults, 2 m / 2 deg drift
    "default": SimConfig(),
    # clean heat-maps; the initial poses and turbine are still wrong
    "noiseless": SimConfig(heatmap_noise=HeatmapNoise()),
    # everything exact: initial estimates = ground truth, clean heat-maps
    "exact": SimConfig(heatmap_noise=HeatmapNoise(), drift_pos_m=0.0, drift_rot_deg=0.0,
                       turbine_sigma=(0.0,) * 7),
    # random machine, large drift, a neighbour in view, poor heat-maps
    "hard": SimConfig(
        turbine="random", drift_pos_m=5.0, drift_rot_deg=5.0, second_turbine=True,
        turbine_sigma=tuple(2.0 * s for s in DEFAULT_TURBINE_SIGMA),
        heatmap_noise=HeatmapNoise(pixel_sigma=0.05, miss_prob=0.15, spurious_rate=2.0,
                                   amplitude_jitter=0.2)),
    # a lens with barrel distortion
    "distorted": SimConfig(distortion=(-0.12, 0.03, 0.0, 0.0, 0.0)),
}


def with_camera(cfg: SimConfig, camera: PinholeCamera) -> SimConfig:
    """``cfg`` with ``camera`` as its photos' camera (size, intrinsics, distortion)."""
    return replace(cfg, width=camera.width, height=camera.height,
                   intrinsics=(camera.fx, camera.fy, camera.cx, camera.cy, camera.skew),
                   distortion=tuple(float(c) for c in camera.distortion))  # type: ignore[arg-type]


def preset(name: str, **overrides: object) -> SimConfig:
    """A named scenario of :data:`PRESETS`, with fields replaced by ``overrides``."""
    if name not in PRESETS:
        raise ValueError(f"unknown simulation preset {name!r}; choose from {', '.join(PRESETS)}")
    return replace(PRESETS[name], **overrides)  # type: ignore[arg-type]


def _place_neighbour(primary: TurbineParams, path_xy: np.ndarray,
                     rng: np.random.Generator) -> TurbineParams:
    """A neighbour turbine whose rotor keeps >= 30 m clear of the flight path."""
    other = neighbour_turbine(primary, rng)
    for _ in range(100):
        reach = other.nacelle_length + other.blade_length + 30.0
        d = np.hypot(path_xy[:, 0] - other.base_x, path_xy[:, 1] - other.base_y)
        if float(d.min()) > reach:
            return other
        other = neighbour_turbine(primary, rng)
    return other


@dataclass(frozen=True)
class FlightPath:
    """A path to fly: ground-truth poses ``world_T_cam`` (N,) at ``timestamps`` (N,) [s,
    increasing]."""

    timestamps: NDArray[np.float64]
    world_T_cam: SE3

    def __post_init__(self) -> None:
        n = self.world_T_cam.batch_shape
        if len(n) != 1 or self.timestamps.shape != n or n[0] < 1:
            raise ValueError(f"{self.timestamps.shape} timestamps for poses of batch {n}")
        if not np.all(np.diff(self.timestamps) > 0):
            raise ValueError("timestamps must increase")

    def __len__(self) -> int:
        return int(self.timestamps.size)


@dataclass(frozen=True)
class Simulation:
    """What :func:`simulate` made.

    Attributes:
        flight: the flight (:func:`simulate_flight`).
        gnss: the GNSS fixes (recorded poses, per-keyframe position sigmas, errors) when
            :attr:`SimConfig.gnss` is set, else None.
        defects: the known defects on the true turbine's blades.
    """

    flight: Flight
    gnss: GnssPoses | None
    defects: list[Defect]


def _streams(seed: int) -> dict[str, np.random.Generator]:
    return dict(zip(_STREAMS, [np.random.default_rng(s) for s in
                               np.random.SeedSequence(seed).spawn(len(_STREAMS))], strict=True))


def true_turbine(cfg: SimConfig) -> TurbineParams:
    """The ground-truth turbine of the flight ``cfg`` simulates (its seed and turbine
    preset alone decide it)."""
    return preset_turbine(cfg.turbine, _streams(cfg.seed)["turbine"])


def simulate_flight(cfg: SimConfig | None = None, progress: bool = False,
                    out: np.ndarray | None = None) -> Flight:
    """Simulate an inspection flight; ``out``: a preallocated float32 array (N, 7, h, w)
    for the heat-maps (e.g. a memory map: flights of large maps need not fit in memory).

    Returns:
        A :class:`~turbinefit.flight.Flight` whose ``world_T_cam`` are the drifted poses
        and ``turbine`` the perturbed turbine (the initial estimates), with
        ``gt_world_T_cam`` / ``gt_turbine`` the truth, ``odometry`` None (``gps``) or the
        body-frame odometry (``vio``, then also ``world_T_cam``), timestamps
        ``t0 + k dt`` and heat-maps rendered from the ground truth (N, 7, h, w) at
        :attr:`SimConfig.heatmap_size`; its camera is :meth:`SimConfig.heatmap_camera`
        (photos are taken with :meth:`SimConfig.camera`).
    """
    return simulate(cfg, progress=progress, out=out).flight


def simulate(cfg: SimConfig | None = None, path: FlightPath | None = None,
             defects: list[Defect] | None = None, progress: bool = False,
             out: np.ndarray | None = None) -> Simulation:
    """Simulate a flight (:func:`simulate_flight`), along ``path`` if given (its poses are
    the ground truth, its timestamps the keyframes'; ``cfg.n_keyframes`` must be its
    length), with ``defects`` (checked: :func:`~turbinefit.sim.defects.check_defects`) or
    :attr:`SimConfig.defects` drawn ones on the blades, and the GNSS fixes of
    :attr:`SimConfig.gnss`."""
    from turbinefit.inspection.defects import check_defects
    from turbinefit.sim.defects import draw_defects

    cfg = cfg or SimConfig()
    rng = _streams(cfg.seed)
    gt_turbine = preset_turbine(cfg.turbine, rng["turbine"])
    if path is None:
        gt_poses = plan_inspection(gt_turbine, cfg.n_keyframes, rng["trajectory"], cfg.geometry,
                                   cfg.trajectory).world_T_cam
        timestamps = cfg.t0 + cfg.dt * np.arange(cfg.n_keyframes, dtype=np.float64)
    else:
        if len(path) != cfg.n_keyframes:
            raise ValueError(f"a path of {len(path)} poses for {cfg.n_keyframes} keyframes")
        gt_poses, timestamps = path.world_T_cam, np.asarray(path.timestamps, dtype=np.float64)
    if defects is None:
        defects = draw_defects(cfg.defects, gt_turbine, rng["defects"])
    else:
        check_defects(defects, gt_turbine)
    distractors = []
    if cfg.second_turbine:
        other = _place_neighbour(gt_turbine, gt_poses.translation[:, :2],
                                 rng["second_turbine"])
        distractors.append(other.to_vector())

    camera = cfg.heatmap_camera()
    maps = render_flight(camera, gt_poses, gt_turbine.to_vector(), cfg.geometry,
                         cfg.render_config(), rng["heatmaps"], distractors, progress=progress,
                         out=out)
    init_poses = drift_poses(gt_poses, rng["drift"], cfg.drift_pos_m, cfg.drift_rot_deg)
    odometry = None
    if cfg.odometry == "vio":
        odometry = body_odometry(gt_poses, rng["odometry"], cfg.odometry_noise)
        init_poses = odometry
    gnss = None
    if cfg.gnss is not None:  # with vio: GNSS keyframes, VIO pairwise motions
        gnss = gnss_poses(gt_poses, timestamps, gnss_model(cfg.gnss), rng["gnss"])
        init_poses = gnss.world_T_cam
    init_turbine = perturb_turbine(gt_turbine, cfg.turbine_sigma, rng["turbine_noise"])
    flight = Flight(
        camera=camera,
        timestamps=timestamps,
        world_T_cam=init_poses,
        heatmaps=HeatmapStack(maps),
        turbine=init_turbine,
        odometry=odometry,
        gt_world_T_cam=gt_poses,
        gt_turbine=gt_turbine,
        # what an RTK receiver reports with each fix, as import dji writes it
        # (keyframes_sigma.csv); a receiver without RTK reports none
        position_sigma=gnss.position_sigma_m if gnss is not None and cfg.gnss == "rtk"
        else None,
    )
    return Simulation(flight, gnss, defects)
