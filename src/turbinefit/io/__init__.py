"""File I/O: TUM trajectories, camera and turbine YAML, flight folders, atomic writes.

Formats, frames and units are described in each module's docstring:

* :mod:`turbinefit.io.tum` - ``timestamp tx ty tz qx qy qz qw`` (xyzw in files, wxyz inside).
* :mod:`turbinefit.io.camera_yaml` - ROS camera_info / OpenCV FileStorage intrinsics.
* :mod:`turbinefit.io.turbine_yaml` - the seven turbine parameters (metres, radians).
* :mod:`turbinefit.io.flight_folder` - a whole flight (the above plus ``heatmaps/*.npy``).
* :mod:`turbinefit.io.heatmap_files` - the ``heatmaps/*.npy`` files, at their own size.
* :mod:`turbinefit.io.images` - photos (reduced JPEG decoding, PNG writing, resizing).
* :mod:`turbinefit.io.atomic` - atomic file and directory output.
* :mod:`turbinefit.io.yaml_files` - strict YAML parsing shared by the YAML formats.

Every bad input raises :class:`turbinefit.errors.InputError` naming the file (and line or
field).
"""

from turbinefit.io.atomic import atomic_output_dir as atomic_output_dir
from turbinefit.io.atomic import write_bytes_atomic as write_bytes_atomic
from turbinefit.io.atomic import write_text_atomic as write_text_atomic
from turbinefit.io.camera_yaml import read_camera_yaml as read_camera_yaml
from turbinefit.io.camera_yaml import write_camera_yaml as write_camera_yaml
from turbinefit.io.flight_folder import read_flight as read_flight
from turbinefit.io.flight_folder import write_flight as write_flight
from turbinefit.io.heatmap_files import heatmap_filename as heatmap_filename
from turbinefit.io.heatmap_files import read_heatmaps as read_heatmaps
from turbinefit.io.tum import read_tum as read_tum
from turbinefit.io.tum import write_tum as write_tum
from turbinefit.io.turbine_yaml import read_turbine_yaml as read_turbine_yaml
from turbinefit.io.turbine_yaml import write_turbine_yaml as write_turbine_yaml

__all__ = [
    "atomic_output_dir",
    "heatmap_filename",
    "read_camera_yaml",
    "read_flight",
    "read_heatmaps",
    "read_tum",
    "read_turbine_yaml",
    "write_bytes_atomic",
    "write_camera_yaml",
    "write_flight",
    "write_text_atomic",
    "write_tum",
    "write_turbine_yaml",
]
