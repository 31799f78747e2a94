"""What the interactive view shows, as the data its page reads: the fitted turbine's solid
with coverage colours, the camera frusta and paths of each estimate, the skeletons of the
initial and ground-truth turbines, the planned path, the photos with the fitted skeleton
reprojected over them, and the first viewpoint.

:func:`scene_data` turns a :class:`ViewScene` (arrays in memory: nothing here reads a
file) into one JSON-ready dict; :mod:`turbinefit.view.page` writes it into the HTML page
and ``viewer.js`` draws it. Arrays travel as base64 of little-endian ``float32`` /
``uint32`` / ``uint8`` (``{"b64": ..., "dtype": ..., "shape": ...}``), positions in metres
relative to :attr:`ViewScene.origin` (the tower base: ``float32`` keeps millimetres even
in a georeferenced frame far from its origin), world frame z up.

The coverage colours are those of ``coverage.png`` (:func:`turbinefit.plots.inspection.gsd_colours`):
each vertex of a blade or the tower takes the best ground sampling distance reached on its
side (the side a camera along the vertex's normal sees,
:meth:`~turbinefit.inspection.surface.TurbineSurface.blade_side`) in its span bin.
"""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.coverage import SideGrid, side_names
from turbinefit.inspection.surface import BLADE_NAMES, PARTS, TOWER, TurbineSurface
from turbinefit.io.mesh import PART_COLOURS, SHARP_EDGE_DEG, smooth_normals
from turbinefit.plots.common import (
    GT_COLOUR,
    INITIAL_COLOUR,
    OPTIMISED_COLOUR,
    REPROJ_INITIAL_COLOUR,
    REPROJ_OPTIMISED_COLOUR,
    project_skeleton,
    skeleton_points,
)
from turbinefit.plots.inspection import GAP_COLOUR, gsd_colours, gsd_range
from turbinefit.turbine.model import LINES, TurbineGeometry, TurbineParams
from turbinefit.turbine.solid import TurbineSolid, solid_mesh

FloatArray = NDArray[np.float64]

#: Colour of the planned path and its photos (matplotlib's purple: no estimate uses it).
PLAN_COLOUR = "#9467bd"
#: Samples per model line of a skeleton drawn over a photo.
OVERLAY_SAMPLES = 16
#: Frustum depth [m] as a share of the turbine's size (tip height), and its bounds.
FRUSTUM_SHARE = 0.03
FRUSTUM_M = (0.5, 8.0)
#: Rings along the tower and the blades at most this far apart [m] when they carry coverage
#: colours (the coverage's bins are 0.5 m by default; a colour is drawn per vertex).
COLOUR_RING_STEP_M = 1.0
#: Vertical field of view of the first viewpoint [deg].
VIEW_FOV_DEG = 40.0
#: The first viewpoint: its azimuth from the rotor's axis (upwind) and its elevation [deg].
VIEW_AZIMUTH_DEG = 40.0
VIEW_ELEVATION_DEG = 18.0
#: Share of the cameras the first viewpoint frames (the rest: take-off, far transits).
VIEW_CAMERA_SHARE = 0.8


@dataclass(frozen=True)
class CameraSet:
    """The poses of one estimate of the keyframes (drawn as a path and frusta).

    Attributes:
        name: ``optimised``, ``initial`` or ``ground_truth``.
        label: its name in the legend.
        colour: the project's colour of that estimate.
        world_T_cam: (N,) one pose per keyframe.
    """

    name: str
    label: str
    colour: str
    world_T_cam: SE3


@dataclass(frozen=True)
class Photo:
    """A keyframe's photo as the page embeds it.

    Attributes:
        keyframe: its keyframe index.
        jpeg: the thumbnail, JPEG bytes.
        width, height: the thumbnail's size [px] (the camera's aspect).
    """

    keyframe: int
    jpeg: bytes
    width: int
    height: int


@dataclass(frozen=True)
class CoverageView:
    """Coverage to colour the turbine with.

    Attributes:
        grids: per part of :data:`~turbinefit.inspection.coverage.COVERED_PARTS` (blades
            A, B, C, the tower), the best GSD per side and span bin.
        max_gsd_mm: the resolution a side must reach [mm/px].
        surface: the surface the sides were named on (its blade pitch and twist).
        source: where it came from, for the legend (a folder, or ``computed``).
    """

    grids: list[SideGrid]
    max_gsd_mm: float
    surface: TurbineSurface
    source: str


@dataclass(frozen=True)
class PlanView:
    """A planned path.

    Attributes:
        path: (M, 3) waypoints in flying order [m, world].
        photo_poses: (P,) ``world_T_cam`` of its photos.
        photo_labels: one caption per photo (part, side, span).
        source: its folder, for the legend.
    """

    path: FloatArray
    photo_poses: SE3
    photo_labels: list[str]
    source: str


@dataclass
class ViewScene:
    """Everything the page shows.

    Attributes:
        title: the page's title.
        facts: (label, text) lines of the page's header.
        turbine, geometry: the fitted turbine and its shape details.
        timestamps: (N,) the keyframes' times [s].
        camera: the photos' camera (None: unknown, frusta drawn 4:3 at 60 deg).
        sets: the estimates of the keyframe poses, optimised first.
        shown: the keyframes drawn as frusta (all are drawn as path points).
        skeletons: (name, label, colour, turbine) of other turbines drawn as skeletons.
        photos: the embedded photos.
        coverage, plan: optional.
        verdict: the fit's verdict (``ok``, ``doubtful``, ``failed``) or None.
        notes: lines the page shows under the header (what is missing and why).
    """

    title: str
    facts: list[tuple[str, str]]
    turbine: TurbineParams
    geometry: TurbineGeometry
    timestamps: FloatArray
    camera: PinholeCamera | None
    sets: list[CameraSet]
    shown: list[int]
    skeletons: list[tuple[str, str, str, TurbineParams]] = field(default_factory=list)
    photos: list[Photo] = field(default_factory=list)
    coverage: CoverageView | None = None
    plan: PlanView | None = None
    verdict: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def origin(self) -> FloatArray:
        """The tower base (3,) [m, world]: the page's positions are relative to it."""
        return np.array([self.turbine.base_x, self.turbine.base_y, 0.0])


def packed(values: ArrayLike, dtype: str = "float32") -> dict[str, Any]:
    """An array as the page reads it: base64 of its little-endian ``dtype`` bytes, with
    its dtype and shape. Non-finite values are refused: the page draws every number."""
    a = np.ascontiguousarray(np.asarray(values).astype(np.dtype(dtype).newbyteorder("<")))
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise ValueError("non-finite values cannot be drawn")
    return {"b64": base64.b64encode(a.tobytes()).decode("ascii"), "dtype": dtype,
            "shape": list(a.shape)}


def unpacked(item: dict[str, Any]) -> NDArray[Any]:
    """The array of :func:`packed` (the tests read pages back with it)."""
    data = base64.b64decode(item["b64"])
    return np.frombuffer(data, dtype=np.dtype(item["dtype"]).newbyteorder("<")).reshape(
        item["shape"])


def frustum_depth(turbine: TurbineParams) -> float:
    """Depth [m] of the drawn frusta: :data:`FRUSTUM_SHARE` of the turbine's tip height."""
    size = abs(turbine.tower_height) + abs(turbine.blade_length)
    return float(np.clip(FRUSTUM_SHARE * size, *FRUSTUM_M))


def frustum_corners(camera: PinholeCamera | None, world_T_cam: SE3, depth: float) -> FloatArray:
    """(N, 5, 3) world points of each pose's frustum: the camera centre, then the image's
    corners (top-left, top-right, bottom-right, bottom-left) ``depth`` metres ahead
    (pinhole: distortion left out). Without a camera, a 4:3 image 60 deg wide."""
    if camera is None:
        half_w, half_h = math.tan(math.radians(30.0)), 0.75 * math.tan(math.radians(30.0))
        xs, ys = (-half_w, half_w), (-half_h, half_h)
    else:
        xs = ((-0.5 - camera.cx) / camera.fx, (camera.width - 0.5 - camera.cx) / camera.fx)
        ys = ((-0.5 - camera.cy) / camera.fy, (camera.height - 0.5 - camera.cy) / camera.fy)
    cam_p = depth * np.array([[0.0, 0.0, 0.0], [xs[0], ys[0], 1.0], [xs[1], ys[0], 1.0],
                              [xs[1], ys[1], 1.0], [xs[0], ys[1], 1.0]])
    poses = SE3(world_T_cam.wxyz_xyz.reshape(-1, 7))
    R, t = poses.rotation_matrix(), poses.translation
    return np.einsum("nij,kj->nki", R, cam_p) + t[:, None, :]


def vertex_gsd(surface: TurbineSurface, part: str, vertices: FloatArray, normals: FloatArray,
               grids: list[SideGrid]) -> FloatArray:
    """The best GSD [mm/px] reached at each vertex (n,) of a mesh part (``tower`` or
    ``blade_1`` .. ``blade_3``, the model's blades), from the side its normal faces and
    its span bin: inf where never seen, NaN more than a bin beyond the bins (the blade's
    root inside the spinner, the tower inside the nacelle) or on a part coverage does not
    cover."""
    out = np.full(len(vertices), np.nan)
    if part == "tower":
        code = TOWER
        span = vertices[:, 2]
        side = surface.tower_face(normals)
    elif part.startswith("blade_"):
        model_index = int(part.split("_")[1]) - 1
        blade = next(i for i, b in enumerate(surface.blades) if b.model_index == model_index)
        code = PARTS.index(f"blade_{BLADE_NAMES[blade]}")
        bl = surface.blades[blade]
        span = (vertices - bl.root) @ bl.axis
        side = surface.blade_side(blade, normals, span)
    else:
        return out
    grid = next((g for g in grids if g.part == code), None)
    if grid is None or grid.spans.size == 0:
        return out
    j = np.floor((span - grid.spans[0]) / grid.step + 0.5).astype(np.int64)
    ok = (j >= -1) & (j <= grid.spans.size)  # a bin's width beyond the ends: the tip's cap
    j = np.clip(j, 0, grid.spans.size - 1)
    out[ok] = grid.best_gsd[side[ok], j[ok]]
    return out


def _srgb_bytes(colour: str | tuple[float, float, float]) -> NDArray[np.uint8]:
    """A colour (``#rrggbb``, or linear RGB 0-1 as :data:`~turbinefit.io.mesh.PART_COLOURS`)
    as sRGB bytes (3,)."""
    if isinstance(colour, str):
        return np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)], dtype=np.uint8)
    c = np.asarray(colour, dtype=np.float64)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    return np.round(255.0 * np.clip(s, 0.0, 1.0)).astype(np.uint8)


def _hex(rgb: NDArray[np.uint8]) -> str:
    """``#rrggbb`` of sRGB bytes (3,)."""
    return "#" + "".join(f"{int(v):02x}" for v in rgb)


def turbine_parts(turbine: TurbineParams, geometry: TurbineGeometry, origin: FloatArray,
                  coverage: CoverageView | None) -> list[dict[str, Any]]:
    """The fitted turbine's solid (the mesh of ``turbine.glb``; with ``coverage``, rings
    :data:`COLOUR_RING_STEP_M` apart along the tower and the blades), part by part:
    vertices relative to ``origin``, smooth normals, triangles, its plain sRGB colour per
    vertex and, with ``coverage``, its coverage colour per vertex."""
    solid = TurbineSolid(turbine.to_vector(), geometry)
    lo_hi = None if coverage is None else gsd_range([g.best_gsd for g in coverage.grids],
                                                    coverage.max_gsd_mm)
    parts = []
    for part in solid_mesh(solid, ring_step=None if coverage is None else COLOUR_RING_STEP_M):
        v, n, f = smooth_normals(part, math.radians(SHARP_EDGE_DEG))
        plain = np.tile(_srgb_bytes(PART_COLOURS[part.name.split("_")[0]]), (len(v), 1))
        item: dict[str, Any] = {"name": part.name, "position": packed(v - origin),
                                "normal": packed(n), "index": packed(f, "uint32"),
                                "plain": packed(plain, "uint8"), "coverage": None}
        if coverage is not None and lo_hi is not None:
            gsd = vertex_gsd(coverage.surface, part.name, v, n, coverage.grids)
            colours = np.where(np.isnan(gsd)[:, None], plain, gsd_colours(gsd, *lo_hi))
            item["coverage"] = packed(colours, "uint8")
        parts.append(item)
    return parts


def overlay_lines(camera: PinholeCamera, world_T_cam: SE3, turbine: TurbineParams,
                  geometry: TurbineGeometry, width: int, height: int
                  ) -> tuple[list[list[float]], list[list[float]]]:
    """The turbine's skeleton seen from ``world_T_cam``, in the pixels of a ``width`` x
    ``height`` thumbnail of the camera's photo: its lines as polylines (flat lists u0, v0,
    u1, v1, ...; split where they leave the drawable range) and its model points (u, v),
    rounded to 0.1 px."""
    lines_uv, points_uv = project_skeleton(camera, world_T_cam,
                                           skeleton_points(turbine, geometry), OVERLAY_SAMPLES)
    scale = np.array([width / camera.width, height / camera.height])

    def thumb(uv: FloatArray) -> FloatArray:
        return np.round((uv + 0.5) * scale - 0.5, 1)

    polylines: list[list[float]] = []
    run: list[float] = []
    for u, v in thumb(lines_uv).tolist():
        if math.isfinite(u) and math.isfinite(v):
            run += [u, v]
            continue
        if len(run) >= 4:
            polylines.append(run)
        run = []
    if len(run) >= 4:
        polylines.append(run)
    points = [[u, v] for u, v in thumb(points_uv).tolist() if math.isfinite(u) and math.isfinite(v)]
    return polylines, points


def initial_view(scene: ViewScene) -> dict[str, Any]:
    """The first viewpoint (relative to the origin): looking at the turbine from
    :data:`VIEW_AZIMUTH_DEG` off its rotor axis, upwind, :data:`VIEW_ELEVATION_DEG` up,
    far enough to frame the turbine and :data:`VIEW_CAMERA_SHARE` of the cameras nearest
    it."""
    t = scene.turbine
    pts = skeleton_points(t, scene.geometry) - scene.origin
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    lo[2] = 0.0
    target = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    cams = scene.sets[0].world_T_cam.translation.reshape(-1, 3) - scene.origin if scene.sets \
        else np.zeros((0, 3))
    if scene.plan is not None:
        cams = np.concatenate([cams, scene.plan.path - scene.origin])
    cams = cams[np.all(np.isfinite(cams), axis=1)]
    if len(cams):
        d = np.sort(np.linalg.norm(cams - target, axis=1))
        radius = max(radius, float(d[int(VIEW_CAMERA_SHARE * (len(d) - 1))]))
    az = t.heading + math.radians(VIEW_AZIMUTH_DEG)
    el = math.radians(VIEW_ELEVATION_DEG)
    direction = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    dist = 1.1 * radius / math.sin(math.radians(0.5 * VIEW_FOV_DEG))
    return {"target": target.tolist(), "position": (target + dist * direction).tolist(),
            "fov": VIEW_FOV_DEG, "radius": radius}


def blade_labels(turbine: TurbineParams, geometry: TurbineGeometry, origin: FloatArray
                 ) -> list[dict[str, Any]]:
    """Labels A, B, C just beyond each blade's tip (names of
    :mod:`turbinefit.inspection.surface`), and ``tower`` at the base."""
    surface = TurbineSurface(turbine, geometry)
    out = []
    for bl in surface.blades:
        tip = bl.root + (bl.length + 0.06 * abs(bl.length) + 2.0) * bl.axis
        out.append({"text": f"blade {bl.name}", "at": (tip - origin).tolist()})
    return out


def scene_data(scene: ViewScene) -> dict[str, Any]:
    """The page's data (see the module docstring)."""
    origin = scene.origin
    depth = frustum_depth(scene.turbine)
    shown = np.asarray(scene.shown, dtype=np.int64)
    cameras = []
    for s in scene.sets:
        poses = SE3(s.world_T_cam.wxyz_xyz.reshape(-1, 7))
        pos = poses.translation - origin
        fr = frustum_corners(scene.camera, poses[shown] if shown.size else SE3(np.zeros((0, 7))),
                             depth) - origin
        cameras.append({"name": s.name, "label": s.label, "colour": s.colour,
                        "positions": packed(pos), "frusta": packed(fr.reshape(-1, 3))})
    skeletons = [{"name": name, "label": label, "colour": colour,
                  "points": packed(skeleton_points(t, scene.geometry) - origin)}
                 for name, label, colour, t in scene.skeletons]
    by_name = {s.name: s for s in scene.sets}
    initial_turbine = next((t for n, _, _, t in scene.skeletons if n == "initial"), None)
    photos = []
    for ph in scene.photos:
        overlays = []
        if scene.camera is not None:
            for name, label, colour, turbine in (
                    ("optimised", "fitted model", REPROJ_OPTIMISED_COLOUR, scene.turbine),
                    ("initial", "initial model", REPROJ_INITIAL_COLOUR, initial_turbine)):
                if turbine is None or name not in by_name:
                    continue
                lines, points = overlay_lines(scene.camera, by_name[name].world_T_cam[ph.keyframe],
                                              turbine, scene.geometry, ph.width, ph.height)
                overlays.append({"name": name, "label": label, "colour": colour,
                                 "lines": lines, "points": points})
        photos.append({"keyframe": ph.keyframe, "width": ph.width, "height": ph.height,
                       "src": "data:image/jpeg;base64," + base64.b64encode(ph.jpeg).decode("ascii"),
                       "overlays": overlays})
    coverage = None
    if scene.coverage is not None:
        cov = scene.coverage
        lo, hi = gsd_range([g.best_gsd for g in cov.grids], cov.max_gsd_mm)
        stops = np.geomspace(lo, hi, 11)
        table = {}
        for g in cov.grids:
            fine, seen = g.covered(cov.max_gsd_mm), g.covered()
            table[PARTS[g.part]] = {side: [round(float(fine[k]), 4), round(float(seen[k]), 4)]
                                    for k, side in enumerate(side_names(g.part))}
        coverage = {"source": cov.source, "max_gsd": cov.max_gsd_mm, "lo": lo, "hi": hi,
                    "stops": [_hex(c) for c in gsd_colours(stops, lo, hi)],
                    "gap": GAP_COLOUR, "table": table}
    plan = None
    if scene.plan is not None:
        p = scene.plan
        fr = frustum_corners(scene.camera, p.photo_poses, depth) - origin
        plan = {"source": p.source, "colour": PLAN_COLOUR, "path": packed(p.path - origin),
                "frusta": packed(fr.reshape(-1, 3)), "labels": p.photo_labels,
                "length": float(np.sum(np.linalg.norm(np.diff(p.path, axis=0), axis=1)))}
    return {
        "title": scene.title, "facts": [list(f) for f in scene.facts], "notes": scene.notes,
        "verdict": scene.verdict, "origin": origin.tolist(),
        "view": initial_view(scene), "frustum_depth": depth,
        "lines": [[a, b] for a, b, _ in LINES],
        "turbine": {"parts": turbine_parts(scene.turbine, scene.geometry, origin, scene.coverage),
                    "labels": blade_labels(scene.turbine, scene.geometry, origin),
                    "colour": OPTIMISED_COLOUR,
                    "skeleton": packed(skeleton_points(scene.turbine, scene.geometry) - origin)},
        "keyframes": {"count": len(scene.timestamps),
                      "timestamps": [round(float(t), 6) for t in scene.timestamps],
                      "shown": shown.tolist()},
        "cameras": cameras, "skeletons": skeletons, "photos": photos,
        "coverage": coverage, "plan": plan,
    }


#: The colours of the three estimates, as the project's figures draw them.
ESTIMATE_COLOURS = {"ground_truth": GT_COLOUR, "initial": INITIAL_COLOUR,
                    "optimised": OPTIMISED_COLOUR}
