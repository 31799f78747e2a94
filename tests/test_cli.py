"""End-to-end tests of the ``turbinefit`` command line, run the way a user runs it.

One small simulated flight (12 keyframes, 160 x 120 heat-maps) is made once per module with
``turbinefit simulate``; every test copies it before changing anything. Most commands run
in-process through :func:`turbinefit.cli.main` (which returns the exit status); a few run
in a subprocess to prove the installed entry point and the real exit status.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

import turbinefit
from turbinefit.cli import build_parser, main
from turbinefit.io import read_tum, read_turbine_yaml
from turbinefit.io.fit_config import read_fit_config
from turbinefit.solver.config import PRESETS, FitConfig

SIM_ARGS = ["--keyframes", "12", "--seed", "3", "--width", "160", "--height", "120"]
N_KEYFRAMES = 12
FIT_OUTPUTS = {"keyframes.txt", "turbine.yaml", "config.yaml", "summary.json"}
PLOTS = {"scene.png", "reprojections.png", "errors.png", "cost.png"}
# keyframes.txt as simulate writes it: a comment, the column header, then keyframe k on line k + 3
FIRST_POSE_LINE = 3


# --------------------------------------------------------------------------- helpers

def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """Run the CLI in-process; returns (exit status, stdout, stderr)."""
    capsys.readouterr()  # drop anything printed before
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def assert_one_line_error(rc: int, out: str, err: str, *patterns: str) -> str:
    """Exit status 2, nothing on stdout, exactly one stderr line ``turbinefit: error: ...``
    matching every regex in ``patterns``, no traceback. Returns the line."""
    assert rc == 2, f"exit status {rc}, stderr: {err!r}"
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one stderr line, got {lines!r}"
    assert err.endswith("\n")
    line = lines[0]
    assert line.startswith("turbinefit: error: "), line
    assert "\r" not in line  # no progress-bar residue in front of the message
    for pat in patterns:
        assert re.search(pat, line), f"{pat!r} not in {line!r}"
    assert out == ""
    return line


def digest(folder: Path) -> dict[str, tuple[str, int]]:
    """{relative path: (sha256, mtime_ns)} of every file below ``folder``, hidden ones too."""
    return {
        str(p.relative_to(folder)): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*")) if p.is_file()
    }


def entries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def assert_valid_png(path: Path) -> tuple[int, int]:
    """Walk the PNG's chunks (CRCs checked), inflate the image data and check its size."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name}: not a PNG"
    pos, kinds, idat, ihdr = 8, [], b"", b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"{path.name}: bad CRC in {kind!r}"
        kinds.append(kind)
        if kind == b"IHDR":
            ihdr = body
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    assert pos == len(data), f"{path.name}: truncated"
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND", kinds
    width, height, depth, colour = struct.unpack(">IIBB", ihdr[:10])
    assert depth == 8 and colour in (0, 2, 4, 6), (depth, colour)
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    assert len(zlib.decompress(idat)) == height * (1 + width * channels)
    assert width >= 200 and height >= 200, (width, height)
    return width, height


def poses_array(path: Path) -> tuple[np.ndarray, np.ndarray]:
    t, poses = read_tum(path)
    return t, np.asarray(poses.wxyz_xyz)


def edit_line(path: Path, lineno: int, edit: Callable[[list[str]], list[str]]) -> None:
    """Replace whitespace-separated line ``lineno`` (1-based) of a text file by edit(tokens)."""
    lines = path.read_text().splitlines()
    lines[lineno - 1] = " ".join(edit(lines[lineno - 1].split()))
    path.write_text("\n".join(lines) + "\n")


def heatmap(flight: Path, k: int) -> Path:
    return flight / "heatmaps" / f"{float(k):.6f}.npy"


# --------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def good_flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small simulated flight with ground truth, made by ``turbinefit simulate``."""
    folder = tmp_path_factory.mktemp("sim") / "flight"
    assert main(["simulate", str(folder), *SIM_ARGS, "--quiet"]) == 0
    return folder


@pytest.fixture
def flight(good_flight: Path, tmp_path: Path) -> Path:
    """A private copy of the good flight (``tmp_path/flight``) to corrupt or fit."""
    return Path(shutil.copytree(good_flight, tmp_path / "flight"))


# --------------------------------------------------------------------------- simulate

def test_simulate_writes_a_complete_flight_folder(good_flight: Path) -> None:
    assert entries(good_flight) == sorted(["camera.yaml", "keyframes.txt", "turbine.yaml", "heatmaps",
                                           "groundtruth.txt", "turbine_groundtruth.yaml",
                                           "simulation.yaml"])
    t, poses = poses_array(good_flight / "keyframes.txt")
    assert len(t) == N_KEYFRAMES and np.all(np.diff(t) > 0)
    assert np.allclose(np.linalg.norm(poses[:, :4], axis=1), 1.0)
    t_gt, _ = poses_array(good_flight / "groundtruth.txt")
    np.testing.assert_array_equal(t_gt, t)
    maps = sorted((good_flight / "heatmaps").iterdir())
    assert [p.name for p in maps] == sorted(f"{x:.6f}.npy" for x in t)
    hm = np.load(maps[0])
    assert hm.dtype == np.float32 and hm.shape == (7, 120, 160)
    assert np.isfinite(hm).all() and hm.max() > 0.5  # the turbine is in view
    cam = yaml.safe_load((good_flight / "camera.yaml").read_text())
    assert (cam["image_width"], cam["image_height"]) == (160, 120)
    read_turbine_yaml(good_flight / "turbine.yaml")
    read_turbine_yaml(good_flight / "turbine_groundtruth.yaml")
    sim = yaml.safe_load((good_flight / "simulation.yaml").read_text())
    assert (sim["n_keyframes"], sim["seed"], sim["width"], sim["height"]) == (12, 3, 160, 120)


def test_simulate_same_seed_same_flight(good_flight: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, _ = run(capsys, "simulate", str(tmp_path / "again"), *SIM_ARGS)
    assert rc == 0
    assert out == f"wrote {N_KEYFRAMES} keyframes to {tmp_path / 'again'}\n"
    strip = {k: v[0] for k, v in digest(good_flight).items()}
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
    (["--turbine-noise", "nan"], [r"--turbine-noise", r"non-negative", r"nan"]),
    (["--heatmap-noise", "-0.5"], [r"--heatmap-noise", r"non-negative"]),
    (["--heatmap-noise", "inf"], [r"--heatmap-noise", r"inf"]),
], ids=["preset", "drift", "turbine", "turbine-noise", "turbine-noise-nan", "heatmap-noise",
        "heatmap-noise-inf"])
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


def test_simulate_overwrite_refuses_a_fit_output(good_flight: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    fitted = tmp_path / "fit"
    rc, _, err = run(capsys, "fit", str(good_flight), "--out", str(fitted), "--no-plots", "--quiet",
                     "--max-iterations", "1")
    assert rc == 0, err
    before = digest(fitted)
    rc, out, err = run(capsys, "simulate", str(fitted), "--keyframes", "2", "--width", "40",
                       "--height", "30", "--overwrite", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(fitted)), r"not part of a flight")
    assert digest(fitted) == before


# --------------------------------------------------------------------------- fit: success

def test_fit_joint_with_plots(good_flight: Path, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(good_flight)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(out_dir))
    assert rc == 0, err
    assert "Traceback" not in err

    # everything written, nothing else, inputs untouched
    assert set(entries(out_dir)) == FIT_OUTPUTS | PLOTS
    assert entries(tmp_path) == ["fit"]  # no temporary siblings left
    assert digest(good_flight) == before
    for name in PLOTS:
        assert_valid_png(out_dir / name)

    # keyframes.txt: same timestamps, unit quaternions, poses moved
    t_in, p_in = poses_array(good_flight / "keyframes.txt")
    t_out, p_out = poses_array(out_dir / "keyframes.txt")
    np.testing.assert_array_equal(t_out, t_in)
    assert np.allclose(np.linalg.norm(p_out[:, :4], axis=1), 1.0)
    assert np.isfinite(p_out).all() and not np.allclose(p_out, p_in, atol=1e-6)

    # config.yaml is the run's configuration (defaults here) and loads back
    cfg = read_fit_config(out_dir / "config.yaml")
    assert cfg == FitConfig()
    assert yaml.safe_load((out_dir / "config.yaml").read_text())["turbinefit_version"] == \
        turbinefit.__version__

    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["num_keyframes"] == N_KEYFRAMES
    assert summary["heatmap_size"] == [160, 120]
    assert FitConfig.from_dict(summary["config"]) == cfg
    solver = summary["solver"]
    assert math.isfinite(solver["final_cost"])
    assert solver["initial_cost"] >= solver["final_cost"]
    assert solver["iterations"] >= 1 and solver["rounds"] >= 1
    assert solver["history"] and all(math.isfinite(h["cost"]) for h in solver["history"])
    assert isinstance(solver["termination"], str) and solver["termination"]
    timing = summary["timing_s"]
    assert {"load", "solve", "total", "plots"} <= set(timing)
    assert all(v >= 0 for v in timing.values())
    assert timing["total"] >= timing["load"] + timing["solve"] - 1e-3

    # turbine.yaml is the optimised turbine of the summary
    th = read_turbine_yaml(out_dir / "turbine.yaml")
    assert th.to_dict() == pytest.approx(summary["turbine"]["optimised"], rel=1e-12)
    assert summary["turbine"]["initial"] == pytest.approx(
        read_turbine_yaml(good_flight / "turbine.yaml").to_dict(), rel=1e-12)
    assert th.to_dict() != pytest.approx(summary["turbine"]["initial"])

    # ground truth exists, so accuracy before/after, and the joint fit improves the model
    acc = summary["accuracy"]
    for when in ("before", "after"):
        assert {"position_error_m", "orientation_error_deg", "model_point_error_m"} <= set(acc[when])
    assert acc["after"]["model_point_error_m"] < acc["before"]["model_point_error_m"]

    # what the user reads on stdout
    assert f"fitted {N_KEYFRAMES} keyframes" in out
    assert re.search(r"^cost \S+ -> \S+$", out, re.M)
    assert "model point error" in out
    assert out.rstrip().endswith(f"wrote {out_dir}")


FIT_VARIANTS = {
    "joint": ["--mode", "joint"],
    "pose": ["--mode", "pose"],
    "turbine": ["--mode", "turbine"],
    "corr-corr": ["--points", "corr", "--lines", "corr"],
    "corr-interp": ["--points", "corr", "--lines", "interp"],
    "interp-corr": ["--points", "interp", "--lines", "corr"],
    "interp-interp": ["--points", "interp", "--lines", "interp"],
}


@pytest.mark.parametrize("variant", list(FIT_VARIANTS))
def test_fit_modes_and_unary_costs(variant: str, good_flight: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    args = FIT_VARIANTS[variant]
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(out_dir), "--no-plots",
                       "--quiet", "--max-iterations", "5", *args)
    assert rc == 0, err
    assert (out, err) == ("", "")  # --quiet
    assert set(entries(out_dir)) == FIT_OUTPUTS

    expected = dict(zip(args[::2], args[1::2], strict=True))
    cfg = read_fit_config(out_dir / "config.yaml")
    for opt, value in expected.items():
        assert getattr(cfg, opt.lstrip("-")) == value
    assert cfg.max_iterations == 5

    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["config"]["max_iterations"] == 5
    assert summary["solver"]["initial_cost"] >= summary["solver"]["final_cost"]
    assert summary["solver"]["iterations"] >= 1
    t_in, p_in = poses_array(good_flight / "keyframes.txt")
    t_out, p_out = poses_array(out_dir / "keyframes.txt")
    np.testing.assert_array_equal(t_out, t_in)
    th_in = read_turbine_yaml(good_flight / "turbine.yaml").to_dict()
    th_out = read_turbine_yaml(out_dir / "turbine.yaml").to_dict()
    if cfg.mode == "pose":  # turbine held fixed
        assert th_out == pytest.approx(th_in, rel=1e-12, abs=1e-12)
        assert not np.allclose(p_out, p_in, atol=1e-6)
    elif cfg.mode == "turbine":  # poses held fixed (up to the TUM text precision)
        np.testing.assert_allclose(p_out, p_in, rtol=0, atol=1e-8)
        assert th_out != pytest.approx(th_in)
    else:
        assert not np.allclose(p_out, p_in, atol=1e-6)
        assert th_out != pytest.approx(th_in)


def test_fit_config_file_round_trip(good_flight: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    first = tmp_path / "first"
    rc, _, err = run(capsys, "fit", str(good_flight), "--out", str(first), "--no-plots", "--quiet",
                     "--points", "interp", "--lambda-pair", "2.5", "--robust", "huber",
                     "--pair-sigma-r", "0.2", "--max-iterations", "5")
    assert rc == 0, err
    cfg1 = read_fit_config(first / "config.yaml")
    assert cfg1 == dataclasses.replace(FitConfig(), points="interp", lambda_pair=2.5, robust="huber",
                                       pair_sigma_r_deg=0.2, max_iterations=5)
    # a previous run's config.yaml as --config; command-line options override it
    second = tmp_path / "second"
    rc, _, err = run(capsys, "fit", str(good_flight), "--out", str(second), "--no-plots", "--quiet",
                     "--config", str(first / "config.yaml"), "--max-iterations", "4")
    assert rc == 0, err
    assert read_fit_config(second / "config.yaml") == dataclasses.replace(cfg1, max_iterations=4)


def test_fit_preset(good_flight: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "fit"
    rc, _, err = run(capsys, "fit", str(good_flight), "--out", str(out_dir), "--no-plots", "--quiet",
                     "--preset", "all-corr", "--max-iterations", "3")
    assert rc == 0, err
    assert read_fit_config(out_dir / "config.yaml") == dataclasses.replace(PRESETS["all-corr"],
                                                                         max_iterations=3)


def test_fit_never_modifies_its_input(flight: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(flight)
    rc, _, err = run(capsys, "fit", str(flight), "--out", str(tmp_path / "fit"), "--quiet", "--no-plots")
    assert rc == 0, err
    assert digest(flight) == before
    assert entries(tmp_path) == ["fit", "flight"]


def test_fit_into_an_existing_empty_dir(good_flight: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "fit"
    out_dir.mkdir()
    rc, _, err = run(capsys, "fit", str(good_flight), "--out", str(out_dir), "--no-plots", "--quiet",
                     "--max-iterations", "2")
    assert rc == 0, err
    assert set(entries(out_dir)) == FIT_OUTPUTS


def test_fit_existing_output_needs_overwrite(good_flight: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "fit"
    common = ["fit", str(good_flight), "--out", str(out_dir), "--no-plots", "--quiet"]
    assert run(capsys, *common, "--max-iterations", "2")[0] == 0
    (out_dir / "scene.png").write_bytes(b"a plot of an older run")
    before = digest(out_dir)

    rc, out, err = run(capsys, *common, "--max-iterations", "3")
    assert_one_line_error(rc, out, err, re.escape(str(out_dir)), "not empty", "--overwrite")
    assert digest(out_dir) == before
    assert entries(tmp_path) == ["fit"]

    rc, _, err = run(capsys, *common, "--max-iterations", "3", "--overwrite")
    assert rc == 0, err
    assert read_fit_config(out_dir / "config.yaml").max_iterations == 3
    assert set(entries(out_dir)) == FIT_OUTPUTS  # replaced, not merged: the old plot is gone
    assert entries(tmp_path) == ["fit"]


def test_entry_point_script_fits(good_flight: Path, tmp_path: Path) -> None:
    script = Path(sys.executable).with_name("turbinefit")
    if not script.exists():
        found = shutil.which("turbinefit")
        if found is None:
            pytest.skip("turbinefit script not installed")
        script = Path(found)
    out_dir = tmp_path / "fit"
    proc = subprocess.run([str(script), "fit", str(good_flight), "--out", str(out_dir), "--no-plots",
                           "--quiet", "--max-iterations", "2"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (proc.stdout, proc.stderr) == ("", "")
    assert set(entries(out_dir)) == FIT_OUTPUTS


def test_module_entry_point_bad_input_exit_status(flight: Path, tmp_path: Path) -> None:
    (flight / "camera.yaml").unlink()
    out_dir = tmp_path / "fit"
    proc = subprocess.run([sys.executable, "-m", "turbinefit.cli", "fit", str(flight), "--out",
                           str(out_dir)], capture_output=True, text=True, timeout=120)
    assert_one_line_error(proc.returncode, proc.stdout, proc.stderr, r"camera\.yaml")
    assert not out_dir.exists()


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"turbinefit {turbinefit.__version__}"


# --------------------------------------------------------------------------- help

def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {"": parser, **action.choices}
    raise AssertionError("no sub-commands")


@pytest.mark.parametrize(("command", "must_mention"), [
    ("", ["simulate", "fit", "--version", "camera.yaml", "keyframes.txt", "odometry.txt",
          "turbine.yaml", "heatmaps/", "groundtruth.txt"]),
    ("simulate", ["OUT_DIR", "--keyframes", "--seed", "--preset", "--width", "--height",
                  "--overwrite", "--quiet", "--list-presets", "--second-turbine"]),
    ("fit", ["FLIGHT_DIR", "--out", "--mode", "--points", "--lines", "--config", "--preset",
             "--no-plots", "--overwrite", "--quiet", "--max-iterations", "joint", "interp",
             "--pair-frame", "--no-warmup", "align", "match"]),
])
def test_help(command: str, must_mention: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    argv = [command, "--help"] if command else ["--help"]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith("usage: turbinefit")
    for word in must_mention:
        assert word in text, word
    # and every option the parser knows of
    parser = _subparsers()[command]
    for action in parser._actions:
        for opt in action.option_strings:
            assert opt in text, opt


@pytest.mark.parametrize(("argv", "pattern"), [
    (["fit", "somewhere"], r"--out"),
    (["fit", "somewhere", "--out", "x", "--mode", "bogus"], r"invalid choice: 'bogus'"),
    (["frobnicate"], r"invalid choice"),
    ([], r"COMMAND"),
    (["simulate", "x", "--seed", "-1"], r"--seed: must be a non-negative whole number"),
    (["simulate", "x", "--seed", "1.5"], r"--seed: expected a whole number"),
    (["fit", "somewhere", "--out", "x", "--preset", "all-corr", "--config", "c.yaml"],
     r"not allowed with argument"),
    (["fit", "somewhere", "--out", "x", "--pair-frame", "world"], r"invalid choice: 'world'"),
])
def test_usage_errors(argv: list[str], pattern: str, tmp_path: Path,
                      capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: turbinefit")
    assert re.search(pattern, err.splitlines()[-1]), err
    assert entries(tmp_path) == []


# --------------------------------------------------------------------------- fit: bad input

def _missing_folder(f: Path) -> Path:
    return f.parent / "no_such_flight"


def _unlink(name: str) -> Callable[[Path], None]:
    return lambda f: (f / name).unlink()


def _tum(k: int, edit: Callable[[list[str]], list[str]]) -> Callable[[Path], None]:
    """Edit the line of keyframe ``k`` in keyframes.txt."""
    return lambda f: edit_line(f / "keyframes.txt", FIRST_POSE_LINE + k, edit)


def _scale_quat(tokens: list[str], s: float) -> list[str]:
    return tokens[:4] + [repr(float(x) * s) for x in tokens[4:]]


def _save_heatmap(k: int, make: Callable[[np.ndarray], np.ndarray]) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        path = heatmap(f, k)
        np.save(path, make(np.load(path)))
    return mutate


def _all_nan(a: np.ndarray) -> np.ndarray:
    return np.full_like(a, np.nan)


def _camera_fx(value: float) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        data = yaml.safe_load((f / "camera.yaml").read_text())
        data["camera_matrix"]["data"][0] = value
        (f / "camera.yaml").write_text(yaml.safe_dump(data))
    return mutate


def _append(name: str, text: str) -> Callable[[Path], None]:
    return lambda f: (f / name).write_text((f / name).read_text() + text)


def _replace_in(name: str, old: str, new: str) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        text = (f / name).read_text()
        assert re.search(old, text, re.M)
        (f / name).write_text(re.sub(old, new, text, count=1, flags=re.M))
    return mutate


def _drop_last_line(name: str) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        lines = (f / name).read_text().splitlines()
        (f / name).write_text("\n".join(lines[:-1]) + "\n")
    return mutate


KF = r"keyframes\.txt"
BAD_FLIGHTS: dict[str, tuple[Callable[[Path], object], list[str]]] = {
    "missing-folder": (_missing_folder, [r"no_such_flight", r"not found"]),
    "missing-camera": (_unlink("camera.yaml"), [r"camera\.yaml", r"missing"]),
    "missing-turbine": (_unlink("turbine.yaml"), [r"turbine\.yaml", r"missing"]),
    "tum-columns": (_tum(4, lambda t: t[:-1]), [KF + r":7:", r"expected 8 columns", r"got 7"]),
    "tum-zero-quaternion": (_tum(2, lambda t: _scale_quat(t, 0.0)), [KF + r":5:", r"zero norm"]),
    "tum-non-unit-quaternion": (_tum(3, lambda t: _scale_quat(t, 1.5)), [KF + r":6:", r"norm 1\.5"]),
    "tum-nan": (_tum(5, lambda t: [t[0], "nan", *t[2:]]), [KF + r":8:", r"non-finite", r"nan"]),
    "tum-not-a-number": (_tum(1, lambda t: [t[0], "1,5", *t[2:]]), [KF + r":4:", r"not a number"]),
    "tum-timestamp-order": (_tum(1, lambda t: ["0.0", *t[1:]]), [KF + r":4:", r"not after"]),
    "groundtruth-short": (_drop_last_line("groundtruth.txt"),
                          [r"groundtruth\.txt", r"11 poses", r"keyframes\.txt has 12"]),
    "heatmap-missing": (_unlink("heatmaps/3.000000.npy"),
                        [r"heatmaps/3\.000000\.npy", r"missing", r"keyframes\.txt, line 6"]),
    "heatmap-shape": (_save_heatmap(2, lambda a: a[:, ::2, ::2].copy()),
                      [r"heatmaps/2\.000000\.npy", r"shape \(7, 60, 80\)", r"\(7, 120, 160\)"]),
    "heatmap-dtype": (_save_heatmap(4, lambda a: a.astype(np.float64)),
                      [r"heatmaps/4\.000000\.npy", r"dtype", r"float32"]),
    "heatmap-nan": (_save_heatmap(5, _all_nan), [r"heatmaps/5\.000000\.npy", r"NaN"]),
    "heatmap-not-npy": (lambda f: heatmap(f, 6).write_text("hello"),
                        [r"heatmaps/6\.000000\.npy", r"not a \.npy"]),
    "camera-fx-zero": (_camera_fx(0.0), [r"camera\.yaml", r"camera_matrix", r"fx must be positive"]),
    "camera-fx-negative": (_camera_fx(-100.0), [r"camera\.yaml", r"fx must be positive", r"-100"]),
    "turbine-malformed-yaml": (_replace_in("turbine.yaml", r"^tower_height:.*$", "tower_height: [86.0"),
                               [r"turbine\.yaml:\d+:", r"invalid YAML"]),
    "turbine-unknown-key": (_append("turbine.yaml", "rotor_diameter: 120.0\n"),
                            [r"turbine\.yaml \[rotor_diameter\]", r"unknown key"]),
    "turbine-missing-key": (_replace_in("turbine.yaml", r"^blade_length:.*$", ""),
                            [r"turbine\.yaml \[blade_length\]", r"missing"]),
    "turbine-negative-height": (_replace_in("turbine.yaml", r"^tower_height:.*$", "tower_height: -5"),
                                [r"turbine\.yaml \[tower_height\]", r"> 0"]),
}


@pytest.mark.parametrize("quiet", [True, False], ids=["quiet", "verbose"])
@pytest.mark.parametrize("case", list(BAD_FLIGHTS))
def test_fit_bad_flight(case: str, quiet: bool, flight: Path, tmp_path: Path,
                        capsys: pytest.CaptureFixture[str]) -> None:
    mutate, patterns = BAD_FLIGHTS[case]
    result = mutate(flight)
    target = result if isinstance(result, Path) else flight
    before = digest(flight)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(target), "--out", str(out_dir), "--no-plots",
                       *(["--quiet"] if quiet else []))
    assert_one_line_error(rc, out, err, *patterns)
    assert not out_dir.exists()
    assert entries(tmp_path) == ["flight"]  # no temporary output left behind
    assert digest(flight) == before


@pytest.mark.parametrize(("where", "overwrite"), [
    ("same", False), ("same", True), ("inside", False), ("parent", True)])
def test_fit_refuses_output_over_its_input(where: str, overwrite: bool, flight: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = {"same": flight, "inside": flight / "fit", "parent": tmp_path}[where]
    before = digest(flight)
    rc, out, err = run(capsys, "fit", str(flight), "--out", str(out_dir), "--no-plots", "--quiet",
                       *(["--overwrite"] if overwrite else []))
    assert_one_line_error(rc, out, err, re.escape(str(out_dir)), r"input")
    assert digest(flight) == before
    assert entries(tmp_path) == ["flight"]


def test_fit_out_is_an_existing_file(good_flight: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "afile"
    dest.write_text("x")
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(dest), "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)))
    assert dest.read_text() == "x"


def test_fit_out_under_an_existing_file(good_flight: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    import turbinefit.jobs.fit

    def fail(*args: object, **kwargs: object) -> None:
        raise AssertionError("read the flight although --out is unusable")

    monkeypatch.setattr(turbinefit.jobs.fit, "read_flight_folder", fail)  # refused before any work
    dest = tmp_path / "afile"
    dest.write_text("x")
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(dest / "sub" / "fit"),
                       "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)), r"not a directory")
    assert dest.read_text() == "x"
    assert entries(tmp_path) == ["afile"]


def test_fit_out_is_a_symlink_loop(good_flight: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(loop), "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(loop)), r"[Ss]ymlink loop")
    assert loop.is_symlink()


def test_fit_out_parent_not_writable(good_flight: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # as root, a chmod does not deny anything: make os.access say what it says to a user
    import turbinefit.io.atomic

    real_access = os.access
    parent = tmp_path / "readonly"
    parent.mkdir()

    def access(path: object, mode: int, **kwargs: object) -> bool:
        if Path(str(path)) == parent:
            return False
        return real_access(path, mode, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(turbinefit.io.atomic.os, "access", access)
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(parent / "new" / "fit"),
                       "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(parent)), r"no permission")
    assert entries(tmp_path) == ["readonly"] and entries(parent) == []


def _permissions_apply(folder: Path) -> bool:
    """Whether a mode-000 file is unreadable here (not for root with CAP_DAC_OVERRIDE)."""
    probe = folder / ".probe"
    probe.write_text("x")
    probe.chmod(0)
    try:
        probe.read_text()
    except PermissionError:
        return True
    else:
        return False
    finally:
        probe.chmod(0o600)
        probe.unlink()


@pytest.mark.parametrize("what", ["config", "out-parent", "flight"])
def test_fit_permission_denied(what: str, flight: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    if not _permissions_apply(tmp_path):
        pytest.skip("file permissions do not apply to this user (root)")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("mode: joint\n")
    ro = tmp_path / "ro"
    ro.mkdir()
    out_dir = ro / "fit" if what == "out-parent" else tmp_path / "fit"
    locked = {"config": cfg, "out-parent": ro, "flight": flight}[what]
    mode = 0o500 if what == "out-parent" else 0o000
    locked.chmod(mode)
    try:
        rc, out, err = run(capsys, "fit", str(flight), "--out", str(out_dir), "--config", str(cfg),
                           "--no-plots", "--quiet")
    finally:
        locked.chmod(0o700 if locked.is_dir() else 0o600)
    assert_one_line_error(rc, out, err, re.escape(str(locked)))
    assert not out_dir.exists()


@pytest.mark.parametrize("overwrite", [False, True])
def test_fit_refuses_output_over_its_config_file(overwrite: bool, good_flight: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    prev = tmp_path / "prev"
    common = ["fit", str(good_flight), "--no-plots", "--quiet", "--max-iterations", "1"]
    assert run(capsys, *common, "--out", str(prev))[0] == 0
    before = digest(prev)
    rc, out, err = run(capsys, *common, "--out", str(prev), "--config", str(prev / "config.yaml"),
                       *(["--overwrite"] if overwrite else []))
    assert_one_line_error(rc, out, err, re.escape(str(prev)), r"input", r"config\.yaml")
    assert digest(prev) == before
    assert entries(tmp_path) == ["prev"]


@pytest.mark.parametrize("kind", ["foreign-file", "flight-folder", "sub-folder"])
def test_fit_overwrite_refuses_a_folder_that_is_not_a_fit_output(
        kind: str, good_flight: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "dest"
    if kind == "flight-folder":
        shutil.copytree(good_flight, dest)
        culprit = "camera.yaml|groundtruth.txt|heatmaps|keyframes.txt|simulation.yaml|turbine"
    else:
        dest.mkdir()
        (dest / "summary.json").write_text("{}")  # a fit output, and one thing that is not
        if kind == "foreign-file":
            (dest / "thesis.tex").write_text("mine\n")
            culprit = r"thesis\.tex"
        else:
            (dest / "scene.png").mkdir()
            (dest / "scene.png" / "keep.txt").write_text("mine\n")
            culprit = r"scene\.png"
    before = digest(dest)
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(dest), "--no-plots", "--quiet",
                       "--overwrite")
    assert_one_line_error(rc, out, err, re.escape(str(dest)), r"refusing to overwrite", culprit,
                          r"not an output of turbinefit fit")
    assert digest(dest) == before
    assert entries(tmp_path) == ["dest"]


def test_fit_write_failure_leaves_nothing(good_flight: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str],
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    import turbinefit.jobs.fit

    def full_disk(out: Path, *args: object) -> None:
        (out / "scene.png").write_bytes(b"half a plot")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(turbinefit.jobs.fit, "write_plots", full_disk)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(out_dir), "--quiet",
                       "--max-iterations", "1")
    assert_one_line_error(rc, out, err, re.escape(str(out_dir)), r"No space left on device")
    assert entries(tmp_path) == []  # neither the output nor its temporary folder


BAD_CONFIGS: dict[str, tuple[bytes | None, list[str]]] = {
    "unknown-option": (b"mode: joint\nbogus_option: 3\n", [r"unknown fit option", r"bogus_option"]),
    "bad-value": (b"max_iterations: 0\n", [r"max_iterations", r">= 1"]),
    "bad-choice": (b"points: sideways\n", [r"points", r"interp, corr or none"]),
    "not-a-mapping": (b"- 1\n- 2\n", [r"mapping"]),
    "malformed-yaml": (b"mode: joint\nlines: [interp\n", [r"cfg\.yaml:\d+:", r"malformed YAML"]),
    "missing": (None, [r"not found"]),
    "duplicate-key": (b"mode: joint\nmode: pose\n", [r"cfg\.yaml:2:", r"duplicate key 'mode'"]),
    "key-not-a-string": (b"1: 2\n", [r"option name 1", r"not a string"]),
    "int-option-not-whole": (b"samples_per_line: 2.5\n", [r"samples_per_line", r"whole number"]),
    "int-option-bool": (b"samples_per_line: true\n", [r"samples_per_line", r"whole number"]),
    "float-option-text": (b"lambda_pair: lots\n", [r"lambda_pair", r"must be a number", r"'lots'"]),
    "pair-information-text": (b"pair_information: '" + b"1" * 36 + b"'\n",
                              [r"pair_information", r"list of 36 numbers"]),
    "pair-information-item": (b"pair_information: [1, x]\n", [r"pair_information\[1\]", r"number"]),
    "geometry-not-a-mapping": (b"geometry: 5\n", [r"geometry", r"mapping", r"shaft_tilt"]),
    "geometry-null": (b"geometry: null\n", [r"geometry", r"mapping"]),
    "geometry-nan": (b"geometry: {blade_cone: .nan}\n", [r"geometry\.blade_cone", r"finite"]),
    "geometry-bool": (b"geometry: {hub_offset: yes}\n", [r"geometry\.hub_offset", r"True"]),
    "geometry-unknown": (b"geometry: {rotor_tilt: 0.1}\n", [r"unknown geometry option", r"rotor_tilt"]),
}


@pytest.mark.parametrize("case", [*BAD_CONFIGS, "directory", "not-utf8", "geometry-not-a-number"])
def test_fit_bad_config_file(case: str, good_flight: Path, tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "cfg.yaml"
    patterns = [r"cfg\.yaml"]
    if case == "directory":
        cfg.mkdir()
    elif case == "not-utf8":
        cfg.write_bytes(b"\xff\xfe mode: joint\n")
    elif case == "geometry-not-a-number":
        cfg.write_bytes(b"geometry: {shaft_tilt: abc}\n")
        patterns = [r"shaft_tilt", r"cfg\.yaml", r"geometry\.shaft_tilt", r"finite real number", r"'abc'"]
    else:
        content, more = BAD_CONFIGS[case]
        if content is not None:
            cfg.write_bytes(content)
        patterns += more
    existing = entries(tmp_path)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(out_dir), "--config", str(cfg),
                       "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, *patterns)
    assert entries(tmp_path) == existing  # out_dir not created


def test_fit_unreadable_config_file(good_flight: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str],
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("mode: joint\n")
    real_read_text = Path.read_text

    def read_text(self: Path, *args: object, **kwargs: object) -> str:
        if self == cfg:
            raise PermissionError(13, "Permission denied", str(self))
        return real_read_text(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Path, "read_text", read_text)
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(tmp_path / "fit"),
                       "--config", str(cfg), "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(cfg)), r"cannot read", r"Permission denied")
    assert entries(tmp_path) == ["cfg.yaml"]


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


@pytest.mark.parametrize(("args", "patterns"), [
    (["--preset", "nope"], [r"--preset", r"'nope'", r"paper-best"]),
    (["--lambda-points", "nan"], [r"lambda_points", r"non-negative"]),
    (["--pixel-sigma", "-1"], [r"pixel_sigma", r"positive"]),
    (["--max-iterations", "0"], [r"max_iterations", r">= 1"]),
    (["--points", "none", "--lines", "none"], [r"both be none"]),
])
def test_fit_bad_options(args: list[str], patterns: list[str], good_flight: Path, tmp_path: Path,
                         capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = run(capsys, "fit", str(good_flight), "--out", str(tmp_path / "fit"), "--quiet", *args)
    assert_one_line_error(rc, out, err, *patterns)
    assert entries(tmp_path) == []


# --------------------------------------------------------------------------- track

TRACK_OUTPUTS = {"causal.txt", "keyframes.txt", "turbine.yaml", "latency.csv", "config.yaml",
                 "summary.json"}
TRACK_PLOTS = {"latency.png", "errors.png", "scene.png"}


def test_track_writes_causal_and_final_estimates(good_flight: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(good_flight)
    out_dir = tmp_path / "track"
    rc, out, err = run(capsys, "track", str(good_flight), "--out", str(out_dir), "--window", "5")
    assert rc == 0, err
    assert set(entries(out_dir)) == TRACK_OUTPUTS | TRACK_PLOTS
    assert entries(tmp_path) == ["track"] and digest(good_flight) == before
    for name in TRACK_PLOTS:
        assert_valid_png(out_dir / name)
    t_in, _ = poses_array(good_flight / "keyframes.txt")
    for name in ("causal.txt", "keyframes.txt"):
        t, p = poses_array(out_dir / name)
        np.testing.assert_array_equal(t, t_in)
        assert np.isfinite(p).all() and np.allclose(np.linalg.norm(p[:, :4], axis=1), 1.0)
    # the causal estimate of the last keyframe is its final one; earlier ones moved on
    _, causal = poses_array(out_dir / "causal.txt")
    _, final = poses_array(out_dir / "keyframes.txt")
    np.testing.assert_allclose(causal[-1], final[-1], atol=1e-9)
    assert not np.allclose(causal[1:-1], final[1:-1], atol=1e-6)
    # latency.csv: one row per keyframe, the timestamps of the flight
    lines = (out_dir / "latency.csv").read_text().splitlines()
    assert lines[0] == "timestamp,latency_ms" and len(lines) == N_KEYFRAMES + 1
    rows = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    np.testing.assert_allclose(rows[:, 0], t_in, atol=1e-6)
    assert np.all(rows[:, 1] > 0) and np.all(np.isfinite(rows[:, 1]))
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["num_keyframes"] == N_KEYFRAMES
    assert summary["config"]["tracker"]["window"] == 5
    assert FitConfig.from_dict(summary["config"]["fit"]) == FitConfig()
    assert summary["latency"]["median_ms"] == pytest.approx(float(np.median(rows[:, 1])), abs=1e-3)
    acc = summary["accuracy"]
    assert acc["final"]["model_point_error_m"] < acc["initial"]["model_point_error_m"]
    th = read_turbine_yaml(out_dir / "turbine.yaml")
    assert th.to_dict() == pytest.approx(summary["turbine"]["final"], rel=1e-12)
    assert f"tracked {N_KEYFRAMES} keyframes" in out and "99th percentile" in out
    assert out.rstrip().endswith(f"wrote {out_dir}")
    # the status line goes to stderr only when it is a terminal: nothing here
    assert "Traceback" not in err


def test_track_unbounded_window_and_options(good_flight: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "track"
    rc, out, err = run(capsys, "track", str(good_flight), "--out", str(out_dir), "--window", "0",
                       "--no-prior", "--points", "interp", "--no-plots", "--quiet")
    assert rc == 0, err
    assert out == "" and set(entries(out_dir)) == TRACK_OUTPUTS
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["config"]["tracker"]["window"] is None
    assert summary["config"]["tracker"]["theta_sigma"] is None
    assert summary["config"]["fit"]["points"] == "interp"


@pytest.mark.parametrize("args, patterns", [
    (["--window", "1"], ["--window", ">= 2"]),
    (["--preset", "turbine-only"], ["mode", "joint or pose"]),
    (["--preset", "nope"], ["unknown preset"]),
])
def test_track_bad_options(args: list[str], patterns: list[str], good_flight: Path,
                           tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "track"
    rc, out, err = run(capsys, "track", str(good_flight), "--out", str(out_dir), *args)
    assert_one_line_error(rc, out, err, *patterns)
    assert not out_dir.exists()


def test_track_bad_heatmap_names_the_file(flight: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    bad = np.load(heatmap(flight, 4))
    bad[2, 3, 3] = np.nan
    np.save(heatmap(flight, 4), bad)
    out_dir = tmp_path / "track"
    rc, out, err = run(capsys, "track", str(flight), "--out", str(out_dir))
    assert_one_line_error(rc, out, err, re.escape("4.000000.npy"), "NaN")
    assert not out_dir.exists() and entries(tmp_path) == ["flight"]


def test_track_refuses_to_write_into_its_input_or_over_other_files(
        good_flight: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = run(capsys, "track", str(good_flight), "--out", str(good_flight / "out"))
    assert_one_line_error(rc, out, err, "inside the input")
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("keep me\n")
    rc, out, err = run(capsys, "track", str(good_flight), "--out", str(other), "--overwrite")
    assert_one_line_error(rc, out, err, "notes.txt", "not an output of turbinefit track")
    assert (other / "notes.txt").read_text() == "keep me\n"
    # its own output is replaced with --overwrite
    mine = tmp_path / "mine"
    assert run(capsys, "track", str(good_flight), "--out", str(mine), "--no-plots")[0] == 0
    rc, out, err = run(capsys, "track", str(good_flight), "--out", str(mine))
    assert_one_line_error(rc, out, err, "--overwrite")
    assert run(capsys, "track", str(good_flight), "--out", str(mine), "--overwrite",
               "--no-plots")[0] == 0
