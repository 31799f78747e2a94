"""Figures: the package's only matplotlib user. Every function writes one PNG and returns
its path.

* :mod:`turbinefit.plots.flight` -- one flight: scene, reprojections, errors, cost history,
  latency (what ``fit`` and ``track`` write);
* :mod:`turbinefit.plots.studies` -- the Monte Carlo studies' figures;
* :mod:`turbinefit.plots.inspection` -- coverage of blades and tower (imported on use);
* :mod:`turbinefit.plots.common` -- colours, figure creation, atomic PNG saving.
"""

from turbinefit.plots.common import choose_keyframes as choose_keyframes
from turbinefit.plots.flight import plot_cost_history as plot_cost_history
from turbinefit.plots.flight import plot_errors as plot_errors
from turbinefit.plots.flight import plot_latency as plot_latency
from turbinefit.plots.flight import plot_pose_errors as plot_pose_errors
from turbinefit.plots.flight import plot_reprojections as plot_reprojections
from turbinefit.plots.flight import plot_scene as plot_scene
from turbinefit.plots.studies import plot_basin as plot_basin
from turbinefit.plots.studies import plot_binned as plot_binned
from turbinefit.plots.studies import plot_error_scatter as plot_error_scatter
from turbinefit.plots.studies import plot_roll as plot_roll
from turbinefit.plots.studies import plot_turbine_recovery as plot_turbine_recovery
