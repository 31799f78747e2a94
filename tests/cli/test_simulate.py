"""``turbinefit simulate``: the flight folder it writes, determinism, presets, and refusing
bad options and output folders before any simulation."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import N_KEYFRAMES, SIM_ARGS, assert_one_line_error, digest, entries, poses_array, run

from turbinefit.io import read_turbine_yaml


def test_simulate_writes_a_complete_flight_folder(sim_flight_dir: Path) -> None:
    assert entries(sim_flight_dir) == sorted(["camera.yaml", "keyframes.txt", "turbine.yaml", "heatmaps",
                                           "groundtruth.txt", "turbine_groundtruth.yaml",
                                           "simulation.yaml"])
    t, poses = poses_array(sim_flight_dir / "keyframes.txt")
    assert len(t) == N_KEYFRAMES and np.all(np.diff(t) > 0)
    assert np.allclose(np.linalg.norm(poses[:, :4], axis=1), 1.0)
    t_gt, _ = poses_array(sim_flight_dir / "groundtruth.txt")
    np.testing.assert_array_equal(t_gt, t)
    maps = sorted((sim_flight_dir / "heatmaps").iterdir())
    assert [p.name for p in maps] == sorted(f"{x:.6f}.npy" for x in t)
    hm = np.load(maps[0])
    assert hm.dtype == np.float16 and hm.shape == (7, 120, 160)
    assert np.isfinite(hm).all() and hm.max() > 0.5  # the turbine is in view
    cam = yaml.safe_load((sim_flight_dir / "camera.yaml").read_text())
    assert (cam["image_width"], cam["image_height"]) == (160, 120)
    read_turbine_yaml(sim_flight_dir / "turbine.yaml")
    read_turbine_yaml(sim_flight_dir / "turbine_groundtruth.yaml")
    sim = yaml.safe_load((sim_flight_dir / "simulation.yaml").read_text())
    assert (sim["n_keyframes"], sim["seed"], sim["width"], sim["height"]) == (12, 3, 160, 120)


def test_simulate_same_seed_same_flight(sim_flight_dir: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(capsys, "simulate", str(tmp_path / "again"), *SIM_ARGS)
    assert rc == 0
    assert out == f"wrote {N_KEYFRAMES} keyframes to {tmp_path / 'again'}\n"
    strip = {k: v[0] for k, v in digest(sim_flight_dir).items()}
    assert {k: v[0] for k, v in digest(tmp_path / "again").items()} == strip


def test_simulate_list_presets(capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(capsys, "simulate", "--list-presets")
    assert rc == 0
    from turbinefit.sim.scenario import PRESETS as SIM_PRESETS

    for name in SIM_PRESETS:
        assert name in out
    assert "random" in out


def test_simulate_refuses_non_empty_dir(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "busy"
    dest.mkdir()
    (dest / "notes.txt").write_text("mine\n")
    before = digest(dest)
    rc, out, err = run(capsys, "simulate", str(dest), *SIM_ARGS, "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)), "not empty", "--overwrite")
    assert digest(dest) == before
    assert entries(tmp_path) == ["busy"]


def test_simulate_overwrite_refuses_a_folder_that_is_not_a_flight(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "busy"
    dest.mkdir()
    (dest / "notes.txt").write_text("mine\n")
    before = digest(dest)
    rc, out, err = run(capsys, "simulate", str(dest), "--keyframes", "2", "--width", "40",
                       "--height", "30", "--overwrite", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)), "notes.txt")
    assert digest(dest) == before
    assert entries(tmp_path) == ["busy"]


def test_simulate_overwrite_replaces_its_own_output(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "flight"
    small = ["--keyframes", "2", "--width", "40", "--height", "30", "--quiet"]
    assert run(capsys, "simulate", str(dest), *small, "--seed", "1")[0] == 0
    rc, _, err = run(capsys, "simulate", str(dest), *small, "--seed", "2", "--overwrite")
    assert rc == 0, err
    assert yaml.safe_load((dest / "simulation.yaml").read_text())["seed"] == 2


@pytest.mark.parametrize(("args", "patterns"), [
    (["--preset", "nope"], [r"--preset", r"'nope'"]),
    (["--drift-m", "-1"], [r"drift_pos_m", r"non-negative"]),
    (["--turbine", "bogus"], [r"unknown turbine 'bogus'"]),
    (["--turbine-noise", "-1"], [r"turbine"]),
    (["--heatmap-noise", "-0.5"], [r"--heatmap-noise", r"non-negative"]),
], ids=["preset", "drift", "turbine", "turbine-noise", "heatmap-noise"])
def test_simulate_bad_options(args: list[str], patterns: list[str], tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "flight"
    rc, out, err = run(capsys, "simulate", str(dest), "--keyframes", "2", "--width", "40",
                       "--height", "30", "--quiet", *args)
    assert_one_line_error(rc, out, err, *patterns)
    assert entries(tmp_path) == []


def test_simulate_into_an_existing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "afile"
    dest.write_text("x")
    rc, out, err = run(capsys, "simulate", str(dest), "--keyframes", "2", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)))
    assert dest.read_text() == "x"


@pytest.fixture
def no_simulation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make simulating fail the test: a bad OUT_DIR must be refused before the (slow) work."""
    import turbinefit.sim.scenario

    def fail(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated although OUT_DIR is unusable")

    monkeypatch.setattr(turbinefit.sim.scenario, "simulate_flight", fail)


@pytest.mark.parametrize("where", ["under-a-file", "not-a-flight", "symlink"])
def test_simulate_refuses_a_bad_out_dir_before_simulating(
        where: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], no_simulation: None) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine\n")
    (tmp_path / "link").symlink_to(tmp_path / "busy")
    dest, patterns = {
        "under-a-file": (afile / "flight", [re.escape(str(afile)), r"not a directory"]),
        "not-a-flight": (tmp_path / "busy", [r"notes\.txt", r"not part of a flight"]),
        "symlink": (tmp_path / "link", [re.escape(str(tmp_path / "link")), r"symbolic link"]),
    }[where]
    before = digest(tmp_path)
    rc, out, err = run(capsys, "simulate", str(dest), *SIM_ARGS, "--overwrite", "--quiet")
    assert_one_line_error(rc, out, err, *patterns)
    assert digest(tmp_path) == before
    assert entries(tmp_path) == ["afile", "busy", "link"]


def test_simulate_overwrite_refuses_a_fit_output(sim_flight_dir: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    fitted = tmp_path / "fit"
    rc, _, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(fitted), "--no-plots", "--quiet",
                     "--max-iterations", "1")
    assert rc == 0, err
    before = digest(fitted)
    rc, out, err = run(capsys, "simulate", str(fitted), "--keyframes", "2", "--width", "40",
                       "--height", "30", "--overwrite", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(fitted)), r"not part of a flight")
    assert digest(fitted) == before


def test_simulate_vio_writes_body_frame_odometry_that_fit_and_track_use(
        sim_flight_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    flight = tmp_path / "vio"
    rc, _, _ = run(capsys, "simulate", str(flight), *SIM_ARGS, "--odometry", "vio")
    assert rc == 0
    assert "odometry.txt" in entries(flight)
    t, odo = poses_array(flight / "odometry.txt")
    t_kf, kf = poses_array(flight / "keyframes.txt")
    np.testing.assert_array_equal(t, t_kf)
    np.testing.assert_array_equal(odo, kf)  # a VIO-only drone: keyframes are its odometry
    _, gt = poses_array(flight / "groundtruth.txt")
    np.testing.assert_allclose(odo[0], gt[0], atol=1e-6)
    assert not np.allclose(odo[-1], gt[-1], atol=1e-3)
    assert yaml.safe_load((flight / "simulation.yaml").read_text())["odometry"] == "vio"
    # the gps flight of the same seed has no odometry.txt and the same ground truth
    assert "odometry.txt" not in entries(sim_flight_dir)
    np.testing.assert_array_equal(gt, poses_array(sim_flight_dir / "groundtruth.txt")[1])
    for command, extra in (("fit", []), ("track", ["--window", "6"])):
        rc, out, _ = run(capsys, command, str(flight), "--out", str(tmp_path / command),
                         "--no-plots", *extra)
        assert rc == 0
        assert "pairwise frame: estimated (odometry.txt: body-frame odometry)\n" in out
        saved = yaml.safe_load((tmp_path / command / "config.yaml").read_text())
        assert (saved.get("fit") or saved)["pair_frame"] == "estimated"
    rc, out, _ = run(capsys, "fit", str(sim_flight_dir), "--out", str(tmp_path / "gps"),
                     "--no-plots")
    assert rc == 0 and "pairwise frame: measured (GPS/IMU keyframes)\n" in out


def test_simulate_heatmap_size(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "big"
    rc, _, err = run(capsys, "simulate", str(out), "--keyframes", "2", "--width", "5280",
                     "--height", "3956", "--quiet")
    assert rc == 0, err
    cam = yaml.safe_load((out / "camera.yaml").read_text())
    assert (cam["image_width"], cam["image_height"]) == (5280, 3956)
    first = next((out / "heatmaps").iterdir())
    assert np.load(first).shape == (7, 240, 320)  # a 20 MP camera's maps at 320 px
    assert first.stat().st_size < 1.1e6  # float16: 1.08 MB a keyframe
    for size, shape in (("200", (7, 150, 200)), ("400x300", (7, 300, 400))):
        rc, _, err = run(capsys, "simulate", str(out), "--keyframes", "2", "--width", "4000",
                         "--height", "3000", "--heatmap-size", size, "--overwrite", "--quiet")
        assert rc == 0, err
        assert np.load(next((out / "heatmaps").iterdir())).shape == shape
    rc, out_text, err = run(capsys, "simulate", str(tmp_path / "x"), "--heatmap-size", "300x300")
    assert_one_line_error(rc, out_text, err, "heatmap_size", "300x300")
    assert not (tmp_path / "x").exists()
