"""``turbinefit view`` on a small simulated fit with photos: the page and what it holds, a
mission folder found by its sub-folders, the outputs of plan and coverage read back, and bad
input refused in one line with nothing written."""

from __future__ import annotations

import base64
import io
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from support import assert_one_line_error, digest, leftovers, run

from turbinefit.cli import main
from turbinefit.inspection.coverage import flight_coverage
from turbinefit.inspection.surface import TurbineSurface
from turbinefit.io.camera_yaml import read_camera_yaml
from turbinefit.jobs.coverage import read_fit_output
from turbinefit.jobs.view import find_inputs, read_coverage_output
from turbinefit.view.scene import unpacked


def page_data(path: Path) -> dict:
    """The scene data of a page."""
    m = re.search(r'<script type="application/json" id="turbinefit-data">(.*?)</script>',
                  path.read_text(encoding="utf-8"), re.S)
    assert m is not None
    return json.loads(m.group(1))


@pytest.fixture(scope="module")
def fit_dir(photo_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("view") / "fit"
    assert main(["fit", str(photo_flight_dir), "--out", str(out), "--no-plots", "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def mission(fit_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A mission folder: the fit, a plan round it and the fit's coverage."""
    m = tmp_path_factory.mktemp("mission") / "mission"
    shutil.copytree(fit_dir, m / "fit")
    assert main(["plan", str(fit_dir), "--standoff", "10", "--out", str(m / "plan"),
                 "--no-plots", "--quiet"]) == 0
    assert main(["coverage", str(fit_dir), "--out", str(m / "coverage"), "--no-plots",
                 "--quiet"]) == 0
    return m


def test_view_writes_one_page_with_cameras_photos_and_coverage(
        fit_dir: Path, photo_flight_dir: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "view.html"
    before = digest(fit_dir) | digest(photo_flight_dir)
    rc, stdout, err = run(capsys, "view", str(fit_dir), "--out", str(out), "--photos", "4",
                          "--thumbnail", "80")
    assert rc == 0, err
    assert "6 keyframes, 4 frusta, 4 photos" in stdout and f"wrote {out}" in stdout
    assert "coverage computed" in stdout and "verdict" in stdout
    assert leftovers(tmp_path) == [] and digest(fit_dir) | digest(photo_flight_dir) == before
    data = page_data(out)
    assert [c["name"] for c in data["cameras"]] == ["optimised", "initial", "ground_truth"]
    assert [s["name"] for s in data["skeletons"]] == ["initial", "ground_truth"]
    assert data["keyframes"]["count"] == 6 and data["keyframes"]["shown"] == [0, 2, 3, 5]
    assert data["verdict"] in ("ok", "doubtful", "failed")
    opt = unpacked(data["cameras"][0]["positions"]) + data["origin"]
    fitted = np.loadtxt(fit_dir / "keyframes.txt")[:, 1:4]
    np.testing.assert_allclose(opt, fitted, atol=1e-3)
    assert [p["keyframe"] for p in data["photos"]] == [0, 2, 3, 5]
    for p in data["photos"]:
        head, b64 = p["src"].split(",", 1)
        assert head == "data:image/jpeg;base64"
        img = Image.open(io.BytesIO(base64.b64decode(b64)))
        assert img.format == "JPEG" and img.size == (80, 60) == (p["width"], p["height"])
        assert {o["name"] for o in p["overlays"]} == {"optimised", "initial"}
    assert data["coverage"]["source"].startswith("computed")
    assert data["plan"] is None


def test_a_mission_folder_is_found_by_its_sub_folders(
        mission: Path, fit_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    inputs = find_inputs(mission)
    assert (inputs.fit_dir, inputs.plan_dir, inputs.coverage_dir, inputs.mission_dir) == (
        mission / "fit", mission / "plan", mission / "coverage", mission)
    out = tmp_path / "mission.html"
    rc, stdout, err = run(capsys, "view", str(mission), "--out", str(out), "--photos", "2")
    assert rc == 0, err
    assert f"plan {mission / 'plan'}" in stdout and f"coverage {mission / 'coverage'}" in stdout
    data = page_data(out)
    plan = json.loads((mission / "plan" / "summary.json").read_text())
    assert len(data["plan"]["labels"]) == plan["photos"]
    assert unpacked(data["plan"]["path"]).shape == (plan["waypoints"], 3)
    # from waypoints.csv (millimetres) against the summary (centimetres): their rounding
    assert data["plan"]["length"] == pytest.approx(plan["length_m"], rel=1e-4)
    assert data["coverage"]["source"] == str(mission / "coverage")
    assert data["title"] == "turbinefit: mission"
    # the page may sit in the mission folder, beside (not inside) what it reads
    assert main(["view", str(mission), "--out", str(mission / "view.html"), "--photos", "0",
                 "--quiet"]) == 0
    (mission / "view.html").unlink()
    assert_one_line_error(*run(capsys, "view", str(mission), "--out",
                               str(mission / "plan" / "view.html")),
                          r"plan/view\.html", r"nest inside the input")
    # the same page from the fit with the folders named
    out2 = tmp_path / "named.html"
    assert main(["view", str(fit_dir), "--plan", str(mission / "plan"), "--coverage",
                 str(mission / "coverage"), "--out", str(out2), "--photos", "2", "--quiet"]) == 0
    named = page_data(out2)
    assert named["plan"]["labels"] == data["plan"]["labels"]
    assert named["coverage"]["table"] == data["coverage"]["table"]


def test_the_coverage_output_reads_back_as_computed(mission: Path, fit_dir: Path) -> None:
    fit = read_fit_output(fit_dir)
    grids, max_gsd, surface = read_coverage_output(mission / "coverage", fit.turbine, fit.geometry)
    assert max_gsd == 2.0
    camera = read_camera_yaml(Path(str(fit.flight_dir)) / "camera.yaml")
    computed = flight_coverage(TurbineSurface(fit.turbine, fit.geometry), camera, fit.world_T_cam)
    assert len(grids) == len(computed.grids) == 4
    for g, c in zip(grids, computed.grids, strict=True):
        assert g.part == c.part and g.step == pytest.approx(c.step)
        np.testing.assert_allclose(g.spans, c.spans, atol=0.006)
        seen = np.isfinite(c.best_gsd)
        assert (np.isfinite(g.best_gsd) == seen).all() and seen.any()
        np.testing.assert_allclose(g.best_gsd[seen], c.best_gsd[seen], rtol=0, atol=6e-4)
    assert surface.shape.blade_pitch == 0.0


def test_overwrite_replaces_only_a_page_view_wrote(
        fit_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "view.html"
    args = ["view", str(fit_dir), "--out", str(out), "--photos", "0", "--quiet"]
    assert main(args) == 0
    first = out.read_bytes()
    assert_one_line_error(*run(capsys, *args), re.escape(str(out)), r"exists \(use --overwrite")
    assert main([*args, "--overwrite", "--title", "Turbine 7"]) == 0
    assert out.read_bytes() != first and page_data(out)["title"] == "Turbine 7"
    other = tmp_path / "notes.html"
    other.write_text("<html>my notes</html>")
    assert_one_line_error(*run(capsys, "view", str(fit_dir), "--out", str(other), "--overwrite"),
                          r"notes\.html", r"is not a page turbinefit wrote")
    assert other.read_text() == "<html>my notes</html>"


def test_without_its_flight_the_fit_alone_is_shown(
        fit_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lone = Path(shutil.copytree(fit_dir, tmp_path / "fit"))
    summary = json.loads((lone / "summary.json").read_text())
    summary["flight"] = str(tmp_path / "gone")
    (lone / "summary.json").write_text(json.dumps(summary))
    rc, stdout, err = run(capsys, "view", str(lone), "--out", str(tmp_path / "v.html"))
    assert rc == 0, err
    assert "note: The fit's flight folder was not found" in stdout
    data = page_data(tmp_path / "v.html")
    assert [c["name"] for c in data["cameras"]] == ["optimised"]
    assert data["photos"] == [] and data["coverage"] is None and data["notes"]


def _make(kind: str, fit_dir: Path, photo_flight_dir: Path, mission: Path, w: Path
          ) -> tuple[list[str], tuple[str, ...]]:
    """The command line of a bad-input case and the patterns of its error line."""
    out = str(w / "out.html")
    if kind == "empty":
        (w / "empty").mkdir()
        return ["view", str(w / "empty"), "--out", out], (r"empty", r"is neither a fit output")
    if kind == "missing":
        return ["view", str(w / "nothing"), "--out", out], (r"nothing", r"not found")
    if kind == "flight":
        return (["view", str(photo_flight_dir), "--out", out],
                (r"neither a fit output", r"it is a flight folder"))
    if kind == "plan":
        return (["view", str(mission / "plan"), "--out", out],
                (r"it is a plan output: view its fit with --plan",))
    if kind == "coverage":
        return ["view", str(mission / "coverage"), "--out", out], (r"it is a coverage output",)
    if kind == "mission-without-fit":
        (w / "m" / "fit").mkdir(parents=True)
        return ["view", str(w / "m"), "--out", out], (r"mission folder whose fit/ is not a fit",)
    if kind == "out-is-a-folder":
        (w / "out.html").mkdir()
        return ["view", str(fit_dir), "--out", out], (r"out\.html", r"is a folder")
    if kind == "out-inside-the-fit":
        return (["view", str(fit_dir), "--out", str(fit_dir / "view.html")],
                (r"view\.html", r"would overwrite or nest inside the input"))
    if kind == "out-inside-the-flight":
        return (["view", str(fit_dir), "--out", str(photo_flight_dir / "view.html")],
                (r"view\.html", r"nest inside the input"))
    if kind == "flight-mismatch":
        other = w / "other"
        assert main(["simulate", str(other), "--keyframes", "4", "--quiet"]) == 0
        return (["view", str(fit_dir), "--flight", str(other), "--out", out],
                (r"other/keyframes\.txt", r"4 keyframes that are not the fit's 6"))
    if kind == "bad-sides":
        cov = Path(shutil.copytree(mission / "coverage", w / "cov"))
        lines = (cov / "sides.csv").read_text().splitlines()
        lines[3] = ",".join([*lines[3].split(",")[:4], "-1", ""])
        (cov / "sides.csv").write_text("\n".join(lines) + "\n")
        return (["view", str(fit_dir), "--coverage", str(cov), "--out", out],
                (r"sides\.csv:4", r"best_gsd_mm_px", r"out of range"))
    if kind == "bad-waypoints":
        plan = Path(shutil.copytree(mission / "plan", w / "plan"))
        lines = (plan / "waypoints.csv").read_text().splitlines()
        lines[2] = lines[2].replace(lines[2].split(",")[1], "nan", 1)
        (plan / "waypoints.csv").write_text("\n".join(lines) + "\n")
        return (["view", str(fit_dir), "--plan", str(plan), "--out", out],
                (r"waypoints\.csv:3", r"\[?x\]?", r"must be a number"))
    if kind == "photo-shape":
        flight = Path(shutil.copytree(photo_flight_dir, w / "fl"))
        Image.new("RGB", (100, 100)).save(flight / "images" / "2.000000.png")
        return (["view", str(fit_dir), "--flight", str(flight), "--out", out],
                (r"fl/images/2\.000000\.png", r"photo is 100x100, not the shape of the "
                 r"camera's 160x120"))
    raise AssertionError(kind)


@pytest.mark.parametrize("kind", [
    "empty", "missing", "flight", "plan", "coverage", "mission-without-fit", "out-is-a-folder",
    "out-inside-the-fit", "out-inside-the-flight", "flight-mismatch", "bad-sides",
    "bad-waypoints", "photo-shape"])
def test_bad_input_is_one_line_and_nothing_is_written(
        kind: str, fit_dir: Path, photo_flight_dir: Path, mission: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    argv, patterns = _make(kind, fit_dir, photo_flight_dir, mission, tmp_path)
    before = {p: digest(p) for p in (fit_dir, photo_flight_dir, mission)}
    made = set(tmp_path.iterdir())
    assert_one_line_error(*run(capsys, *argv), *patterns)
    assert set(tmp_path.iterdir()) == made and leftovers(tmp_path) == []
    assert not (fit_dir / "view.html").exists() and not (photo_flight_dir / "view.html").exists()
    assert {p: digest(p) for p in before} == before


@pytest.mark.parametrize(("option", "value"), [
    ("--thumbnail", "10"), ("--thumbnail", "100.5"), ("--photos", "-1"), ("--gsd", "nan"),
    ("--gsd", "0")])
def test_bad_numbers_are_usage_errors(option: str, value: str, fit_dir: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["view", str(fit_dir), "--out", str(tmp_path / "v.html"), option, value])
    assert exc.value.code == 2
    err = capsys.readouterr().err.splitlines()[-1]
    assert err.startswith("turbinefit view: error: argument " + option)
    assert list(tmp_path.iterdir()) == []
