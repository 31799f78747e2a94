"""TUM trajectory files: one pose per line.

Format (TUM RGB-D benchmark)::

    # comment lines and blank lines are ignored; "#" also starts a trailing comment
    timestamp tx ty tz qx qy qz qw

* ``timestamp``: seconds (any origin), strictly increasing down the file.
* ``tx ty tz``: translation [m]; ``qx qy qz qw``: unit quaternion, **xyzw order in the
  file**. Together they are the pose ``a_T_b`` mapping frame-b points into frame a; for
  keyframes, odometry and ground truth that is the camera-to-world pose ``world_T_cam``
  (camera frame: OpenCV, x right, y down, z forward).
* Columns are separated by any whitespace.

Inside turbinefit quaternions are wxyz (see :mod:`turbinefit.geometry.se3`); this module
is the only place that converts. On reading, a quaternion whose norm is within 1e-3 of 1
is normalised silently (and flipped to w >= 0); anything further off, zero, non-numeric or
non-finite is an :class:`~turbinefit.errors.InputError` naming the file and line, as are
a wrong number of columns, non-increasing timestamps, a file without poses, and absurd
magnitudes: a translation beyond 1e8 m or a timestamp beyond 1e11 s
(:mod:`turbinefit.io.limits`). Files above 256 MiB are refused before reading.

On writing, timestamps are printed ``%.6f`` (microseconds), translations ``%.9f``
(nanometres) and quaternions ``%.12f``, so a read-back reproduces translations to 5e-10 m
and quaternions to 5e-13, and timestamps to 5e-7 s (exactly for timestamps that already
have at most six decimals). Timestamps that collapse to the same ``%.6f`` text are
refused.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.errors import InputError, plain_number
from turbinefit.geometry.se3 import SE3
from turbinefit.io.atomic import StrPath, read_text, write_text_atomic
from turbinefit.io.limits import MAX_COORDINATE_M, MAX_TIMESTAMP_S

FloatArray = NDArray[np.float64]

#: Largest |norm - 1| of a quaternion that is normalised silently.
QUAT_NORM_TOLERANCE = 1e-3
#: Header line written at the top of every TUM file.
TUM_HEADER = "# timestamp tx ty tz qx qy qz qw"

_COLUMNS = 8


@dataclass(frozen=True)
class TumTrajectory:
    """A TUM file's contents with the line number of each pose (for error messages)."""

    timestamps: FloatArray
    poses: SE3
    lines: NDArray[np.int_]


def _parse_float(token: str) -> float:
    if "_" in token:  # Python's float() accepts "1_000"; a TUM file should not
        raise ValueError(token)
    return float(token)


def read_tum_lines(path: StrPath) -> TumTrajectory:
    """Like :func:`read_tum`, also returning the line number of every pose."""
    text = read_text(path)
    stamps: list[float] = []
    rows: list[tuple[float, ...]] = []
    lines: list[int] = []
    prev_t = -math.inf
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        if len(tokens) != _COLUMNS:
            raise InputError(f"expected {_COLUMNS} columns (timestamp tx ty tz qx qy qz qw), "
                             f"got {len(tokens)}", path=path, line=lineno)
        values = []
        for token in tokens:
            try:
                v = _parse_float(token)
            except ValueError:
                raise InputError(f"not a number: {token!r}", path=path, line=lineno) from None
            if not math.isfinite(v):
                raise InputError(f"non-finite value {token!r}", path=path, line=lineno)
            values.append(v)
        t, tx, ty, tz, qx, qy, qz, qw = values
        if not abs(t) <= MAX_TIMESTAMP_S:
            raise InputError(f"timestamp {tokens[0]} is beyond {MAX_TIMESTAMP_S:g} s (seconds "
                             "expected)", path=path, line=lineno)
        for axis, token, v in zip("xyz", tokens[1:4], (tx, ty, tz), strict=True):
            if not abs(v) <= MAX_COORDINATE_M:
                raise InputError(f"translation t{axis} = {token} m is beyond "
                                 f"{MAX_COORDINATE_M:g} m (metres expected)", path=path,
                                 line=lineno)
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if norm < 1e-12:
            raise InputError("quaternion has zero norm", path=path, line=lineno)
        if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
            raise InputError(f"quaternion (qx qy qz qw) has norm {norm:.6g}, expected 1 "
                             f"(tolerance {QUAT_NORM_TOLERANCE:g})", path=path, line=lineno)
        if not t > prev_t:
            raise InputError(f"timestamp {tokens[0]} is not after the previous one "
                             f"({plain_number(stamps[-1])}, line {lines[-1]})", path=path,
                             line=lineno)
        prev_t = t
        stamps.append(t)
        # file xyzw -> package wxyz
        s = 1.0 / norm if qw >= 0.0 else -1.0 / norm
        rows.append((qw * s, qx * s, qy * s, qz * s, tx, ty, tz))
        lines.append(lineno)
    if not rows:
        raise InputError("no poses in file (empty or only comments)", path=path)
    return TumTrajectory(np.array(stamps, dtype=np.float64), SE3(np.array(rows, dtype=np.float64)),
                         np.array(lines, dtype=np.int_))


def read_tum(path: StrPath) -> tuple[FloatArray, SE3]:
    """Read a TUM trajectory file (see the module docstring).

    Returns:
        timestamps: (N,) seconds, strictly increasing.
        poses: (N,) ``SE3`` (wxyz quaternions, unit, w >= 0; metres).

    Raises:
        InputError: naming the file and line, for any malformed content.
    """
    traj = read_tum_lines(path)
    return traj.timestamps, traj.poses


def format_timestamps(timestamps: ArrayLike, path: StrPath | None = None) -> list[str]:
    """The ``%.6f`` texts of timestamps, checked finite and strictly increasing as texts.

    ``path`` only names the destination in error messages.
    """
    t = np.asarray(timestamps, dtype=np.float64)
    if t.ndim != 1 or t.size == 0:
        raise InputError(f"need a non-empty 1-D array of timestamps, got shape {t.shape}",
                         path=path, field="timestamps")
    if not np.all(np.isfinite(t)):
        raise InputError("timestamps must be finite", path=path, field="timestamps")
    texts = [f"{x:.6f}" for x in t.tolist()]
    parsed = np.array([float(s) for s in texts])
    bad = np.nonzero(np.diff(parsed) <= 0.0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(f"timestamp {k} ({plain_number(t[k])}) is not after timestamp {k - 1} "
                         f"({plain_number(t[k - 1])}) at microsecond resolution", path=path,
                         field="timestamps")
    return texts


def format_tum(timestamps: ArrayLike, poses: SE3, path: StrPath | None = None,
               comment: str | None = None) -> str:
    """The text of a TUM file (what :func:`write_tum` writes); ``path`` names errors."""
    texts = format_timestamps(timestamps, path)
    v = np.asarray(poses.wxyz_xyz, dtype=np.float64)
    if v.shape != (len(texts), 7):
        raise InputError(f"{len(texts)} timestamps but poses of shape {v.shape[:-1]}",
                         path=path, field="poses")
    if not np.all(np.isfinite(v)):
        k = int(np.nonzero(~np.isfinite(v).all(axis=1))[0][0])
        raise InputError(f"pose {k} is not finite", path=path, field="poses")
    norms = np.linalg.norm(v[:, :4], axis=1)
    off = np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE
    if np.any(off):
        k = int(np.nonzero(off)[0][0])
        raise InputError(f"pose {k} has a quaternion of norm {norms[k]:.6g}, expected 1",
                         path=path, field="poses")
    q = v[:, :4] / norms[:, None]
    q = np.where(q[:, :1] < 0.0, -q, q)
    out = [TUM_HEADER]
    if comment:
        out[:0] = ["# " + c for c in comment.splitlines()]
    for ts, (w, x, y, z), (tx, ty, tz) in zip(texts, q.tolist(), v[:, 4:].tolist(), strict=True):
        out.append(f"{ts} {tx:.9f} {ty:.9f} {tz:.9f} {x:.12f} {y:.12f} {z:.12f} {w:.12f}")
    return "\n".join(out) + "\n"


def write_tum(path: StrPath, timestamps: ArrayLike, poses: SE3,
              comment: str | None = None) -> None:
    """Write a TUM trajectory file atomically (see the module docstring).

    Args:
        path: destination file (replaced if it exists).
        timestamps: (N,) seconds; must be strictly increasing at microsecond resolution.
        poses: (N,) ``SE3`` (wxyz inside the package; written as xyzw).
        comment: optional text written as ``#`` lines above the column header.

    Raises:
        InputError: naming ``path``, for non-finite or mismatched data or a failed write.
    """
    write_text_atomic(path, format_tum(timestamps, poses, path, comment))
