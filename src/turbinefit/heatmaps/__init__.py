"""Heat-maps, the concept shared by the simulator, the detector, training and the costs.

* :mod:`turbinefit.heatmaps.channels` - the seven channels and their order;
* :mod:`turbinefit.heatmaps.stack` - :class:`HeatmapStack`, read access to a flight's maps;
* :mod:`turbinefit.heatmaps.targets` - target maps drawn from 2-D keypoints, and the
  drawing primitives (blobs, ridges) the simulator shares;
* :mod:`turbinefit.heatmaps.model_info` - a heat-map model's settings (its metadata);
* :mod:`turbinefit.heatmaps.resize` - resizing maps;
* :mod:`turbinefit.heatmaps.peaks` - a channel's maximum and local maxima, sub-pixel.

The package imports only NumPy, SciPy (peaks) and the turbine model (and Pillow when maps
are resized).
"""

from turbinefit.heatmaps.channels import CHANNEL_NAMES as CHANNEL_NAMES
from turbinefit.heatmaps.channels import NUM_CHANNELS as NUM_CHANNELS
from turbinefit.heatmaps.stack import HeatmapStack as HeatmapStack
from turbinefit.heatmaps.stack import HeatmapValueError as HeatmapValueError
from turbinefit.heatmaps.stack import NonFiniteHeatmapError as NonFiniteHeatmapError

__all__ = ["CHANNEL_NAMES", "NUM_CHANNELS", "HeatmapStack", "HeatmapValueError",
           "NonFiniteHeatmapError"]
