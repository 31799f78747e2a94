"""Array helpers of the image renderer: float32, channels-first colours and directions.

Colours and directions are (3, n) columns: numpy broadcasting over a trailing axis of length
3 is 10-20x slower than over a long one. The small matrix products avoid BLAS, whose threads
cost more than they save on such shapes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
IntArray = NDArray[np.intp]
#: A colour, RGB in [0, 1].
RGB = tuple[float, float, float]


def column(c: RGB | FloatArray | F32) -> F32:
    """A colour as a (3, 1) float32 column."""
    return np.asarray(c, dtype=np.float32).reshape(3, 1)


def lerp3(a: RGB | F32, b: RGB | F32, t: F32) -> F32:
    """(3, n) colours a + (b - a) t."""
    a_ = column(a)
    return a_ + (column(b) - a_) * t[None]


def blend(col: F32, target: F32, w: F32) -> F32:
    """(3, n) ``col`` moved towards ``target`` ((3, 1) or (3, n)) by weights ``w`` (n,)."""
    return col + (target - col) * w[None]


def matmul3(M: FloatArray | F32, D: F32) -> F32:
    """``M @ D`` for a small (k, 3) matrix and (3, n) columns, without BLAS (whose threads
    cost more than they save on such shapes)."""
    M32 = np.asarray(M, dtype=np.float32)
    out = M32[:, 0, None] * D[0][None]
    out += M32[:, 1, None] * D[1][None]
    out += M32[:, 2, None] * D[2][None]
    return out


def dot3(v: FloatArray | F32, D: F32) -> F32:
    """``v @ D`` for a 3-vector and (3, n) columns, without BLAS."""
    return np.float32(v[0]) * D[0] + np.float32(v[1]) * D[1] + np.float32(v[2]) * D[2]


def take_cols(a: F32, idx: IntArray) -> F32:
    """Columns ``idx`` of a (k, N) array."""
    return np.take(a, idx, axis=1)


def put_cols(a: F32, idx: IntArray, v: F32) -> None:
    """``a[:, idx] = v`` for a (k, N) array (row by row: much faster)."""
    for k in range(a.shape[0]):
        a[k][idx] = v[k]


def smoothstep(e0: float, e1: float, x: F32) -> F32:
    t = np.clip((x - e0) * (1.0 / (e1 - e0)), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def smoothstep64(e0: float, e1: float, x: FloatArray) -> FloatArray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)
