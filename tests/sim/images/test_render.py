"""Procedural RGB images (turbinefit.sim.images): determinism, output format, the turbine
drawn where the skeletal model projects, degenerate views, depth."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from support import CAMERA

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, world_T_cam_from_angles
from turbinefit.sim.images import (
    NO_EFFECTS,
    Scene,
    points_in_sight,
    render_flight_images,
    render_image,
    render_image_and_depth,
    sample_scene,
    sample_training_view,
)
from turbinefit.sim.turbines import PRESETS, REALISTIC_GEOMETRY, sample_turbine
from turbinefit.turbine.model import model_points

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")  # no NaN/inf on the way


TURBINE = PRESETS["nrel5mw"]


def _pose(pos: tuple[float, float, float], yaw: float, pitch: float, roll: float = 0.0) -> SE3:
    """world_T_cam of an OpenCV camera at ``pos`` looking along yaw/pitch [rad]."""
    return world_T_cam_from_angles(np.asarray(pos, dtype=float), yaw, pitch, roll)


def _look_at(eye: np.ndarray, target: np.ndarray) -> SE3:
    d = target - eye
    return _pose(tuple(eye), math.atan2(d[1], d[0]), math.atan2(d[2], math.hypot(d[0], d[1])))


@pytest.fixture(scope="module")
def scene() -> Scene:
    return sample_scene(np.random.default_rng(5), TURBINE)


@pytest.fixture(scope="module")
def clear_scene() -> Scene:
    """A clear, sunny scene without hills, neighbours or camera effects."""
    sc = sample_scene(np.random.default_rng(11), TURBINE)
    return replace(sc, overcast=0.0, cloud_cover=0.0, hills=(), neighbours=(), visibility=30000.0,
                   sky_zenith=(0.22, 0.42, 0.8), sky_horizon=(0.7, 0.8, 0.9),
                   haze_colour=(0.75, 0.82, 0.9), sun_azimuth=0.3, sun_elevation=0.7,
                   effects=NO_EFFECTS)


def test_deterministic_from_rng_state(scene: Scene) -> None:
    T = _look_at(np.array([150.0, 40.0, 30.0]), np.array([0.0, 0.0, 80.0]))
    a = render_image(CAMERA, T, TURBINE.to_vector(), scene, np.random.default_rng(3))
    b = render_image(CAMERA, T, TURBINE.to_vector(), scene, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    # the same scene sampled again from the same seed renders the same image
    scene2 = sample_scene(np.random.default_rng(5), TURBINE)
    assert scene2 == scene
    c = render_image(CAMERA, T, TURBINE.to_vector(), scene2, np.random.default_rng(3))
    np.testing.assert_array_equal(a, c)


def test_shape_and_dtype(scene: Scene) -> None:
    T = _look_at(np.array([200.0, -50.0, 60.0]), np.array([0.0, 0.0, 70.0]))
    for cam in (CAMERA, CAMERA.scaled(0.5), PinholeCamera(200, 150, 150.0, 160.0, 99.0, 77.0)):
        img = render_image(cam, T, TURBINE.to_vector(), scene, np.random.default_rng(0))
        assert img.shape == (cam.height, cam.width, 3)
        assert img.dtype == np.uint8
        assert img.std() > 2.0  # not a blank image


def test_turbine_drawn_where_the_model_projects(clear_scene: Scene) -> None:
    """Low camera in front of the rotor looking up at the hub: the hub and the tower's
    mid-point are against the sky and must differ clearly from the sky 30 px beside them."""
    theta = TURBINE.to_vector()  # heading 0 (rotor faces +x), blade 1 up
    p, _ = model_points(theta)
    T = _look_at(np.array([130.0, 0.0, 3.0]), p[2])
    img = render_image(CAMERA, T, theta, clear_scene, np.random.default_rng(0)).astype(float)
    mid = 0.5 * (p[0] + p[1])
    cam_p = T.inverse() @ np.stack([p[2], mid])
    uv, ok, _ = CAMERA.project(cam_p)
    assert ok.all()
    for u, v in uv:
        i, j = round(v), round(u)
        on = img[i, j]
        for side in (-30, 30):
            off = img[i, j + side]
            assert off[2] > off[0] + 15  # blue sky beside the turbine
            assert np.abs(on - off).sum() > 45, (u, v, on, off)


def test_geometry_is_respected(clear_scene: Scene) -> None:
    """With a tilted shaft and the hub above the tower top the hub still is drawn."""
    theta = TURBINE.to_vector()
    p, _ = model_points(theta, REALISTIC_GEOMETRY)
    T = _look_at(np.array([130.0, 0.0, 3.0]), p[2])
    img = render_image(CAMERA, T, theta, clear_scene, np.random.default_rng(0), REALISTIC_GEOMETRY)
    (u, v), = CAMERA.project(T.inverse() @ p[2:3])[0]
    hub = img[round(v), round(u)].astype(float)
    sky = img[round(v), round(u) + 30].astype(float)
    assert np.abs(hub - sky).sum() > 45


@pytest.mark.parametrize(
    "pose",
    [
        _pose((400.0, 0.0, 50.0), 0.0, 0.0),  # looking away from the turbine (at the horizon)
        _pose((60.0, 30.0, 20.0), 0.3, math.pi / 2),  # straight up
        _pose((15.0, 10.0, 40.0), 1.0, -math.pi / 2),  # straight down, beside the tower
        _pose((8.0, 0.0, 3.0), math.pi, -1.2),  # down at the tower base, close
        _pose((30.0, 0.0, 0.0), math.pi, 0.0),  # camera on the ground
        _pose((30.0, 0.0, -2.0), math.pi, 0.1),  # camera below the ground
        _pose((5000.0, 3000.0, 300.0), math.pi + 0.5, -0.05),  # far away
        _pose((2.5, 0.0, 40.0), math.pi, 0.0),  # inside the tower's radius
        _pose((-6.0, 0.0, 90.0), 0.0, 0.0),  # inside the nacelle
        _pose((5.0, 0.0, 90.0), math.pi, 0.0),  # in the spinner, looking back
        _pose((30.0, 0.0, 1.0e5), 0.0, 0.3),  # above the cloud deck
    ],
)
def test_degenerate_views_give_valid_images(scene: Scene, pose: SE3) -> None:
    img = render_image(CAMERA, pose, TURBINE.to_vector(), scene, np.random.default_rng(1))
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8


def test_distorted_camera(scene: Scene) -> None:
    cam = PinholeCamera(160, 120, 114.0, 114.0, 79.5, 59.5, distortion=(-0.3, 0.1, 0.001, -0.001, 0.0))
    T = _look_at(np.array([120.0, 30.0, 50.0]), np.array([0.0, 0.0, 80.0]))
    img = render_image(cam, T, TURBINE.to_vector(), scene, np.random.default_rng(1))
    assert img.shape == (120, 160, 3) and img.std() > 2.0


def test_every_terrain_and_sky_renders() -> None:
    rng = np.random.default_rng(0)
    cam = CAMERA.scaled(0.5)
    seen = set()
    for _ in range(12):
        t = sample_turbine(rng)
        sc = sample_scene(rng, t)
        seen.add(sc.terrain)
        T = sample_training_view(rng, t, cam)
        img = render_image(cam, T, t.to_vector(), sc, rng)
        assert img.shape == (120, 160, 3)
    assert len(seen) >= 4


def test_flight_images() -> None:
    theta = TURBINE.to_vector()
    eyes = np.array([[150.0, 0.0, 60.0], [140.0, 40.0, 70.0], [120.0, 70.0, 80.0]])
    poses = SE3(np.stack([_look_at(e, np.array([0.0, 0.0, 85.0])).wxyz_xyz for e in eyes]))
    cam = CAMERA.scaled(0.5)
    a = list(render_flight_images(cam, poses, theta, seed=4))
    b = list(render_flight_images(cam, poses, theta, seed=4))
    assert len(a) == 3
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    # frame 0 of a shorter flight (same seed) is the same image: per-frame streams
    first = next(render_flight_images(cam, poses[:1], theta, seed=4))
    np.testing.assert_array_equal(first, a[0])
    assert not np.array_equal(a[0], a[1])


def test_depth_and_points_in_sight(clear_scene: Scene) -> None:
    """The depth buffer holds the distance to the turbine's surface (the tower seen across
    its axis: distance minus its radius), inf on the sky; a point just behind the tower is
    not in sight, the same point in front of it is."""
    theta = TURBINE.to_vector()
    eye = np.array([-60.0, 80.0, 40.0])  # beside the tower, level with its middle
    T = _look_at(eye, np.array([0.0, 0.0, 40.0]))
    img0 = render_image(CAMERA, T, theta, clear_scene, np.random.default_rng(0))
    img, depth = render_image_and_depth(CAMERA, T, theta, clear_scene, np.random.default_rng(0))
    np.testing.assert_array_equal(img, img0)
    assert depth.shape == (CAMERA.height, CAMERA.width) and depth.dtype == np.float32
    axis = np.array([0.0, 0.0, 40.0])
    dist = float(np.linalg.norm(axis - eye))
    c = round(CAMERA.cy), round(CAMERA.cx)
    assert dist - 4.0 < depth[c] < dist - 1.0  # a tower of 2-4 m radius there
    assert np.isinf(depth[2, 2])  # sky (camera looks level: the top row is sky)
    toward = (eye - axis) / dist
    behind, front = axis - 8.0 * toward, axis + 8.0 * toward
    aside = axis + 40.0 * np.cross(toward, [0.0, 0.0, 1.0])
    out = axis + np.array([0.0, 0.0, 500.0])  # far above the image
    seen = points_in_sight(CAMERA, T, np.stack([behind, front, aside, out]), depth)
    assert seen.tolist() == [False, True, True, False]


def test_clutter_is_drawn_where_it_projects(clear_scene: Scene) -> None:
    """A wire and a building of the scene's clutter darken the sky / ground where they
    project and nowhere else; a scene's clutter is drawn from its seed alone."""
    from turbinefit.sim.images.clutter import Clutter

    cam = PinholeCamera(80, 60, 60.0, 60.0, 39.5, 29.5)
    pose = _pose((-300.0, -300.0, 40.0), 0.0, 0.05)  # looking along +x, the turbine aside
    wire = (-250.0, -330.0, 45.0, -250.0, -270.0, 45.0, 0.05, 0.1, 0.1, 0.1)
    shed = (-200.0, -300.0, 4.0, 6.0, 6.0, 4.0, 0.0, 0.6, 0.2, 0.15)
    bare = replace(clear_scene, clutter=Clutter())
    with_ = replace(clear_scene, clutter=Clutter(rods=(wire,), boxes=(shed,)))
    th = TURBINE.to_vector()
    a = render_image(cam, pose, th, bare, np.random.default_rng(0)).astype(float)
    b = render_image(cam, pose, th, with_, np.random.default_rng(0)).astype(float)
    changed = np.abs(a - b).sum(axis=-1) > 6
    uv, _, _ = cam.project_unbounded(pose.inverse().apply(np.array([[-250.0, -300.0, 45.0],
                                                                    [-200.0, -300.0, 4.0]])))
    for u, v in uv:
        assert changed[round(v) - 1:round(v) + 2, round(u) - 1:round(u) + 2].any()
    rows = np.flatnonzero(changed.any(axis=1))
    assert rows.size < 30  # a thin wire and a small shed, not the whole image
    s1 = sample_scene(np.random.default_rng(8), TURBINE)
    s2 = sample_scene(np.random.default_rng(8), TURBINE)
    assert s1.clutter == s2.clutter and s1.wear == s2.wear


def test_labels_follow_the_depth_buffer(scene: Scene) -> None:
    """render_labels: a part wherever the photo's depth buffer holds a turbine surface, the
    tower's span is the height of its surface point, blade angles only on blades, and the
    photo itself is unchanged by labelling."""
    from turbinefit.sim.images.painter import LABEL_CODES
    from turbinefit.sim.images.render import render_labels

    theta = TURBINE.to_vector()
    eye = np.array([-60.0, 80.0, 60.0])
    T = _look_at(eye, np.array([0.0, 0.0, 70.0]))
    img0, depth = render_image_and_depth(CAMERA, T, theta, scene, np.random.default_rng(0))
    lab = render_labels(CAMERA, T, theta, scene)
    img1 = render_image(CAMERA, T, theta, scene, np.random.default_rng(0))
    np.testing.assert_array_equal(img0, img1)
    np.testing.assert_array_equal(lab.part > 0, np.isfinite(depth))
    np.testing.assert_allclose(lab.depth[np.isfinite(depth)], depth[np.isfinite(depth)])
    tower = lab.part == LABEL_CODES.index("tower")
    blades = lab.part >= LABEL_CODES.index("blade_0")
    blades &= lab.part <= LABEL_CODES.index("blade_2")
    assert tower.sum() > 50 and blades.sum() > 50
    # the tower's surface point at the ray distance has the labelled height
    v, u = np.nonzero(tower)
    rays = np.stack([(u - CAMERA.cx) / CAMERA.fx, (v - CAMERA.cy) / CAMERA.fy, np.ones(u.size)], -1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    z = (T.rotation_matrix() @ rays.T)[2] * lab.depth[tower] + eye[2]
    np.testing.assert_allclose(lab.span[tower], z, atol=0.05)
    assert np.isfinite(lab.side_angle[blades]).all() and np.isnan(lab.side_angle[tower]).all()
    assert (lab.span[blades] >= 0).all() and (lab.span[blades] <= TURBINE.blade_length).all()


def test_flight_scenes_leave_out_the_training_renders_details() -> None:
    """Wear, dirt, seams, blade marks and clutter are drawn in training renders only: a
    flight's scene is the training scene of its seed without them, and its blades render
    as they do without marks (the flights' photos stay those the fits were measured on)."""
    from turbinefit.sim.images.clutter import NO_CLUTTER
    from turbinefit.sim.images.scene import flight_scene

    th = TURBINE.to_vector()
    fl = flight_scene(th, 5)
    assert (fl.wear, fl.dirt, fl.tower_section, fl.clutter, fl.blade_marks) == (
        0.0, 0.0, 0.0, NO_CLUTTER, False)
    trained = [sample_scene(np.random.default_rng(s), TURBINE) for s in range(20)]
    assert all(s.blade_marks for s in trained) and any(s.clutter != NO_CLUTTER for s in trained)
    # a close view of a blade's marks: they change the picture only where enabled
    cam = PinholeCamera(80, 60, 60.0, 60.0, 39.5, 29.5)
    tip = model_points(th)[0][3]
    pose = _look_at(tip + np.array([0.0, -12.0, 0.0]), tip)
    plain = render_image(cam, pose, th, fl, np.random.default_rng(0))
    again = render_image(cam, pose, th, replace(fl, blade_marks=False), np.random.default_rng(0))
    marked = render_image(cam, pose, th, replace(fl, blade_marks=True), np.random.default_rng(0))
    np.testing.assert_array_equal(plain, again)
    assert np.abs(plain.astype(int) - marked.astype(int)).max() > 0
