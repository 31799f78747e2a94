"""The command line as a whole: ``--version``, ``--help`` of every command, usage errors, and
the installed entry points (run in a subprocess for the real exit status)."""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from support import FIT_OUTPUTS, assert_one_line_error, entries, run

import turbinefit
from turbinefit.cli import build_parser, main


def test_entry_point_script_fits(sim_flight_dir: Path, tmp_path: Path) -> None:
    script = Path(sys.executable).with_name("turbinefit")
    if not script.exists():
        found = shutil.which("turbinefit")
        if found is None:
            pytest.skip("turbinefit script not installed")
        script = Path(found)
    out_dir = tmp_path / "fit"
    proc = subprocess.run([str(script), "fit", str(sim_flight_dir), "--out", str(out_dir), "--no-plots",
                           "--quiet", "--max-iterations", "2"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (proc.stdout, proc.stderr) == ("", "")
    assert set(entries(out_dir)) == FIT_OUTPUTS


def test_module_entry_point_bad_input_exit_status(flight_copy: Path, tmp_path: Path) -> None:
    (flight_copy / "camera.yaml").unlink()
    out_dir = tmp_path / "fit"
    proc = subprocess.run([sys.executable, "-m", "turbinefit.cli", "fit", str(flight_copy), "--out",
                           str(out_dir)], capture_output=True, text=True, timeout=120)
    assert_one_line_error(proc.returncode, proc.stdout, proc.stderr, r"camera\.yaml")
    assert not out_dir.exists()


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"turbinefit {turbinefit.__version__}"


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


def test_a_full_disk_anywhere_is_one_line_naming_the_final_path(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    import turbinefit.cli.report

    def full(args: argparse.Namespace) -> int:  # e.g. a figure saved into a temporary folder
        raise OSError(errno.ENOSPC, "No space left on device",
                      "/data/.out.tmp-123-0badc0de-0123456789ab/scene.png")

    monkeypatch.setattr(turbinefit.cli.report, "run", full)
    rc, out, err = run(capsys, "report", "anywhere")
    assert_one_line_error(rc, out, err, r"^turbinefit: error: no space left on device writing "
                          r"/data/out/scene\.png$")


def _all_parsers() -> dict[str, argparse.ArgumentParser]:
    """Every command's parser, sub-commands included ('import dji'), by name."""
    found: dict[str, argparse.ArgumentParser] = {}

    def walk(name: str, parser: argparse.ArgumentParser) -> None:
        found[name] = parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, p in action.choices.items():
                    walk(f"{name} {sub}".strip(), p)

    walk("", build_parser())
    return found


#: Every option that takes coordinates or a list of numbers, with negative values.
NEGATIVE_VALUES = [
    (["import", "dji", "p.jpg", "--out", "o", "--origin", "-5.2,-35.6,-12"], "origin",
     (-5.2, -35.6, -12.0)),
    (["import", "dji", "p.jpg", "--out", "o", "--turbine", "-33.9,-70.5"], "turbine",
     (-33.9, -70.5)),
    (["init", "f", "--near", "-40,-3.5"], "near", (-40.0, -3.5)),
    (["init", "f", "--near-wgs84", "-35.6,-149.1"], "near_wgs84", (-35.6, -149.1)),
    (["import", "rosbag", "b.bag", "--out", "o", "--image-topic", "/i", "--odometry-topic",
      "/o", "--body-T-cam", "-0.1,-0.2,-0.3,0,0,0,1"], "body_T_cam",
     (-0.1, -0.2, -0.3, 0.0, 0.0, 0.0, 1.0)),
    (["coverage", "fit", "--out", "o", "--blade-pitch", "-5e0"], "blade_pitch", -5.0),
]


@pytest.mark.parametrize(("argv", "dest", "expected"), NEGATIVE_VALUES)
def test_negative_numbers_are_values_of_every_option(argv: list[str], dest: str,
                                                     expected: object) -> None:
    args = build_parser({argv[0]}).parse_args(argv)
    value = getattr(args, dest)
    assert (tuple(value) if isinstance(value, tuple) else value) == pytest.approx(expected)


def test_every_option_of_several_numbers_is_tested_with_negative_values() -> None:
    # an option whose value is a comma-separated list of numbers (its metavar has a comma)
    # must be in NEGATIVE_VALUES above; those of train take no negative values
    tested = {opt for argv, _, _ in NEGATIVE_VALUES for opt in argv if opt.startswith("--")}
    lists = {opt for parser in _all_parsers().values() for action in parser._actions
             if action.metavar and "," in str(action.metavar)
             for opt in action.option_strings[:1]}
    assert lists, "no option of several numbers found"
    assert lists - tested == {"--channel-weights", "--widths"}


@pytest.mark.parametrize(("argv", "pattern"), [
    (["init", "f", "--near", "nan,0"], r"--near: X must be a number, got nan"),
    (["init", "f", "--near-wgs84", "nan,nan"], r"latitude must be a number, got nan"),
    (["init", "f", "--near-wgs84", "91,0"], r"latitude 91.0 deg is out of range"),
    (["import", "dji", "p.jpg", "--out", "o", "--origin", "-5.2,-35.6"],
     r"expected LAT,LON,ALT"),
    (["import", "dji", "p.jpg", "--out", "o", "--origin", "0,0,1e9"],
     r"altitude 1000000000.0 m is out of range"),
    (["coverage", "fit", "--out", "o", "--gsd", "inf"], r"--gsd"),
    (["import", "dji", "p.jpg", "--out", "o", "--origin", "95,0,10"],
     r"--origin: latitude 95.0 deg is out of range"),
    (["fit", "f", "--out", "o", "--lambda-points", "nan"],
     r"--lambda-points: expected a finite number, got 'nan'"),
    (["simulate", "o", "--turbine-noise", "nan"], r"--turbine-noise: expected a finite number"),
    (["simulate", "o", "--heatmap-noise", "inf"], r"--heatmap-noise: expected a finite number"),
])
def test_numbers_out_of_range_are_usage_errors(argv: list[str], pattern: str, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str],
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert re.search(pattern, err.splitlines()[-1]), err
    assert entries(tmp_path) == []
