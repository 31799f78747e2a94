"""The inspection mission in the loop: an approach orbit, the initial turbine, the plan,
then waypoint by waypoint the photo, the tracker's update and the plan's correction
(:mod:`turbinefit.mission.loop`, configured by :mod:`turbinefit.mission.config`,
replanning by :mod:`turbinefit.mission.replan`); and what the mission achieved against the truth:
coverage, clearance, the estimate and the defects located (:mod:`turbinefit.mission.outcome`).

Sits above the simulator, the inspection geometry, the detector and the solver; the
``mission`` command (:mod:`turbinefit.jobs.mission`) writes its outputs."""

from turbinefit.mission.config import MISSION_CAMERA, InitialError, MissionConfig
from turbinefit.mission.loop import Mission, run_mission
from turbinefit.mission.outcome import MissionOutcome, mission_outcome

__all__ = ["MISSION_CAMERA", "InitialError", "Mission", "MissionConfig", "MissionOutcome",
           "mission_outcome", "run_mission"]
