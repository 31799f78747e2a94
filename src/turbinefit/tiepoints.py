"""Tie points between consecutive photos: the relative motion they measure, for the
tie-point term of the fit and the tracker (:mod:`turbinefit.costs.relative_motion`).

For each pair of consecutive photos: SIFT features (OpenCV) on the photos decoded at most
:attr:`TiePointOptions.max_width` wide, matched with Lowe's ratio test and checked both
ways, undistorted to normalised coordinates with the camera's intrinsics, and an
essential matrix by MAGSAC++ (OpenCV's ``USAC_MAGSAC``); :func:`cv2.recoverPose` picks
the rotation and translation direction that put the inliers in front of both cameras.
Nothing here is written by hand but the information matrix of each measurement: the
Gauss-Newton information of the inliers' Sampson errors (in pixels) w.r.t. the five
degrees of freedom (rotation, direction), with the pixel noise estimated from the
inliers' own residuals (no library returns it). A measurement is kept when at least
:attr:`TiePointOptions.min_inliers` tie points agree with it; photos without texture (sky
only, overexposed, blurred) give none, and the fit goes on on its other terms.

OpenCV (``opencv-python-headless``) is imported only when tie points are measured.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.relative_motion import RelativeMotions, perpendicular_basis
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import matrix_to_quat, so3_exp

FloatArray = NDArray[np.float64]
U8Image = NDArray[np.uint8]


@dataclass(frozen=True)
class TiePointOptions:
    """How tie points are found and when their relative motion counts.

    Attributes:
        max_width: photos are matched at most this wide [px] (larger ones are reduced).
        features: at most this many SIFT features per photo.
        ratio: Lowe's ratio test (best against second-best descriptor distance).
        ransac_px: inlier threshold of the essential matrix [px at ``max_width``].
        min_inliers: fewer inliers than this: no measurement.
        min_sigma_px: floor of the pixel noise estimated from the inliers [px].
        inflation: the information is divided by this: the essential matrices' errors
            on the simulator's renders are 12-16 times the standard deviations the
            inliers' Sampson errors give (squared Mahalanobis norms of 5 x 140-265 at 320
            and 1280 px, ``benchmarks/bench_precision.py``): the tie points' errors are
            not independent (far ground near the horizon, features on one texture,
            RANSAC's choice of inliers).
    """

    max_width: int = 1280
    features: int = 4000
    ratio: float = 0.8
    ransac_px: float = 1.0
    min_inliers: int = 30
    min_sigma_px: float = 0.3
    inflation: float = 250.0


@dataclass(frozen=True)
class Features:
    """A photo's tie-point features: (n, 2) normalised image coordinates (undistorted)
    and their (n, 128) SIFT descriptors."""

    xy: FloatArray
    descriptors: NDArray[np.float32]


def _cv2() -> Any:
    import cv2

    return cv2


def photo_features(image: U8Image, camera: PinholeCamera,
                   options: TiePointOptions = TiePointOptions()) -> Features:
    """SIFT features of ``image`` (H, W[, 3]) uint8 taken with ``camera`` (at the image's
    size), undistorted to normalised coordinates."""
    cv2 = _cv2()
    gray = image if image.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(image),
                                                      cv2.COLOR_RGB2GRAY)
    sift = cv2.SIFT_create(nfeatures=options.features, contrastThreshold=0.01)
    kps, desc = sift.detectAndCompute(gray, None)
    if desc is None or not kps:
        return Features(np.zeros((0, 2)), np.zeros((0, 128), dtype=np.float32))
    uv = np.array([k.pt for k in kps], dtype=np.float64)
    dist = np.asarray(camera.distortion, dtype=np.float64)
    xy = cv2.undistortPoints(uv.reshape(-1, 1, 2), camera.K, dist).reshape(-1, 2)
    return Features(np.asarray(xy, dtype=np.float64), desc)


def _matches(a: Features, b: Features, ratio: float) -> NDArray[np.int64]:
    """(m, 2) indices of mutual ratio-test matches between ``a`` and ``b``."""
    if len(a.xy) < 2 or len(b.xy) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    cv2 = _cv2()
    bf = cv2.BFMatcher(cv2.NORM_L2)

    def one_way(p: Features, q: Features) -> dict[int, int]:
        out = {}
        for pair in bf.knnMatch(p.descriptors, q.descriptors, k=2):
            if len(pair) == 2 and pair[0].distance < ratio * pair[1].distance:
                out[pair[0].queryIdx] = pair[0].trainIdx
        return out

    ab, ba = one_way(a, b), one_way(b, a)
    pairs = [(i, j) for i, j in ab.items() if ba.get(j) == i]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def _sampson(x1: FloatArray, x2: FloatArray, R: FloatArray, d: FloatArray) -> FloatArray:
    """Sampson errors (n,) [normalised units] of ``x2^T E x1 = 0`` with ``E = [t]x R``,
    for camera 2 at direction ``d`` from camera 1 (in 1's frame) and rotation ``R`` of 2
    in 1 (``X_1 = R X_2 + c``, so ``X_2 = R^T X_1 - R^T c``)."""
    Rt = R.T
    t = -Rt @ d
    E = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]]) @ Rt
    h1 = np.c_[x1, np.ones(len(x1))]
    h2 = np.c_[x2, np.ones(len(x2))]
    Ex1 = h1 @ E.T
    Etx2 = h2 @ E
    num = np.sum(h2 * Ex1, axis=1)
    den = Ex1[:, 0] ** 2 + Ex1[:, 1] ** 2 + Etx2[:, 0] ** 2 + Etx2[:, 1] ** 2
    return num / np.sqrt(np.maximum(den, 1e-300))


def _perturbed(R: FloatArray, d: FloatArray, B: FloatArray, step: FloatArray
               ) -> tuple[FloatArray, FloatArray]:
    """(R, d) moved by ``step`` (5,): rotation ``R Exp(step[:3])``, direction
    ``normalise(d + B step[3:])``."""
    da = d + B @ step[3:]
    return R @ so3_exp(step[:3]), da / np.linalg.norm(da)


def _sampson_jacobian(x1: FloatArray, x2: FloatArray, R: FloatArray, d: FloatArray,
                      focal: float) -> tuple[FloatArray, FloatArray]:
    """Sampson errors (n,) [px] and their forward-difference Jacobian (n, 5) w.r.t. the
    five degrees of freedom of :func:`_perturbed`."""
    B = perpendicular_basis(d[None])[0]
    r0 = _sampson(x1, x2, R, d) * focal
    J = np.empty((len(r0), 5))
    h = 1e-7
    for a in range(5):
        step = np.zeros(5)
        step[a] = h
        J[:, a] = (_sampson(x1, x2, *_perturbed(R, d, B, step)) * focal - r0) / h
    return r0, J


def _refine(x1: FloatArray, x2: FloatArray, R: FloatArray, d: FloatArray, focal: float,
            scale_px: float, iterations: int = 10) -> tuple[FloatArray, FloatArray]:
    """(R, d) minimising the inliers' Sampson errors under a Cauchy loss of scale
    ``scale_px`` (Gauss-Newton with iteratively reweighted least squares): MAGSAC++'s
    model comes from minimal samples and a local optimisation on a subset, not from the
    maximum-likelihood fit of all the inliers that the information describes."""
    for _ in range(iterations):
        r, J = _sampson_jacobian(x1, x2, R, d, focal)
        w = 1.0 / (1.0 + (r / scale_px) ** 2)
        H = J.T @ (w[:, None] * J)
        g = J.T @ (w * r)
        try:
            step = -np.linalg.solve(H + 1e-9 * np.trace(H) * np.eye(5), g)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)):
            break
        R, d = _perturbed(R, d, perpendicular_basis(d[None])[0], step)
        if float(np.linalg.norm(step)) < 1e-10:
            break
    return R, d


def _information(x1: FloatArray, x2: FloatArray, R: FloatArray, d: FloatArray, focal: float,
                 options: TiePointOptions) -> FloatArray | None:
    """The (5, 5) information of (rotation, direction) from the inliers' Sampson errors,
    or None if it is not positive definite."""
    r0, J = _sampson_jacobian(x1, x2, R, d, focal)
    n = len(r0)
    sigma2 = max(float(np.sum(r0 * r0)) / max(n - 5, 1), options.min_sigma_px ** 2)
    info = J.T @ J / (sigma2 * options.inflation)
    info = 0.5 * (info + info.T)
    if not np.all(np.isfinite(info)) or np.linalg.eigvalsh(info)[0] <= 0:
        return None
    return info


@dataclass(frozen=True)
class Motion:
    """One measured relative motion (see :class:`RelativeMotions`), or None fields."""

    i_q_j: FloatArray
    i_dir_j: FloatArray
    sqrt_info: FloatArray
    inliers: int


def relative_motion(a: Features, b: Features, camera: PinholeCamera,
                    options: TiePointOptions = TiePointOptions()) -> Motion | None:
    """The motion from the photo of ``a`` to that of ``b`` (``camera``: the photos'
    intrinsics at the size the features were found at), or None when too few tie points
    agree."""
    m = _matches(a, b, options.ratio)
    if len(m) < max(options.min_inliers, 8):
        return None
    cv2 = _cv2()
    x1 = a.xy[m[:, 0]]
    x2 = b.xy[m[:, 1]]
    focal = 0.5 * (camera.fx + camera.fy)
    try:
        E, mask = cv2.findEssentialMat(x1, x2, np.eye(3), cv2.USAC_MAGSAC, 0.999,
                                       options.ransac_px / focal)
        if E is None or E.shape != (3, 3) or mask is None:
            return None
        _, R, t, mask = cv2.recoverPose(E, x1, x2, np.eye(3), mask=mask.copy())
    except cv2.error:  # degenerate sets (e.g. all points on a line)
        return None
    inl = mask.ravel() > 0
    if int(inl.sum()) < options.min_inliers:
        return None
    # cv2: X_b = R X_a + t  ->  rotation of b in a: R^T, centre of b in a: -R^T t
    i_R_j = R.T
    d = (-R.T @ t).ravel()
    norm = float(np.linalg.norm(d))
    if not math.isfinite(norm) or norm == 0:
        return None
    d /= norm
    i_R_j, d = _refine(x1[inl], x2[inl], i_R_j, d, focal, options.ransac_px)
    r = np.abs(_sampson(x1, x2, i_R_j, d)) * focal
    inl = r < options.ransac_px
    if int(inl.sum()) < options.min_inliers:
        return None
    info = _information(x1[inl], x2[inl], i_R_j, d, focal, options)
    if info is None:
        return None
    L = np.asarray(np.linalg.cholesky(info).T, dtype=np.float64)
    return Motion(matrix_to_quat(i_R_j), d, L, int(inl.sum()))


def stack_motions(motions: list[Motion | None]) -> RelativeMotions:
    """:class:`RelativeMotions` of one entry per element (None: no measurement)."""
    rm = RelativeMotions.none(len(motions))
    for k, m in enumerate(motions):
        if m is not None:
            rm.i_q_j[k] = m.i_q_j
            rm.i_dir_j[k] = m.i_dir_j
            rm.sqrt_info[k] = m.sqrt_info
            rm.valid[k] = True
            rm.inliers[k] = m.inliers
    return rm


class MotionMeter:
    """Tie points photo by photo (the tracker): :meth:`add` takes each photo in turn and
    returns the motion from the previous one (None for the first, or when none is
    measured)."""

    def __init__(self, camera: PinholeCamera, options: TiePointOptions = TiePointOptions()
                 ) -> None:
        self.camera = camera
        self.options = options
        self._prev: Features | None = None

    def add(self, image: U8Image) -> Motion | None:
        f = photo_features(image, self.camera, self.options)
        prev, self._prev = self._prev, f
        return None if prev is None else relative_motion(prev, f, self.camera, self.options)


def measure_motions(read: Callable[[int], U8Image], n: int, camera: PinholeCamera,
                    options: TiePointOptions = TiePointOptions()) -> RelativeMotions:
    """The motions of ``n`` photos, ``read(k)`` giving photo k at ``camera``'s size."""
    meter = MotionMeter(camera, options)
    return stack_motions([meter.add(read(k)) for k in range(n)])
