"""Fit configuration files (turbinefit.io.fit_config)."""

from __future__ import annotations

from pathlib import Path

import yaml

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
