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


@pytest.mark.parametrize(("width", "scale"), [(160, 1.0), (320, 1.0), (640, 2.0), (1280, 4.0),
                                              (5280, 16.5)])
def test_pixel_settings_follow_the_maps_width(width, scale):
    from turbinefit.solver.config import PIXEL_FIELDS, resolve_pixel_scale

    cfg = FitConfig(pixel_sigma=2.0)
    used = resolve_pixel_scale(cfg, width)
    assert used.pixel_scale == scale
    for name in PIXEL_FIELDS:  # stated at 320 px, used in the maps' pixels
        assert used.px(name) == pytest.approx(getattr(cfg, name) * scale)
    assert used.px("corr_radius") == 20.0 * scale and used.px("pixel_sigma") == 2.0 * scale
    assert used.robust_scale == cfg.robust_scale  # whitened units: follows pixel_sigma
    # resolving is idempotent, and a scale that is set is kept whatever the maps
    assert resolve_pixel_scale(used, 320) == used
    fixed = FitConfig(pixel_scale=1.0)
    assert resolve_pixel_scale(fixed, width).px("line_search") == 20.0
    with pytest.raises(ValueError, match="not a pixel setting"):
        used.px("robust_scale")


@pytest.mark.parametrize("bad", [0.0, -1.0, float("inf"), True])
def test_pixel_scale_must_be_positive_or_unset(bad):
    with pytest.raises(ValueError, match="pixel_scale"):
        FitConfig(pixel_scale=bad)
