"""Levenberg-Marquardt over keyframe poses and turbine parameters."""

from turbinefit.solver.config import PRESETS as PRESETS
from turbinefit.solver.config import FitConfig as FitConfig
from turbinefit.solver.fit import FitResult as FitResult
from turbinefit.solver.fit import fit as fit
from turbinefit.solver.problem import FitProblem as FitProblem
from turbinefit.solver.tracker import Tracker as Tracker
from turbinefit.solver.tracker import TrackerConfig as TrackerConfig
from turbinefit.solver.tracker import TrackEstimate as TrackEstimate
