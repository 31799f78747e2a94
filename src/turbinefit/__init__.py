"""turbinefit: simultaneous drone localisation and wind-turbine model fitting.

Implements Moolan-Feroze et al., "Simultaneous drone localisation and wind turbine model
fitting during autonomous surface inspection" (IROS 2019).
"""

from turbinefit.flight import Flight as Flight
from turbinefit.geometry import SE3 as SE3
from turbinefit.geometry import PinholeCamera as PinholeCamera
from turbinefit.heatmaps import CHANNEL_NAMES as CHANNEL_NAMES
from turbinefit.heatmaps import HeatmapStack as HeatmapStack
from turbinefit.turbine import TurbineGeometry as TurbineGeometry
from turbinefit.turbine import TurbineParams as TurbineParams

__version__ = "0.1.0"
