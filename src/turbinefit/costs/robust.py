"""Robust losses rho(s) of the squared residual norm s (Ceres' convention).

``cost = 1/2 rho(s)``. The solver scales a residual block and its Jacobian by
``sqrt(rho'(s))`` (Ceres' corrector with alpha = 0), which gives the exact gradient
``rho'(s) J^T r`` and a Gauss-Newton Hessian ``rho'(s) J^T J``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
LossName = Literal["none", "huber", "cauchy"]


@dataclass(frozen=True)
class RobustLoss:
    """A robust loss with scale ``scale`` (in units of the whitened residual)."""

    name: LossName = "none"
    scale: float = 1.0

    def __post_init__(self) -> None:
        if self.name not in ("none", "huber", "cauchy"):
            raise ValueError(f"unknown robust loss {self.name!r} (none, huber, cauchy)")
        if not self.scale > 0:
            raise ValueError(f"robust loss scale must be positive, got {self.scale}")

    def evaluate(self, s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``rho(s)`` and ``rho'(s)`` for squared norms ``s >= 0``."""
        c2 = self.scale * self.scale
        if self.name == "huber":
            inside = s <= c2
            root = np.sqrt(np.maximum(s, 1e-300))
            rho = np.where(inside, s, 2.0 * self.scale * root - c2)
            d = np.where(inside, 1.0, self.scale / root)
            return rho, d
        if self.name == "cauchy":
            return c2 * np.log1p(s / c2), 1.0 / (1.0 + s / c2)
        return s, np.ones_like(s)
