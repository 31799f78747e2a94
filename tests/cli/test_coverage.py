"""``turbinefit coverage`` on a small simulated fit: its outputs, and bad input refused in
one line with nothing written."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest
from support import assert_one_line_error, assert_valid_png, run

from turbinefit.cli import main


@pytest.fixture(scope="module")
def fit_dir(sim_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cov") / "fit"
    assert main(["fit", str(sim_flight_dir), "--out", str(out), "--no-plots", "--quiet"]) == 0
    return out


def test_coverage_writes_rows_per_keyframe_and_part(fit_dir: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cov"
    rc, stdout, err = run(capsys, "coverage", str(fit_dir), "--out", str(out))
    assert rc == 0, err
    assert "blade_A" in stdout and "clockwise from 12 o'clock" in stdout
    assert sorted(p.name for p in out.iterdir()) == [
        "coverage.csv", "coverage.png", "sides.csv", "summary.json"]
    rows = list(csv.DictReader((out / "coverage.csv").open()))
    assert rows and {r["part"] for r in rows} <= {"blade_A", "blade_B", "blade_C", "tower"}
    keyframes = {int(r["keyframe"]) for r in rows}
    assert keyframes <= set(range(12)) and len(keyframes) >= 6
    for r in rows:
        assert float(r["span_from_m"]) < float(r["span_to_m"])
        assert float(r["gsd_mm_px"]) > 0 and float(r["distance_m"]) > 0
        assert set(r["sides"].split("+")) <= {"leading_edge", "pressure_side", "trailing_edge",
                                              "suction_side", "front", "right", "back", "left"}
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["blades"]) == {"A", "B", "C"}
    assert 0.0 < summary["coverage"]["blade_A"]["pressure_side"]["seen"] <= 1.0
    assert_valid_png(out / "coverage.png")
    sides = list(csv.DictReader((out / "sides.csv").open()))
    assert {r["side"] for r in sides if r["part"] == "tower"} == {"front", "right", "back",
                                                                    "left"}
    # the same again is refused without --overwrite, accepted with it
    rc, _, err = run(capsys, "coverage", str(fit_dir), "--out", str(out), "--no-plots")
    assert_one_line_error(rc, "", err, "overwrite")
    assert main(["coverage", str(fit_dir), "--out", str(out), "--overwrite", "--quiet"]) == 0


@pytest.mark.parametrize("remove, words", [
    ("turbine.yaml", r"turbine\.yaml.*without fitted turbine"),
    ("keyframes.txt", r"keyframes\.txt.*without fitted poses"),
    ("summary.json", r"summary\.json.*--flight"),
])
def test_coverage_refuses_a_fit_folder_without(remove: str, words: str, fit_dir: Path,
                                               tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    broken = Path(shutil.copytree(fit_dir, tmp_path / "fit"))
    (broken / remove).unlink()
    out = tmp_path / "cov"
    rc, stdout, err = run(capsys, "coverage", str(broken), "--out", str(out))
    assert_one_line_error(rc, stdout, err, words)
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["fit"]


def test_coverage_with_flight_given_and_bad_pitch(fit_dir: Path, sim_flight_dir: Path,
                                                  tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    broken = Path(shutil.copytree(fit_dir, tmp_path / "fit"))
    (broken / "summary.json").unlink()
    out = tmp_path / "cov"
    assert main(["coverage", str(broken), "--flight", str(sim_flight_dir), "--out", str(out),
                 "--no-plots", "--quiet"]) == 0
    assert (out / "coverage.csv").is_file() and not (out / "coverage.png").exists()
    rc, stdout, err = run(capsys, "coverage", str(broken), "--out", str(tmp_path / "c2"),
                          "--flight", str(sim_flight_dir), "--blade-pitch", "120")
    assert_one_line_error(rc, stdout, err, r"--blade-pitch")
    rc, stdout, err = run(capsys, "coverage", str(broken), "--out", str(broken / "inside"),
                          "--flight", str(sim_flight_dir))
    assert_one_line_error(rc, stdout, err, r"input")
