"""Rigid transforms (one pose type, wxyz quaternions) and the pinhole camera."""

from turbinefit.geometry.camera import PinholeCamera as PinholeCamera
from turbinefit.geometry.se3 import SE3 as SE3
from turbinefit.geometry.se3 import pose_errors as pose_errors
