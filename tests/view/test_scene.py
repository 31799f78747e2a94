"""The view's scene data: frusta on the camera's image corners, coverage colours on the side
each vertex faces, the skeleton reprojected into a thumbnail, a first viewpoint that frames
the turbine, arrays that survive their encoding."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from support import look_at, tiny_turbine

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.inspection.coverage import SideGrid, flight_coverage
from turbinefit.inspection.surface import PARTS, TOWER, TurbineSurface
from turbinefit.io.mesh import smooth_normals
from turbinefit.plots.common import skeleton_points
from turbinefit.plots.inspection import GAP_COLOUR, gsd_colours, gsd_range
from turbinefit.turbine.model import PAPER_GEOMETRY, TurbineParams
from turbinefit.turbine.solid import TurbineSolid, solid_mesh
from turbinefit.view.scene import (
    CameraSet,
    CoverageView,
    ViewScene,
    frustum_corners,
    initial_view,
    overlay_lines,
    packed,
    scene_data,
    unpacked,
    vertex_gsd,
)

TURBINE = TurbineParams(3.0, -2.0, 90.0, 0.7, 5.0, 0.4, 60.0)
CAMERA = PinholeCamera(640, 480, 500.0, 510.0, 330.0, 235.0)


def _poses(n: int = 8, distance: float = 60.0) -> SE3:
    ang = np.linspace(0.0, 1.5, n)
    eye = np.stack([distance * np.cos(ang), distance * np.sin(ang), np.full(n, 80.0)], axis=1)
    return look_at(eye, np.tile([3.0, -2.0, 80.0], (n, 1)))


def test_frusta_start_at_the_camera_and_reach_the_image_corners() -> None:
    poses = _poses(3)
    fr = frustum_corners(CAMERA, poses, 4.0)
    assert fr.shape == (3, 5, 3)
    np.testing.assert_allclose(fr[:, 0], poses.translation, atol=1e-9)
    for k in range(3):
        cam_p = poses[k].inverse() @ fr[k, 1:]
        np.testing.assert_allclose(cam_p[:, 2], 4.0, atol=1e-9)  # the image plane 4 m ahead
        uv, _, _ = CAMERA.project(cam_p)
        np.testing.assert_allclose(uv, [[-0.5, -0.5], [639.5, -0.5], [639.5, 479.5], [-0.5, 479.5]],
                                   atol=1e-6)
    # no camera: a 4:3 frustum 60 degrees wide
    fr = frustum_corners(None, poses[:1], 1.0)
    cam_p = poses[0].inverse() @ fr[0, 1:]
    assert math.degrees(2 * math.atan(cam_p[1, 0])) == pytest.approx(60.0)
    assert cam_p[2, 1] / cam_p[1, 0] == pytest.approx(0.75)


def _grids(value_of_side: list[float], surface: TurbineSurface) -> list[SideGrid]:
    """Grids whose every span bin holds ``value_of_side[k]`` on side k (spans 0.5 m apart)."""
    grids = []
    for part in range(4):
        top = surface.h if part == TOWER else surface.b
        spans = np.arange(0.25, top, 0.5)
        best = np.tile(np.array(value_of_side)[:, None], (1, spans.size))
        grids.append(SideGrid(part, spans, 0.5, best, np.zeros(best.shape, dtype=np.int64)))
    return grids


def test_each_blade_vertex_takes_the_coverage_of_the_side_its_normal_faces() -> None:
    surface = TurbineSurface(TURBINE, PAPER_GEOMETRY)
    grids = _grids([10.0, 20.0, 30.0, 40.0], surface)
    parts = {p.name: p for p in solid_mesh(TurbineSolid(TURBINE.to_vector(), PAPER_GEOMETRY))}
    for i in range(3):
        v, n, _ = smooth_normals(parts[f"blade_{i + 1}"], math.radians(40.0))
        gsd = vertex_gsd(surface, f"blade_{i + 1}", v, n, grids)
        bl = next(b for b in surface.blades if b.model_index == i)
        span = (v - bl.root) @ bl.axis
        inside = span > 1.0  # out of the spinner, in the bins
        assert np.isfinite(gsd[inside]).all() and set(np.unique(gsd[inside])) <= {10, 20, 30, 40}
        for direction, value in ((bl.chord, 10), (bl.normal, 20), (-bl.chord, 30), (-bl.normal, 40)):
            facing = inside & (n @ direction > math.cos(math.radians(30)))
            assert facing.sum() > 5 and (gsd[facing] == value).all(), (i, value)
    # the tower by its faces; the spinner and the nacelle are not covered parts
    v, n, _ = smooth_normals(parts["tower"], math.radians(40.0))
    gsd = vertex_gsd(surface, "tower", v, n, grids)
    front = (n @ surface.heading_dir > 0.9) & (v[:, 2] < 80)
    assert front.sum() > 2 and (gsd[front] == 10).all()
    v, n, _ = smooth_normals(parts["nacelle"], math.radians(40.0))
    assert np.isnan(vertex_gsd(surface, "nacelle", v, n, grids)).all()


def test_coverage_colours_are_the_coverage_figures() -> None:
    lo, hi = gsd_range([np.array([[1.0, np.inf], [4.0, 8.0]])], 2.0)
    assert lo == pytest.approx(0.9) and hi == pytest.approx(9.0)
    c = gsd_colours([lo, hi, np.inf, 1e9], lo, hi)
    assert c.dtype == np.uint8 and c.shape == (4, 3)
    assert tuple(c[0]) == (253, 231, 37)  # viridis_r: yellow at the fine end
    assert tuple(c[1]) == (68, 1, 84)  # dark purple at the coarse end
    assert "#" + "".join(f"{v:02x}" for v in c[2]) == GAP_COLOUR
    assert tuple(c[3]) == tuple(c[1])  # beyond the scale: its end


def test_the_skeleton_is_reprojected_into_the_thumbnail() -> None:
    pose = _poses(1, 250.0)[0]
    lines, points = overlay_lines(CAMERA, pose, TURBINE, PAPER_GEOMETRY, 320, 240)
    uv, ok, _ = CAMERA.project(pose.inverse() @ skeleton_points(TURBINE, PAPER_GEOMETRY))
    assert ok.all()
    np.testing.assert_allclose(points, (uv + 0.5) / 2 - 0.5, atol=0.051)
    assert len(lines) == 5 and all(len(p) == 2 * 16 for p in lines)
    np.testing.assert_allclose(lines[0][:2], points[0], atol=1e-9)  # base -> tower top
    # looking away from the turbine: nothing drawable
    away = look_at(np.array([[3.0, 200.0, 80.0]]), np.array([[3.0, 400.0, 80.0]]))[0]
    lines, points = overlay_lines(CAMERA, away, TURBINE, PAPER_GEOMETRY, 320, 240)
    assert lines == [] and points == []


def _scene(**kw: object) -> ViewScene:
    poses = _poses(8)
    args: dict = dict(title="t", facts=[("a", "b")], turbine=TURBINE, geometry=PAPER_GEOMETRY,
                      timestamps=np.arange(8.0), camera=CAMERA,
                      sets=[CameraSet("optimised", "optimised", "#1f77b4", poses)], shown=[0, 4, 7])
    args.update(kw)
    return ViewScene(**args)


def test_the_first_view_frames_the_turbine_and_the_cameras() -> None:
    scene = _scene()
    v = initial_view(scene)
    eye, target = np.array(v["position"]), np.array(v["target"])
    cam = look_at(eye[None], target[None])[0]
    pts = np.concatenate([skeleton_points(TURBINE, PAPER_GEOMETRY),
                          scene.sets[0].world_T_cam.translation]) - scene.origin
    p = cam.inverse() @ pts
    half = math.tan(math.radians(v["fov"] / 2))
    assert (p[:, 2] > 0).all()
    assert (np.abs(p[:, 1] / p[:, 2]) < half).all()  # vertically inside the view
    # it looks at the rotor from upwind (the hub's side of the tower)
    assert (eye[:2] @ [math.cos(TURBINE.heading), math.sin(TURBINE.heading)]) > 0


def test_arrays_survive_their_encoding_and_nan_is_refused() -> None:
    a = np.random.default_rng(0).normal(size=(7, 3))
    np.testing.assert_allclose(unpacked(packed(a)), a.astype(np.float32))
    np.testing.assert_array_equal(unpacked(packed([[1, 2, 3]], "uint32")), [[1, 2, 3]])
    with pytest.raises(ValueError, match="non-finite"):
        packed([0.0, np.nan])


def test_scene_data_is_strict_json_with_every_part() -> None:
    surface = TurbineSurface(TURBINE, PAPER_GEOMETRY)
    cov = flight_coverage(surface, CAMERA, _poses(8))
    data = scene_data(_scene(coverage=CoverageView(cov.grids, 2.0, surface, "computed"),
                             skeletons=[("initial", "initial turbine", "#d62728", tiny_turbine())]))
    json.dumps(data, allow_nan=False)
    cams = data["cameras"][0]
    assert unpacked(cams["positions"]).shape == (8, 3)
    assert unpacked(cams["frusta"]).shape == (3 * 5, 3)
    np.testing.assert_allclose(unpacked(cams["positions"])[4],
                               _poses(8).translation[4] - [3.0, -2.0, 0.0], atol=1e-4)
    parts = {p["name"]: p for p in data["turbine"]["parts"]}
    assert set(parts) == {"tower", "nacelle", "spinner", "blade_1", "blade_2", "blade_3"}
    for p in parts.values():
        n = unpacked(p["position"]).shape[0]
        assert unpacked(p["coverage"]).shape == unpacked(p["plain"]).shape == (n, 3)
        assert unpacked(p["index"]).max() < n
    # nacelle: plain colours; blades: coverage colours of the scale
    np.testing.assert_array_equal(unpacked(parts["nacelle"]["coverage"]),
                                  unpacked(parts["nacelle"]["plain"]))
    assert set(data["coverage"]["table"]) == set(PARTS[:4])
    assert len(data["coverage"]["stops"]) == 11
    assert [s["name"] for s in data["skeletons"]] == ["initial"]
    assert data["keyframes"]["shown"] == [0, 4, 7]
    labels = [lab["text"] for lab in data["turbine"]["labels"]]
    assert labels == ["blade A", "blade B", "blade C"]
