"""The edge term: the turbine's silhouette edges in the photo itself, at its own resolution.

The heat-maps are read at 320 px; the photo is often four times finer or more. The tower
and the blades are solids round the skeleton's lines whose cross-sections are centred on
them (:mod:`turbinefit.turbine.solid`: a round tapered tower, elliptic blade sections), so
in a photo each shows two sharp silhouette edges, one on either side of the projected
line and, to within perspective's asymmetry, equally far from it. As model-based trackers
do (RAPID, Harris 1992; Drummond and Cipolla 2002; ViSP's moving edges), each line sample
of the tower and the blades is searched for along the projected line's normal, here in
the photo's grey levels: the profile is sampled every half pixel of the photo
(bilinear), differentiated by a derivative of Gaussian, and the pair of gradient extrema
whose separation fits the part's width (from the solid's proportions at that depth),
strongest first, is the silhouette. The two edges may have the same sign: the lit side
of a white tower is brighter than the sky behind it while its shaded side is darker
(requiring opposite signs took the tower's midpoints from 0.13 to 0.23 map px off the
truth at 1280 px, ``benchmarks/bench_precision.py``). Their midpoint, to sub-pixel precision
(a parabola through each extremum), is the line's position in the photo: a
correspondence along the normal for the line sample, whitened by ``edge_sigma`` px of the
photo (the cost and Jacobians of :mod:`turbinefit.costs.correspondence`'s normal
residual).

The search is centred on the net's own correspondence for the sample (the line channel's
peak along the same normal) and reaches only a few map pixels past the expected
half-width: the net gives the basin, the edges give the precision. Where it finds no
such pair (no contrast, clutter, the other blade crossing, a part wider than the search),
the sample keeps only the net's evidence.

Written here rather than taken from a library: ViSP's moving-edge tracker needs its own
CAD model format and camera loop, and OpenCV has no 1-D edge search along given normals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Profile samples per photo pixel.
SUBSTEP = 2
#: Standard deviation of the derivative of Gaussian along the profile [photo px].
DOG_SIGMA = 1.0
#: Separations of the two edges within [1 / t, t] times the expected widths count.
WIDTH_TOLERANCE = 1.4
#: Extrema of each profile considered for the pair (the strongest).
PEAKS = 12
#: Least gradient of an edge [grey levels per photo px] (sensor noise is ~1-3 levels).
MIN_CONTRAST = 4.0


@dataclass(frozen=True)
class PhotoStack:
    """Grey-level photos of N keyframes for the edge term.

    Attributes:
        images: (N, H, W) uint8 grey levels, or float32 (N, H, W).
        scale: photo pixels per heat-map pixel (the photos are ``scale`` times the maps'
            size; pixel centres map as ``u_photo = (u_map + 0.5) scale - 0.5``).
    """

    images: NDArray[np.generic]
    scale: float

    def __post_init__(self) -> None:
        if self.images.ndim != 3:
            raise ValueError(f"photos must be (N, H, W), got shape {self.images.shape}")
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"photo scale must be positive, got {self.scale}")

    def __len__(self) -> int:
        return int(self.images.shape[0])

    def take(self, keyframes: NDArray[np.int_]) -> PhotoStack:
        return PhotoStack(self.images[np.asarray(keyframes, dtype=np.int64)], self.scale)


def _bilinear(images: NDArray[np.generic], kf: NDArray[np.int_], u: FloatArray,
              v: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Grey levels of ``images[kf]`` at (u, v) (broadcast), and whether each is inside."""
    _, H, W = images.shape
    inside = (u >= 0) & (v >= 0) & (u <= W - 1) & (v <= H - 1)
    uc = np.clip(u, 0, W - 1.001)
    vc = np.clip(v, 0, H - 1.001)
    x0 = np.floor(uc).astype(np.int64)
    y0 = np.floor(vc).astype(np.int64)
    fx = uc - x0
    fy = vc - y0
    flat = images.reshape(-1)
    base = kf * (H * W) + y0 * W + x0
    a = flat[base].astype(np.float64)
    b = flat[base + 1].astype(np.float64)
    c = flat[base + W].astype(np.float64)
    d = flat[base + W + 1].astype(np.float64)
    return (a * (1 - fx) * (1 - fy) + b * fx * (1 - fy) + c * (1 - fx) * fy
            + d * fx * fy), inside


def _extremum(g: FloatArray, i: NDArray[np.int_]) -> FloatArray:
    """Sub-sample position of the extremum of rows of ``g`` at indices ``i`` (parabola)."""
    rows = np.arange(g.shape[0])
    n = g.shape[1]
    ii = np.clip(i, 1, n - 2)
    a, b, c = g[rows, ii - 1], g[rows, ii], g[rows, ii + 1]
    den = a - 2 * b + c
    off = np.where(np.abs(den) > 1e-12, 0.5 * (a - c) / np.where(den == 0, 1, den), 0.0)
    return ii + np.clip(off, -0.5, 0.5)


def find_edge_correspondences(
    photos: PhotoStack, keyframes: NDArray[np.int_], centre: FloatArray, normal: FloatArray,
    usable: NDArray[np.bool_], half_width: FloatArray, reach: float,
    width_tolerance: float = WIDTH_TOLERANCE, min_contrast: float = MIN_CONTRAST,
    chunk: int = 1024,
) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """The silhouettes' midpoints along the normals (module docstring), and the
    separations of their two edges (the part's apparent width: the width term of
    :mod:`turbinefit.costs.silhouette_width`).

    Args:
        photos: the flight's grey photos (indexed by ``keyframes``).
        keyframes: (N,) the photo of each row.
        centre: (N, M, 2) where to centre each search [map px] (the net's correspondence).
        normal: (N, M, 2) unit search directions (the projected line's normals).
        usable: (N, M) which samples to search.
        half_width: (N, M, 2) least and greatest expected half-width of the part along
            the normal [map px].
        reach: how far the midpoint may lie from ``centre`` [map px].
        width_tolerance: separations within ``[2 lo / t, 2 hi t]`` count.
        min_contrast: least gradient magnitude of each edge [grey levels per photo px].
        chunk: samples searched at once (memory: chunk x profile length).

    Returns:
        ``(target, found, separation)``: (N, M, 2) midpoints [map px], (N, M) where one
        was found, and (N, M) the separations of the two edges [map px] (0 where none was
        found).
    """
    N, M = usable.shape
    target = np.zeros((N, M, 2))
    found = np.zeros((N, M), dtype=bool)
    separation = np.zeros((N, M))
    sel = (usable & np.all(np.isfinite(centre), axis=-1) & np.all(np.isfinite(half_width), -1)
           & (half_width[..., 0] > 0))
    n_idx, m_idx = np.nonzero(sel)
    kf = np.asarray(keyframes, dtype=np.int64)
    for a in range(0, n_idx.size, chunk):
        nn, mm = n_idx[a:a + chunk], m_idx[a:a + chunk]
        tgt, has, sep = _search(photos, kf[nn], centre[nn, mm], normal[nn, mm],
                                half_width[nn, mm], reach, width_tolerance, min_contrast)
        target[nn[has], mm[has]] = tgt[has]
        found[nn[has], mm[has]] = True
        separation[nn[has], mm[has]] = sep[has]
    return target, found, separation


def _search(photos: PhotoStack, kf: NDArray[np.int_], centre: FloatArray, nrm: FloatArray,
            half_width: FloatArray, reach: float, width_tolerance: float,
            min_contrast: float) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """:func:`find_edge_correspondences` on K samples (K,): targets (K, 2) [map px],
    whether each was found, and the edges' separations (K,) [map px]."""
    s = photos.scale
    c = (centre + 0.5) * s - 0.5  # photo px
    lo = 2 * half_width[:, 0] * s / width_tolerance
    hi = 2 * half_width[:, 1] * s * width_tolerance
    half_len = 0.5 * float(np.max(hi)) + reach * s + 3 * DOG_SIGMA
    t = np.arange(-half_len, half_len + 1e-9, 1.0 / SUBSTEP)  # photo px along the normal
    u = c[:, None, 0] + t[None] * nrm[:, None, 0]
    v = c[:, None, 1] + t[None] * nrm[:, None, 1]
    prof, inside = _bilinear(photos.images, kf[:, None], u, v)
    from scipy.ndimage import gaussian_filter1d  # only with the edge term: fit loads no scipy

    g = gaussian_filter1d(prof, DOG_SIGMA * SUBSTEP, axis=-1, order=1) * SUBSTEP
    ag = np.abs(g)
    pad = int(np.ceil(3 * DOG_SIGMA * SUBSTEP))
    ok = inside & (ag >= min_contrast)
    ok[:, :pad] = False
    ok[:, -pad:] = False
    peak = np.zeros_like(ok)
    peak[:, 1:-1] = (ag[:, 1:-1] >= ag[:, :-2]) & (ag[:, 1:-1] > ag[:, 2:])
    peak &= ok
    # the strongest pair (of either sign) among the PEAKS strongest extrema whose
    # separation fits the width and whose midpoint is within reach of the centre
    K, T = g.shape
    P = min(PEAKS, T)
    cand = np.argsort(-np.where(peak, ag, -1.0), axis=1)[:, :P]  # (K, P) profile indices
    rows = np.arange(K)[:, None]
    cg = g[rows, cand]
    cok = peak[rows, cand]
    ct = t[cand]
    sep = ct[:, :, None] - ct[:, None, :]  # [j, i]: t_j - t_i
    mid = 0.5 * (ct[:, :, None] + ct[:, None, :])
    pair = (cok[:, :, None] & cok[:, None, :]
            & (sep > lo[:, None, None]) & (sep < hi[:, None, None])
            & (np.abs(mid) <= reach * s))
    cag = np.abs(cg)
    strength = np.where(pair, np.minimum(cag[:, :, None], cag[:, None, :]), -1.0)
    flat = strength.reshape(K, -1).argmax(axis=1)
    has = strength.reshape(K, -1)[np.arange(K), flat] > 0
    j = cand[np.arange(K), flat // P]
    i = cand[np.arange(K), flat % P]
    grid = np.arange(T)
    ti = np.interp(_extremum(ag, i), grid, t)
    tj = np.interp(_extremum(ag, j), grid, t)
    tgt = c + (0.5 * (ti + tj))[:, None] * nrm
    return (tgt + 0.5) / s - 0.5, has, np.abs(tj - ti) / s
