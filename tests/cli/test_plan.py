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
                          "--camera", str(camera_yaml), "--platform", "unlimited",
                          "--out", str(out))
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
    (["--standoff", "10", "--position-margin", "12"],
     r"--position-margin: the position margin must be between 0 and the stand-off \(10 m\)"),
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
    (["--standoff", "10", "--blade-pitch", "95"], r"--blade-pitch: blade angle 95\.0 deg is out"),
    (["--standoff", "10", "--blade-twist", "nan"], r"--blade-twist: .* must be a number"),
    (["--standoff", "10", "--position-margin", "-1"],
     r"--position-margin: position margin -1\.0 m is out of range"),
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


# ---- issue 47: mission files, platforms, GIS twins -------------------------------------------

ORIGIN = "51.45,-2.51,40"


def _read_missions(out: Path, pattern: str, reader) -> list:
    """The waypoints of a plan's numbered missions, each after the first without the point
    it resumes from."""
    points: list = []
    for k, path in enumerate(sorted(out.glob(pattern))):
        read = reader(path)
        points += read if k == 0 else read[1:]
    return points


def test_plan_writes_mission_files_that_fly_the_plan(fit_dir: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """A simulated fit placed with --origin: each format, read back by its own reader, flies
    waypoints.csv's path to 1 cm with its headings and gimbal pitches to 0.1 deg; missions
    split at the platform's 99 waypoints; the gimbal kept within the platform's +20 deg."""
    from turbinefit.io import mission_readers as R

    out = tmp_path / "plan"
    rc, stdout, err = run(capsys, "plan", str(fit_dir), "--standoff", "10", "--origin", ORIGIN,
                          "--format", "litchi,qgc,mavlink,kml", "--out", str(out))
    assert rc == 0, err
    assert "platform generic: gimbal up to 20 deg" in stdout and "litchi: litchi_01.csv" in stdout
    rows = list(csv.DictReader((out / "waypoints.csv").open()))
    assert len(rows) > 99 and max(float(r["gimbal_pitch_deg"]) for r in rows) <= 20.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["platform"] == "generic" and summary["georeference"] == "--origin"
    files = summary["missions"]["formats"]
    # 99 waypoints a mission, each after the first starting at the previous one's last
    n = 1 + math.ceil((len(rows) - 99) / 98)
    assert files["litchi"] == [f"litchi_{k:02d}.csv" for k in range(1, n + 1)]
    georef = Georef(51.45, -2.51, 40.0)
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    heading = (90.0 - np.array([float(r["yaw_deg"]) for r in rows])) % 360.0
    photo = np.array([r["photo"] == "1" for r in rows])
    pitch = np.array([float(r["gimbal_pitch_deg"]) for r in rows])
    for pattern, reader in (("litchi_*.csv", R.read_litchi_csv), ("mission_*.plan", R.read_qgc_plan),
                            ("mission_*.waypoints", R.read_mavlink_wpl)):
        pts = _read_missions(out, pattern, reader)
        assert len(pts) == len(rows), pattern
        enu = georef.enu([p.latitude for p in pts], [p.longitude for p in pts],
                         [40.0 + p.height for p in pts])
        assert np.abs(enu - xyz).max() < 0.01, pattern  # waypoints.csv's millimetres aside
        dh = (np.array([p.heading for p in pts]) - heading + 180.0) % 360.0 - 180.0
        assert np.abs(dh).max() < 0.1, pattern
        assert [p.photo for p in pts] == photo.tolist(), pattern
        got = np.array([p.gimbal_pitch for p in pts])[photo]
        assert np.abs(got - pitch[photo]).max() < 0.1, pattern
    for path in out.glob("litchi_*.csv"):
        assert len(R.read_litchi_csv(path)) <= 99


def test_plan_writes_dji_wpml_for_a_dji_enterprise_platform(fit_dir: Path, tmp_path: Path,
                                                            camera_yaml: Path) -> None:
    from turbinefit.io.mission_readers import read_wpml_kmz

    out = tmp_path / "plan"
    assert main(["plan", str(fit_dir), "--standoff", "10", "--origin", ORIGIN, "--platform",
                 "m30t", "--format", "dji-wpml", "--out", str(out), "--no-plots",
                 "--quiet"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "dji.kmz", "keyframes.txt", "summary.json", "turbine.yaml", "waypoints.csv",
        "waypoints.geojson", "waypoints_wgs84.csv", "waypoints_wgs84.geojson"]
    summary = json.loads((out / "summary.json").read_text())
    # the M30T's wide camera (4.5 mm, 6.4 mm sensor, 4000 px): f = 2812.5 px
    assert summary["camera"]["fx"] == pytest.approx(2812.5) and summary["max_gimbal_up_deg"] == 30
    pts = read_wpml_kmz(out / "dji.kmz")
    rows = list(csv.DictReader((out / "waypoints.csv").open()))
    assert len(pts) == len(rows) == summary["waypoints"]
    assert sum(p.photo for p in pts) == summary["photos"]
    assert max(p.gimbal_pitch for p in pts) <= 30.0


@pytest.mark.parametrize("argv, words", [
    (["--platform", "m31t"], r"--platform: unknown platform 'm31t'; known: generic, m300-h20t"),
    (["--format", "dji-wpml"], r"--format: platform generic does not fly dji-wpml missions .*"
     r"dji-wpml: --platform m300-h20t, m350-h20t, m30t, m3e"),
    (["--format", "litchi", "--platform", "m3e"], r"--format: platform m3e does not fly litchi"),
    (["--max-gimbal-up", "30"], r"--max-gimbal-up: 30 deg is beyond the gimbal of platform "
     r"generic .*up to 20 deg"),
    (["--platform", "px4", "--speed", "13"], r"--speed: 13 m/s is faster than platform px4"),
])
def test_plan_refuses_what_the_platform_cannot_fly(argv: list[str], words: str, fit_dir: Path,
                                                   tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan"
    rc, stdout, err = run(capsys, "plan", str(fit_dir), "--standoff", "10", "--origin", ORIGIN,
                          *argv, "--out", str(out))
    assert_one_line_error(rc, stdout, err, words)
    assert list(tmp_path.iterdir()) == []


def test_mission_files_need_a_georeference(fit_dir: Path, sim_flight_dir: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan"
    rc, stdout, err = run(capsys, "plan", str(fit_dir), "--standoff", "10", "--format",
                          "litchi,kml", "--out", str(out))
    assert_one_line_error(rc, stdout, err, r"--format: litchi, kml need a georeferenced fit: "
                          r"a flight with georef\.yaml .* or --origin LAT,LON,ALT")
    flight = Path(shutil.copytree(sim_flight_dir, tmp_path / "flight"))
    (flight / "georef.yaml").write_text(format_georef_yaml(Georef(51.45, -2.51, 40.0)))
    rc, stdout, err = run(capsys, "plan", str(fit_dir), "--flight", str(flight), "--standoff",
                          "10", "--origin", ORIGIN, "--out", str(out))
    assert_one_line_error(rc, stdout, err, r"--origin: the flight is georeferenced")
    assert not out.exists()
    # --format unknown: a usage error
    with pytest.raises(SystemExit) as info:
        main(["plan", str(fit_dir), "--standoff", "10", "--format", "kmz", "--out", str(out)])
    assert info.value.code == 2
    assert "argument --format: unknown mission format 'kmz'" in capsys.readouterr().err


def test_plan_says_which_sides_the_gimbal_cannot_see(fit_dir: Path, camera_yaml: Path,
                                                     tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """The default gimbal (+20 deg) cannot look straight at the lower edge of a blade near
    horizontal (views along the blade see part of it): the plan says how much of it its
    photos show rather than leaving it to the coverage."""
    rc, stdout, err = run(capsys, "plan", str(fit_dir), "--standoff", "10", "--camera",
                          str(camera_yaml), "--out", str(tmp_path / "plan"), "--no-plots")
    assert rc == 0, err
    summary = json.loads((tmp_path / "plan" / "summary.json").read_text())
    covered = summary["covered"]
    assert len(covered) == 12
    unseen = [k for k in summary["beyond_gimbal"] if covered[k] < 0.95]
    assert unseen and all(k.split("/")[1] in ("leading_edge", "trailing_edge") for k in unseen)
    shares = ", ".join(f"{k} {100 * covered[k]:.0f} %" for k in unseen)
    assert f"photographed in part, views beyond the gimbal's 20 deg up: {shares} of the " \
           f"span at {summary['covered_mm_px']:.2f} mm/px" in stdout
    # the other sides are covered whole
    assert all(v >= 0.95 for k, v in covered.items() if k not in unseen)


def test_the_gis_twins_open_in_gdal_as_wgs84_points(fit_dir: Path, tmp_path: Path) -> None:
    """waypoints.csv gains latitude, longitude, altitude; its GeoJSON twin, read by GDAL
    (pyogrio), is WGS84 points at the same places."""
    pyogrio = pytest.importorskip("pyogrio")
    out = tmp_path / "plan"
    assert main(["plan", str(fit_dir), "--standoff", "10", "--origin", ORIGIN, "--out",
                 str(out), "--no-plots", "--quiet"]) == 0
    rows = list(csv.DictReader((out / "waypoints.csv").open()))
    assert list(rows[0])[-3:] == ["latitude", "longitude", "altitude"]
    for stem in ("waypoints", "waypoints_wgs84"):
        info = pyogrio.read_info(out / f"{stem}.geojson")
        # WGS84 (GDAL names a GeoJSON with heights EPSG:4979, WGS84 in three dimensions)
        assert info["crs"] in ("EPSG:4326", "EPSG:4979") and info["geometry_type"] == "Point Z"
        assert info["features"] == len(rows)
        meta, _, _, fields = pyogrio.raw.read(out / f"{stem}.geojson")
        lat = fields[list(meta["fields"]).index("latitude")]
        assert np.allclose(lat, [float(r["latitude"]) for r in rows], atol=1e-9)
