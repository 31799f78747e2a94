"""The inspection mission in the loop (turbinefit.mission): a short mission closes the
loop and writes what the commands write; the closed loop keeps the stand-off where flying
the typed-in turbine's plan on GNSS alone does not; the figures are judged against the
truth."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.mission import InitialError, MissionConfig, mission_outcome, run_mission
from turbinefit.mission.loop import Navigation
from turbinefit.turbine.model import TurbineParams

#: A small inspection camera: 1280 x 960, 4.2 mm/px at 10 m (flown 10.3 m).
SMALL = PinholeCamera(1280, 960, 2400.0, 2400.0, 639.5, 479.5)


@dataclass(frozen=True)
class HeadingOff(InitialError):
    """The typed-in turbine off by exactly ``degrees`` in heading, nothing else."""

    degrees: float = 10.0

    def draw(self, truth: TurbineParams, rng: np.random.Generator) -> TurbineParams:
        v = truth.to_vector()
        v[3] += math.radians(self.degrees)
        return TurbineParams.from_vector(v)


def _config(**kw: object) -> MissionConfig:
    base = {"camera": SMALL, "gsd_mm": 5.0, "maps": "ideal", "defects": 0, "seed": 3}
    base.update(kw)
    return MissionConfig(**base)  # type: ignore[arg-type]


def test_the_navigation_flies_to_where_it_believes_the_waypoint_is() -> None:
    from turbinefit.geometry.se3 import SE3, quat_exp, quat_multiply

    nav = Navigation(closed_loop=True)
    target = SE3(np.array([1.0, 0.0, 0.0, 0.0, 10.0, -4.0, 50.0]))
    assert np.allclose(nav.command(target).wxyz_xyz, target.wxyz_xyz)  # nothing learnt yet
    # the tracker found the recorded pose 1.2 m east and 2 deg of yaw off its estimate
    estimated = SE3(np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 30.0]))
    dq = quat_exp(np.array([0.0, 0.0, math.radians(2.0)]))
    recorded = SE3(np.concatenate([quat_multiply(dq, estimated.wxyz), [1.2, 0.0, 30.0]]))
    nav.correct(recorded, estimated)
    cmd = nav.command(target)
    assert np.allclose(cmd.translation, target.translation + np.array([1.2, 0.0, 0.0]))
    assert np.allclose(cmd.wxyz, quat_multiply(dq, target.wxyz))
    assert np.allclose(nav.believed(cmd).wxyz_xyz, target.wxyz_xyz)
    open_loop = Navigation(closed_loop=False)
    open_loop.correct(recorded, estimated)
    assert np.allclose(open_loop.command(target).wxyz_xyz, target.wxyz_xyz)


def test_a_short_mission_closes_the_loop(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                         ) -> None:
    from turbinefit.cli import main
    from turbinefit.io.camera_yaml import write_camera_yaml
    from turbinefit.io.flight_folder import read_flight_folder

    cam = tmp_path / "camera.yaml"
    write_camera_yaml(cam, SMALL)
    out = tmp_path / "mission"
    assert main(["mission", str(out), "--camera", str(cam), "--gsd", "5", "--maps", "ideal",
                 "--defects", "6", "--max-photos", "18", "--seed", "3", "--no-plots",
                 "--width-term", "on"]) == 0
    text = capsys.readouterr().out
    assert "mission closed loop, 24 approach + 18 inspection photos" in text
    s = json.loads((out / "mission.json").read_text())
    assert s["photos"] == {"orbit": 24, "inspection": 18}
    # the photos: a flight folder fit and track read, with its truth
    flight = read_flight_folder(out / "flight")
    assert flight.num_keyframes == 42 and flight.odometry is not None
    assert (out / "fit" / "turbine.yaml").is_file() and (out / "coverage" / "sides.csv").is_file()
    # the width term (--width-term on; auto: with standard GNSS): the fit of the
    # flight folder read its photos
    assert s["config"]["width_term"] is True
    fit_summary = json.loads((out / "fit" / "summary.json").read_text())
    assert fit_summary["solver"]["final_terms"].get("width", 0.0) > 0.0
    assert len((out / "track" / "causal.txt").read_text().splitlines()) >= 42
    # the loop closed: the estimate in the turbine's own frame beats the GNSS poses with the
    # typed-in turbine, and the drone kept its distance
    est = s["estimate"]
    assert est["fit"]["turbine_frame_position_m"] < 0.5 * est["recorded"]["turbine_frame_position_m"]
    assert s["closest_true_approach_m"]["rotor"] >= 0.8 * 10.0
    assert s["tracker_update_ms"]["median"] > 0
    # every position flown, true, recorded and believed
    path = np.loadtxt(out / "path.csv", delimiter=",", skiprows=1)
    assert path.shape[1] == 10 and len(path) >= 42


def test_the_closed_loop_keeps_the_standoff_where_the_open_loop_does_not() -> None:
    # the operator's turbine 10 deg off in heading: its plan puts the blades' faces metres
    # from where they are; flown on GNSS alone it comes within the stand-off, while the
    # loop (approach, init, tracker, replanning) keeps it
    cfg = _config(initial_error=HeadingOff(10.0), max_photos=60)
    closed = mission_outcome(run_mission(cfg))
    opened = mission_outcome(run_mission(MissionConfig(**{**cfg.__dict__, "closed_loop": False})))
    assert closed.clearance_rotor_m >= 0.8 * cfg.standoff
    assert opened.clearance_rotor_m < 0.8 * cfg.standoff


def test_a_widened_standoff_the_planner_refuses_falls_back_to_the_one_asked_for(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The first plan's stand-off is widened by the tracker's uncertainty; when the planner
    refuses it (the stand-off then meets the rotor: a 14.2 m one did on a 126 m rotor), the
    mission is planned at the stand-off asked for, and says why."""
    from dataclasses import replace

    import turbinefit.mission.loop as loop
    from turbinefit.inspection.plan import PlanOptions

    real = loop.plan_options

    def widened(cfg: MissionConfig, sigma: float, structure: float,
                widen_standoff: bool = True) -> PlanOptions:
        options = real(cfg, sigma, structure, widen_standoff=widen_standoff)
        # widened: longer than the blades
        return replace(options, standoff=70.0) if widen_standoff else options

    monkeypatch.setattr(loop, "plan_options", widened)
    mission = run_mission(_config(max_photos=3))
    assert len(mission.inspection) == 3
    assert "70 m" in mission.replan_errors[0]
    assert mission.plans[0].min_rotor_clearance >= 10.0


def test_the_gnss_fixes_weight_in_the_tracker_and_the_fit() -> None:
    """By default the GNSS model's horizontal sigma (standard 1.5 m, RTK centimetres) in
    the tracker and the final fit; ``gps_sigma`` sets both, ``fit_gps_sigma`` the final
    fit's alone; a weight that is not a positive number is refused."""
    assert MissionConfig().fit_config().gps_sigma == pytest.approx(1.5)
    assert MissionConfig().final_fit_config().gps_sigma == pytest.approx(1.5)
    assert MissionConfig(gnss="rtk").fit_config().gps_sigma < 0.05
    both = MissionConfig(gps_sigma=5.0)
    assert both.fit_config().gps_sigma == both.final_fit_config().gps_sigma == 5.0
    after = MissionConfig(fit_gps_sigma=5.0)
    assert after.fit_config().gps_sigma == pytest.approx(1.5)
    assert after.final_fit_config().gps_sigma == 5.0
    for name in ("gps_sigma", "fit_gps_sigma"):
        for bad in (0.0, -1.0, math.nan, math.inf):
            with pytest.raises(ValueError, match=f"{name} must be a positive number"):
                MissionConfig(**{name: bad})  # type: ignore[arg-type]
