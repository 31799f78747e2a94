"""Replanning in flight (:mod:`turbinefit.mission.loop`): the plan's options from what the
tracker knows (the stand-off, overlap and tower clearance widened by the standard
deviations of the drone's position and of where the tower and the nacelle are), the rest
of the path planned again from the current estimate, and whether an estimate is
plausible enough to plan from."""

from __future__ import annotations

import math

import numpy as np

from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.clearance import ROTOR, path_clearance, solid_samples
from turbinefit.inspection.plan import (
    Plan,
    PlanOptions,
    Waypoint,
    check_margin,
    plan_path,
    tower_clearance,
)
from turbinefit.inspection.surface import TurbineSurface
from turbinefit.mission.config import InitialError, MissionConfig
from turbinefit.solver.tracker import (
    DEFAULT_THETA_SIGMA,
    Tracker,
    TrackEstimate,
)
from turbinefit.turbine.model import TurbineParams, model_points


def moved(a: TurbineParams, b: TurbineParams) -> float:
    """The largest distance between the model points of two turbines [m] (tips matched
    modulo the blades' symmetry)."""
    pa, _ = model_points(a.to_vector())
    pb, _ = model_points(b.to_vector())
    d = float(np.max(np.linalg.norm(pa[:3] - pb[:3], axis=1)))
    tips = np.linalg.norm(pa[3:, None] - pb[None, 3:], axis=-1)
    return max(d, float(tips.min(axis=1).max()))


def position_sigma(tracker: Tracker, est: TrackEstimate | None = None) -> float:
    """The largest standard deviation [m] of the latest pose's position, in its worst
    direction (0 if unknown)."""
    cov = None if est is None else est.pose_covariance
    if cov is None:
        return 0.0
    w = np.linalg.eigvalsh(0.5 * (cov[:3, :3] + cov[:3, :3].T))
    return float(math.sqrt(max(float(w[-1]), 0.0)))


def structure_sigma(tracker: Tracker, est: TrackEstimate | None, least: float) -> float:
    """The standard deviation [m] of where the tower and the nacelle are, apart from the
    drone's own position: the turbine estimate's base (its worst horizontal direction)
    and nacelle length, at least ``least``. Photos of the blades fix the hub well but
    hardly where the tower stands behind it (a base further downwind and a shorter nacelle
    put the hub at the same place), and the tracker's covariance of them is overconfident:
    0.2 m where the estimate was 1.5 m off (RTK, seed 6; ``benchmarks/bench_mission.py``).
    Without a covariance (singular information), the tracker's start-up prior's."""
    cov = None if est is None else est.theta_covariance
    if cov is None or not np.all(np.isfinite(cov)):
        sig = tracker.config.theta_sigma or DEFAULT_THETA_SIGMA
        return max(least, math.hypot(max(sig[0], sig[1]), sig[4]))
    base = np.linalg.eigvalsh(0.5 * (cov[:2, :2] + cov[:2, :2].T))[-1]
    return max(least, math.sqrt(max(float(base), 0.0) + max(float(cov[4, 4]), 0.0)))


def plan_options(cfg: MissionConfig, sigma: float, structure_sigma: float,
                 widen_standoff: bool = True) -> PlanOptions:
    """The plan's options for a pose known to a standard deviation ``sigma`` [m], and a
    tower and nacelle known to ``structure_sigma`` [m] apart from it: the stand-off asked
    for, widened (unless not ``widen_standoff``: the planner refused the widened one) by
    ``safety_sigmas`` times ``sigma`` (at most half the stand-off, and no
    further than the camera still reaches the GSD from, as far again nearer: a photo taken
    that much further off still reaches it), the photos' overlap along the
    part widened by as much (at most 0.7), so that a photo taken that far off its station
    still meets its neighbours, and the tower clearance widened by ``safety_sigmas`` times
    both standard deviations together (at most the stand-off); the views added where the
    stations leave a side unseen must show it from anywhere within ``safety_sigmas`` times
    ``sigma`` of their waypoints (``PlanOptions.position_margin``)."""
    f = math.sqrt(cfg.camera.fx * cfg.camera.fy)
    reach = cfg.gsd_mm * f / 1000.0 - 0.5  # the planner flies its check's margin further
    widen = min(cfg.safety_sigmas * sigma, 0.5 * cfg.standoff)
    standoff = max(cfg.standoff, min(cfg.standoff + widen, reach - widen)) \
        if widen_standoff else cfg.standoff
    foot = min(cfg.camera.width, cfg.camera.height) * standoff / f
    overlap = min(0.7, cfg.overlap + cfg.safety_sigmas * sigma / foot)
    base = tower_clearance(PlanOptions(standoff, cfg.gsd_mm))
    tower = min(standoff, base + cfg.safety_sigmas * math.hypot(sigma, structure_sigma))
    return PlanOptions(round(standoff, 1), cfg.gsd_mm, overlap=round(overlap, 2),
                       max_gimbal_up_deg=cfg.max_gimbal_up_deg,
                       tower_clearance=math.floor(10 * tower) / 10,
                       position_margin=round(min(cfg.safety_sigmas * sigma, 0.5 * standoff), 2))


def replan(surface: TurbineSurface, cfg: MissionConfig, options: PlanOptions,
            done: set[tuple[int, int, float]], here: SE3) -> Plan | None:
    """The rest of the path planned again from ``surface`` (the current estimate): a
    station of the new plan is left out if the photos taken (``done``: part, side, span)
    already cover its share of the side (its span, half a station's spacing either way,
    within the footprints of those photos along the part), and the path starts at the
    believed pose ``here``. If the new estimate puts ``here`` within the stand-off, the
    path starts by backing away along the view until it keeps it (a transit point). None
    if nothing is left to photograph."""
    f = math.sqrt(cfg.camera.fx * cfg.camera.fy)
    foot = min(cfg.camera.width, cfg.camera.height) * options.standoff / f  # along the part
    step = max((1.0 - options.overlap) * foot, 0.1)
    taken: dict[tuple[int, int], list[float]] = {}
    for p, s, x in done:
        taken.setdefault((p, s), []).append(x)

    def photographed(part: int, side: int, span: float) -> bool:
        spans = sorted(taken.get((part, side), []))
        lo, hi = span - 0.5 * step, span + 0.5 * step
        for x in spans:  # the union of the footprints, swept from below
            if x - 0.5 * foot > lo:
                return False
            lo = max(lo, x + 0.5 * foot)
            if lo >= hi:
                return True
        return False

    samples = solid_samples(surface)
    start = here.translation
    need = options.standoff + check_margin(samples) + 0.1
    backward = -here.rotation_matrix()[:, 2]
    retreat: list[Waypoint] = []
    for _ in range(20):
        dist = path_clearance(start[None], samples).least(ROTOR, legs=False)[0]
        if dist >= need:
            break
        start = start + max(need - dist, 0.25) * backward
        retreat = [Waypoint(start.copy(), float(np.arctan2(-backward[1], -backward[0])), 0.0)]
    plan = plan_path(surface, cfg.camera, options, samples, start=start, done=photographed)
    if not plan.photos:
        return None
    if retreat:  # fly here -> retreat point (the plan's start) -> the stations
        plan.waypoints = [Waypoint(here.translation.copy(), 0.0, 0.0), *plan.waypoints]
    return plan


def plausible(estimate: TurbineParams, typed_in: TurbineParams, error: InitialError,
              factor: float = 3.0) -> bool:
    """Whether ``estimate`` lies within ``factor`` times the typed-in turbine's error bounds
    of it (base, heading, blade rotation modulo a third of a turn, sizes): an estimate
    beyond them is not trusted (an approach photographed from afar can mistake the rotor's
    side, or a tracker lose its way) and the typed-in turbine stands."""
    e, t = estimate.to_vector(), typed_in.to_vector()

    def angle(a: float, b: float, period: float) -> float:
        return abs((a - b + period / 2) % period - period / 2)

    base = math.hypot(e[0] - t[0], e[1] - t[1])
    sizes = [abs(e[i] / t[i] - 1.0) for i in (2, 6) if t[i] > 0]
    return bool(base <= factor * error.base_m * math.sqrt(2.0) + 1.0
                and angle(e[3], t[3], 2 * math.pi) <= math.radians(factor * error.heading_deg)
                and angle(e[5], t[5], 2 * math.pi / 3)
                <= math.radians(factor * error.blade_rotation_deg)
                and all(s <= factor * error.size + 0.02 for s in sizes))
