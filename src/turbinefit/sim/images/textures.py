"""Per-scene textures of the image renderer: periodic noise tiles (clouds, terrain colour,
fine detail, sea waves) and distant hill silhouettes, generated from a scene's seed and
cached per scene, with their bilinear lookup and the terrain-detail table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtr

from turbinefit.sim.images.arrays import F32, RGB, FloatArray, smoothstep64

if TYPE_CHECKING:
    from turbinefit.sim.images.scene import Scene

_TILE = 256  # noise tiles are _TILE x _TILE float32, periodic
#: Azimuth samples of a hill silhouette.
HILL_SAMPLES = 2048


@dataclass(frozen=True)
class Tile:
    """A periodic texture of ``size`` x ``size`` texels and ``channels`` channels, stored
    flat with one wrapped row and column, channels first: ``(channels, (size + 1) ** 2)``."""

    data: F32
    size: int

    @staticmethod
    def make(a: NDArray[np.floating]) -> Tile:
        """From an (S, S) or (S, S, C) periodic array."""
        s = a.shape[0]
        a3 = a[..., None] if a.ndim == 2 else a
        p = np.concatenate([a3, a3[:1]], axis=0)
        p = np.concatenate([p, p[:, :1]], axis=1)
        flat = np.ascontiguousarray(np.moveaxis(p, -1, 0).reshape(a3.shape[-1], -1),
                                    dtype=np.float32)
        return Tile(flat, s)


def sample_tile(tile: Tile, x: F32, y: F32, channels: tuple[int, ...] | None = None) -> F32:
    """Bilinear, periodic lookup at texel coordinates (x, y) (n,): (channels, n), of all
    channels or of the given ones."""
    s = tile.size
    fx = np.floor(x)
    fy = np.floor(y)
    ax = x - fx
    ay = y - fy
    m = s - 1
    i00 = (fx.astype(np.intp) & m) + (fy.astype(np.intp) & m) * (s + 1)
    i01 = i00 + 1
    i10 = i00 + (s + 1)
    i11 = i00 + (s + 2)
    chans = range(tile.data.shape[0]) if channels is None else channels
    out = np.empty((len(chans), x.size), dtype=np.float32)
    for c, ch in enumerate(chans):
        d = tile.data[ch]
        v00 = np.take(d, i00)
        top = v00 + ax * (np.take(d, i01) - v00)
        v10 = np.take(d, i10)
        bot = v10 + ax * (np.take(d, i11) - v10)
        out[c] = top + ay * (bot - top)
    return out


def _gauss_field(rng: np.random.Generator, beta: float, size: int = _TILE) -> FloatArray:
    """Periodic Gaussian noise (power spectrum ~ f^-beta), zero mean, unit variance."""
    fy = np.fft.fftfreq(size)[:, None]
    fx = np.fft.rfftfreq(size)[None, :]
    fr = np.sqrt(fx * fx + fy * fy)
    fr[0, 0] = 1.0
    spec = np.fft.rfft2(rng.standard_normal((size, size))) * fr ** (-0.5 * beta)
    spec[0, 0] = 0.0
    t = np.fft.irfft2(spec, s=(size, size))
    return (t - t.mean()) / max(float(t.std()), 1e-12)


def _blur(a: FloatArray, sigma: float) -> FloatArray:
    """Periodic Gaussian blur of a square tile (by FFT), ``sigma`` in texels."""
    s = a.shape[0]
    fy = np.fft.fftfreq(s)[:, None]
    fx = np.fft.rfftfreq(s)[None, :]
    g = np.exp(-2.0 * (math.pi * sigma) ** 2 * (fx * fx + fy * fy))
    return np.fft.irfft2(np.fft.rfft2(a) * g, s=a.shape)


def _zoom(g: FloatArray, k: int, shift: tuple[int, int]) -> FloatArray:
    """The periodic field ``g`` repeated k times across its own period (k x finer)."""
    s = g.shape[0]
    idx = (np.arange(s) * k) % s
    return np.roll(g[np.ix_(idx, idx)], shift, axis=(0, 1))


@dataclass(frozen=True)
class Assets:
    clouds: Tile  # noise, darkness, (density, darkness) x 2 blur levels; period cloud_scale
    macro: Tile  # RGB terrain colour (brightness for fields), period macro_period(scene)
    detail: Tile  # uniform noise in [0, 1], used at several small periods
    waves: Tile  # sea surface noise in [0, 1], period WAVE_PERIOD
    hills: tuple[F32, ...]  # silhouette height [m] per azimuth sample, per layer


WAVE_PERIOD = 48.0
#: Blur [texels] of the cloud tile's levels 0, 1, 2.
_CLOUD_MIP_SIGMAS = (0.0, 1.5, 5.0)


def macro_period(scene: Scene) -> float:
    return 1600.0 * scene.texture_scale


def _macro_colour(scene: Scene, large: FloatArray, mid: FloatArray) -> FloatArray:
    """Terrain colour (S, S, 3) from uniform noise at the macro scale and 8x finer."""
    p = [np.asarray(c) for c in scene.ground_colours]
    L, M = large[..., None], mid[..., None]
    kind = scene.terrain
    if kind == "fields":
        return np.repeat((0.85 + 0.3 * L) * (0.9 + 0.2 * M), 3, axis=-1)
    if kind == "grass":
        col = p[0] + (p[1] - p[0]) * L
        col = col + (p[2] - col) * smoothstep64(0.6, 0.8, M)
        return col * (0.8 + 0.4 * M)
    if kind == "scrub":
        col = p[0] + (p[1] - p[0]) * M
        col = col + (p[4] - col) * smoothstep64(0.3, 0.15, L)
        col = col + (p[3] - col) * smoothstep64(0.8, 0.88, 0.5 * L + 0.5 * M)
        return col * (0.85 + 0.3 * L)
    if kind == "forest":
        col = p[0] + (p[1] - p[0]) * M
        col = col + (p[2] - col) * smoothstep64(0.25, 0.18, 0.7 * L + 0.3 * M)
        return col * (0.85 + 0.3 * M)
    if kind == "dry":
        col = p[0] + (p[1] - p[0]) * L
        col = col + (p[3] - col) * smoothstep64(0.75, 0.9, M) * 0.6
        return col * (0.85 + 0.3 * M)
    if kind == "snow":
        col = p[0] + (p[1] - p[0]) * (0.6 * M + 0.4 * L)
        return col + (p[2] - col) * (0.6 * smoothstep64(0.8, 0.92, 0.6 * L + 0.4 * M))
    return np.broadcast_to(np.asarray(scene.sea_colour), (*large.shape, 3)).copy()


@lru_cache(maxsize=16)
def scene_assets(scene: Scene) -> Assets:
    """Noise tiles and hill silhouettes of a scene (deterministic from its seed)."""
    rng = np.random.default_rng(scene.seed)
    g_cloud = _gauss_field(rng, 3.0)
    g_wisp = _gauss_field(rng, 2.2)
    n = ndtr((0.9 * g_cloud + 0.35 * _zoom(g_wisp, 2, (17, 91))) / math.hypot(0.9, 0.35))
    thr = 1.0 - scene.cloud_cover
    dens = smoothstep64(thr - 0.08, thr + 0.1, n)
    # shading (thick cloud is darker underneath) follows a smoothed field: no mottling
    dark = smoothstep64(thr - 0.05, thr + 0.5, _blur(n, 2.5))
    # three blur levels (a small mip pyramid): far clouds are looked up blurred, not aliased
    levels = [n, dark]  # level 0: raw noise, thresholded per pixel after interpolation
    for sigma in _CLOUD_MIP_SIGMAS[1:]:
        levels += [_blur(dens, sigma), _blur(dark, sigma)]
    clouds = Tile.make(np.stack(levels, axis=-1))
    g_terr = _gauss_field(rng, 2.2)
    large = ndtr(g_terr)
    mid = ndtr(_zoom(g_terr, 8, (101, 37)))
    macro = Tile.make(_macro_colour(scene, large, mid))
    g_det = _gauss_field(rng, 1.4)
    detail = Tile.make(ndtr(g_det))
    waves = Tile.make(ndtr(0.8 * g_det + 0.6 * _zoom(g_det, 6, (5, 77))))
    hills = []
    k = np.arange(1, 65)
    az = np.linspace(-math.pi, math.pi, HILL_SAMPLES, endpoint=False)
    for _, base, amp, rough, *_c in scene.hills:
        a = rng.standard_normal(64) * k ** (-rough)
        ph = rng.uniform(0.0, 2 * math.pi, 64)
        prof = (a[:, None] * np.cos(k[:, None] * az[None] + ph[:, None])).sum(0)
        prof = (prof - prof.min()) / max(float(np.ptp(prof)), 1e-9)
        ridge = 1.0 - np.abs(2.0 * prof - 1.0)  # sharpen into ridges a little
        prof = 0.7 * prof + 0.3 * ridge
        hills.append(np.append(base + amp * prof, base + amp * prof[0]).astype(np.float32))
    return Assets(clouds, macro, detail, waves, tuple(hills))


#: Per-kind fine-detail modulation: (period [m], threshold lo, hi, RGB strength); the
#: modulation is ``1 + strength * (smoothstep(lo, hi, n) - mean)``, zero-mean over the
#: uniform noise n, so far away (where it fades out) the average colour is unchanged.
DETAIL: dict[str, tuple[float, float, float, RGB]] = {
    "fields": (30.0, 0.0, 1.0, (0.25, 0.25, 0.25)),
    "grass": (30.0, 0.0, 1.0, (0.2, 0.18, 0.2)),
    "scrub": (25.0, 0.55, 0.7, (-0.6, -0.45, -0.6)),
    "forest": (10.0, 0.2, 0.8, (0.9, 0.8, 0.9)),
    "dry": (30.0, 0.72, 0.8, (-0.6, -0.45, -0.65)),
    "snow": (30.0, 0.0, 1.0, (0.08, 0.08, 0.06)),
    "offshore": (30.0, 0.0, 1.0, (0.0, 0.0, 0.0)),
}


def smooth_mean(lo: float, hi: float) -> float:
    """Mean of smoothstep(lo, hi, n) for n uniform in [0, 1]."""
    return (1.0 - hi) + 0.5 * (hi - lo)


def cell_hash(ix: NDArray[np.int32], iy: NDArray[np.int32], salt: int) -> F32:
    """Pseudo-random float32 in [0, 1) per integer cell."""
    h = (ix.astype(np.uint32) * np.uint32(374761393) + iy.astype(np.uint32) * np.uint32(668265263)
         + np.uint32(salt * 2246822519 % 2**32))
    h = (h ^ (h >> np.uint32(13))) * np.uint32(1274126177)
    h = h ^ (h >> np.uint32(16))
    return (h & np.uint32(0xFFFF)).astype(np.float32) * np.float32(1.0 / 65536.0)
