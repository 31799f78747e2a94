"""``turbinefit simulate --path``: flying a given path (plan's keyframes) with GNSS error
models, known defects painted on the blades and their boxes located by ``coverage
--damage --truth``; and refusing bad paths, defects and options before writing anything."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import assert_one_line_error, look_at, poses_array, run

from turbinefit.inspection.defects import Defect, defect_point
from turbinefit.inspection.surface import SurfaceShape, TurbineSurface
from turbinefit.io.defects import format_defects_csv
from turbinefit.io.tum import write_tum
from turbinefit.sim.images.scene import flight_scene
from turbinefit.sim.scenario import SimConfig, true_turbine
from turbinefit.turbine.model import model_points
from turbinefit.turbine.solid import ROOT_TWIST

SEED = 4
SMALL = ["--seed", str(SEED), "--width", "160", "--height", "120", "--quiet"]


def _fit_from_truth(flight: Path, dest: Path) -> Path:
    """A folder ``coverage`` and ``plan`` read as a fit: the flight's ground truth."""
    dest.mkdir()
    shutil.copy(flight / "camera.yaml", dest / "camera.yaml")
    shutil.copy(flight / "groundtruth.txt", dest / "keyframes.txt")
    shutil.copy(flight / "turbine_groundtruth.yaml", dest / "turbine.yaml")
    return dest


@pytest.fixture(scope="module")
def plan_keyframes(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """plan's keyframes.txt at 10 m round the true turbine of seed SEED."""
    from turbinefit.cli import main

    w = tmp_path_factory.mktemp("plan")
    assert main(["simulate", str(w / "flight"), "--keyframes", "12", *SMALL]) == 0
    fit = _fit_from_truth(w / "flight", w / "fit")
    assert main(["plan", str(fit), "--flight", str(fit), "--standoff", "10", "--out",
                 str(w / "plan"), "--quiet"]) == 0
    return w / "plan" / "keyframes.txt"


def _horizontal_rms(flight: Path) -> tuple[float, float, float]:
    """RMS horizontal and vertical error [m] of keyframes.txt against the ground truth,
    and the median rotation error [deg]."""
    _, kf = poses_array(flight / "keyframes.txt")
    _, gt = poses_array(flight / "groundtruth.txt")
    d = kf[:, 4:] - gt[:, 4:]
    q = np.abs(np.sum(kf[:, :4] * gt[:, :4], axis=1)).clip(0, 1)
    return (float(np.sqrt(np.mean(np.sum(d[:, :2] ** 2, axis=1) / 2))),
            float(np.sqrt(np.mean(d[:, 2] ** 2))), float(np.degrees(np.median(2 * np.arccos(q)))))


def test_path_is_flown_with_gnss_errors_of_each_model(
        plan_keyframes: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    t_path, path = poses_array(plan_keyframes)
    errors = {}
    for model in ("standard", "rtk"):
        out = tmp_path / model
        rc, _, err = run(capsys, "simulate", str(out), "--path", str(plan_keyframes),
                         "--gnss", model, *SMALL)
        assert rc == 0, err
        t_gt, gt = poses_array(out / "groundtruth.txt")
        np.testing.assert_allclose(t_gt, t_path, atol=1e-6)  # timestamps from the file
        np.testing.assert_allclose(gt, path, atol=1e-8)  # the path is the ground truth
        sim = yaml.safe_load((out / "simulation.yaml").read_text())
        assert sim["gnss"] == model and sim["path"] == str(plan_keyframes)
        assert sim["n_keyframes"] == len(t_path)
        errors[model] = _horizontal_rms(out)
    # metre-level (1.5 m, 0.5 m published 1-sigma) against centimetres (1.5 cm, 2 cm)
    h, v, rot = errors["standard"]
    assert 0.3 < h < 5.0 and 0.05 < v < 2.0 and 0.05 < rot < 10.0
    h, v, rot = errors["rtk"]
    assert 0.002 < h < 0.06 and 0.002 < v < 0.08 and 0.05 < rot < 10.0
    # an RTK receiver reports its sigmas with each fix (import dji writes them the same way)
    assert not (tmp_path / "standard" / "keyframes_sigma.csv").exists()
    sig = np.loadtxt(tmp_path / "rtk" / "keyframes_sigma.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(sig[:, 0], t_path, atol=1e-6)
    np.testing.assert_allclose(sig[:, 1:], np.tile([0.015, 0.015, 0.02], (len(t_path), 1)))


def test_path_with_vio_odometry(plan_keyframes: Path, tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    rc, _, err = run(capsys, "simulate", str(tmp_path / "f"), "--path", str(plan_keyframes),
                     "--odometry", "vio", *SMALL)
    assert rc == 0, err
    _, odo = poses_array(tmp_path / "f" / "odometry.txt")
    _, path = poses_array(plan_keyframes)
    np.testing.assert_allclose(odo[0], path[0], atol=1e-8)  # chained from the first pose
    assert not np.allclose(odo[-1], path[-1], atol=1e-3)
    _, kf = poses_array(tmp_path / "f" / "keyframes.txt")
    np.testing.assert_array_equal(kf, odo)  # VIO alone: keyframes are the odometry
    rc, _, err = run(capsys, "simulate", str(tmp_path / "g"), "--path", str(plan_keyframes),
                     "--odometry", "vio", "--gnss", "rtk", *SMALL)
    assert rc == 0, err
    _, odo_g = poses_array(tmp_path / "g" / "odometry.txt")
    _, kf_g = poses_array(tmp_path / "g" / "keyframes.txt")
    np.testing.assert_allclose(odo_g, odo, atol=1e-8)  # the same VIO
    assert np.abs(kf_g[:, 4:] - path[:, 4:]).max() < 0.2  # RTK keyframes, no VIO drift


def _defects_and_path(tmp: Path) -> tuple[Path, Path]:
    """Six defects (two per blade, every side) and a path of one photo of each, 7 m off its
    surface, looking at it from its side."""
    turbine = true_turbine(SimConfig(seed=SEED))
    defects = [Defect("E1", "blade_A", "leading_edge", 50.0, 1.0, 0.4, "erosion"),
               Defect("C1", "blade_A", "suction_side", 30.0, 0.2, 0.45, "crack"),
               Defect("B1", "blade_B", "pressure_side", 61.0, 0.0, 0.3, "burn"),
               Defect("E2", "blade_B", "trailing_edge", 40.0, -1.0, 0.4, "erosion"),
               Defect("E3", "blade_C", "pressure_side", 45.0, 0.6, 0.45, "erosion"),
               Defect("C2", "blade_C", "suction_side", 35.0, -0.4, 0.45, "crack")]
    pitch = flight_scene(turbine.to_vector(), SEED, True).blade_pitch
    surface = TurbineSurface(turbine, shape=SurfaceShape(-pitch, -ROOT_TWIST))
    eyes, targets = [], []
    for d in defects:
        p, n = defect_point(surface, d)
        axis = surface.blades[["blade_A", "blade_B", "blade_C"].index(d.part)].axis
        off = n + 0.25 * axis  # along the blade: the same side, never straight up
        eyes.append(p + 7.0 * off / np.linalg.norm(off))
        targets.append(p)
    path = tmp / "path.txt"
    write_tum(path, np.arange(len(defects), dtype=float), look_at(np.array(eyes),
                                                                  np.array(targets)))
    csv = tmp / "defects.csv"
    csv.write_text(format_defects_csv(defects))
    return path, csv


def test_defects_are_located_on_their_blade_side_and_span(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, csv = _defects_and_path(tmp_path)
    flight = tmp_path / "flight"
    rc, _, err = run(capsys, "simulate", str(flight), "--path", str(path), "--defects-file",
                     str(csv), "--images", "--seed", str(SEED), "--width", "320", "--height",
                     "240", "--quiet")
    assert rc == 0, err
    truth = (flight / "defects_groundtruth.csv").read_text().splitlines()
    assert truth[0] == "defect,part,side,span_m,chord,size_m,kind" and len(truth) == 7
    boxes = (flight / "defect_boxes.csv").read_text().splitlines()
    assert boxes[0].endswith(",defect")
    seen = {b.split(",")[-1] for b in boxes[1:]}
    assert seen == {"E1", "C1", "B1", "E2", "E3", "C2"}  # each photo shows its defect
    sim = yaml.safe_load((flight / "simulation.yaml").read_text())
    fit = _fit_from_truth(flight, tmp_path / "fit")
    rc, out, err = run(capsys, "coverage", str(fit), "--flight", str(flight), "--damage",
                       str(flight / "defect_boxes.csv"), "--truth",
                       str(flight / "defects_groundtruth.csv"), "--blade-pitch",
                       str(sim["blade_pitch_deg"]), "--blade-twist", str(sim["blade_twist_deg"]),
                       "--out", str(tmp_path / "cov"), "--no-plots")
    assert rc == 0, err
    assert "damage score: 6 of 6 defects seen" in out
    score = json.loads((tmp_path / "cov" / "summary.json").read_text())["damage_score"]
    assert score["right_part"] == 1.0 and score["right_part_and_side"] == 1.0
    assert score["span_error_median_m"] < 0.1 and score["span_error_p95_m"] < 0.3
    assert score["chord_error_median"] < 0.2
    damage = (tmp_path / "cov" / "damage.csv").read_text().splitlines()
    assert damage[0].endswith(",chord,defect")
    assert {row.split(",")[-1] for row in damage[1:]} == seen


def _write(tmp: Path, name: str, text: str) -> Path:
    (tmp / name).write_text(text)
    return tmp / name


def _hub() -> np.ndarray:
    p, _ = model_points(true_turbine(SimConfig(seed=SEED)).to_vector())
    return p[2]


GOOD_POSE = "0 0 -120 60 0 0 0 1\n"
DEFECT_HEAD = "defect,part,side,span_m,chord,size_m,kind\n"


@pytest.mark.parametrize(("files", "extra", "patterns"), [
    ({"p.txt": GOOD_POSE + "1 0 -120 nan 0 0 0 1\n"}, ["--path", "{p.txt}"],
     [r"p\.txt:2", "non-finite"]),
    ({"p.txt": GOOD_POSE + "1 {hub} 0 0 0 1\n"}, ["--path", "{p.txt}"],
     [r"p\.txt:2", r"inside the simulated turbine \((hub|nacelle|tower)"]),
    ({"p.txt": GOOD_POSE + "1 0 -120 -3 0 0 0 1\n"}, ["--path", "{p.txt}"],
     [r"p\.txt:2", "below the ground"]),
    ({"d.csv": DEFECT_HEAD + "D1,blade_A,pressure_side,70,0,0.2,crack\n"},
     ["--defects-file", "{d.csv}"], [r"d\.csv:2 \[span_m\]", r"not on the blade.*63\.00 m"]),
    ({"d.csv": DEFECT_HEAD + "D1,blade_A,pressure_side,30,1.5,0.2,crack\n"},
     ["--defects-file", "{d.csv}"], [r"d\.csv:2 \[chord\]", "chord 1.5 is out of range"]),
    ({"d.csv": DEFECT_HEAD + "D1,blade_D,pressure_side,30,0,0.2,crack\n"},
     ["--defects-file", "{d.csv}"], [r"d\.csv:2 \[part\]", "unknown blade 'blade_D'"]),
    ({"d.csv": DEFECT_HEAD + "D1,blade_A,tip,30,0,0.2,crack\n"},
     ["--defects-file", "{d.csv}"], [r"d\.csv:2 \[side\]", "unknown side 'tip'"]),
    ({"d.csv": DEFECT_HEAD + "D1,blade_A,leading_edge,30,0.5,0.2,erosion\n"},
     ["--defects-file", "{d.csv}"], [r"d\.csv:2 \[chord\]", "lies on the edge"]),
    ({"d.csv": DEFECT_HEAD + "D1,A,leading_edge,30,1,0.2,erosion\n"
      "D1,B,leading_edge,30,1,0.2,erosion\n"},
     ["--defects-file", "{d.csv}"], [r"d\.csv:3 \[defect\]", "named twice"]),
    ({"d.csv": "defect,part,side,span\n"}, ["--defects-file", "{d.csv}"],
     [r"d\.csv:1", "expected the columns"]),
])
def test_bad_paths_and_defects_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           files: dict[str, str], extra: list[str],
                                           patterns: list[str]) -> None:
    hub = " ".join(f"{v:.3f}" for v in _hub())
    paths = {name: str(_write(tmp_path, name, text.replace("{hub}", hub)))
             for name, text in files.items()}
    args = [a.format(**{k.replace(".", "_"): v for k, v in paths.items()})
            if a.startswith("{") else a for a in
            [x.replace(".", "_") if x.startswith("{") else x for x in extra]]
    rc, out, err = run(capsys, "simulate", str(tmp_path / "out"), *args, "--seed", str(SEED),
                       "--quiet")
    assert_one_line_error(rc, out, err, *patterns)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["0", "1.5", "nan"])
def test_photo_scale_out_of_range(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                  value: str) -> None:
    with pytest.raises(SystemExit) as e:
        run(capsys, "simulate", str(tmp_path / "out"), "--photo-scale", value)
    assert e.value.code == 2
    assert "--photo-scale" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_camera_file_and_photo_scale(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cam = _write(tmp_path, "cam.yaml", "image_width: 800\nimage_height: 600\n"
                 "camera_matrix: {rows: 3, cols: 3, data: [700, 0, 401.5, 0, 700, 299.5, 0, 0, 1]}\n"
                 "distortion_model: plumb_bob\ndistortion_coefficients: "
                 "{rows: 1, cols: 5, data: [-0.05, 0.01, 0, 0, 0]}\n")
    out = tmp_path / "f"
    rc, _, err = run(capsys, "simulate", str(out), "--camera", str(cam), "--photo-scale", "0.25",
                     "--keyframes", "3", "--images", "--quiet")
    assert rc == 0, err
    written = yaml.safe_load((out / "camera.yaml").read_text())
    assert (written["image_width"], written["image_height"]) == (200, 150)
    k = written["camera_matrix"]["data"]
    assert math.isclose(k[0], 175.0) and math.isclose(k[2], (401.5 + 0.5) * 0.25 - 0.5)
    assert written["distortion_coefficients"]["data"][0] == pytest.approx(-0.05)
    from PIL import Image

    with Image.open(next((out / "images").iterdir())) as im:
        assert im.size == (200, 150)
    hm = np.load(next((out / "heatmaps").iterdir()))
    assert hm.shape == (7, 150, 200)


def test_drawn_defects_and_the_blades_as_drawn(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = run(capsys, "simulate", str(tmp_path / "f"), "--keyframes", "3",
                       "--defects", "5", "--seed", str(SEED), "--width", "64", "--height", "48")
    assert rc == 0, err
    sim = yaml.safe_load((tmp_path / "f" / "simulation.yaml").read_text())
    assert out.splitlines()[-1] == (f"blades drawn at coverage --blade-pitch "
                                    f"{sim['blade_pitch_deg']:g} --blade-twist -14")
    rows = (tmp_path / "f" / "defects_groundtruth.csv").read_text().splitlines()
    assert len(rows) == 6 and not (tmp_path / "f" / "defect_boxes.csv").exists()  # no photos
