"""Flight simulator: realistic turbines, inspection trajectories, CNN-like heat-maps and
drifting GPS/IMU poses, with ground truth.

World frame: metres, z up, ground z = 0; poses are ``world_T_cam`` (camera-to-world) of
OpenCV cameras; heat-maps are float32 (7, H, W) in [0, 1] in the channel order of
:mod:`turbinefit.heatmaps`.

Entry point: ``simulate_flight(SimConfig(...)) -> Flight`` (or ``PRESETS["hard"]``).
"""

from turbinefit.sim.noise import DEFAULT_TURBINE_SIGMA as DEFAULT_TURBINE_SIGMA
from turbinefit.sim.noise import drift_poses as drift_poses
from turbinefit.sim.noise import perturb_turbine as perturb_turbine
from turbinefit.sim.render import HeatmapNoise as HeatmapNoise
from turbinefit.sim.render import RenderConfig as RenderConfig
from turbinefit.sim.render import render_flight as render_flight
from turbinefit.sim.render import render_heatmaps as render_heatmaps
from turbinefit.sim.scenario import PRESETS as PRESETS
from turbinefit.sim.scenario import SimConfig as SimConfig
from turbinefit.sim.scenario import preset as preset
from turbinefit.sim.scenario import simulate_flight as simulate_flight
from turbinefit.sim.trajectory import InspectionPath as InspectionPath
from turbinefit.sim.trajectory import TrajectoryConfig as TrajectoryConfig
from turbinefit.sim.trajectory import inspection_trajectory as inspection_trajectory
from turbinefit.sim.trajectory import plan_inspection as plan_inspection
from turbinefit.sim.turbines import PRESETS as TURBINE_PRESETS  # noqa: F401
from turbinefit.sim.turbines import preset_turbine as preset_turbine
from turbinefit.sim.turbines import sample_turbine as sample_turbine
