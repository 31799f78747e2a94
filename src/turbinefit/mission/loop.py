"""The autonomous inspection, simulated in the loop: fly an approach orbit, estimate the
turbine, plan, then fly the plan waypoint by waypoint while the tracker corrects the
drone's pose and the turbine, replanning the rest of the path from the current estimate.

**The world.** A true turbine of a preset type (:mod:`turbinefit.sim.turbines`; heading,
blade rotation and base drawn from the seed) with known defects painted on its blades
(:func:`~turbinefit.sim.defects.draw_defects`), and what the operator types in before the
flight: the true turbine off by up to ``InitialError`` (heading and blade rotation +-5 deg,
base +-3 m, sizes +-5 %, uniform). The drone records a GNSS pose with every photo
(:class:`~turbinefit.sim.gnss.GnssReceiver`: metre-level and slowly varying with
``standard`` GNSS, centimetres with ``rtk``, a compass yaw bias of a few degrees either
way).

**How the drone flies.** A waypoint is a camera pose in the frame the plan was made in:
the frame of the turbine estimate, which the tracker anchors to the first keyframe's
recorded pose. The drone flies until the pose its navigation believes it has is the
waypoint's; its true pose is that minus the GNSS error of the moment
(``recorded = true + error``, so the recorded pose is the one commanded):

* **open loop** (``closed_loop=False``, as inspections are flown today): the navigation
  believes the GNSS, and the first plan is flown to the end;
* **closed loop**: after each photo the tracker's estimate of that keyframe's pose gives
  the navigation its correction (the recorded position minus the estimated one, and the
  rotation between them), applied to every later command until the next photo; and when
  the turbine estimate has moved by more than ``replan_m`` at any model point since the
  plan in use was made, the stations not yet photographed are planned again from it,
  starting where the drone is (:func:`~turbinefit.inspection.plan.plan_path` with
  ``done`` and ``start``), with the stand-off kept from the current estimate.

**Photos and heat-maps.** Each photo is rendered at the true pose with the camera scaled
to ``photo_width`` pixels wide (:class:`~turbinefit.sim.photos.FlightPhotos`: the scene,
the defects and the boxes of those in view); coverage and resolution are judged at the
camera's full size. The heat-maps are the CNN's on the photo (``maps="photos"``, the
shipped model through onnxruntime, at its own resolution) or the simulator's ideal ones
(``maps="ideal"``: a fast stand-in for tests and for separating the loop from the net).

**Open loop** skips the approach: the first plan is made from the typed-in turbine, as
inspections are planned today; the tracker still follows the photos (its estimates are
reported), but nothing the drone does depends on it.

**The approach.** ``orbit_photos`` photos on a circle round the estimated tower at the
hub's height, far enough for the rotor to fill the frame's short side; the initial turbine
is estimated from them (:func:`~turbinefit.solver.init.initial_turbine`, near the typed-in
base, which fills in a parameter the images do not determine), then refined by a batch
fit of the orbit (:func:`~turbinefit.solver.fit.fit`), and the tracker starts from it.

Written here rather than with a robotics simulator (Gazebo, AirSim): what is simulated
is not flight dynamics but where the drone is when it takes each photo, given what it
believes; the renderer, the GNSS model, the planner and the tracker are the project's own.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, quat_exp, quat_multiply, world_T_cam_from_angles
from turbinefit.heatmaps import HeatmapStack
from turbinefit.inspection.defects import Defect
from turbinefit.inspection.plan import (
    Plan,
    PlanError,
    Waypoint,
    plan_path,
)
from turbinefit.inspection.surface import SurfaceShape, TurbineSurface
from turbinefit.io.images import to_grey
from turbinefit.mission.config import InitialError, MissionConfig
from turbinefit.mission.replan import (
    moved,
    plan_options,
    plausible,
    position_sigma,
    replan,
    structure_sigma,
)
from turbinefit.sim.defects import draw_defects
from turbinefit.sim.gnss import GnssReceiver, gnss_model
from turbinefit.sim.noise import OdometrySensor
from turbinefit.sim.photos import DefectBox, FlightPhotos
from turbinefit.sim.render import RenderConfig, render_heatmaps
from turbinefit.sim.scenario import DEFAULT_HEATMAP_NOISE
from turbinefit.sim.turbines import preset_turbine
from turbinefit.solver.config import FitConfig
from turbinefit.solver.fit import fit
from turbinefit.solver.init import NotDetermined, TurbinePrior, initial_turbine
from turbinefit.solver.tracker import (
    Tracker,
    TrackEstimate,
)
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineParams, model_points
from turbinefit.turbine.solid import ROOT_TWIST

FloatArray = NDArray[np.float64]

#: Streams of the mission's random numbers (spawned from the seed, in this order).
_STREAMS = ("turbine", "initial", "defects", "gnss", "maps", "odometry")


@dataclass
class Keyframe:
    """One photo of the mission.

    Attributes:
        index: its number; timestamp: when it was taken [s].
        stage: ``orbit`` or ``inspection``.
        true: the camera's true pose; recorded: the pose its GNSS fix recorded.
        position_sigma: (3,) the fix's reported position standard deviations [m].
        heatmaps: (7, h, w) its heat-maps (the maps' camera); image: the photo (None with
            ideal maps and no defects).
        odometry: the odometry's pose (``odometry="vio"``), else None.
        causal: the tracker's estimate of the pose as the photo arrived (None: before the
            tracker started).
        waypoint: the plan's waypoint it was taken at (None: orbit).
        boxes: the known defects in view (boxes in the rendered photo's pixels).
        update_s: the tracker's update time, detection included [s] (None: orbit).
    """

    index: int
    timestamp: float
    stage: str
    true: SE3
    recorded: SE3
    position_sigma: FloatArray
    heatmaps: NDArray[np.float32]
    image: NDArray[np.uint8] | None = None
    causal: SE3 | None = None
    odometry: SE3 | None = None
    waypoint: Waypoint | None = None
    boxes: tuple[DefectBox, ...] = ()
    update_s: float | None = None


@dataclass
class Mission:
    """What happened in a simulated mission (:func:`run_mission`).

    Attributes:
        config: its configuration.
        truth: the true turbine; typed_in: the operator's turbine; initial: the turbine
            estimated from the approach orbit (the first plan's).
        defects: the known defects.
        keyframes: every photo in order (the orbit's first).
        path_true, path_recorded: (M, 3) every position flown (waypoints and transit
            points, the orbit's included), true and as the GNSS recorded it [m].
        path_estimated: (M, 3) where the navigation believed it was.
        plans: the plans flown (the first, then each replan); plan_turbines: the turbine
            estimate each was made for.
        replans: how many times the rest of the path was planned again.
        replan_failures: replans the planner refused (the previous plan was kept).
        tracker: the tracker at the end of the flight.
        init_note: how the initial turbine was found.
        timings: seconds per stage.
        replan_errors: why the planner refused each replan it refused.
        blade_pitch: the blades' pitch as the renderer draws them [rad].
        known_pitch: the pitch the operator knows (``blade_pitch`` to within
            :attr:`InitialError.blade_pitch_deg`), in the same terms [rad].
        estimates_rejected: replans not made because the tracker's turbine was not
            :func:`plausible`.
    """

    config: MissionConfig
    truth: TurbineParams
    typed_in: TurbineParams
    initial: TurbineParams
    defects: list[Defect]
    keyframes: list[Keyframe]
    path_true: FloatArray
    path_recorded: FloatArray
    path_estimated: FloatArray
    plans: list[Plan]
    replans: int
    replan_failures: int
    tracker: Tracker
    init_note: str
    timings: dict[str, float]
    replan_errors: list[str] = field(default_factory=list)
    blade_pitch: float = 0.0
    plan_turbines: list[TurbineParams] = field(default_factory=list)
    estimates_rejected: int = 0
    known_pitch: float = 0.0

    @property
    def inspection(self) -> list[Keyframe]:
        return [k for k in self.keyframes if k.stage == "inspection"]

    @property
    def shape(self) -> SurfaceShape:
        """The blades as the photos show them (the renderer's pitch and twist, in
        :class:`~turbinefit.inspection.surface.SurfaceShape`'s terms): what locating a
        defect's side and chord needs, and what the truth's coverage is judged on."""
        return SurfaceShape(blade_pitch=-self.blade_pitch, blade_twist=-ROOT_TWIST)


# ---- the drone's navigation ---------------------------------------------------------------


def _pose(w: Waypoint) -> SE3:
    return world_T_cam_from_angles(np.asarray(w.position, dtype=np.float64), w.yaw, w.pitch,
                                   0.0)


def _remove_error(recorded: SE3, position_error: FloatArray, rotation_error: FloatArray
                  ) -> SE3:
    """The true pose whose GNSS fix, with these errors, records ``recorded``."""
    q = quat_multiply(quat_exp(-np.asarray(rotation_error)), recorded.wxyz)
    q = q / np.linalg.norm(q)
    return SE3(np.concatenate([q, recorded.translation - position_error]))


class Navigation:
    """What the drone believes of its pose: its GNSS fix, corrected in closed loop by the
    tracker's estimate of the last photo's pose (module docstring)."""

    def __init__(self, closed_loop: bool) -> None:
        self.closed_loop = closed_loop
        self.dp = np.zeros(3)
        self.dq = np.array([1.0, 0.0, 0.0, 0.0])

    def command(self, target: SE3) -> SE3:
        """The pose to fly to (as the GNSS will record it) to be at ``target`` in the
        estimate's frame."""
        q = quat_multiply(self.dq, target.wxyz)
        return SE3(np.concatenate([q / np.linalg.norm(q), target.translation + self.dp]))

    def believed(self, recorded: SE3) -> SE3:
        """Where the drone believes it is when its GNSS records ``recorded``."""
        q = quat_multiply(self.dq * np.array([1.0, -1.0, -1.0, -1.0]), recorded.wxyz)
        return SE3(np.concatenate([q / np.linalg.norm(q), recorded.translation - self.dp]))

    def correct(self, recorded: SE3, estimated: SE3) -> None:
        """The tracker estimated the pose recorded as ``recorded`` to be ``estimated``."""
        if not self.closed_loop:
            return
        self.dp = recorded.translation - estimated.translation
        conj = estimated.wxyz * np.array([1.0, -1.0, -1.0, -1.0])
        dq = quat_multiply(recorded.wxyz, conj)
        self.dq = dq / np.linalg.norm(dq)


# ---- the mission ----------------------------------------------------------------------------


def orbit_poses(turbine: TurbineParams, camera: PinholeCamera, n: int) -> SE3:
    """``n`` cameras on a circle round ``turbine``'s tower at its hub's height, looking at
    the hub, far enough that the rotor (and a margin) fills the frame's short side; the
    first straight upwind."""
    pts, _ = model_points(turbine.to_vector())
    hub = pts[2]
    half = min(camera.width / camera.fx, camera.height / camera.fy) / 2.0  # tan(half fov)
    radius = 1.15 * (abs(turbine.blade_length) + abs(turbine.nacelle_length)) / half
    a = turbine.heading + 2.0 * math.pi * np.arange(n) / n
    pos = np.stack([hub[0] + radius * np.cos(a), hub[1] + radius * np.sin(a),
                    np.full(n, hub[2])], axis=1)
    view = hub[None] - pos
    yaw = np.arctan2(view[:, 1], view[:, 0])
    return world_T_cam_from_angles(pos, yaw, np.zeros(n), 0.0)


class _Maps:
    """The heat-maps of a photo: the CNN's (on the rendered photo) or the simulator's."""

    def __init__(self, cfg: MissionConfig, truth: TurbineParams,
                 rng: np.random.Generator) -> None:
        self.kind = cfg.maps
        self.camera = cfg.map_camera()
        self.truth = truth.to_vector()
        self.rng = rng
        self.detector = None
        if self.kind == "photos":
            from turbinefit.detect import HeatmapDetector

            self.detector = HeatmapDetector()
        k = self.camera.width / 320.0
        lo, hi = DEFAULT_HEATMAP_NOISE.spurious_length_px
        noise = replace(DEFAULT_HEATMAP_NOISE, spurious_length_px=(lo * k, hi * k))
        self.render = RenderConfig(sigma_px=2.0 * k, noise=noise)

    def __call__(self, image: NDArray[np.uint8] | None, true: SE3) -> NDArray[np.float32]:
        if self.detector is not None:
            assert image is not None
            return self.detector.detect(image, size=(self.camera.width, self.camera.height))
        return render_heatmaps(self.camera, true, self.truth, PAPER_GEOMETRY, self.render,
                               self.rng)


def run_mission(cfg: MissionConfig, progress: Callable[[str, int, int], None] | None = None
                ) -> Mission:
    """Simulate one inspection mission (module docstring). ``progress(stage, done,
    total)`` is called after each photo."""
    t_start = time.perf_counter()
    timings = {"render_s": 0.0, "maps_s": 0.0, "track_s": 0.0, "plan_s": 0.0}
    streams = dict(zip(_STREAMS, (np.random.default_rng(s) for s in np.random.SeedSequence(
        cfg.seed).spawn(len(_STREAMS))), strict=True))
    truth = preset_turbine(cfg.turbine, streams["turbine"])
    typed_in = cfg.initial_error.draw(truth, streams["initial"])
    defects = draw_defects(cfg.defects, truth, streams["defects"]) if cfg.defects else []
    photos = FlightPhotos(cfg.photo_camera(), truth, cfg.seed, defects=defects,
                          surface=True)
    # the blades as the operator knows them: the blade type's twist, the parked pitch
    known_shape = SurfaceShape(
        blade_pitch=-cfg.initial_error.draw_pitch(photos.scene.blade_pitch, streams["initial"]),
        blade_twist=-ROOT_TWIST)
    maps_of = _Maps(cfg, truth, streams["maps"])
    receiver = GnssReceiver(gnss_model(cfg.gnss), streams["gnss"])
    vio = OdometrySensor(streams["odometry"]) if cfg.odometry == "vio" else None
    rtk = cfg.gnss == "rtk"
    nav = Navigation(cfg.closed_loop)
    keyframes: list[Keyframe] = []
    path_true: list[FloatArray] = []
    path_rec: list[FloatArray] = []
    path_est: list[FloatArray] = []
    clock = [0.0]
    last: list[FloatArray | None] = [None]  # the last commanded position

    def fly(target: SE3, photo: bool, stage: str, waypoint: Waypoint | None) -> Keyframe | None:
        """Fly to ``target`` (in the estimate's frame) and, with ``photo``, take one."""
        cmd = nav.command(target)
        p = cmd.translation
        if last[0] is not None:
            clock[0] += float(np.linalg.norm(p - last[0])) / cfg.speed_m_s
        last[0] = p
        clock[0] += cfg.photo_s if photo else 0.5
        fix = receiver.measure(clock[0], cmd)
        true = _remove_error(cmd, fix.position_error_m, fix.rotation_error)
        path_true.append(true.translation)
        path_rec.append(cmd.translation)
        path_est.append(target.translation)
        if not photo:
            return None
        k = len(keyframes)
        t0 = time.perf_counter()
        shot = photos.photo(k, true) if cfg.maps == "photos" or defects else None
        timings["render_s"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        maps = maps_of(None if shot is None else shot.image, true)
        dt_maps = time.perf_counter() - t0
        timings["maps_s"] += dt_maps
        kf = Keyframe(k, clock[0], stage, true, cmd, fix.position_sigma_m.copy(), maps,
                      None if shot is None else shot.image, waypoint=waypoint,
                      boxes=() if shot is None else shot.boxes)
        kf.update_s = dt_maps
        kf.odometry = None if vio is None else vio.measure(true)
        keyframes.append(kf)
        return kf

    fit_cfg = cfg.fit_config(-known_shape.blade_pitch)
    here: FloatArray | None = None
    last_est: TrackEstimate | None = None
    if cfg.closed_loop:
        # -- the approach orbit, on GNSS alone
        orbit = orbit_poses(typed_in, cfg.camera, cfg.orbit_photos)
        for i in range(cfg.orbit_photos):
            fly(orbit[i], True, "orbit", None)
            if progress is not None:
                progress("orbit", i + 1, cfg.orbit_photos)
        timings["orbit_s"] = time.perf_counter() - t_start
        # -- the initial turbine: init near the typed-in base, refined by a fit of the orbit
        t0 = time.perf_counter()
        initial, init_note = _initial_turbine(keyframes, cfg.map_camera(), typed_in, fit_cfg,
                                              cfg.initial_error)
        tracker = Tracker(cfg.map_camera(), initial, replace(cfg.tracker, fit=fit_cfg))
        for kf in keyframes:
            last_est = _update(tracker, kf, rtk)
            kf.causal = last_est.world_T_cam
        nav.correct(keyframes[-1].recorded, tracker.world_T_cam()[len(keyframes) - 1])
        here = nav.believed(keyframes[-1].recorded).translation
        timings["init_s"] = time.perf_counter() - t0
    else:  # as inspections are flown today: the typed-in turbine, no approach
        initial, init_note = typed_in, "the typed-in turbine (open loop)"
        tracker = Tracker(cfg.map_camera(), initial, replace(cfg.tracker, fit=fit_cfg))

    # -- the plan, then waypoint by waypoint
    sigmas = ((position_sigma(tracker, last_est),
               structure_sigma(tracker, last_est, cfg.structure_sigma_min))
              if cfg.closed_loop else (0.0, 0.0))
    options = plan_options(cfg, *sigmas)
    t0 = time.perf_counter()
    planned_for = tracker.turbine
    replan_errors: list[str] = []
    try:
        plan = plan_path(TurbineSurface(planned_for, shape=known_shape), cfg.camera, options,
                         start=here)
    except PlanError as e:  # widened, the stand-off may meet the rotor: plan as asked
        if options.standoff == cfg.standoff:
            raise
        replan_errors.append(str(e))
        options = plan_options(cfg, *sigmas, widen_standoff=False)
        plan = plan_path(TurbineSurface(planned_for, shape=known_shape), cfg.camera, options,
                         start=here)
    timings["plan_s"] += time.perf_counter() - t0
    plans = [plan]
    plan_turbines = [planned_for]
    done: set[tuple[int, int, float]] = set()
    replans = failures = since = rejected = 0
    queue = list(plan.waypoints[1:] if here is not None else plan.waypoints)
    total = len(plan.photos)
    while queue and len(done) < cfg.max_photos:
        w = queue.pop(0)
        shot = fly(_pose(w), w.photo, "inspection", w)
        if shot is None:
            continue
        kf = shot
        t0 = time.perf_counter()
        est = _update(tracker, kf, rtk)
        kf.update_s = (kf.update_s or 0.0) + time.perf_counter() - t0
        timings["track_s"] += time.perf_counter() - t0
        kf.causal = est.world_T_cam
        nav.correct(kf.recorded, est.world_T_cam)
        done.add((w.part, w.side, round(w.span, 6)))
        since += 1
        if progress is not None:
            progress("inspection", len(done), total)
        if not cfg.closed_loop or since < cfg.replan_every:
            continue
        wanted = plan_options(cfg, position_sigma(tracker, est),
                          structure_sigma(tracker, est, cfg.structure_sigma_min))
        if (moved(planned_for, tracker.turbine) < cfg.replan_m
                and abs(wanted.standoff - options.standoff) < cfg.replan_m
                and (wanted.tower_clearance or 0.0) <= (options.tower_clearance or 0.0)
                and abs(wanted.overlap - options.overlap) < 0.1):
            continue
        if not plausible(tracker.turbine, typed_in, cfg.initial_error):
            rejected += 1  # the tracker has lost its way: keep flying the plan in use
            since = 0
            continue
        t0 = time.perf_counter()
        since = 0
        try:
            again = replan(TurbineSurface(tracker.turbine, shape=known_shape), cfg, wanted, done,
                            nav.believed(kf.recorded))
        except PlanError as e:
            failures += 1
            replan_errors.append(str(e))
            again = None
        timings["plan_s"] += time.perf_counter() - t0
        if again is None:
            continue
        replans += 1
        planned_for = tracker.turbine
        options = wanted
        plan = again
        plans.append(plan)
        plan_turbines.append(planned_for)
        queue = list(plan.waypoints[1:])
        total = len(done) + len(plan.photos)
    timings["total_s"] = time.perf_counter() - t_start
    return Mission(cfg, truth, typed_in, initial, defects, keyframes, np.array(path_true),
                   np.array(path_rec), np.array(path_est), plans, replans, failures,
                   tracker, init_note, timings, replan_errors, photos.scene.blade_pitch,
                   plan_turbines, rejected, -known_shape.blade_pitch)


def _update(tracker: Tracker, kf: Keyframe, rtk: bool) -> TrackEstimate:
    """The tracker's update with keyframe ``kf`` (its odometry, and its fix's sigmas with
    RTK)."""
    return tracker.update(kf.timestamp, kf.recorded, kf.heatmaps, odometry=kf.odometry,
                          position_sigma=kf.position_sigma if rtk else None,
                          photo=grey_photo(kf) if tracker.config.fit.uses_photos else None)


def grey_photo(kf: Keyframe) -> NDArray[np.uint8] | None:
    """The keyframe's photo in grey levels (H, W), or None without one."""
    return None if kf.image is None else to_grey(kf.image)


def _initial_turbine(keyframes: list[Keyframe], camera: PinholeCamera,
                     typed_in: TurbineParams, config: FitConfig,
                     error: InitialError) -> tuple[TurbineParams, str]:
    """The turbine the plan starts from: ``init`` on the orbit's ``keyframes`` (near the
    typed-in base, with its sizes as the type's), then a batch fit of the orbit
    (``config``) from it, or from the typed-in turbine when ``init`` cannot tell or its
    answer is not :func:`plausible`; a fit that fails or is not plausible is not used."""
    heatmaps = HeatmapStack(np.stack([k.heatmaps for k in keyframes]))
    world_T_cam = SE3(np.stack([k.recorded.wxyz_xyz for k in keyframes]))
    odometry = None
    if keyframes[0].odometry is not None:
        odometry = SE3(np.stack([k.odometry.wxyz_xyz for k in keyframes  # type: ignore[union-attr]
                                 ]))
    prior = TurbinePrior(near_xy=(typed_in.base_x, typed_in.base_y),
                         hub_height=typed_in.tower_height, blade_length=typed_in.blade_length,
                         nacelle_length=typed_in.nacelle_length)
    starts: list[tuple[TurbineParams, str]] = []
    try:
        found = initial_turbine(heatmaps, camera, world_T_cam, prior).turbine
        if plausible(found, typed_in, error):
            starts.append((found, "init from the approach orbit"))
        else:
            starts.append((typed_in, "the typed-in turbine (init from the approach orbit "
                           "was implausible)"))
    except NotDetermined as e:
        starts.append((typed_in, f"the typed-in turbine (init: {e})"))
    if starts[0][0] is not typed_in:
        starts.append((typed_in, "the typed-in turbine"))
    for start, note in starts:
        flight = Flight(camera=camera, timestamps=np.array([k.timestamp for k in keyframes]),
                        world_T_cam=world_T_cam, heatmaps=heatmaps, turbine=start,
                        odometry=odometry)
        result = fit(flight, config)
        if result.verdict != "failed" and plausible(result.turbine, typed_in, error):
            return result.turbine, note + ", refined by a fit of the orbit"
    return typed_in, "the typed-in turbine (the orbit's fits failed)"
