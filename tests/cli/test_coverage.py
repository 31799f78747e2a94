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
    with pytest.raises(SystemExit):  # a usage error (argparse: usage, then its line)
        main(["coverage", str(broken), "--out", str(tmp_path / "c2"), "--flight",
              str(sim_flight_dir), "--blade-pitch", "120"])
    assert "--blade-pitch: blade angle 120.0 deg is out of range" in capsys.readouterr().err
    assert not (tmp_path / "c2").exists()
    rc, stdout, err = run(capsys, "coverage", str(broken), "--out", str(broken / "inside"),
                          "--flight", str(sim_flight_dir))
    assert_one_line_error(rc, stdout, err, r"input")


def _blade_a_pixel(fit_dir: Path, flight: Path) -> tuple[int, float, float]:
    """A keyframe and the pixel where its photo shows blade A 20 m from the hub (fitted
    turbine and pose; the lookup confirms the blade)."""
    from turbinefit.inspection import TurbineSurface, lookup_pixel
    from turbinefit.io import read_tum, read_turbine_yaml
    from turbinefit.io.camera_yaml import read_camera_yaml

    _, poses = read_tum(fit_dir / "keyframes.txt")
    surface = TurbineSurface(read_turbine_yaml(fit_dir / "turbine.yaml"))
    cam = read_camera_yaml(flight / "camera.yaml")
    blade = surface.blades[0]
    point = blade.root + 20.0 * blade.axis
    for k in range(len(poses)):
        uv, _, _ = cam.project_unbounded(poses[k].inverse().apply(point[None]))
        u, v = (float(c) for c in uv[0])
        hit = lookup_pixel(surface, cam, poses[k], u, v)
        if 3 <= u < cam.width - 3 and 3 <= v < cam.height - 3 and hit is not None \
                and hit.blade == "A":
            return k, u, v
    raise AssertionError("blade A is not in view")


def test_damage_boxes_are_located_on_their_blade(fit_dir: Path, flight_copy: Path,
                                                 tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A box round blade A 20 m out, on an original photo that the flight's images/ holds as
    a hard link (as import dji makes) and on a photo named by its timestamp, is located on
    blade A near 20 m; a photo that is no keyframe is refused in one line, nothing written."""
    import os

    from turbinefit.io.camera_yaml import read_camera_yaml
    from turbinefit.io.tum import read_tum

    k, u, v = _blade_a_pixel(fit_dir, flight_copy)
    t, _ = read_tum(fit_dir / "keyframes.txt")
    cam = read_camera_yaml(flight_copy / "camera.yaml")
    photos = tmp_path / "photos"
    photos.mkdir()
    (photos / "DJI_0007.JPG").write_bytes(b"not decoded" * 10)
    (flight_copy / "images").mkdir()
    os.link(photos / "DJI_0007.JPG", flight_copy / "images" / f"{t[k]:.6f}.jpg")
    (photos / f"{t[k]:.6f}.png").write_bytes(b"x")
    box = f"{u - 1.5:.2f},{v - 1.5:.2f},{u + 2.5:.2f},{v + 2.5:.2f}"
    big = f"{2 * (u - 1.5):.2f},{2 * (v - 1.5):.2f},{2 * (u + 2.5):.2f},{2 * (v + 2.5):.2f}"
    damage = tmp_path / "damage.csv"
    damage.write_text("filename,width,height,class,xmin,ymin,xmax,ymax\n"
                      f"DJI_0007.JPG,{cam.width},{cam.height},erosion,{box}\n"
                      f"{t[k]:.6f}.png,{2 * cam.width},{2 * cam.height},crack,{big}\n")
    out = tmp_path / "cov"
    rc, stdout, err = run(capsys, "coverage", str(fit_dir), "--flight", str(flight_copy),
                          "--out", str(out), "--no-plots", "--damage", str(damage),
                          "--damage-photos", str(photos))
    assert rc == 0, err
    assert "damage DJI_0007.JPG erosion: blade_A" in stdout
    rows = list(csv.DictReader((out / "damage.csv").open()))
    assert [(r["photo"], r["class"], int(r["keyframe"]), r["part"]) for r in rows] == [
        ("DJI_0007.JPG", "erosion", k, "blade_A"), (f"{t[k]:.6f}.png", "crack", k, "blade_A")]
    for r in rows:
        assert abs(float(r["span_m"]) - 20.0) < 1.5
        assert float(r["span_from_m"]) <= float(r["span_m"]) <= float(r["span_to_m"])
        assert r["side"] in {"leading_edge", "pressure_side", "trailing_edge", "suction_side"}
        assert float(r["on_part"]) > 0.5
    assert json.loads((out / "summary.json").read_text())["damage_boxes"] == 2
    # a photo that is no keyframe's
    (photos / "DJI_0099.JPG").write_bytes(b"another photo")
    damage.write_text(f"DJI_0099.JPG,{cam.width},{cam.height},erosion,{box}\n")
    out2 = tmp_path / "cov2"
    rc, stdout, err = run(capsys, "coverage", str(fit_dir), "--flight", str(flight_copy),
                          "--out", str(out2), "--damage", str(damage), "--damage-photos",
                          str(photos))
    assert_one_line_error(rc, stdout, err, r"damage\.csv:1.*DJI_0099\.JPG is not the photo of "
                          "any keyframe")
    assert not out2.exists()


def test_coverage_of_a_flight_folder_uses_its_own_poses(sim_flight_dir: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    """Before any fit: a flight folder is its own flight (camera.yaml, keyframes.txt and
    turbine.yaml as measured)."""
    out = tmp_path / "cov"
    rc, stdout, err = run(capsys, "coverage", str(sim_flight_dir), "--out", str(out),
                          "--no-plots")
    assert rc == 0, err
    assert "clockwise from 12 o'clock" in stdout
    rows = list(csv.DictReader((out / "coverage.csv").open()))
    assert len({r["keyframe"] for r in rows}) >= 6
    flight = json.loads((out / "summary.json").read_text())["flight"]  # relative to out
    assert (out / flight).resolve() == sim_flight_dir.resolve()
