"""Robust losses (turbinefit.costs.robust)."""

import numpy as np
import pytest

from turbinefit.costs.robust import RobustLoss


def test_robust_losses():
    s = np.linspace(0, 20, 201)
    for name in ("huber", "cauchy"):
        loss = RobustLoss(name, 2.0)
        rho, d = loss.evaluate(s)
        np.testing.assert_allclose(rho[:3], s[:3], rtol=0.03)  # ~quadratic near 0
        assert np.all(rho[-1] < s[-1])
        num = np.gradient(rho, s)
        np.testing.assert_allclose(d[1:-1], num[1:-1], atol=0.02)
    with pytest.raises(ValueError):
        RobustLoss("tukey")
