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


def test_pair_frame_auto_resolves_from_the_measurements():
    from turbinefit.solver.config import pair_frame_line, resolve_pair_frame

    auto = FitConfig()
    assert auto.pair_frame == "auto"
    assert resolve_pair_frame(auto, has_odometry=True).pair_frame == "estimated"
    assert resolve_pair_frame(auto, has_odometry=False).pair_frame == "measured"
    for frame in ("measured", "estimated"):
        cfg = FitConfig(pair_frame=frame)  # type: ignore[arg-type]
        assert resolve_pair_frame(cfg, True) == resolve_pair_frame(cfg, False) == cfg
    used = resolve_pair_frame(auto, True)
    assert pair_frame_line(auto, used) == (
        "pairwise frame: estimated (odometry.txt: body-frame odometry)")
    assert pair_frame_line(auto, resolve_pair_frame(auto, False)) == (
        "pairwise frame: measured (GPS/IMU keyframes)")
    assert pair_frame_line(used, used) == "pairwise frame: estimated (set in the options)"
