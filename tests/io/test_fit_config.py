"""Fit configuration files (turbinefit.io.fit_config)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from turbinefit.errors import InputError
from turbinefit.io.fit_config import read_fit_config


def test_load_fit_config_accepts_numbers_yaml_reads_as_text(tmp_path: Path) -> None:
    # YAML 1.1 (PyYAML) reads 1e-12 (no dot) as a string; a hand-written config has them
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("gradient_tolerance: 1e-12\nlambda_pair: 2\ngeometry: {shaft_tilt: 0.087, "
                   "hub_offset: 2}\n")
    loaded = read_fit_config(cfg)
    assert loaded.gradient_tolerance == 1e-12
    assert loaded.lambda_pair == 2.0
    assert (loaded.geometry.shaft_tilt, loaded.geometry.hub_offset) == (0.087, 2.0)
    assert isinstance(loaded.geometry.hub_offset, float)
    # and what fit writes reads back
    again = tmp_path / "again.yaml"
    again.write_text(yaml.safe_dump(loaded.to_dict(), sort_keys=False))
    assert read_fit_config(again) == loaded


def test_pixel_scale_round_trips_through_config_yaml(tmp_path: Path) -> None:
    """config.yaml records the resolved pixel scale; read back, it is the same config; an
    unset scale (auto) stays unset; a hand-written one may be numeric text; a bad one is
    one InputError naming the file."""
    from turbinefit.io.fit_config import format_fit_config
    from turbinefit.solver.config import FitConfig, resolve_pixel_scale

    for cfg in (resolve_pixel_scale(FitConfig(lines="corr"), 1280), FitConfig()):
        path = tmp_path / "config.yaml"
        path.write_text(format_fit_config(cfg))
        assert read_fit_config(path) == cfg
    assert yaml.safe_load(format_fit_config(resolve_pixel_scale(FitConfig(), 5280)))[
        "pixel_scale"] == 16.5
    path.write_text("pixel_scale: 4e0\n")
    assert read_fit_config(path).pixel_scale == 4.0
    path.write_text("pixel_scale: 0\n")
    with pytest.raises(InputError, match="pixel_scale"):
        read_fit_config(path)
