"""turbinefit: simultaneous drone localisation and wind-turbine model fitting.

Implements Moolan-Feroze et al., "Simultaneous drone localisation and wind turbine model
fitting during autonomous surface inspection" (IROS 2019).

The names below are loaded on first use, so that ``import turbinefit`` (and the command
line's ``--help``) stays cheap.
"""

from __future__ import annotations

from turbinefit._lazy import lazy_exports

TYPE_CHECKING = False  # not typing's: the command line imports this before its signal handlers

if TYPE_CHECKING:
    from turbinefit.flight import Flight as Flight
    from turbinefit.geometry import SE3 as SE3
    from turbinefit.geometry import PinholeCamera as PinholeCamera
    from turbinefit.heatmaps import CHANNEL_NAMES as CHANNEL_NAMES
    from turbinefit.heatmaps import HeatmapStack as HeatmapStack
    from turbinefit.solver.config import FitConfig as FitConfig
    from turbinefit.turbine import TurbineGeometry as TurbineGeometry
    from turbinefit.turbine import TurbineParams as TurbineParams

__version__ = "0.1.0"

_WHERE = {
    "Flight": "turbinefit.flight",
    "SE3": "turbinefit.geometry",
    "PinholeCamera": "turbinefit.geometry",
    "CHANNEL_NAMES": "turbinefit.heatmaps",
    "HeatmapStack": "turbinefit.heatmaps",
    "FitConfig": "turbinefit.solver.config",
    "TurbineGeometry": "turbinefit.turbine",
    "TurbineParams": "turbinefit.turbine",
}

__all__ = ["__version__", *sorted(_WHERE)]


__getattr__ = lazy_exports(__name__, _WHERE)
