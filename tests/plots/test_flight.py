"""Smoke tests of the flight figures (turbinefit.plots.flight): each writes a readable,
non-blank PNG of plausible size and survives empty data, a turbine out of view and cameras
behind or inside the turbine."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import CAMERA, look_at

from turbinefit.errors import InputError
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.plots import choose_keyframes, plot_cost_history, plot_errors, plot_reprojections, plot_scene
from turbinefit.turbine.model import LINES, TurbineParams, model_points

GT = TurbineParams(0.0, 0.0, 80.0, 0.3, 5.0, 0.1, 50.0)

INITIAL = TurbineParams(4.0, -3.0, 84.0, 0.38, 5.5, 0.25, 47.0)

OPTIMISED = TurbineParams(0.6, -0.4, 80.7, 0.31, 5.1, 0.12, 49.5)

N = 12


def orbit(n: int = N, radius: float = 150.0) -> SE3:
    """Cameras on an arc ~150 m in front of the rotor, looking at the nacelle."""
    ang = GT.heading + np.linspace(-0.9, 0.9, n)
    eye = np.stack([radius * np.cos(ang), radius * np.sin(ang), 60.0 + 15 * np.sin(3 * ang)], -1)
    return look_at(eye, np.tile([0.0, 0.0, 75.0], (n, 1)))


def drift(poses: SE3, scale: float, seed: int) -> SE3:
    """Sequential (random-walk) noise on position and orientation, as the paper simulates."""
    rng = np.random.default_rng(seed)
    n = len(poses)
    dt = np.cumsum(rng.normal(0.0, scale, (n, 3)), axis=0)
    dphi = np.cumsum(rng.normal(0.0, 0.004 * scale, (n, 3)), axis=0)
    return poses.retract(np.concatenate([dt, dphi], axis=-1))


def render(poses: SE3, turbine: TurbineParams, h: int = 240, w: int = 320) -> np.ndarray:
    """Blurred point and line heat-maps (N, 7, h, w) of ``turbine`` seen from ``poses``."""
    pts, _ = model_points(turbine.to_vector())
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    sx, sy = w / CAMERA.width, h / CAMERA.height
    out = np.zeros((len(poses), 7, h, w), dtype=np.float32)
    for k in range(len(poses)):
        cam_p = poses[k].inverse() @ pts
        uv, front, _ = CAMERA.project_unbounded(cam_p)
        uv = (uv + 0.5) * np.array([sx, sy]) - 0.5
        for i, ch in enumerate((0, 1, 2, 3, 3, 3)):
            if front[i]:
                d2 = (u - uv[i, 0]) ** 2 + (v - uv[i, 1]) ** 2
                out[k, ch] = np.maximum(out[k, ch], np.exp(-d2 / (2 * 3.0**2)))
        for a, b, ch in LINES:
            if not (front[a] and front[b]):
                continue
            ab = uv[b] - uv[a]
            s = ((u - uv[a, 0]) * ab[0] + (v - uv[a, 1]) * ab[1]) / max(ab @ ab, 1e-9)
            s = np.clip(s, 0.0, 1.0)
            d2 = (u - uv[a, 0] - s * ab[0]) ** 2 + (v - uv[a, 1] - s * ab[1]) ** 2
            out[k, ch] = np.maximum(out[k, ch], np.exp(-d2 / (2 * 2.0**2)))
    return out


@pytest.fixture(scope="module")
def flight() -> dict:
    gt = orbit()
    return {
        "gt": gt,
        "initial": drift(gt, 0.8, seed=1),
        "optimised": drift(gt, 0.1, seed=2),
        "heatmaps": HeatmapStack(render(gt, GT)),
        "timestamps": 1000.0 + 0.5 * np.arange(N),
    }


def assert_png(path: Path, min_w: int = 300, min_h: int = 200) -> np.ndarray:
    from matplotlib.image import imread

    assert path.is_file() and path.suffix == ".png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(path.parent.glob("*.tmp.png")), "temporary file left behind"
    img = imread(path)
    assert img.ndim == 3 and img.shape[2] in (3, 4)
    assert img.shape[0] >= min_h and img.shape[1] >= min_w
    assert img[..., :3].std() > 0.01, "blank image"
    return img


def test_plot_scene(tmp_path, flight):
    out = plot_scene(tmp_path / "new" / "dir" / "scene.png", initial_poses=flight["initial"],
                     optimised_poses=flight["optimised"], initial_turbine=INITIAL,
                     optimised_turbine=OPTIMISED, gt_poses=flight["gt"], gt_turbine=GT)
    img = assert_png(out, 1500, 700)
    # the three colours are all present
    rgb = img[..., :3]
    for colour in ((0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.12, 0.47, 0.71)):
        assert np.any(np.all(np.abs(rgb - colour) < 0.05, axis=-1))
    # overwriting an existing file works too
    assert plot_scene(out, initial_poses=flight["initial"], optimised_poses=flight["optimised"],
                      initial_turbine=INITIAL, optimised_turbine=OPTIMISED, title="x") == out


def test_plot_scene_degenerate(tmp_path, flight):
    empty = SE3(np.zeros((0, 7)))
    assert_png(plot_scene(tmp_path / "empty.png", initial_poses=empty, optimised_poses=empty,
                          initial_turbine=INITIAL, optimised_turbine=OPTIMISED))
    one = flight["gt"][3]  # a single pose, batch shape ()
    assert_png(plot_scene(tmp_path / "one.png", initial_poses=one, optimised_poses=one,
                          initial_turbine=INITIAL, optimised_turbine=OPTIMISED, gt_poses=one))


def test_plot_reprojections(tmp_path, flight):
    kfs = choose_keyframes(N, 6)
    out = plot_reprojections(
        tmp_path / "reproj.png", camera=CAMERA, heatmaps=flight["heatmaps"], keyframes=kfs,
        initial_poses=flight["initial"], initial_turbine=INITIAL,
        optimised_poses=flight["optimised"], optimised_turbine=OPTIMISED,
        timestamps=flight["timestamps"])
    img = assert_png(out, 1000, 500)
    rgb = img[..., :3]
    # red (initial) and bright green (optimised) overlays are drawn
    assert np.any((rgb[..., 0] > 0.7) & (rgb[..., 1] < 0.3) & (rgb[..., 2] < 0.3))
    assert np.any((rgb[..., 1] > 0.8) & (rgb[..., 0] < 0.4) & (rgb[..., 2] < 0.3))


def test_plot_reprojections_out_of_view(tmp_path, flight):
    away = look_at(np.array([[150.0, 40.0, 60.0], [0.0, 0.0, 140.0], [10.0, 0.0, 40.0]]),
                   np.array([[400.0, 40.0, 60.0], [5.0, 0.0, 300.0], [10.0, 30.0, 45.0]]))
    # looking away (turbine behind), looking up from above the rotor, and a camera next to
    # the tower with model lines crossing the image plane
    poses = SE3(np.concatenate([away.wxyz_xyz, flight["gt"].wxyz_xyz[:1]]))
    heat = HeatmapStack(np.zeros((4, 7, 240, 320), dtype=np.float32))
    out = plot_reprojections(tmp_path / "away.png", camera=CAMERA, heatmaps=heat,
                             keyframes=[0, 1, 2, 3], initial_poses=poses,
                             initial_turbine=INITIAL, optimised_poses=poses,
                             optimised_turbine=OPTIMISED)
    assert_png(out)
    # no keyframes at all
    assert_png(plot_reprojections(tmp_path / "none.png", camera=CAMERA, heatmaps=heat,
                                  keyframes=[], initial_poses=poses, initial_turbine=INITIAL,
                                  optimised_poses=poses, optimised_turbine=OPTIMISED),
               min_w=200, min_h=150)
    with pytest.raises(InputError, match="keyframe index 7"):
        plot_reprojections(tmp_path / "bad.png", camera=CAMERA, heatmaps=heat, keyframes=[7],
                           initial_poses=poses, initial_turbine=INITIAL, optimised_poses=poses,
                           optimised_turbine=OPTIMISED)


def test_plot_reprojections_low_resolution_heatmaps(tmp_path, flight):
    """Heat-maps at half the camera's resolution are stretched over the image."""
    heat = HeatmapStack(render(flight["gt"][:2], GT, h=120, w=160))
    assert_png(plot_reprojections(tmp_path / "half.png", camera=CAMERA, heatmaps=heat,
                                  keyframes=[0, 1], initial_poses=flight["initial"],
                                  initial_turbine=INITIAL, optimised_poses=flight["optimised"],
                                  optimised_turbine=OPTIMISED))


def test_plot_errors(tmp_path, flight):
    from turbinefit.geometry.se3 import pose_errors

    ip, ir = pose_errors(flight["initial"], flight["gt"])
    op, orr = pose_errors(flight["optimised"], flight["gt"])
    out = plot_errors(tmp_path / "errors.png", timestamps=flight["timestamps"],
                      initial_pos_err=ip, optimised_pos_err=op,
                      initial_rot_err_deg=np.degrees(ir), optimised_rot_err_deg=np.degrees(orr))
    assert_png(out, 1000, 700)
    assert_png(plot_errors(tmp_path / "empty_err.png", timestamps=None, initial_pos_err=[],
                           optimised_pos_err=[], initial_rot_err_deg=[],
                           optimised_rot_err_deg=[]))


def test_plot_cost_history(tmp_path):
    costs = [5e4 * 0.5**i + 10.0 for i in range(15)]
    assert_png(plot_cost_history(tmp_path / "cost.png", costs), 800, 500)
    assert_png(plot_cost_history(tmp_path / "cost_empty.png", []))
    assert_png(plot_cost_history(tmp_path / "cost_zero.png", [3.0, 0.0, float("nan")]))
    stages = ["align"] * 5 + ["match"] * 4 + ["refine"] * 6
    assert_png(plot_cost_history(tmp_path / "cost_stages.png", costs, stages), 800, 500)
    with pytest.raises(ValueError, match="stage names"):
        plot_cost_history(tmp_path / "bad.png", costs, stages[:-1])


def test_plot_reprojections_over_photos(tmp_path, flight):
    """With ``photo``, each panel shows the keyframe's photo (any size, stretched), the
    heat-maps faint on top, the models over both."""
    asked = []

    def photo(k):
        asked.append(k)
        return np.full((60, 80, 3), (150, 90, 200), dtype=np.uint8)  # a lilac photo

    kfs = [0, 3]
    out = plot_reprojections(
        tmp_path / "photos.png", camera=CAMERA, heatmaps=flight["heatmaps"], keyframes=kfs,
        initial_poses=flight["initial"], initial_turbine=INITIAL,
        optimised_poses=flight["optimised"], optimised_turbine=OPTIMISED, photo=photo)
    rgb = assert_png(out)[..., :3]
    assert asked == kfs
    lilac = np.all(np.abs(rgb - np.array([150, 90, 200]) / 255) < 0.03, axis=-1)
    assert lilac.mean() > 0.2  # the photo fills the panels where the maps are dark
    assert np.any((rgb[..., 1] > 0.8) & (rgb[..., 0] < 0.4) & (rgb[..., 2] < 0.3))  # the model
