"""A simulated flight's photos, one at a time, and the known defects each shows.

:class:`FlightPhotos` holds what every photo of a flight shares (the camera, the true
turbine, the scene drawn from the seed, the painted defects) and renders the photo of any
keyframe from any pose: :meth:`FlightPhotos.image` the photo alone,
:meth:`FlightPhotos.photo` the photo and the box of every defect in view. A mission loop
calls it photo by photo; ``simulate`` calls it along the whole flight. Keyframe ``k``'s
photo depends only on the seed, ``k`` and the pose (the camera effects of keyframe ``k``
come from :func:`~turbinefit.sim.images.render.keyframe_rng`).

A defect is in view where the renderer's labels (:func:`~turbinefit.sim.images.render.render_photo`,
the same pass as the photo) say it covers most of a pixel: in front of the camera, inside
the photo, on the side facing it and not hidden behind another part, the landscape or
clutter. Its box (:class:`DefectBox`) bounds those pixels, in pixel edges (``xmax`` is
one past the last column), as a box CSV gives boxes (:mod:`turbinefit.io.regions`); a
defect covering fewer than :data:`MIN_BOX_PIXELS` pixels is not listed (it cannot be
told from a speck).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.defects import Defect
from turbinefit.sim.defects import painted_defects
from turbinefit.sim.images.render import keyframe_rng, render_image, render_photo
from turbinefit.sim.images.scene import flight_scene
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineGeometry, TurbineParams

#: Fewest pixels a defect must cover to be in view.
MIN_BOX_PIXELS = 4


@dataclass(frozen=True)
class DefectBox:
    """A defect in view on one photo.

    Attributes:
        defect: the defect's name (:attr:`~turbinefit.sim.defects.Defect.defect`).
        kind: its kind.
        box: (xmin, ymin, xmax, ymax), pixel edges.
        pixels: the pixels it covers.
    """

    defect: str
    kind: str
    box: tuple[int, int, int, int]
    pixels: int


@dataclass(frozen=True)
class Photo:
    """One rendered photo (uint8 (H, W, 3) RGB) and the defects in view."""

    image: NDArray[np.uint8]
    boxes: tuple[DefectBox, ...]


def defect_boxes(defect_index: NDArray[np.integer], defects: list[Defect],
                 min_pixels: int = MIN_BOX_PIXELS) -> tuple[DefectBox, ...]:
    """The box of every defect of ``defects`` that covers at least ``min_pixels`` pixels of
    ``defect_index`` (H, W): per pixel the index into ``defects`` shown, -1 none."""
    ids = defect_index.ravel()
    shown = ids >= 0
    if not np.any(shown):
        return ()
    w = defect_index.shape[1]
    flat = np.flatnonzero(shown)
    which = ids[flat]
    out = []
    for k in np.unique(which).tolist():
        at = flat[which == k]
        if at.size < min_pixels:
            continue
        rows, cols = at // w, at % w
        d = defects[k]
        out.append(DefectBox(d.defect, d.kind, (int(cols.min()), int(rows.min()),
                                                int(cols.max()) + 1, int(rows.max()) + 1),
                             int(at.size)))
    return tuple(out)


class FlightPhotos:
    """The photos of a simulated flight (module docstring).

    Args:
        camera: the photos' camera (their size; distortion applied).
        turbine: the true turbine.
        seed: the flight's seed (the scene's look and each keyframe's camera effects).
        geometry: the true turbine's shape details.
        defects: the known defects painted on its blades (checked by the caller:
            :func:`~turbinefit.sim.defects.check_defects`).
        surface: draw the blades' and tower's surface (wear, dirt, seams, receptors,
            gelcoat mottling; :attr:`~turbinefit.sim.images.Scene.surface_detail`), as an
            inspection's close-ups show it; without it (the default when there are no
            defects) the photos are those of the flights the fits were measured on.
    """

    def __init__(self, camera: PinholeCamera, turbine: TurbineParams, seed: int,
                 geometry: TurbineGeometry = PAPER_GEOMETRY, defects: list[Defect] | None = None,
                 surface: bool | None = None) -> None:
        self.camera = camera
        self.turbine = turbine
        self.theta = turbine.to_vector()
        self.seed = seed
        self.geometry = geometry
        self.defects = list(defects or [])
        surface = bool(self.defects) if surface is None else surface
        self.scene = flight_scene(self.theta, seed, surface,
                                  painted_defects(self.defects, turbine))

    def image(self, k: int, world_T_cam: SE3) -> NDArray[np.uint8]:
        """Keyframe ``k``'s photo from ``world_T_cam``."""
        return render_image(self.camera, world_T_cam, self.theta, self.scene,
                            keyframe_rng(self.seed, k), self.geometry)

    def photo(self, k: int, world_T_cam: SE3) -> Photo:
        """Keyframe ``k``'s photo from ``world_T_cam`` and the defects in view (the same
        image as :meth:`image`)."""
        image, labels = render_photo(self.camera, world_T_cam, self.theta, self.scene,
                                     keyframe_rng(self.seed, k), self.geometry)
        boxes: tuple[DefectBox, ...] = ()
        if labels.defect is not None and self.defects:
            boxes = defect_boxes(labels.defect, self.defects)
        return Photo(image, boxes)
