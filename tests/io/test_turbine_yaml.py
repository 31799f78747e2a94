"""Turbine files (turbinefit.io.turbine_yaml): exact round trips, plain files, bad input
named by file and key."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from support import raises_input_error

from turbinefit.io import read_turbine_yaml, write_turbine_yaml
from turbinefit.turbine.model import TurbineParams


def test_turbine_round_trip_exact(tmp_path: Path) -> None:
    params = TurbineParams(1e-7, -3.0000000000000004, 80.1, 1.2345678901234567, 0.0,
                           -0.3, 40.7)
    path = tmp_path / "turbine.yaml"
    write_turbine_yaml(path, params, comment="fitted\nby test")
    assert read_turbine_yaml(path) == params
    text = path.read_text()
    assert text.startswith("# fitted\n# by test\n")
    assert yaml.safe_load(text) == params.to_dict()


TURBINE_TEXT = ("base_x: 1.0\nbase_y: 2.0\ntower_height: 80\nheading: 0.5\n"
                "nacelle_length: 4.0\nblade_rotation: 0.1\nblade_length: 40.0\n")


def test_turbine_read_plain_file(tmp_path: Path) -> None:
    path = tmp_path / "turbine.yaml"
    path.write_text("# a turbine\n" + TURBINE_TEXT.replace("heading: 0.5", "heading: 5e-1"))
    assert read_turbine_yaml(path) == TurbineParams(1.0, 2.0, 80.0, 0.5, 4.0, 0.1, 40.0)


@pytest.mark.parametrize(
    ("old", "new", "field", "message"),
    [
        ("base_y: 2.0\n", "", "base_y", "missing"),
        ("heading: 0.5\n", "heading: 0.5\nrotor_speed: 3\n", "rotor_speed", "unknown key"),
        ("heading: 0.5", "heading: north", "heading", "not a number"),
        ("heading: 0.5", "heading: [0.5]", "heading", "not a number"),
        ("heading: 0.5", "heading: .nan", "heading", "finite"),
        ("base_x: 1.0", "base_x: -.inf", "base_x", "finite"),
        ("tower_height: 80", "tower_height: 0", "tower_height", "> 0"),
        ("blade_length: 40.0", "blade_length: -40.0", "blade_length", "> 0"),
        ("nacelle_length: 4.0", "nacelle_length: -0.1", "nacelle_length", ">= 0"),
    ],
)
def test_turbine_bad_input_names_file_and_key(tmp_path: Path, old: str, new: str, field: str,
                                              message: str) -> None:
    path = tmp_path / "turbine.yaml"
    assert old in TURBINE_TEXT
    path.write_text(TURBINE_TEXT.replace(old, new))
    with raises_input_error(path, field=field) as info:
        read_turbine_yaml(path)
    assert message in str(info.value)


def test_turbine_duplicate_key_and_not_mapping(tmp_path: Path) -> None:
    path = tmp_path / "turbine.yaml"
    path.write_text(TURBINE_TEXT + "heading: 0.7\n")
    with raises_input_error(path, line=8):
        read_turbine_yaml(path)
    path.write_text("just text\n")
    with raises_input_error(path):
        read_turbine_yaml(path)


def test_write_turbine_rejects_out_of_range(tmp_path: Path) -> None:
    path = tmp_path / "turbine.yaml"
    with raises_input_error(path, field="blade_length"):
        write_turbine_yaml(path, TurbineParams(0, 0, 80, 0, 4, 0, -40))
    assert not path.exists()


def test_turbine_std_round_trip(tmp_path: Path) -> None:
    """A fitted file carries a std block; reading tolerates and checks it."""
    from turbinefit.io.turbine_yaml import read_turbine_std

    params = TurbineParams(1.5, -2.0, 87.6, 0.6, 5.0, 0.3, 63.0)
    std = {n: 0.1 * (i + 1) for i, n in enumerate(TurbineParams.NAMES)}
    std["heading"] = None
    path = tmp_path / "turbine.yaml"
    write_turbine_yaml(path, params, comment="fitted", std=std)
    assert read_turbine_yaml(path) == params
    assert read_turbine_std(path) == std
    write_turbine_yaml(path, params)
    assert read_turbine_std(path) is None


@pytest.mark.parametrize(("block", "field", "message"), [
    ("std: 3\n", "std", "mapping"),
    ("std:\n  rotor: 1.0\n", "std.rotor", "unknown key"),
    ("std:\n  tower_height: -1.0\n", "std.tower_height", ">= 0"),
    ("std:\n  tower_height: .inf\n", "std.tower_height", "finite"),
])
def test_turbine_std_bad(tmp_path: Path, block: str, field: str, message: str) -> None:
    path = tmp_path / "turbine.yaml"
    path.write_text(TURBINE_TEXT + block)
    with raises_input_error(path, field=field) as exc:
        read_turbine_yaml(path)
    assert message in str(exc.value)
