"""The initial turbine from the heat-maps and the poses alone: no angle given.

:func:`initial_turbine` estimates θ = (base_x, base_y, tower_height, heading,
nacelle_length, blade_rotation, blade_length) from a flight's heat-maps and its initial
(GPS/IMU or VIO) poses, optionally near a known position and with priors of a turbine
type, in three steps:

1. **Peaks.** Each keyframe's four point channels (base, tower top, hub, tips) give their
   local maxima above :attr:`InitOptions.peak_threshold`, refined to sub-pixel; each peak
   is a ray from the keyframe's camera (distortion removed).
2. **Robust triangulation** (RANSAC over pairs of rays from different keyframes, the
   candidate scored by the number of *keyframes* with a ray passing within
   :attr:`InitOptions.inlier_m` m plus :attr:`InitOptions.inlier_rad` of it, then a
   weighted least-squares refit on the inliers): the tower top and the hub; the base with
   ``z = 0`` (one ray meets the ground: each ray is a candidate); the tips one after the
   other (three instances in one channel: the best point, its rays removed, the next),
   kept when they lie at a common distance from the hub. With ``near`` given, only
   candidates within :attr:`InitOptions.near_radius_m` of it count (a neighbour turbine
   is ignored).
3. **Assembly.** The tower axis (base and tower top, weighted by their spreads) gives
   base and tower height; the rotor plane through the hub and the tips gives the heading
   (modulo pi, the side from the hub's offset from the tower axis) and the blade length;
   each tip's angle about the nacelle axis gives the blade rotation (the mean of the
   three modulo 2 pi / 3: the rotor's three-fold symmetry); the hub's horizontal distance
   from the tower axis gives the nacelle length. A prior (``--type``) replaces what the
   images cannot determine (and the nacelle length, which the images determine poorly).

Each parameter carries a spread: the standard deviation propagated from the
triangulations' residuals, or the prior's when it came from the prior. A parameter neither
the images nor a prior determine raises :class:`NotDetermined` naming it.

The batch fit (:func:`turbinefit.solver.fit.fit`) then refines θ with the poses; its
align stage absorbs the few metres and degrees the triangulation leaves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import TurbinefitError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.heatmaps.peaks import strongest_peaks
from turbinefit.turbine.model import BLADE_PERIOD, HEADING_PERIOD, TurbineParams

FloatArray = NDArray[np.float64]

#: Point channels (base, tower top, hub, tip) of the heat-maps.
BASE_CH, TOP_CH, HUB_CH, TIP_CH = 0, 1, 2, 3


class NotDetermined(TurbinefitError):
    """A parameter of θ that neither the images nor a prior determine.

    Attributes:
        parameter: its name (one of :attr:`TurbineParams.NAMES`, or ``turbine`` when the
            turbine is not seen at all).
        hint: what the user may add (``--type``, ``--near``, ...).
    """

    def __init__(self, parameter: str, why: str, hint: str) -> None:
        super().__init__(f"cannot determine {parameter}: {why}; {hint}")
        self.parameter = parameter
        self.hint = hint


@dataclass(frozen=True)
class TurbinePrior:
    """What is known of the turbine before the images: its type's sizes (``--type``, or
    ``--hub-height``/``--rotor-diameter``) and where it roughly stands (``--near``).

    Attributes:
        near_xy: rough base position in the flight's frame [m], or None.
        hub_height: tower height (the model's hub height) [m], or None.
        blade_length: rotor radius [m], or None.
        nacelle_length: rotor overhang [m], or None.
        name: the type's name, for summaries.
    """

    near_xy: tuple[float, float] | None = None
    hub_height: float | None = None
    blade_length: float | None = None
    nacelle_length: float | None = None
    name: str | None = None


@dataclass(frozen=True)
class InitOptions:
    """Settings of :func:`initial_turbine`.

    Attributes:
        peak_threshold: a heat-map peak counts above this value.
        max_peaks: at most this many peaks per channel and keyframe (the strongest).
        inlier_m, inlier_rad: a ray supports a point passing within ``inlier_m`` +
            ``inlier_rad`` x range of it (pose drift: metres and degrees).
        min_keyframes: keyframes that must support a triangulated point.
        hypotheses: RANSAC hypotheses per point.
        near_radius_m: with a ``near`` position, points farther from it horizontally
            (the rotor's reach added for the hub and tips) are not this turbine.
        prior_nacelle_sigma: spread given to the nacelle length taken from a prior [m].
        default_nacelle_ratio: without a prior and without a hub, nacelle length =
            this x blade length (NREL 5 MW: 5 / 63).
        seed: RANSAC's random stream.
    """

    peak_threshold: float = 0.4
    max_peaks: int = 6
    inlier_m: float = 2.0
    inlier_rad: float = math.radians(2.5)
    min_keyframes: int = 3
    hypotheses: int = 300
    near_radius_m: float = 30.0
    prior_nacelle_sigma: float = 1.0
    default_nacelle_ratio: float = 5.0 / 63.0
    seed: int = 0


@dataclass(frozen=True)
class Rays:
    """Rays of heat-map peaks: origin (camera centre) and unit direction in the world,
    the keyframe and the peak's value."""

    origin: FloatArray
    direction: FloatArray
    keyframe: NDArray[np.int_]
    value: FloatArray

    def __len__(self) -> int:
        return len(self.keyframe)

    def subset(self, mask: NDArray[np.bool_]) -> Rays:
        return Rays(self.origin[mask], self.direction[mask], self.keyframe[mask],
                    self.value[mask])


@dataclass(frozen=True)
class Triangulated:
    """A robustly triangulated point: position [m], its covariance [m²] and the number of
    keyframes supporting it."""

    point: FloatArray
    cov: FloatArray
    keyframes: int


@dataclass
class InitResult:
    """What :func:`initial_turbine` found.

    Attributes:
        turbine: the estimate (canonical angle ranges).
        std: spread of each parameter (metres, radians).
        source: where each parameter came from (``images``, ``prior``, ``default``).
        points: the triangulated model points (``base``, ``tower_top``, ``hub``,
            ``tip``) with their supporting keyframes.
        keyframes_seen: keyframes with a peak of the turbine.
    """

    turbine: TurbineParams
    std: dict[str, float]
    source: dict[str, str]
    points: dict[str, list[Triangulated]] = field(default_factory=dict)
    keyframes_seen: int = 0


# ----------------------------------------------------------------------------- peaks

def normalized_rays(camera: PinholeCamera, uv: FloatArray) -> FloatArray:
    """Camera-frame unit directions (P, 3) of pixels (P, 2), distortion removed (fixed
    point iterations of the plumb_bob model)."""
    yd = (uv[:, 1] - camera.cy) / camera.fy
    xd = (uv[:, 0] - camera.cx - camera.skew * yd) / camera.fx
    x, y = xd.copy(), yd.copy()
    if camera.has_distortion:
        k1, k2, p1, p2, k3 = camera.distortion
        for _ in range(20):
            r2 = x * x + y * y
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
            x = (xd - dx) / radial
            y = (yd - dy) / radial
    d = np.stack([x, y, np.ones_like(x)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def peak_rays(heatmaps: HeatmapStack, camera: PinholeCamera, world_T_cam: SE3,
              keyframes: NDArray[np.int_], options: InitOptions) -> list[Rays]:
    """The rays of every point channel's peaks in ``keyframes`` (one :class:`Rays` per
    point channel: base, tower top, hub, tip)."""
    per: list[list[tuple[int, FloatArray, FloatArray]]] = [[], [], [], []]
    for k in keyframes.tolist():
        maps = heatmaps[k]
        for c in range(len(per)):
            uv, v = strongest_peaks(maps[c], options.peak_threshold, options.max_peaks)
            if len(v):
                per[c].append((k, uv, v))
    R = world_T_cam.rotation_matrix()
    t = world_T_cam.translation
    out = []
    for items in per:
        if not items:
            out.append(Rays(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, dtype=np.int64),
                            np.zeros(0)))
            continue
        kf = np.concatenate([np.full(len(v), k) for k, _, v in items])
        uv = np.concatenate([uv for _, uv, _ in items])
        val = np.concatenate([v for _, _, v in items])
        d_cam = normalized_rays(camera, uv)
        d = np.einsum("pij,pj->pi", R[kf], d_cam)
        out.append(Rays(t[kf].copy(), d, kf.astype(np.int64), val))
    return out


# ------------------------------------------------------------------------- triangulation

def _ray_distance(rays: Rays, p: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Perpendicular distance of ``p`` from each ray, and its range along the ray
    (negative: behind the camera)."""
    w = p - rays.origin
    s = np.einsum("pi,pi->p", w, rays.direction)
    perp = w - s[:, None] * rays.direction
    return np.linalg.norm(perp, axis=-1), s


def _inliers(rays: Rays, p: FloatArray, options: InitOptions) -> NDArray[np.bool_]:
    dist, s = _ray_distance(rays, p)
    return (s > 1.0) & (dist < options.inlier_m + options.inlier_rad * np.maximum(s, 0.0))


def _support(rays: Rays, inl: NDArray[np.bool_]) -> int:
    return int(np.unique(rays.keyframe[inl]).size)


def _refit(rays: Rays, p: FloatArray, on_ground: bool, options: InitOptions,
           iterations: int = 3) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Weighted least squares of the point nearest to the inlier rays (weights 1/range²:
    angular errors), re-selecting the inliers; returns point, covariance, inliers."""
    cov = np.full((3, 3), np.inf)
    inl = _inliers(rays, p, options)
    for _ in range(iterations):
        if inl.sum() < 2:
            break
        o, d = rays.origin[inl], rays.direction[inl]
        _, s = _ray_distance(rays.subset(inl), p)
        w = 1.0 / np.maximum(s, 1.0) ** 2
        P = np.eye(3)[None] - d[:, :, None] * d[:, None, :]  # (n, 3, 3)
        A = np.einsum("n,nij->ij", w, P)
        b = np.einsum("n,nij,nj->i", w, P, o)
        dims = 2 if on_ground else 3
        A_ = A[:dims, :dims] + 1e-9 * np.eye(dims)
        try:
            sol = np.linalg.solve(A_, b[:dims])
        except np.linalg.LinAlgError:
            break
        p = np.array([sol[0], sol[1], 0.0]) if on_ground else sol
        # covariance: residual variance (angles) times (A)^-1
        dist, s = _ray_distance(rays.subset(inl), p)
        n = int(inl.sum())
        ang2 = float(np.sum((dist / np.maximum(s, 1.0)) ** 2)) / max(n - dims, 1)
        ang2 = max(ang2, (0.5 * options.inlier_rad / 2.5) ** 2 / 4.0)
        c = np.linalg.inv(A_) * ang2
        # pose drift shared by neighbouring keyframes does not average out: half the RMS
        # distance of the inlier rays is a floor on the spread
        c += np.eye(dims) * float(np.mean(dist ** 2)) / 4.0
        cov = np.zeros((3, 3))
        cov[:dims, :dims] = c
        inl = _inliers(rays, p, options)
    return p, cov, inl


def _pair_point(o1: FloatArray, d1: FloatArray, o2: FloatArray, d2: FloatArray
                ) -> FloatArray | None:
    """Midpoint of the closest approach of two rays (None if nearly parallel or behind)."""
    w0 = o1 - o2
    a, b, c = d1 @ d1, d1 @ d2, d2 @ d2
    d, e = d1 @ w0, d2 @ w0
    den = a * c - b * b
    if den < 1e-4:  # under ~0.6 deg apart
        return None
    s = (b * e - c * d) / den
    t = (a * e - b * d) / den
    if s <= 1.0 or t <= 1.0:
        return None
    return 0.5 * ((o1 + s * d1) + (o2 + t * d2))


def triangulate(rays: Rays, options: InitOptions, rng: np.random.Generator, *,
                on_ground: bool = False, near_xy: FloatArray | None = None,
                near_radius: float = math.inf, max_z: float = math.inf
                ) -> Triangulated | None:
    """The point most keyframes' rays pass near (RANSAC, then least squares), or None if
    fewer than :attr:`InitOptions.min_keyframes` support any.

    ``on_ground``: the point lies on z = 0 (each ray is a candidate: where it meets the
    ground). ``near_xy``, ``near_radius``: candidates farther than this horizontally are
    refused; ``max_z``: so are candidates above it.
    """
    n = len(rays)
    if n < 2 and not (on_ground and n >= 1):
        return None
    best: FloatArray | None = None
    best_score = -1.0

    def consider(p: FloatArray) -> None:
        nonlocal best, best_score
        if not np.all(np.isfinite(p)) or p[2] > max_z or p[2] < -1.0:
            return
        if near_xy is not None and math.hypot(p[0] - near_xy[0], p[1] - near_xy[1]) > near_radius:
            return
        inl = _inliers(rays, p, options)
        score = _support(rays, inl) + 1e-3 * float(rays.value[inl].sum())
        if score > best_score:
            best, best_score = p, score

    if on_ground:
        down = np.nonzero(rays.direction[:, 2] < -0.02)[0]
        if down.size > options.hypotheses:
            down = rng.choice(down, options.hypotheses, replace=False)
        for i in down.tolist():
            s = -rays.origin[i, 2] / rays.direction[i, 2]
            consider(rays.origin[i] + s * rays.direction[i])
    else:
        for _ in range(options.hypotheses):
            i, j = rng.integers(0, n, 2)
            if rays.keyframe[i] == rays.keyframe[j]:
                continue
            p = _pair_point(rays.origin[i], rays.direction[i], rays.origin[j], rays.direction[j])
            if p is not None:
                consider(p)
    if best is None:
        return None
    p, cov, inl = _refit(rays, best, on_ground, options)
    support = _support(rays, inl)
    if support < options.min_keyframes or not np.all(np.isfinite(cov)):
        return None
    return Triangulated(p, cov, support)


def triangulate_many(rays: Rays, count: int, options: InitOptions, rng: np.random.Generator,
                     **kwargs: object) -> list[Triangulated]:
    """Up to ``count`` points from one channel (the tips): the best, its rays removed,
    the next."""
    found: list[Triangulated] = []
    left = rays
    for _ in range(count):
        t = triangulate(left, options, rng, **kwargs)  # type: ignore[arg-type]
        if t is None:
            break
        found.append(t)
        left = left.subset(~_inliers(left, t.point, options))
    return found


# ------------------------------------------------------------------------------ assembly

def _xy_std(t: Triangulated) -> float:
    return math.sqrt(max(float(t.cov[0, 0] + t.cov[1, 1]) / 2.0, 1e-12))


def _pick_tips(hub: FloatArray, tips: list[Triangulated], blade_prior: float | None
               ) -> list[Triangulated]:
    """The tips at a common distance from the hub (within 12 %; with a prior, within 25 %
    of it), at most three, best supported first."""
    if not tips:
        return []
    dist = np.array([np.linalg.norm(t.point - hub) for t in tips])
    centres = [c for c in dist.tolist()
               if blade_prior is None or abs(c - blade_prior) < 0.25 * blade_prior]
    best: list[int] = []
    for c in centres:
        idx = [i for i in range(len(tips)) if abs(dist[i] - c) < 0.12 * c and dist[i] > 3.0]
        score = sum(tips[i].keyframes for i in idx[:3])
        if score > sum(tips[i].keyframes for i in best[:3]):
            best = idx
    return [tips[i] for i in best[:3]]


def _heading_from_tips(hub: FloatArray, tips: list[Triangulated]
                       ) -> tuple[float, float] | None:
    """Axis of the rotor (modulo pi) from the horizontal directions hub -> tip, and its
    spread [rad]; None if the tips are (nearly) straight above or below the hub."""
    v = np.array([t.point[:2] - hub[:2] for t in tips])
    M = v.T @ v
    if np.trace(M) < 4.0:  # every tip within ~2 m of the vertical through the hub
        return None
    evals, evecs = np.linalg.eigh(M)
    n = evecs[:, 0]
    std_tip = math.sqrt(sum(_xy_std(t) ** 2 for t in tips) / len(tips))
    spread = std_tip / math.sqrt(max(float(evals[1]), 1e-9))
    return math.atan2(n[1], n[0]), spread


def _blade_rotation(hub: FloatArray, tips: list[Triangulated], heading: float) -> float:
    """Mean over the tips of each tip's rotor angle modulo 2 pi / 3."""
    y_axis = np.array([-math.sin(heading), math.cos(heading), 0.0])
    ang = np.array([math.atan2(-float((t.point - hub) @ y_axis), float(t.point[2] - hub[2]))
                    for t in tips])
    m = np.mean(np.exp(3j * ang))
    return float(np.angle(m) / 3.0) % BLADE_PERIOD


def assemble(base: Triangulated | None, top: Triangulated | None, hub: Triangulated | None,
             tips: list[Triangulated], prior: TurbinePrior, options: InitOptions,
             hint_near: bool) -> tuple[TurbineParams, dict[str, float], dict[str, str]]:
    """θ, each parameter's spread and its source from the triangulated points and the
    prior (see the module docstring). Raises :class:`NotDetermined`."""
    type_hint = "give --type NAME (or --hub-height and --rotor-diameter)"
    see_hint = "the photos must show it from several keyframes"
    source: dict[str, str] = {}
    std: dict[str, float] = {}
    if hub is None and len(tips) >= 3:
        centre = np.mean([t.point for t in tips[:3]], axis=0)
        hub = Triangulated(centre, np.mean([t.cov for t in tips[:3]], axis=0), 0)
    # tower height
    if top is not None:
        h, std["tower_height"], source["tower_height"] = (
            float(top.point[2]), math.sqrt(top.cov[2, 2]), "images")
    elif hub is not None:
        h, std["tower_height"], source["tower_height"] = (
            float(hub.point[2]), math.sqrt(hub.cov[2, 2]), "images (hub)")
    elif prior.hub_height is not None:
        h, std["tower_height"], source["tower_height"] = prior.hub_height, 0.1 * prior.hub_height, "prior"
    else:
        raise NotDetermined("tower_height", "no tower top or hub is seen in enough keyframes",
                            type_hint)
    # blade length and the tips
    tips = _pick_tips(hub.point, tips, prior.blade_length) if hub is not None else []
    if tips and hub is not None:
        d = np.array([np.linalg.norm(t.point - hub.point) for t in tips])
        b = float(d.mean())
        std["blade_length"] = float(np.sqrt(np.mean([_xy_std(t) ** 2 for t in tips])
                                            / len(tips)) + (d.std() if d.size > 1 else 0.0))
        source["blade_length"] = "images"
    elif prior.blade_length is not None:
        b, std["blade_length"], source["blade_length"] = (
            prior.blade_length, 0.05 * prior.blade_length, "prior")
    else:
        raise NotDetermined("blade_length", "no blade tip is seen in enough keyframes", type_hint)
    # heading: the rotor plane (modulo pi), its side from the hub's offset
    if hub is None:
        raise NotDetermined("heading", "neither the hub nor three blade tips are seen in "
                            "enough keyframes", see_hint)
    axis = _heading_from_tips(hub.point, tips) if tips else None
    c_xy = _tower_axis(base, top)
    if c_xy is None:
        c_xy = hub.point[:2].copy(), _xy_std(hub) + 5.0
    off = hub.point[:2] - c_xy[0]
    if axis is None:
        if np.linalg.norm(off) < 2.0 * (c_xy[1] + _xy_std(hub)):
            raise NotDetermined("heading", "no blade tip off the vertical through the hub is "
                                "seen, and the hub's offset from the tower is unclear", see_hint)
        heading = math.atan2(off[1], off[0])
        std["heading"] = (c_xy[1] + _xy_std(hub)) / float(np.linalg.norm(off))
    else:
        heading, std["heading"] = axis
        if math.cos(heading - math.atan2(off[1], off[0])) < 0:
            heading += math.pi
    source["heading"] = "images"
    heading %= HEADING_PERIOD
    u = np.array([math.cos(heading), math.sin(heading)])
    # nacelle length: the rotor plane's distance from the tower axis
    if prior.nacelle_length is not None:
        r, std["nacelle_length"], source["nacelle_length"] = (
            prior.nacelle_length, options.prior_nacelle_sigma, "prior")
    elif base is not None or top is not None:
        pts = [hub.point] + [t.point for t in tips]
        r = float(np.mean([(p[:2] - c_xy[0]) @ u for p in pts]))
        std["nacelle_length"] = c_xy[1] + _xy_std(hub)
        source["nacelle_length"] = "images"
    else:
        r, std["nacelle_length"], source["nacelle_length"] = (
            options.default_nacelle_ratio * b, 0.5 * options.default_nacelle_ratio * b, "default")
    r = min(max(r, 0.0), 25.0)
    # base: the tower axis, or the hub moved back along the heading
    if base is not None or top is not None:
        c = c_xy[0]
        std["base_x"] = std["base_y"] = c_xy[1]
        source["base_x"] = source["base_y"] = "images"
    else:
        c = hub.point[:2] - r * u
        std["base_x"] = std["base_y"] = _xy_std(hub) + std["nacelle_length"]
        source["base_x"] = source["base_y"] = "images (hub)"
    # blade rotation
    if tips:
        phi = _blade_rotation(hub.point, tips, heading)
        std["blade_rotation"] = math.sqrt(np.mean([_xy_std(t) ** 2 for t in tips])) / b
        source["blade_rotation"] = "images"
    else:
        raise NotDetermined("blade_rotation", "no blade tip is seen in enough keyframes",
                            see_hint)
    del hint_near
    theta = TurbineParams(float(c[0]), float(c[1]), h, heading, r, phi, b).canonical()
    return theta, std, source


def _tower_axis(base: Triangulated | None, top: Triangulated | None
                ) -> tuple[FloatArray, float] | None:
    """The tower axis's horizontal position (inverse-variance mean of base and tower top)
    and its spread, or None if neither is known."""
    pts = [t for t in (base, top) if t is not None]
    if not pts:
        return None
    w = np.array([1.0 / _xy_std(t) ** 2 for t in pts])
    xy = np.sum([wi * t.point[:2] for wi, t in zip(w, pts, strict=True)], axis=0) / w.sum()
    return xy, 1.0 / math.sqrt(float(w.sum()))


def initial_turbine(heatmaps: HeatmapStack, camera: PinholeCamera, world_T_cam: SE3,
                    prior: TurbinePrior | None = None, options: InitOptions | None = None,
                    keyframes: NDArray[np.int_] | None = None) -> InitResult:
    """Estimate θ from the heat-maps and the poses (see the module docstring).

    Args:
        heatmaps: the flight's maps, at ``camera``'s size.
        camera: the maps' camera.
        world_T_cam: (N,) initial camera-to-world poses.
        prior: what is known beforehand (position, type), or None.
        options: settings (None = defaults).
        keyframes: which keyframes to use (None = all).

    Raises:
        NotDetermined: naming a parameter neither the images nor the prior determine.
    """
    prior = prior or TurbinePrior()
    opt = options or InitOptions()
    rng = np.random.default_rng(opt.seed)
    kfs = np.arange(len(heatmaps)) if keyframes is None else np.asarray(keyframes)
    rays = peak_rays(heatmaps, camera, world_T_cam, kfs, opt)
    seen = int(np.unique(np.concatenate([r.keyframe for r in rays])).size)
    hint = "give --near X,Y (or --near-wgs84) near the turbine"
    if seen < opt.min_keyframes:
        raise NotDetermined("turbine", f"it is seen in {seen} keyframe(s), "
                            f"at least {opt.min_keyframes} are needed", hint)
    near = None if prior.near_xy is None else np.asarray(prior.near_xy, dtype=np.float64)
    reach = opt.near_radius_m + (prior.blade_length or 80.0) + (prior.nacelle_length or 10.0)
    top = triangulate(rays[TOP_CH], opt, rng, near_xy=near, near_radius=opt.near_radius_m)
    hub = triangulate(rays[HUB_CH], opt, rng, near_xy=near, near_radius=opt.near_radius_m + 25.0)
    axis_xy = (top.point[:2] if top is not None else hub.point[:2] if hub is not None else near)
    base = triangulate(rays[BASE_CH], opt, rng, on_ground=True, near_xy=axis_xy,
                       near_radius=opt.near_radius_m if axis_xy is not None else math.inf)
    tips = triangulate_many(rays[TIP_CH], 6, opt, rng, near_xy=near if hub is None else hub.point[:2],
                            near_radius=reach)
    theta, std, source = assemble(base, top, hub, tips, prior, opt, near is not None)
    points = {"base": [base] if base else [], "tower_top": [top] if top else [],
              "hub": [hub] if hub else [], "tip": tips}
    return InitResult(theta, std, source, points, seen)
