"""Heat-maps as a CNN would give them: the projected skeletal model, blurred, with faults.

Frames and units: poses are ``world_T_cam`` (camera-to-world, world metres, z up); the
camera frame is OpenCV's; pixels follow :mod:`turbinefit.geometry.camera` (pixel (0, 0) is
the centre of the top-left pixel; heat-map element ``[c, i, j]`` is at ``u = j, v = i``).
Channel order is that of :mod:`turbinefit.heatmaps`. Output: float32 (7, H, W) in [0, 1].

What is drawn (``sigma`` = :attr:`RenderConfig.sigma_px`):

* each model point in front of the camera (depth > ``MIN_DEPTH``): a Gaussian blob of
  standard deviation ``sigma`` and peak 1 centred on its projection, in its point channel
  (all three tips in ``point_blade_tip``);
* each model line: a Gaussian-profile ridge (same ``sigma``, peak 1) along its projection,
  with rounded (Gaussian) ends, in its line channel. The 3-D segment is first clipped to
  depth > ``MIN_DEPTH``, so a line whose end is behind the camera is drawn only for its
  visible part. Without lens distortion its image is exactly a straight segment; with
  ``plumb_bob`` distortion the segment is sampled densely (uniformly in the undistorted
  image plane, i.e. 3-D samples in projective spacing) and each sample projected, the
  curve being drawn as short straight pieces; samples outside the distortion model's
  trusted range are dropped;
* overlapping responses combine by maximum (a CNN's sigmoid output saturates at 1).

Distances are computed only inside the bounding box (+ 4 sigma) of each short piece
(at most :attr:`RenderConfig.piece_px` long), never over the whole image. Blobs and ridges
are drawn by the primitives of :mod:`turbinefit.heatmaps.targets`, which draws the CNN's
targets from labelled keypoints the same way.

Imperfections (:class:`HeatmapNoise`, all off at 0): missed points and missed stretches of
lines, peak amplitude jitter, spurious responses (blobs in point channels, short streaks in
line channels), additive Gaussian pixel noise clipped to [0, 1] (drawn by inverse-CDF
lookup of 16-bit uniform integers: Gaussian to 16-bit quantisation, tails cut at 4.3
sigma), and, given
``distractors``, other turbines (e.g. a neighbour of the wind farm) drawn into the same
channels.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtri
from tqdm import tqdm

from turbinefit.geometry.camera import MIN_DEPTH, PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import NUM_CHANNELS
from turbinefit.heatmaps.targets import (
    CUTOFF_SIGMAS,
    clip_segment_rect,
    draw_blob,
    draw_polyline,
)
from turbinefit.turbine.model import (
    LINES,
    PAPER_GEOMETRY,
    POINT_CHANNELS,
    TurbineGeometry,
    model_points,
)

FloatArray = NDArray[np.float64]
F32Array = NDArray[np.float32]

_POINT_CH = tuple(int(c) for c in POINT_CHANNELS)
#: Standard normal quantiles at the centres of 65536 equal-probability bins: indexing it
#: with uniform 16-bit integers draws (16-bit quantised, |x| < 4.33) standard normal
#: pixel noise ~3x faster than ``Generator.standard_normal``.
_NORMAL_TABLE = ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)
_LINE_CH = (4, 5, 6)


@dataclass(frozen=True)
class HeatmapNoise:
    """Imperfections of the simulated CNN output; every one is off when set to 0.

    Attributes:
        pixel_sigma: standard deviation of additive Gaussian noise on every pixel (the
            result is clipped to [0, 1]).
        miss_prob: probability that a model point is not detected at all, and
            (independently) that a stretch of a model line is not.
        miss_fraction: (min, max) length of a missed stretch, as a fraction of the line.
        spurious_rate: expected number (Poisson) of false responses per keyframe, each in
            a random channel: a blob in a point channel, a short streak in a line channel.
        spurious_amplitude: (min, max) peak of a false response (uniform).
        spurious_length_px: (min, max) length [px] of a false streak.
        amplitude_jitter: peaks are ``1 - |N(0, amplitude_jitter)|`` (clipped at 0),
            drawn per point and per line.
    """

    pixel_sigma: float = 0.0
    miss_prob: float = 0.0
    miss_fraction: tuple[float, float] = (0.1, 0.5)
    spurious_rate: float = 0.0
    spurious_amplitude: tuple[float, float] = (0.3, 1.0)
    spurious_length_px: tuple[float, float] = (5.0, 40.0)
    amplitude_jitter: float = 0.0

    @property
    def enabled(self) -> bool:
        """Whether any imperfection is on (then rendering needs an rng)."""
        return (self.pixel_sigma > 0 or self.miss_prob > 0 or self.spurious_rate > 0
                or self.amplitude_jitter > 0)


@dataclass(frozen=True)
class RenderConfig:
    """How heat-maps are drawn.

    Attributes:
        sigma_px: standard deviation [px] of blobs and of the ridge profile of lines.
        noise: imperfections (default: none).
        piece_px: lines are drawn as straight pieces at most this long [px] (each with its
            own bounding box, for speed; pieces of a straight line join seamlessly).
        noise_block: the pixel noise is drawn once per block of ``noise_block`` x
            ``noise_block`` pixels (maps k times the reference size: k, so that their
            noise is that of the reference maps at k times the resolution).
    """

    sigma_px: float = 2.0
    noise: HeatmapNoise = field(default_factory=HeatmapNoise)
    piece_px: float = 24.0
    noise_block: int = 1

    def __post_init__(self) -> None:
        if not (self.sigma_px > 0 and math.isfinite(self.sigma_px)):
            raise ValueError(f"sigma_px must be positive, got {self.sigma_px}")
        if not self.piece_px > 0:
            raise ValueError(f"piece_px must be positive, got {self.piece_px}")
        if not (isinstance(self.noise_block, int) and self.noise_block >= 1):
            raise ValueError(f"noise_block must be a whole number >= 1, got {self.noise_block}")


# ---- projection -------------------------------------------------------------------------


def _clip_depth(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """The part of the camera-frame segment a-b with depth > MIN_DEPTH, or None."""
    za, zb = a[2], b[2]
    if za <= MIN_DEPTH and zb <= MIN_DEPTH:
        return None
    if za < MIN_DEPTH:
        a = a + (MIN_DEPTH - za) / (zb - za) * (b - a)
        a[2] = MIN_DEPTH
    elif zb < MIN_DEPTH:
        b = b + (MIN_DEPTH - zb) / (za - zb) * (a - b)
        b[2] = MIN_DEPTH
    return a, b


class _Painter:
    """Draws one keyframe's projected skeleton(s) into a (7, H, W) float32 array."""

    def __init__(self, camera: PinholeCamera, cfg: RenderConfig) -> None:
        self.camera = camera
        self.cfg = cfg
        self.sigma = cfg.sigma_px
        m = CUTOFF_SIGMAS * cfg.sigma_px
        self.lo = np.array([-m, -m])
        self.hi = np.array([camera.width - 1 + m, camera.height - 1 + m])
        self.distorted = bool(camera.has_distortion)
        # normalised-plane box that contains every trusted (drawable) undistorted point
        cx = (np.array([0.0, camera.width - 1.0]) - camera.cx) / camera.fx
        cy = (np.array([0.0, camera.height - 1.0]) - camera.cy) / camera.fy
        rc = 1.5 * math.sqrt(float(np.max(cx**2) + np.max(cy**2)))
        self.norm_lo = np.array([-rc, -rc])
        self.norm_hi = np.array([rc, rc])
        self.f = max(camera.fx, camera.fy)

    def _pinhole(self, xy: FloatArray) -> FloatArray:
        c = self.camera
        return np.stack([c.fx * xy[..., 0] + c.skew * xy[..., 1] + c.cx,
                         c.fy * xy[..., 1] + c.cy], axis=-1)

    def amplitude(self, rng: np.random.Generator | None) -> float:
        j = self.cfg.noise.amplitude_jitter
        if j <= 0 or rng is None:
            return 1.0
        return max(0.0, 1.0 - abs(float(rng.normal(0.0, j))))

    def points(self, img: F32Array, cam_p: FloatArray, rng: np.random.Generator | None) -> None:
        """Blobs of the six model points ``cam_p`` (6, 3) [m, camera frame]."""
        uv, ok, _ = self.camera.project_unbounded(cam_p)
        miss = self.cfg.noise.miss_prob
        for i in range(len(cam_p)):
            amp = self.amplitude(rng)
            if miss > 0 and rng is not None and rng.uniform() < miss:
                continue
            if not ok[i]:
                continue
            draw_blob(img[_POINT_CH[i]], float(uv[i, 0]), float(uv[i, 1]), amp, self.sigma)

    def lines(self, img: F32Array, cam_p: FloatArray, rng: np.random.Generator | None) -> None:
        """Ridges of the five model lines between the points ``cam_p`` (6, 3)."""
        noise = self.cfg.noise
        for a_i, b_i, ch in LINES:
            amp = self.amplitude(rng)
            a, b = cam_p[a_i], cam_p[b_i]
            parts = [(0.0, 1.0)]
            if noise.miss_prob > 0 and rng is not None and rng.uniform() < noise.miss_prob:
                frac = rng.uniform(*noise.miss_fraction)
                s0 = rng.uniform(0.0, 1.0 - frac)
                parts = [(0.0, s0), (s0 + frac, 1.0)]
            for t0, t1 in parts:
                if t1 - t0 <= 1e-9:
                    continue
                self.segment(img[ch], a + t0 * (b - a), a + t1 * (b - a), amp)

    def segment(self, img: F32Array, a: FloatArray, b: FloatArray, amp: float) -> None:
        """Draw the camera-frame 3-D segment a-b (clipped to depth > MIN_DEPTH)."""
        clipped = _clip_depth(a, b)
        if clipped is None:
            return
        a, b = clipped
        na, nb = a[:2] / a[2], b[:2] / b[2]
        if not self.distorted:
            pa, pb = self._pinhole(na), self._pinhole(nb)
            rng_t = clip_segment_rect(pa, pb, self.lo, self.hi)
            if rng_t is None:
                return
            t0, t1 = rng_t
            d = pb - pa
            draw_polyline(img, np.stack([pa + t0 * d, pa + t1 * d]), amp, self.sigma,
                          self.cfg.piece_px)
            return
        rng_t = clip_segment_rect(na, nb, self.norm_lo, self.norm_hi)
        if rng_t is None:
            return
        t0, t1 = rng_t
        d = nb - na
        length_px = self.f * float(np.hypot(*d)) * (t1 - t0)
        n = int(min(1024, max(2, math.ceil(length_px / (0.5 * self.cfg.piece_px)) + 1)))
        t = np.linspace(t0, t1, n)[:, None]
        xy = na + t * d
        uv, ok, _ = self.camera.project_unbounded(
            np.concatenate([xy, np.ones((n, 1))], axis=-1))
        # draw runs of consecutive trusted samples
        start = None
        for k in range(n + 1):
            good = k < n and bool(ok[k])
            if good and start is None:
                start = k
            elif not good and start is not None:
                run = uv[start:k]
                if len(run) == 1:
                    draw_blob(img, float(run[0, 0]), float(run[0, 1]), amp, self.sigma)
                else:
                    inside = ((run[:, 0] >= self.lo[0]) & (run[:, 0] <= self.hi[0])
                              & (run[:, 1] >= self.lo[1]) & (run[:, 1] <= self.hi[1]))
                    # keep pieces with at least one end near the image
                    keep = inside[:-1] | inside[1:]
                    for kk in np.nonzero(keep)[0]:
                        draw_polyline(img, run[kk:kk + 2], amp, self.sigma, self.cfg.piece_px)
                start = None

    def spurious(self, img: F32Array, rng: np.random.Generator) -> None:
        """False responses: blobs in point channels, short streaks in line channels."""
        noise = self.cfg.noise
        h, w = img.shape[1:]
        for _ in range(int(rng.poisson(noise.spurious_rate))):
            ch = int(rng.integers(NUM_CHANNELS))
            u, v = rng.uniform(0, w - 1), rng.uniform(0, h - 1)
            amp = rng.uniform(*noise.spurious_amplitude)
            if ch in _LINE_CH:
                length = rng.uniform(*noise.spurious_length_px)
                ang = rng.uniform(0.0, math.pi)
                du, dv = 0.5 * length * math.cos(ang), 0.5 * length * math.sin(ang)
                draw_polyline(img[ch], np.array([[u - du, v - dv], [u + du, v + dv]]), amp,
                              self.sigma, self.cfg.piece_px)
            else:
                draw_blob(img[ch], u, v, amp, self.sigma)


def _render_into(out: F32Array, painter: _Painter, world_R_cam: FloatArray,
                 world_t_cam: FloatArray, scenes: Sequence[FloatArray],
                 rng: np.random.Generator | None) -> None:
    out.fill(0.0)
    for world_p in scenes:
        cam_p = (world_p - world_t_cam) @ world_R_cam  # R^T (p - t), row-wise
        painter.points(out, cam_p, rng)
        painter.lines(out, cam_p, rng)
    noise = painter.cfg.noise
    if rng is None:
        return
    if noise.spurious_rate > 0:
        painter.spurious(out, rng)
    if noise.pixel_sigma > 0:
        b = painter.cfg.noise_block
        c, h, w = out.shape
        shape = (c, -(-h // b), -(-w // b)) if b > 1 else out.shape
        n = _NORMAL_TABLE[rng.integers(0, _NORMAL_TABLE.size, shape, dtype=np.uint16)]
        n *= np.float32(noise.pixel_sigma)
        if b > 1:  # one value per block of b x b pixels
            n = np.repeat(np.repeat(n, b, axis=1), b, axis=2)[:, :h, :w]
        out += n
        np.clip(out, 0.0, 1.0, out=out)


def _scenes(turbine_vec: ArrayLike, geometry: TurbineGeometry,
            distractors: Sequence[ArrayLike]) -> list[FloatArray]:
    scenes = [model_points(turbine_vec, geometry)[0]]
    scenes += [model_points(d, geometry)[0] for d in distractors]
    return scenes


def _check_rng(cfg: RenderConfig, rng: np.random.Generator | None) -> None:
    if cfg.noise.enabled and rng is None:
        raise ValueError("heat-map noise is enabled: pass an rng")


def render_heatmaps(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine_vec: ArrayLike,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    cfg: RenderConfig | None = None,
    rng: np.random.Generator | None = None,
    distractors: Sequence[ArrayLike] = (),
) -> F32Array:
    """Heat-maps (7, H, W) float32 in [0, 1] of one keyframe.

    Args:
        camera: intrinsics; H, W = its image size.
        world_T_cam: the keyframe's camera-to-world pose (a single pose, batch shape ()).
        turbine_vec: turbine parameters theta (7,) [m, rad].
        geometry: shape details beyond the paper's model.
        cfg: blob/ridge width and imperfections (default: sigma 2 px, no noise).
        rng: random source; needed only when ``cfg.noise`` is enabled.
        distractors: parameters (7,) of other turbines drawn into the same channels.
    """
    cfg = cfg or RenderConfig()
    _check_rng(cfg, rng)
    if world_T_cam.batch_shape != ():
        raise ValueError(f"expected one pose, got batch {world_T_cam.batch_shape}")
    out = np.zeros((NUM_CHANNELS, camera.height, camera.width), dtype=np.float32)
    _render_into(out, _Painter(camera, cfg), world_T_cam.rotation_matrix(),
                 world_T_cam.translation, _scenes(turbine_vec, geometry, distractors), rng)
    return out


def render_flight(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine_vec: ArrayLike,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    cfg: RenderConfig | None = None,
    rng: np.random.Generator | None = None,
    distractors: Sequence[ArrayLike] = (),
    progress: bool = True,
    out: F32Array | None = None,
) -> F32Array:
    """Heat-maps (N, 7, H, W) float32 of every keyframe of ``world_T_cam`` (N,).

    Each keyframe gets its own child generator of ``rng`` (``rng.spawn(N)``), so keyframe
    k's noise depends only on ``rng``'s state and k. ``out`` may be a preallocated array
    (e.g. a memory map) of the right shape; ``progress`` shows a tqdm bar. Arguments as in
    :func:`render_heatmaps`.
    """
    cfg = cfg or RenderConfig()
    _check_rng(cfg, rng)
    if len(world_T_cam.batch_shape) != 1:
        raise ValueError(f"expected a batch (N,) of poses, got {world_T_cam.batch_shape}")
    n = world_T_cam.batch_shape[0]
    shape = (n, NUM_CHANNELS, camera.height, camera.width)
    if out is None:
        out = np.empty(shape, dtype=np.float32)
    elif out.shape != shape or out.dtype != np.float32:
        raise ValueError(f"out must be float32 {shape}, got {out.dtype} {out.shape}")
    rngs: list[np.random.Generator | None] = (
        list(rng.spawn(n)) if (rng is not None and cfg.noise.enabled) else [None] * n)
    painter = _Painter(camera, cfg)
    scenes = _scenes(turbine_vec, geometry, distractors)
    R = world_T_cam.rotation_matrix()
    t = world_T_cam.translation
    for k in tqdm(range(n), desc="rendering heat-maps", unit="kf", disable=not progress):
        _render_into(out[k], painter, R[k], t[k], scenes, rngs[k])
    return out
