"""Monte Carlo sweeps and studies: a tiny sweep end to end, its numbers against the fits
it ran, resume after an interruption, bad configurations, failing fits as rows."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from turbinefit.cli import main
from turbinefit.eval.metrics import accuracy
from turbinefit.experiments import (
    SweepConfig,
    read_rows,
    run_study,
    run_sweep,
    study_config,
    write_report,
)
from turbinefit.experiments import sweep as sweep_mod
from turbinefit.experiments.studies import basin_table, reduction_stats, summarize
from turbinefit.experiments.sweep import COLUMNS, flight_specs, run_flight
from turbinefit.solver.fit import fit

TINY = dict(flights=3, keyframes=12, width=160, height=120)


def tiny(study: str = "unary", **kw: object) -> SweepConfig:
    import dataclasses

    return dataclasses.replace(study_config(study), **{**TINY, **kw})  # type: ignore[arg-type]


def test_tiny_unary_sweep_end_to_end(tmp_path: Path) -> None:
    cfg = tiny("unary")
    out = tmp_path / "unary"
    seen: list[tuple[int, int]] = []
    rep = run_study(cfg, out, workers=1, progress=lambda d, t: seen.append((d, t)))
    assert rep.new_rows == 3 * 4 and seen[-1] == (3, 3)
    for name in ("rows.csv", "sweep.yaml", "runs.json", "summary.json", "report.md",
                 "errors.png", "turbine.png"):
        assert (out / name).is_file(), name
    rows = read_rows(out / "rows.csv")
    assert len(rows) == 12 and all(r["status"] == "ok" for r in rows)
    assert {r["config"] for r in rows} == set(cfg.configs)
    # the sweep configuration round-trips and is the resolved one
    assert SweepConfig.from_dict(yaml.safe_load((out / "sweep.yaml").read_text())) == cfg
    report = (out / "report.md").read_text()
    assert "Ranking by median final position error" in report and "![" in report
    for name in cfg.configs:
        assert f"| {name} | 3 |" in report


def test_rows_are_the_fits_they_ran() -> None:
    """A row's numbers are those of simulating its flight and fitting it directly."""
    cfg = tiny("joint", flights=1)
    spec = flight_specs(cfg)[0]
    rows = run_flight(cfg, spec, ["joint"])
    assert len(rows) == 1 and rows[0]["status"] == "ok"
    from turbinefit.sim.scenario import simulate_flight

    flight = simulate_flight(sweep_mod._sim_config(cfg, spec))
    assert flight.gt_world_T_cam is not None and flight.gt_turbine is not None
    res = fit(flight, sweep_mod.fit_config(cfg.configs, "joint"))
    before = accuracy(flight.world_T_cam, flight.turbine, flight.gt_world_T_cam,
                      flight.gt_turbine)
    after = accuracy(res.world_T_cam, res.turbine, flight.gt_world_T_cam, flight.gt_turbine)
    r = rows[0]
    assert r["init_position_m"] == pytest.approx(before.position_error_m, rel=1e-12)
    assert r["final_position_m"] == pytest.approx(after.position_error_m, rel=1e-9)
    assert r["final_model_points_m"] == pytest.approx(after.model_point_error_m, rel=1e-9)
    assert r["final_cost"] == pytest.approx(res.final_cost, rel=1e-9)
    assert r["iterations"] == res.iterations
    # a summary's statistics are those of the rows
    s = reduction_stats(rows, "position_m")
    assert s["final_median"] == pytest.approx(after.position_error_m, rel=1e-9)
    assert s["reduction_median_pct"] == pytest.approx(
        100 * (1 - after.position_error_m / before.position_error_m), rel=1e-9)


def test_flights_do_not_depend_on_the_sweep_size() -> None:
    a = flight_specs(tiny(flights=3))
    b = flight_specs(tiny(flights=5))
    assert a == b[:3] and len({s.seed for s in b}) == 5
    lo, hi = tiny().pose_scale
    assert all(lo <= s.pose_scale <= hi for s in b)


def test_interrupted_sweep_resumes_without_redoing_rows(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = tiny("joint")
    out = tmp_path / "joint"
    calls: list[int] = []
    real = sweep_mod.run_flight

    def flaky(c: SweepConfig, spec: sweep_mod.FlightSpec, names: list[str]) -> list[dict]:
        calls.append(spec.index)
        if spec.index == 2:
            raise KeyboardInterrupt  # the user pressed Ctrl-C during flight 2
        return real(c, spec, names)

    monkeypatch.setattr(sweep_mod, "run_flight", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(cfg, out, workers=1)
    rows = read_rows(out / "rows.csv")
    assert sorted({r["flight"] for r in rows}) == [0, 1] and len(rows) == 4
    # a line cut short by the interruption is ignored, and that flight is redone
    with open(out / "rows.csv", "a") as f:
        f.write("2,joint,ok,,123")
    monkeypatch.setattr(sweep_mod, "run_flight", real)
    calls.clear()
    monkeypatch.setattr(sweep_mod, "run_flight",
                        lambda c, s, n: (calls.append(s.index), real(c, s, n))[1])
    rep = run_sweep(cfg, out, workers=1)
    assert calls == [2] and rep.new_rows == 2
    rows = read_rows(out / "rows.csv")
    assert len(rows) == 6 and sorted({r["flight"] for r in rows}) == [0, 1, 2]
    # a third run has nothing to do
    calls.clear()
    assert run_sweep(cfg, out, workers=1).new_rows == 0 and calls == []


def test_parallel_workers_give_the_same_rows(tmp_path: Path) -> None:
    cfg = tiny("turbine", flights=2)
    a = run_sweep(cfg, tmp_path / "a", workers=1).rows
    b = run_sweep(cfg, tmp_path / "b", workers=2).rows
    keys = [c for c in COLUMNS if c != "time_s"]
    assert [[r[k] for k in keys] for r in a] == [[r[k] for k in keys] for r in b]


def test_a_failing_fit_is_a_row_with_its_reason(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    def boom(*args: object, **kw: object) -> None:
        raise np.linalg.LinAlgError("singular matrix")

    monkeypatch.setattr(sweep_mod, "fit", boom)
    out = tmp_path / "s"
    rep = run_study(tiny("turbine", flights=2), out, workers=1)
    assert [r["status"] for r in rep.rows] == ["error", "error"]
    assert all("LinAlgError: singular matrix" in r["reason"] for r in rep.rows)
    assert all(r["final_position_m"] is None and math.isfinite(r["init_position_m"])
               for r in read_rows(out / "rows.csv"))
    assert "## Failed fits" in (out / "report.md").read_text()


@pytest.mark.parametrize("change, why", [
    ({"flights": 0}, "flights"),
    ({"pose_scale": (2.0, 1.0)}, "pose_scale"),
    ({"configs": {}}, "configs"),
    ({"configs": {"x": {"points": "nope"}}}, "configs.x"),
    ({"configs": {"x": {"no_such_option": 1}}}, "unknown fit option"),
    ({"configs": {"x": {"preset": "nope"}}}, "unknown preset"),
    ({"turbine": "windmill"}, "unknown turbine"),
])
def test_bad_sweep_configurations(change: dict, why: str) -> None:
    d = {**tiny().to_dict(), **change}
    with pytest.raises(ValueError, match=why):
        SweepConfig.from_dict(d)


def test_unknown_sweep_key_and_cli_errors(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="unknown sweep option"):
        SweepConfig.from_dict({"flihgts": 3})
    bad = tmp_path / "bad.yaml"
    bad.write_text("flights: 3\nkeyframez: 10\n")
    out = tmp_path / "out"
    assert main(["experiment", "unary", "--config", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.yaml" in err[0] and "keyframez" in err[0]
    assert not out.exists()  # nothing started
    assert main(["report", str(tmp_path)]) == 2
    assert "not an experiment folder" in capsys.readouterr().err


def test_a_folder_of_another_sweep_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "s"
    run_sweep(tiny("turbine", flights=1), out, workers=1)
    from turbinefit.errors import InputError

    with pytest.raises(InputError, match="different sweep"):
        run_sweep(tiny("turbine", flights=1, seed=5), out, workers=1)
    # a folder of the user's own files is never written into
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.md").write_text("my notes\n")
    with pytest.raises(InputError, match="holds no sweep"):
        run_sweep(tiny("turbine", flights=1), mine, workers=1)
    assert [p.name for p in mine.iterdir()] == ["report.md"]


def test_cli_experiment_and_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tiny("roll", flights=2)
    sweep_file = tmp_path / "roll.yaml"
    sweep_file.write_text(yaml.safe_dump(cfg.to_dict()))
    out = tmp_path / "roll"
    assert main(["experiment", "roll", "--config", str(sweep_file), "--out", str(out),
                 "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "roll: 4 rows" in printed and "rows/s" in printed
    report = (out / "report.md").read_text()
    assert "Mean absolute camera roll error" in report and (out / "roll.png").is_file()
    # the report is rebuilt from the rows alone
    (out / "report.md").unlink()
    (out / "roll.png").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "report.md").read_text() == report and (out / "roll.png").is_file()
    # `report` on a parent folder rebuilds every study below it
    shutil.copytree(out, tmp_path / "all" / "roll")
    assert main(["report", str(tmp_path / "all")]) == 0
    index = (tmp_path / "all" / "report.md").read_text()
    assert "| roll | 2 x 2 |" in index and "(roll/report.md)" in index


def test_roll_artefact_pose_only_rolls_joint_does_not(tmp_path: Path) -> None:
    """A wrong blade rotation: pose-only optimisation rolls the cameras to match the
    blades, joint optimisation fixes the blades instead (paper Section IV-B)."""
    cfg = tiny("roll", flights=2, keyframes=20, width=320, height=240)
    rep = run_sweep(cfg, tmp_path / "roll", workers=1)
    s = summarize(cfg, rep.rows)["roll_deg_mean_abs"]
    assert s["initial"] < 0.05  # exact attitude to start with
    assert s["pose-only"] > 5 * s["joint"] and s["pose-only"] > 0.3, s


def test_basin_table_counts_successes() -> None:
    rows = [
        {"status": "ok", "theta_scale": 0.5, "pose_scale": 0.5, "final_position_m": 0.2,
         "final_model_points_m": 0.1},
        {"status": "ok", "theta_scale": 0.7, "pose_scale": 0.2, "final_position_m": 0.9,
         "final_model_points_m": 0.1},
        {"status": "error", "theta_scale": 4.5, "pose_scale": 0.5, "final_position_m": None,
         "final_model_points_m": None},
    ]
    b = basin_table(rows)
    assert b["count"][0][0] == 2 and b["rate"][0][0] == 0.5
    assert b["rate"][4][0] == 0.0 and b["by_theta_scale"][0] == 0.5
    assert b["rate"][1][1] is None


def test_report_rebuild_is_deterministic(tmp_path: Path) -> None:
    out = tmp_path / "t"
    run_study(tiny("turbine", flights=2), out, workers=1)
    first = (out / "report.md").read_text()
    write_report(out)
    assert (out / "report.md").read_text() == first


def test_ray_backend_gives_the_same_rows(tmp_path: Path) -> None:
    """The Ray backend on a local Ray instance (the cluster case differs only in
    ``RAY_ADDRESS``). Needs ``pip install ray``; skipped without it."""
    ray = pytest.importorskip("ray")
    cfg = tiny("turbine", flights=2)
    try:
        b = run_sweep(cfg, tmp_path / "ray", backend="ray").rows
    finally:
        ray.shutdown()
    a = run_sweep(cfg, tmp_path / "local", workers=1).rows
    keys = [c for c in COLUMNS if c != "time_s"]
    assert [[r[k] for k in keys] for r in a] == [[r[k] for k in keys] for r in b]


def test_ray_backend_without_ray_is_one_clear_error(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    real_import = builtins.__import__

    def no_ray(name: str, *args: object, **kw: object) -> object:
        if name == "ray":
            raise ImportError("No module named 'ray'")
        return real_import(name, *args, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(builtins, "__import__", no_ray)
    from turbinefit.errors import InputError

    with pytest.raises(InputError, match="pip install"):
        run_sweep(tiny("turbine", flights=1), tmp_path / "s", backend="ray")


def test_quality_and_length_studies(tmp_path: Path) -> None:
    q = tiny("quality", flights=4)
    specs = flight_specs(q)
    assert all(0.5 <= s.blur_scale <= 3.0 and 0 <= s.heatmap_scale <= 4 for s in specs)
    rep = run_study(q, tmp_path / "q", workers=1)
    assert len(rep.rows) == 8 and all(r["status"] == "ok" for r in rep.rows)
    assert {r["second_turbine"] for r in rep.rows} <= {True, False}
    report = (tmp_path / "q" / "report.md").read_text()
    assert "by heat-map blob width" in report and (tmp_path / "q" / "factors.png").is_file()
    import dataclasses

    n = dataclasses.replace(study_config("length"), flights=6, width=160, height=120,
                            keyframes=8, keyframes_max=30)
    ks = [s.keyframes for s in flight_specs(n)]
    assert all(8 <= k <= 30 for k in ks) and len(set(ks)) > 1
    rows = run_sweep(n, tmp_path / "n", workers=1).rows
    assert [r["keyframes"] for r in rows] == ks
    s = summarize(n, rows)["factors"]["keyframes"]["joint"]
    assert sum(b["flights"] for b in s) == sum(25 <= k < 400 for k in ks)


def test_second_turbine_fraction() -> None:
    specs = flight_specs(tiny(flights=200, second_turbine=0.5))
    share = np.mean([s.second_turbine for s in specs])
    assert 0.4 < share < 0.6
    assert not any(s.second_turbine for s in flight_specs(tiny(flights=20)))
    assert SweepConfig.from_dict({**tiny().to_dict(), "second_turbine": True}).second_turbine == 1.0
    with pytest.raises(ValueError, match="second_turbine"):
        SweepConfig.from_dict({**tiny().to_dict(), "second_turbine": 1.5})
