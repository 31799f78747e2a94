"""Jobs: what the commands run, one module per job, each a typed function over folders.

* :mod:`turbinefit.jobs.simulate` -- :func:`simulate_folder`
* :mod:`turbinefit.jobs.fit` -- :func:`fit_folder`
* :mod:`turbinefit.jobs.track` -- :func:`track_folder`
* :mod:`turbinefit.jobs.detect` -- :func:`detect_images`
* :mod:`turbinefit.jobs.evaluate` -- :func:`evaluate_labels`
* :mod:`turbinefit.jobs.import_dji` -- :func:`import_dji` (DJI photos to a flight folder)
* :mod:`turbinefit.jobs.import_rosbag` -- :func:`import_rosbag` (a ROS bag to a flight folder)
* :mod:`turbinefit.jobs.coverage` -- :func:`coverage_folder` (what each keyframe of a fit shows)
* :mod:`turbinefit.jobs.plan` -- :func:`plan_folder` (the next inspection flight's waypoints)

Shared: :mod:`turbinefit.jobs.sources` (where a flight's heat-maps come from: files or
photos) and :mod:`turbinefit.jobs.outputs` (the output-folder rules). Each job writes its
outputs atomically and returns a report dataclass; the summaries it writes are dataclasses
too. Importing this package imports no job: each is loaded on first use, so a command
loads only what it runs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from turbinefit._lazy import lazy_exports

if TYPE_CHECKING:
    from turbinefit.jobs.coverage import CoverageReport as CoverageReport
    from turbinefit.jobs.coverage import coverage_folder as coverage_folder
    from turbinefit.jobs.detect import DetectReport as DetectReport
    from turbinefit.jobs.detect import detect_images as detect_images
    from turbinefit.jobs.evaluate import EvaluateReport as EvaluateReport
    from turbinefit.jobs.evaluate import evaluate_labels as evaluate_labels
    from turbinefit.jobs.fit import FitReport as FitReport
    from turbinefit.jobs.fit import FitSummary as FitSummary
    from turbinefit.jobs.fit import fit_folder as fit_folder
    from turbinefit.jobs.import_dji import DjiImportSummary as DjiImportSummary
    from turbinefit.jobs.import_dji import import_dji as import_dji
    from turbinefit.jobs.import_rosbag import RosbagOptions as RosbagOptions
    from turbinefit.jobs.import_rosbag import RosbagSummary as RosbagSummary
    from turbinefit.jobs.import_rosbag import import_rosbag as import_rosbag
    from turbinefit.jobs.plan import PlanReport as PlanReport
    from turbinefit.jobs.plan import plan_folder as plan_folder
    from turbinefit.jobs.simulate import simulate_folder as simulate_folder
    from turbinefit.jobs.track import TrackReport as TrackReport
    from turbinefit.jobs.track import TrackSummary as TrackSummary
    from turbinefit.jobs.track import track_folder as track_folder

_WHERE = {name: f"turbinefit.jobs.{module}" for module, names in {
    "simulate": ("simulate_folder",),
    "fit": ("fit_folder", "FitReport", "FitSummary"),
    "track": ("track_folder", "TrackReport", "TrackSummary"),
    "detect": ("detect_images", "DetectReport"),
    "evaluate": ("evaluate_labels", "EvaluateReport"),
    "import_dji": ("import_dji", "DjiImportSummary"),
    "import_rosbag": ("import_rosbag", "RosbagOptions", "RosbagSummary"),
    "coverage": ("coverage_folder", "CoverageReport"),
    "plan": ("plan_folder", "PlanReport"),
}.items() for name in names}

__all__ = sorted(_WHERE)


__getattr__ = lazy_exports(__name__, _WHERE)
