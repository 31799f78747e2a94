"""Levenberg-Marquardt over keyframe poses and turbine parameters: the batch fit
(:func:`fit`) and the in-flight tracker (:class:`Tracker`).

:func:`fit` is imported with the package (its name is also that of its module, which
would otherwise shadow it); the other names are loaded on first use, so that importing
:mod:`turbinefit.solver.config` does not load the tracker.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from turbinefit._lazy import lazy_exports
from turbinefit.solver.fit import fit as fit

if TYPE_CHECKING:
    from turbinefit.solver.config import PRESETS as PRESETS
    from turbinefit.solver.config import FitConfig as FitConfig
    from turbinefit.solver.config import TrackerConfig as TrackerConfig
    from turbinefit.solver.fit import FitResult as FitResult
    from turbinefit.solver.problem import FitProblem as FitProblem
    from turbinefit.solver.tracker import TrackAssessment as TrackAssessment
    from turbinefit.solver.tracker import Tracker as Tracker
    from turbinefit.solver.tracker import TrackEstimate as TrackEstimate

_WHERE = {
    "PRESETS": "turbinefit.solver.config", "FitConfig": "turbinefit.solver.config",
    "FitResult": "turbinefit.solver.fit",
    "FitProblem": "turbinefit.solver.problem",
    "Tracker": "turbinefit.solver.tracker", "TrackerConfig": "turbinefit.solver.config",
    "TrackEstimate": "turbinefit.solver.tracker", "TrackAssessment": "turbinefit.solver.tracker",
}

__all__ = sorted([*_WHERE, "fit"])

__getattr__ = lazy_exports(__name__, _WHERE)
