"""The inspection: from a fitted turbine and poses to which photo shows which part of
which blade (:mod:`~turbinefit.inspection.surface`: named blades, sides, ray casting, the
pixel lookup; :mod:`~turbinefit.inspection.coverage`: what each keyframe shows, at what
resolution), the next flight's path (:mod:`~turbinefit.inspection.plan`) and how far a
path keeps from the solid (:mod:`~turbinefit.inspection.clearance`, the check of every
path).

Pure geometry above the core: it imports :mod:`turbinefit.geometry` and
:mod:`turbinefit.turbine` only (no files, simulator, plots or commands).
"""

from turbinefit.inspection.clearance import PathClearance as PathClearance
from turbinefit.inspection.clearance import path_clearance as path_clearance
from turbinefit.inspection.clearance import solid_samples as solid_samples
from turbinefit.inspection.coverage import Coverage as Coverage
from turbinefit.inspection.coverage import flight_coverage as flight_coverage
from turbinefit.inspection.plan import PlanOptions as PlanOptions
from turbinefit.inspection.plan import plan_path as plan_path
from turbinefit.inspection.surface import BoxLocation as BoxLocation
from turbinefit.inspection.surface import PixelHit as PixelHit
from turbinefit.inspection.surface import SurfaceShape as SurfaceShape
from turbinefit.inspection.surface import TurbineSurface as TurbineSurface
from turbinefit.inspection.surface import blade_names as blade_names
from turbinefit.inspection.surface import locate_box as locate_box
from turbinefit.inspection.surface import lookup_pixel as lookup_pixel
from turbinefit.inspection.surface import lookup_pixels as lookup_pixels
