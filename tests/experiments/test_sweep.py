"""Monte Carlo sweeps (turbinefit.experiments.sweep): a tiny sweep end to end, its rows
against the fits they ran, resume after an interruption, parallel and Ray backends, bad
configurations, failing fits as rows."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import tiny_sweep

from turbinefit.eval.metrics import accuracy
from turbinefit.experiments import SweepConfig, read_rows, run_study, run_sweep
from turbinefit.experiments import sweep as sweep_mod
from turbinefit.experiments.studies import reduction_stats
from turbinefit.experiments.sweep import COLUMNS, flight_specs, run_flight
from turbinefit.solver.fit import fit


def test_tiny_unary_sweep_end_to_end(tmp_path: Path) -> None:
    cfg = tiny_sweep("unary")
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
    cfg = tiny_sweep("joint", flights=1)
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
    a = flight_specs(tiny_sweep(flights=3))
    b = flight_specs(tiny_sweep(flights=5))
    assert a == b[:3] and len({s.seed for s in b}) == 5
    lo, hi = tiny_sweep().pose_scale
    assert all(lo <= s.pose_scale <= hi for s in b)


def test_interrupted_sweep_resumes_without_redoing_rows(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = tiny_sweep("joint")
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
    cfg = tiny_sweep("turbine", flights=2)
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
    rep = run_study(tiny_sweep("turbine", flights=2), out, workers=1)
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
    d = {**tiny_sweep().to_dict(), **change}
    with pytest.raises(ValueError, match=why):
        SweepConfig.from_dict(d)


def test_a_folder_of_another_sweep_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "s"
    run_sweep(tiny_sweep("turbine", flights=1), out, workers=1)
    from turbinefit.errors import InputError

    with pytest.raises(InputError, match="different sweep"):
        run_sweep(tiny_sweep("turbine", flights=1, seed=5), out, workers=1)
    # a folder of the user's own files is never written into
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.md").write_text("my notes\n")
    with pytest.raises(InputError, match="holds no sweep"):
        run_sweep(tiny_sweep("turbine", flights=1), mine, workers=1)
    assert [p.name for p in mine.iterdir()] == ["report.md"]


def test_ray_backend_gives_the_same_rows(tmp_path: Path) -> None:
    """The Ray backend on a local Ray instance (the cluster case differs only in
    ``RAY_ADDRESS``). Needs ``pip install ray``; skipped without it."""
    ray = pytest.importorskip("ray")
    cfg = tiny_sweep("turbine", flights=2)
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
        run_sweep(tiny_sweep("turbine", flights=1), tmp_path / "s", backend="ray")


def test_second_turbine_fraction() -> None:
    specs = flight_specs(tiny_sweep(flights=200, second_turbine=0.5))
    share = np.mean([s.second_turbine for s in specs])
    assert 0.4 < share < 0.6
    assert not any(s.second_turbine for s in flight_specs(tiny_sweep(flights=20)))
    assert SweepConfig.from_dict({**tiny_sweep().to_dict(), "second_turbine": True}).second_turbine == 1.0
    with pytest.raises(ValueError, match="second_turbine"):
        SweepConfig.from_dict({**tiny_sweep().to_dict(), "second_turbine": 1.5})
