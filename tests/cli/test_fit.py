"""``turbinefit fit`` run the way a user runs it: outputs, modes, unary costs, presets,
configuration files, and fitting from photos. Most runs are in-process through
:func:`turbinefit.cli.main`; the flight is the session's ``sim_flight_dir`` (conftest.py)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import (
    FIT_OUTPUTS,
    N_KEYFRAMES,
    assert_one_line_error,
    assert_turbine_glb,
    assert_valid_png,
    digest,
    entries,
    one_line_error,
    poses_array,
    run,
)

import turbinefit
from turbinefit.cli import main
from turbinefit.io import read_turbine_yaml
from turbinefit.io.fit_config import read_fit_config
from turbinefit.io.images import read_image, write_png
from turbinefit.jobs.sources import FILE_FIT_DEFAULTS
from turbinefit.solver.config import PRESETS, FitConfig

PLOTS = {"scene.png", "reprojections.png", "errors.png", "cost.png"}


def test_fit_joint_with_plots(sim_flight_dir: Path, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(sim_flight_dir)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(out_dir))
    assert rc == 0, err
    assert "Traceback" not in err

    # everything written, nothing else, inputs untouched
    assert set(entries(out_dir)) == FIT_OUTPUTS | PLOTS
    assert entries(tmp_path) == ["fit"]  # no temporary siblings left
    assert digest(sim_flight_dir) == before
    for name in PLOTS:
        assert_valid_png(out_dir / name)

    # keyframes.txt: same timestamps, unit quaternions, poses moved
    t_in, p_in = poses_array(sim_flight_dir / "keyframes.txt")
    t_out, p_out = poses_array(out_dir / "keyframes.txt")
    np.testing.assert_array_equal(t_out, t_in)
    assert np.allclose(np.linalg.norm(p_out[:, :4], axis=1), 1.0)
    assert np.isfinite(p_out).all() and not np.allclose(p_out, p_in, atol=1e-6)

    # config.yaml is the run's configuration (defaults here, with pair_frame="auto"
    # resolved: GPS/IMU keyframes, no odometry.txt; pixel_scale resolved: 160 px maps use
    # the pixel settings as written) and loads back
    cfg = read_fit_config(out_dir / "config.yaml")
    # no options: the defaults for heat-map files, the pairwise frame resolved
    assert cfg == FitConfig(pair_frame="measured", pixel_scale=1.0, **FILE_FIT_DEFAULTS)
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
        read_turbine_yaml(sim_flight_dir / "turbine.yaml").to_dict(), rel=1e-12)
    assert th.to_dict() != pytest.approx(summary["turbine"]["initial"])
    # turbine.glb is that turbine, dressed (read back by an independent glTF reader)
    assert_turbine_glb(out_dir / "turbine.glb", th, cfg.geometry)

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
def test_fit_modes_and_unary_costs(variant: str, sim_flight_dir: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    args = FIT_VARIANTS[variant]
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(out_dir), "--no-plots",
                       "--quiet", "--max-iterations", "5", *args)
    assert rc == 0, err
    summary = json.loads((out_dir / "summary.json").read_text())
    # --quiet: nothing but the warning of a doubtful verdict (5 iterations on 12 keyframes;
    # pose-only and turbine-only fits keep a wrong half of the problem)
    assert out == ""
    assert err == ("" if summary["verdict"] == "ok" else
                   f"turbinefit: warning: fit doubtful: {'; '.join(summary['reasons'])} "
                   f"(outputs in {out_dir})\n")
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
    t_in, p_in = poses_array(sim_flight_dir / "keyframes.txt")
    t_out, p_out = poses_array(out_dir / "keyframes.txt")
    np.testing.assert_array_equal(t_out, t_in)
    th_in = read_turbine_yaml(sim_flight_dir / "turbine.yaml").to_dict()
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


def test_fit_config_file_round_trip(sim_flight_dir: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    first = tmp_path / "first"
    rc, _, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(first), "--no-plots", "--quiet",
                     "--points", "interp", "--lambda-pair", "2.5", "--robust", "huber",
                     "--pair-sigma-r", "0.2", "--max-iterations", "5")
    assert rc == 0, err
    cfg1 = read_fit_config(first / "config.yaml")
    assert cfg1 == dataclasses.replace(FitConfig(**FILE_FIT_DEFAULTS), points="interp",
                                       lambda_pair=2.5, robust="huber",
                                       pair_sigma_r_deg=0.2, max_iterations=5,
                                       pair_frame="measured", pixel_scale=1.0)  # resolved
    # a previous run's config.yaml as --config; command-line options override it
    second = tmp_path / "second"
    rc, _, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(second), "--no-plots", "--quiet",
                     "--config", str(first / "config.yaml"), "--max-iterations", "4")
    assert rc == 0, err
    assert read_fit_config(second / "config.yaml") == dataclasses.replace(cfg1, max_iterations=4)


def test_fit_preset(sim_flight_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "fit"
    rc, _, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(out_dir), "--no-plots", "--quiet",
                     "--preset", "all-corr", "--max-iterations", "3")
    assert rc == 0, err
    assert read_fit_config(out_dir / "config.yaml") == dataclasses.replace(
        PRESETS["all-corr"], max_iterations=3, pair_frame="measured", pixel_scale=1.0)


def test_fit_never_modifies_its_input(flight_copy: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    before = digest(flight_copy)
    rc, _, err = run(capsys, "fit", str(flight_copy), "--out", str(tmp_path / "fit"), "--quiet", "--no-plots")
    assert rc == 0, err
    assert digest(flight_copy) == before
    assert entries(tmp_path) == ["fit", "flight"]


def test_fit_into_an_existing_empty_dir(sim_flight_dir: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "fit"
    out_dir.mkdir()
    rc, _, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(out_dir), "--no-plots", "--quiet",
                     "--max-iterations", "2")
    assert rc == 0, err
    assert set(entries(out_dir)) == FIT_OUTPUTS


def test_fit_existing_output_needs_overwrite(sim_flight_dir: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = tmp_path / "fit"
    common = ["fit", str(sim_flight_dir), "--out", str(out_dir), "--no-plots", "--quiet"]
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


def test_simulate_images_and_fit_from_them(photo_flight: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    photos = sorted((photo_flight / "images").iterdir())
    assert len(photos) == 6 and photos[0].name == "0.000000.png"
    assert read_image(photos[0]).shape == (120, 160, 3)
    # no heat-maps: fit detects them from the photos
    shutil.rmtree(photo_flight / "heatmaps")
    out = tmp_path / "fit"
    assert main(["fit", str(photo_flight), "--out", str(out), "--no-plots", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["heatmaps"].startswith("detected from images/")
    assert not (photo_flight / "heatmaps").exists()
    # --no-flip reaches the detector: other heat-maps, another (if close) fit
    assert main(["fit", str(photo_flight), "--out", str(tmp_path / "fit_nf"), "--no-plots",
                 "--quiet", "--no-flip"]) == 0
    assert (tmp_path / "fit_nf" / "turbine.yaml").read_text() != \
        (out / "turbine.yaml").read_text()
    # so does --tip-shift (0: the net's own tip channel)
    assert main(["fit", str(photo_flight), "--out", str(tmp_path / "fit_ts"), "--no-plots",
                 "--quiet", "--tip-shift", "0"]) == 0
    assert (tmp_path / "fit_ts" / "turbine.yaml").read_text() != \
        (out / "turbine.yaml").read_text()
    # a photo missing / of the wrong size: one clear error, nothing written
    capsys.readouterr()  # the warnings of doubtful verdicts (6 keyframes)
    photos[3].unlink()
    assert main(["fit", str(photo_flight), "--out", str(tmp_path / "fit2"), "--quiet"]) == 2
    one_line_error(capsys, "keyframe 3")
    write_png(photos[3], np.zeros((60, 80, 3), np.uint8))
    assert main(["fit", str(photo_flight), "--out", str(tmp_path / "fit2"), "--quiet"]) == 2
    one_line_error(capsys, "80x60", "camera.yaml")
    assert not (tmp_path / "fit2").exists()


def test_fit_defaults_follow_the_heatmap_source(photo_flight_dir: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """With no --config or --preset, fit starts from the options measured best for its
    kind of heat-maps (FILE_FIT_DEFAULTS, PHOTO_FIT_DEFAULTS), says so, and records them;
    options given on the command line still win, and a preset replaces the defaults."""
    from turbinefit.jobs.sources import PHOTO_FIT_DEFAULTS

    assert dict(FILE_FIT_DEFAULTS) != dict(PHOTO_FIT_DEFAULTS)

    def run_fit(name: str, *extra: str) -> tuple[dict, dict, str]:
        out = tmp_path / name
        assert main(["fit", str(photo_flight_dir), "--out", str(out), "--no-plots",
                     "--max-iterations", "2", *extra]) == 0
        text = capsys.readouterr().out
        return (yaml.safe_load((out / "config.yaml").read_text()),
                json.loads((out / "summary.json").read_text()), text)

    cfg, summary, text = run_fit("files")
    assert {k: cfg[k] for k in FILE_FIT_DEFAULTS} == dict(FILE_FIT_DEFAULTS)
    assert summary["defaults"].startswith("heat-map files")
    assert "options: the defaults for heat-map files" in text
    cfg, summary, text = run_fit("photos", "--from-images")
    assert {k: cfg[k] for k in PHOTO_FIT_DEFAULTS} == dict(PHOTO_FIT_DEFAULTS)
    assert "detected from photos" in summary["defaults"] and "detected from photos" in text
    cfg, summary, _ = run_fit("photos_interp", "--from-images", "--points", "interp")
    assert (cfg["points"], cfg["robust"]) == ("interp", PHOTO_FIT_DEFAULTS["robust"])
    cfg, summary, _ = run_fit("photos_preset", "--from-images", "--preset", "paper-best")
    assert (cfg["lines"], cfg["robust"]) == ("interp", "huber") and "defaults" not in summary
    # 320 px photos: coarse to fine has nothing to add, and turning it off changes nothing
    _, refined, _ = run_fit("photos_refine", "--from-images")
    _, plain, _ = run_fit("photos_no_refine", "--from-images", "--no-refine")
    assert refined["turbine"] == plain["turbine"] and refined["heatmaps"] == plain["heatmaps"]
    assert "coarse to fine" not in refined["heatmaps"]


@pytest.mark.parametrize("value", [0.0, 1.0, 0.3])
def test_fit_without_evidence_fails_with_status_3(value: float, flight_copy: Path,
                                                  tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Heat-maps in range but without evidence: the outputs are written for inspection,
    the verdict is failed, one warning line, exit status 3; summary.json is strict JSON."""
    for f in (flight_copy / "heatmaps").iterdir():
        np.save(f, np.full_like(np.load(f), value))
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(flight_copy), "--out", str(out_dir), "--no-plots")
    assert rc == 3
    assert set(entries(out_dir)) == FIT_OUTPUTS
    assert "verdict: failed" in out
    assert err.count("\n") == 1 and err.startswith("turbinefit: warning: fit failed: ")
    assert "heat-map evidence" in err and str(out_dir) in err

    def strict(text: str) -> None:
        raise AssertionError(f"non-strict JSON constant {text}")

    summary = json.loads((out_dir / "summary.json").read_text(), parse_constant=strict)
    assert summary["verdict"] == "failed" and summary["reasons"]
    assert summary["signals"]["evidence_share"] == 0.0
    th = read_turbine_yaml(out_dir / "turbine.yaml")
    assert th.nacelle_length >= 0 and th.tower_height >= 10 and th.blade_length >= 5


def test_fit_help_documents_the_exit_statuses(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    out = capsys.readouterr().out
    assert "3 verdict failed (outputs written)" in out


@pytest.mark.parametrize("command", ["fit", "track"])
def test_help_gives_the_defaults_a_job_starts_from(command: str,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """Each fit option's help gives the default of a job with neither --config nor
    --preset (per kind of heat-maps where they differ: FILE_FIT_DEFAULTS,
    PHOTO_FIT_DEFAULTS), and FitConfig's where that differs; no preset is called the
    default."""
    from turbinefit.jobs.sources import PHOTO_FIT_DEFAULTS

    with pytest.raises(SystemExit):
        main([command, "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "(default)" not in out
    assert FILE_FIT_DEFAULTS["lines"] == PHOTO_FIT_DEFAULTS["lines"] == "corr"
    assert "--lines {interp,corr,none} Unary cost of the line samples (same choices). " \
        "(default: corr; FitConfig: interp)" in out
    assert "(default: 2 on heat-map files, 0.5 from photos)" in out  # robust_scale
    assert "(default: 0.5 on heat-map files, 2 from photos)" in out  # pixel_sigma
    assert "(default: cauchy; FitConfig: huber)" in out
    assert "--gauge {first,gps} first: hold the first keyframe's pose; gps: weak absolute " \
        "position priors instead. (default: first)" in out


def test_summary_json_is_strict() -> None:
    from turbinefit.jobs.outputs import summary_json

    class S:
        def to_dict(self) -> dict:
            return {"a": math.inf, "b": [math.nan, 1.0], "c": {"d": -math.inf}}

    assert json.loads(summary_json(S())) == {"a": None, "b": [None, 1.0], "c": {"d": None}}

