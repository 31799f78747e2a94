"""Levenberg-Marquardt over keyframe poses and turbine parameters."""

from turbinefit.solver.config import PRESETS as PRESETS
from turbinefit.solver.config import FitConfig as FitConfig
from turbinefit.solver.fit import FitResult as FitResult
from turbinefit.solver.fit import fit as fit
from turbinefit.solver.problem import FitProblem as FitProblem
