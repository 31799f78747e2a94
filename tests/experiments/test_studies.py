"""Studies and their reports (turbinefit.experiments.studies): the roll artefact, basin
tables, deterministic reports, the quality and length studies."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

from support import tiny_sweep

from turbinefit.experiments import run_study, run_sweep, study_config, write_report
from turbinefit.experiments.studies import basin_table, summarize
from turbinefit.experiments.sweep import flight_specs


def test_roll_artefact_pose_only_rolls_joint_does_not(tmp_path: Path) -> None:
    """A wrong blade rotation: pose-only optimisation rolls the cameras to match the
    blades, joint optimisation fixes the blades instead (paper Section IV-B)."""
    cfg = tiny_sweep("roll", flights=2, keyframes=20, width=320, height=240)
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
    run_study(tiny_sweep("turbine", flights=2), out, workers=1)
    first = (out / "report.md").read_text()
    write_report(out)
    assert (out / "report.md").read_text() == first


def test_quality_and_length_studies(tmp_path: Path) -> None:
    q = tiny_sweep("quality", flights=4)
    specs = flight_specs(q)
    assert all(0.5 <= s.blur_scale <= 3.0 and 0 <= s.heatmap_scale <= 4 for s in specs)
    rep = run_study(q, tmp_path / "q", workers=1)
    assert len(rep.rows) == 8 and all(r["status"] == "ok" for r in rep.rows)
    assert {r["second_turbine"] for r in rep.rows} <= {True, False}
    report = (tmp_path / "q" / "report.md").read_text()
    assert "by heat-map blob width" in report and (tmp_path / "q" / "factors.png").is_file()


    n = dataclasses.replace(study_config("length"), flights=6, width=160, height=120,
                            keyframes=8, keyframes_max=30)
    ks = [s.keyframes for s in flight_specs(n)]
    assert all(8 <= k <= 30 for k in ks) and len(set(ks)) > 1
    rows = run_sweep(n, tmp_path / "n", workers=1).rows
    assert [r["keyframes"] for r in rows] == ks
    s = summarize(n, rows)["factors"]["keyframes"]["joint"]
    assert sum(b["flights"] for b in s) == sum(25 <= k < 400 for k in ks)


def test_odometry_study_compares_the_pair_frames_on_both_kinds_of_flight(tmp_path: Path) -> None:
    from turbinefit.experiments.sweep import COLUMNS, read_rows

    cfg = tiny_sweep("odometry", flights=4)
    specs = flight_specs(cfg)
    assert {s.odometry for s in specs} == {"gps", "vio"}
    # the odometry draw comes last: the flights are those of a sweep without it
    plain = flight_specs(dataclasses.replace(cfg, odometry=0.0))
    assert [dataclasses.replace(s, odometry="gps") for s in specs] == plain
    assert {s.odometry for s in plain} == {"gps"}
    rep = run_study(cfg, tmp_path / "o", workers=1)
    assert len(rep.rows) == 16 and all(r["status"] == "ok" for r in rep.rows)
    for r in rep.rows:
        assert r["odometry"] == specs[r["flight"]].odometry
    by = summarize(cfg, rep.rows)["by_odometry"]
    assert set(by) == {"gps", "vio"} and set(by["vio"]) == set(cfg.configs)
    # auto is measured on gps flights and estimated on vio flights
    gps = {r["config"]: r["final_position_m"] for r in rep.rows if r["odometry"] == "gps"
           and r["flight"] == next(s.index for s in specs if s.odometry == "gps")}
    assert gps["auto"] == gps["measured"]
    vio = {r["config"]: r["final_position_m"] for r in rep.rows if r["odometry"] == "vio"
           and r["flight"] == next(s.index for s in specs if s.odometry == "vio")}
    assert vio["auto"] == vio["estimated"]
    assert "by kind of pose measurements" in (tmp_path / "o" / "report.md").read_text()
    # a table written before the odometry column is read as gps flights
    table = tmp_path / "o" / "rows.csv"
    with open(table, newline="") as f:
        lines = list(csv.reader(f))
    i = COLUMNS.index("odometry")
    with open(table, "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(
            [c for j, c in enumerate(line) if j != i] for line in lines)
    assert {r["odometry"] for r in read_rows(table)} == {"gps"}
