"""Fit configuration (turbinefit.solver.config): validation."""

import pytest

from turbinefit.solver import FitConfig


def test_fit_config_validation():
    with pytest.raises(ValueError, match="mode"):
        FitConfig(mode="everything")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="both be none"):
        FitConfig(points="none", lines="none")
    with pytest.raises(ValueError, match="pixel_sigma"):
        FitConfig(pixel_sigma=-1.0)
    with pytest.raises(ValueError, match="unknown fit option"):
        FitConfig.from_dict({"nonsense": 1})
    with pytest.raises(ValueError, match="samples_per_line"):
        FitConfig(samples_per_line=2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="pair_information"):
        FitConfig(pair_information=(float("nan"),) * 36)
    with pytest.raises(ValueError, match="pair_frame"):
        FitConfig(pair_frame="world")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="warmup_match_rounds"):
        FitConfig(warmup_match_rounds=-1)
    cfg = FitConfig(points="interp", robust="huber")
    assert FitConfig.from_dict(cfg.to_dict()) == cfg
