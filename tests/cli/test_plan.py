"""``turbinefit plan`` on a small simulated fit: its outputs (georeferenced too), the plan
folder read back by ``coverage``, and bad input refused in one line with nothing written."""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from support import assert_one_line_error, assert_valid_png, run

from turbinefit.cli import main
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.io.camera_yaml import write_camera_yaml
from turbinefit.io.georef import Georef, format_georef_yaml


@pytest.fixture(scope="module")
def fit_dir(sim_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("plan") / "fit"
    assert main(["fit", str(sim_flight_dir), "--out", str(out), "--no-plots", "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def camera_yaml(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cam") / "camera.yaml"
    write_camera_yaml(path, PinholeCamera(5280, 3956, 7350.0, 7350.0, 2639.5, 1977.5))
    return path


def test_plan_writes_waypoints_and_coverage_reads_them(
        fit_dir: Path, camera_yaml: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan"
    rc, stdout, err = run(capsys, "plan", str(fit_dir), "--standoff", "10", "--gsd", "2",
                          "--camera", str(camera_yaml), "--out", str(out))
    assert rc == 0, err
    assert "photos" in stdout and "clearance from the rotor" in stdout
    assert sorted(p.name for p in out.iterdir()) == [
        "keyframes.txt", "path.png", "summary.json", "turbine.yaml", "waypoints.csv"]
    rows = list(csv.DictReader((out / "waypoints.csv").open()))
    photos = [r for r in rows if r["photo"] == "1"]
    assert len(photos) > 100 and len(rows) > len(photos)
    assert {r["part"] for r in photos} == {"blade_A", "blade_B", "blade_C", "tower"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["min_rotor_clearance_m"] >= 10.0 - 1e-3
    flown = 10.0 + summary["clearance_check"]["margin_m"]
    assert summary["gsd_mm_px"] == pytest.approx(1000 * flown / 7350, abs=1e-3)
    assert summary["min_tower_clearance_m"] >= summary["tower_clearance_m"] == 2.5
    assert summary["length_m"] > 0 and summary["photos"] == len(photos)
    assert_valid_png(out / "path.png")
    cov = tmp_path / "cov"
    assert main(["coverage", str(out), "--camera", str(camera_yaml), "--out", str(cov),
                 "--no-plots", "--quiet"]) == 0
    c = json.loads((cov / "summary.json").read_text())["coverage"]
    for blade in ("blade_A", "blade_B", "blade_C"):
        assert min(v["covered"] for v in c[blade].values()) > 0.9


def test_plan_of_a_georeferenced_flight(fit_dir: Path, sim_flight_dir: Path, camera_yaml: Path,
                                        tmp_path: Path) -> None:
    flight = Path(shutil.copytree(sim_flight_dir, tmp_path / "flight"))
    georef = Georef(51.45, -2.51, 40.0)
    (flight / "georef.yaml").write_text(format_georef_yaml(georef))
    out = tmp_path / "plan"
    assert main(["plan", str(fit_dir), "--flight", str(flight), "--standoff", "12",
                 "--camera", str(camera_yaml), "--out", str(out), "--no-plots",
                 "--quiet"]) == 0
    world = list(csv.DictReader((out / "waypoints.csv").open()))
    wgs = list(csv.DictReader((out / "waypoints_wgs84.csv").open()))
    assert len(world) == len(wgs)
    enu = georef.enu(np.array([float(r["latitude"]) for r in wgs]),
                     np.array([float(r["longitude"]) for r in wgs]),
                     np.array([float(r["altitude"]) for r in wgs]))
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in world])
    np.testing.assert_allclose(enu, xyz, atol=2e-3)
    # gimbal yaw clockwise from north: a view along +x (east) has yaw 90
    for w, g in zip(world, wgs, strict=True):
        assert (float(w["yaw_deg"]) + float(g["yaw"]) - 90.0 + 180.0) % 360.0 == \
            pytest.approx(180.0, abs=1e-3)
    root = ET.parse(out / "waypoints.kml").getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    marks = root.findall(".//k:Placemark", ns)
    assert len(marks) == 1 + sum(r["photo"] == "1" for r in world)
    coords = root.find(".//k:LineString/k:coordinates", ns).text.split()
    assert len(coords) == len(world)
    lon, lat, alt = (float(v) for v in coords[0].split(","))
    assert lat == pytest.approx(float(wgs[0]["latitude"]), abs=1e-8)
    assert lon == pytest.approx(float(wgs[0]["longitude"]), abs=1e-8)
    assert alt == pytest.approx(float(wgs[0]["altitude"]), abs=0.01)


@pytest.mark.parametrize("argv, words", [
    (["--standoff", "99"], r"--standoff.*meets the rotor"),
    (["--standoff", "10", "--gsd", "0.5"], r"--gsd.*1\.40 mm/px at a stand-off of 10 m"),
    (["--standoff", "10", "--tower-clearance", "12"], r"--tower-clearance.*at most the stand-off"),
])
def test_plan_refuses(argv: list[str], words: str, fit_dir: Path, camera_yaml: Path,
                      tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan"
    rc, stdout, err = run(capsys, "plan", str(fit_dir), *argv, "--camera", str(camera_yaml),
                          "--out", str(out))
    assert_one_line_error(rc, stdout, err, words)
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("remove, words", [
    ("turbine.yaml", r"turbine\.yaml.*without fitted turbine"),
    ("keyframes.txt", r"keyframes\.txt.*without fitted poses"),
])
def test_plan_refuses_a_fit_folder_without(remove: str, words: str, fit_dir: Path,
                                           tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    broken = Path(shutil.copytree(fit_dir, tmp_path / "fit"))
    (broken / remove).unlink()
    rc, stdout, err = run(capsys, "plan", str(broken), "--standoff", "10", "--out",
                          str(tmp_path / "plan"))
    assert_one_line_error(rc, stdout, err, words)
    assert [p.name for p in tmp_path.iterdir()] == ["fit"]


@pytest.mark.parametrize("argv, words", [
    # the audit of issue 49: stand-offs below the documented minimum were planned into the
    # blades (least rotor clearance -0.04 m at 0.5 m, -0.449 m at 1e-6 m, 0.747 m at 1 m)
    (["--standoff", "0.5"], r"--standoff: stand-off 0\.5 m is out of range: it must be "
     r"between 3 and 100 m"),
    (["--standoff", "1e-6"], r"--standoff: stand-off 1e-06 m is out of range"),
    (["--standoff", "1"], r"--standoff: stand-off 1\.0 m is out of range"),
    (["--standoff", "nan"], r"--standoff: stand-off must be a number, got nan"),
    (["--standoff", "101"], r"--standoff: stand-off 101\.0 m is out of range"),
    # the gimbal's range: nan and 1000 were accepted, -1000 failed naming a hidden file
    (["--standoff", "10", "--max-gimbal-up", "nan"], r"--max-gimbal-up: .* must be a number"),
    (["--standoff", "10", "--max-gimbal-up", "1000"],
     r"--max-gimbal-up: largest upward gimbal pitch 1000\.0 deg is out of range: it must be "
     r"between 0 and 90 deg"),
    (["--standoff", "10", "--max-gimbal-up", "-1000"], r"--max-gimbal-up: .*-1000\.0 deg is out"),
    (["--standoff", "10", "--gsd", "0"], r"--gsd: resolution 0\.0 mm/px is out of range"),
    (["--standoff", "10", "--overlap", "0.95"], r"--overlap: overlap 0\.95 is out of range"),
    (["--standoff", "10", "--tower-clearance", "1"], r"--tower-clearance: tower clearance 1\.0 m"),
])
def test_plan_refuses_options_out_of_range(argv: list[str], words: str, fit_dir: Path,
                                           tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan"
    with pytest.raises(SystemExit) as info:
        main(["plan", str(fit_dir), *argv, "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert re.search(r"turbinefit plan: error: argument " + words, err.splitlines()[-1]), err
    assert ".tmp-" not in err and not out.exists()


@pytest.mark.parametrize("kwargs, words", [
    ({"standoff": 0.5}, r"^--standoff: stand-off 0\.5 m is out of range"),
    ({"standoff": 10.0, "max_gimbal_up_deg": math.nan}, r"^--max-gimbal-up: .*must be a number"),
    ({"standoff": 10.0, "max_gimbal_up_deg": -1000.0}, r"^--max-gimbal-up: .* out of range"),
    ({"standoff": 10.0, "overlap": 1.0}, r"^--overlap: "),
])
def test_plan_folder_refuses_the_same(kwargs: dict[str, float], words: str, fit_dir: Path,
                                      tmp_path: Path) -> None:
    from turbinefit.errors import InputError
    from turbinefit.jobs.plan import plan_folder

    with pytest.raises(InputError, match=words):
        plan_folder(fit_dir, tmp_path / "plan", **kwargs)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("standoff", [3.0, 5.0])
def test_plan_at_the_least_standoff_keeps_it(standoff: float, fit_dir: Path, tmp_path: Path
                                             ) -> None:
    """The written path, read back and checked again from the file: every waypoint and
    leg keeps the stand-off from the rotor and the tower clearance from the tower."""
    from turbinefit.inspection.clearance import ROTOR, STRUCTURE, path_clearance
    from turbinefit.inspection.surface import TurbineSurface
    from turbinefit.jobs.coverage import read_fit_output

    out = tmp_path / "plan"
    assert main(["plan", str(fit_dir), "--standoff", str(standoff), "--out", str(out),
                 "--no-plots", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["min_rotor_clearance_m"] >= standoff
    assert summary["min_tower_clearance_m"] >= summary["tower_clearance_m"] == 2.0
    rows = list(csv.DictReader((out / "waypoints.csv").open()))
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    fit = read_fit_output(fit_dir, None, need_camera=False)
    check = path_clearance(xyz, TurbineSurface(fit.turbine, fit.geometry), leg_step=0.1)
    # the file's millimetres aside
    assert check.least(ROTOR)[0] >= standoff - 0.01
    assert check.least(STRUCTURE)[0] >= 2.0 - 0.01


def test_recorded_paths_work_from_any_directory(
        sim_flight_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``fit`` run on relative paths records its flight relative to the fit folder, so
    ``plan`` and ``coverage`` find the flight's camera from another working directory (and
    record their own inputs the same way)."""
    data = tmp_path / "work" / "data"
    shutil.copytree(sim_flight_dir, data / "flight")
    monkeypatch.chdir(data)
    assert main(["fit", "flight", "--out", "../runs/fit", "--no-plots", "--quiet"]) == 0
    fit = tmp_path / "work" / "runs" / "fit"
    assert json.loads((fit / "summary.json").read_text())["flight"] == "../../data/flight"
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    assert main(["plan", "../work/runs/fit", "--standoff", "10", "--out", "plan",
                 "--no-plots", "--quiet"]) == 0
    plan = json.loads((tmp_path / "elsewhere" / "plan" / "summary.json").read_text())
    assert (plan["fit"], plan["flight"]) == ("../../work/runs/fit", "../../work/data/flight")
    assert main(["coverage", "../work/runs/fit", "--out", "cov", "--no-plots", "--quiet"]) == 0
    cov = json.loads((tmp_path / "elsewhere" / "cov" / "summary.json").read_text())
    assert (tmp_path / "elsewhere" / "cov" / cov["flight"] / "camera.yaml").is_file()
