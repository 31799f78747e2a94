"""``turbinefit init``: turbine.yaml from the images (printed or --out), its table, priors,
bad input (one line, exit 2, nothing written); ``fit`` and ``track`` without turbine.yaml
run it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from turbinefit.cli import main
from turbinefit.io import read_turbine_yaml
from turbinefit.io.turbine_yaml import read_turbine_std
from turbinefit.turbine.model import model_point_error


def test_init_prints_turbine_yaml_close_to_the_truth(sim_flight_dir: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["init", str(sim_flight_dir)]) == 0
    out, err = capsys.readouterr()
    (tmp_path / "t.yaml").write_text(out)
    est = read_turbine_yaml(tmp_path / "t.yaml")
    truth = read_turbine_yaml(sim_flight_dir / "turbine_groundtruth.yaml")
    assert model_point_error(est, truth) < 2.0
    assert set(read_turbine_std(tmp_path / "t.yaml") or {}) == set(truth.NAMES)
    assert "parameter" in err and "heading" in err  # the table, on stderr


def test_init_out_writes_once_and_refuses_inputs(flight_copy: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    (flight_copy / "turbine.yaml").unlink()
    out = flight_copy / "turbine.yaml"
    assert main(["init", str(flight_copy), "--out", str(out), "--type", "nrel-5mw"]) == 0
    assert "wrote" in capsys.readouterr().out
    before = out.read_text()
    assert main(["init", str(flight_copy), "--out", str(out)]) == 2
    assert "exists; use --overwrite" in capsys.readouterr().err
    assert main(["init", str(flight_copy), "--out", str(flight_copy / "keyframes.txt")]) == 2
    assert "input of the flight" in capsys.readouterr().err
    assert out.read_text() == before


def test_init_with_a_far_near_names_the_turbine(sim_flight_dir: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "t.yaml"
    assert main(["init", str(sim_flight_dir), "--near", "500,500", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot determine" in err[0], err
    assert not out.exists()


def test_init_near_wgs84_needs_georef(sim_flight_dir: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["init", str(sim_flight_dir), "--near-wgs84", "51.5,-2.6"]) == 2
    assert "georef.yaml" in capsys.readouterr().err


def test_init_without_tips_needs_a_type(flight_copy: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    for p in (flight_copy / "heatmaps").glob("*.npy"):
        m = np.load(p)
        m[3] = 0.0
        np.save(p, m)
    assert main(["init", str(flight_copy)]) == 2
    err = capsys.readouterr().err
    assert "cannot determine blade_length" in err and "--type" in err
    assert main(["init", str(flight_copy), "--type", "nrel-5mw", "--quiet"]) == 2
    assert "blade_rotation" in capsys.readouterr().err  # the type gives the length only


@pytest.mark.parametrize("command", ["fit", "track"])
def test_fit_and_track_without_turbine_yaml_run_init(command: str, flight_copy: Path,
                                                     tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    (flight_copy / "turbine.yaml").unlink()
    out = tmp_path / "out"
    assert main([command, str(flight_copy), "--out", str(out), "--no-plots"]) in (0, 3)
    assert "no turbine.yaml: initial turbine estimated from the images" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["turbine_init"]["keyframes_seen"] > 0
    # the turbine estimated is the one the command started from
    start = summary["turbine"]["initial"]
    assert start == pytest.approx(summary["turbine_init"]["turbine"])
