"""Jobs: what the commands run, one module per job, each a typed function over folders.

* :mod:`turbinefit.jobs.simulate` -- :func:`simulate_folder`
* :mod:`turbinefit.jobs.fit` -- :func:`fit_folder`
* :mod:`turbinefit.jobs.track` -- :func:`track_folder`
* :mod:`turbinefit.jobs.detect` -- :func:`detect_images`
* :mod:`turbinefit.jobs.evaluate` -- :func:`evaluate_labels`

Shared: :mod:`turbinefit.jobs.sources` (where a flight's heat-maps come from: files or
photos) and :mod:`turbinefit.jobs.outputs` (the output-folder rules). Each job writes its
outputs atomically and returns a report dataclass; the summaries it writes are dataclasses
too. Importing this package imports no job: each is loaded on first use, so a command
loads only what it runs.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from turbinefit.jobs.detect import DetectReport as DetectReport
    from turbinefit.jobs.detect import detect_images as detect_images
    from turbinefit.jobs.evaluate import EvaluateReport as EvaluateReport
    from turbinefit.jobs.evaluate import evaluate_labels as evaluate_labels
    from turbinefit.jobs.fit import FitReport as FitReport
    from turbinefit.jobs.fit import FitSummary as FitSummary
    from turbinefit.jobs.fit import fit_folder as fit_folder
    from turbinefit.jobs.simulate import simulate_folder as simulate_folder
    from turbinefit.jobs.track import TrackReport as TrackReport
    from turbinefit.jobs.track import TrackSummary as TrackSummary
    from turbinefit.jobs.track import track_folder as track_folder

_WHERE = {
    "simulate_folder": "simulate",
    "fit_folder": "fit", "FitReport": "fit", "FitSummary": "fit",
    "track_folder": "track", "TrackReport": "track", "TrackSummary": "track",
    "detect_images": "detect", "DetectReport": "detect",
    "evaluate_labels": "evaluate", "EvaluateReport": "evaluate",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"turbinefit.jobs.{module}"), name)
