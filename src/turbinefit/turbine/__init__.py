"""The paper's skeletal turbine model."""

from turbinefit.turbine.model import TurbineGeometry as TurbineGeometry
from turbinefit.turbine.model import TurbineParams as TurbineParams
from turbinefit.turbine.model import model_point_error as model_point_error
from turbinefit.turbine.model import model_points as model_points
from turbinefit.turbine.model import param_errors as param_errors
