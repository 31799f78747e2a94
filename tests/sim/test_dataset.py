"""Rendered training data (turbinefit.sim.dataset): deterministic samples, targets on the
projected points, resumable builds, data versions."""

from __future__ import annotations

import json
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

from turbinefit.errors import InputError
from turbinefit.eval.detection import peak
from turbinefit.heatmaps.targets import render_keypoint_heatmaps
from turbinefit.sim.dataset import (
    DATA_VERSION,
    DatasetSpec,
    build_dataset,
    check_dataset_folder,
    render_sample,
    sample_view,
)


def test_samples_are_deterministic_and_independent_of_size() -> None:
    a = render_sample(DatasetSpec(5, seed=3), 2)
    b = render_sample(DatasetSpec(50, seed=3), 2)
    np.testing.assert_array_equal(a.image, b.image)
    np.testing.assert_array_equal(a.target, b.target)
    c = render_sample(DatasetSpec(5, seed=4), 2)
    assert not np.array_equal(a.image, c.image)


def test_sample_view_is_the_view_a_sample_shows() -> None:
    """Another renderer drawing views with sample_view (as benchmarks/bench_blender.py
    does) sees exactly the turbine and camera of the training sample of the same rng; and
    the views of a seed are pinned: a change of what they are changes every dataset, and
    needs a new DATA_VERSION."""
    from turbinefit.turbine.model import model_points

    spec = DatasetSpec(4, seed=21)
    for i in range(4):
        s = render_sample(spec, i)
        view = sample_view(np.random.default_rng(np.random.SeedSequence([spec.seed, i])))
        assert (view.camera.width, view.camera.height) == (spec.width, spec.height)
        world_p, _ = model_points(view.turbine.to_vector(), view.geometry)
        uv, front, _ = view.camera.project_unbounded(view.world_T_cam.inverse().apply(world_p))
        visible = front & view.camera.in_image(uv)
        np.testing.assert_array_equal(visible, s.visible)
        np.testing.assert_allclose(uv[visible], s.points[visible], rtol=0, atol=1e-9)
    view = sample_view(np.random.default_rng(np.random.SeedSequence([21, 1])))
    np.testing.assert_allclose(view.turbine.to_vector(), [
        0.0, 0.0, 72.12173178164132, 2.7107535082172802, 5.238251484281074, 0.9538311948663633,
        42.479769917621205], rtol=1e-9)
    np.testing.assert_allclose(view.world_T_cam.translation,
                               [14.81353863815756, 150.8898512668583, 92.47999403150467],
                               rtol=1e-9)
    assert view.camera.fx == pytest.approx(96.18616235224613, rel=1e-9)
    assert view.geometry.shaft_tilt == pytest.approx(0.0007710878035333921, rel=1e-9)
    assert DATA_VERSION == 4  # the version these views belong to


def test_image_scales_show_the_same_scene() -> None:
    """A photo of image scale 2 (320 x 240) resized to 160 x 120 is the scale-1 photo,
    with the same targets and points (both are rendered at 320 x 240)."""
    from turbinefit.io.images import resize_image

    one = render_sample(DatasetSpec(3, seed=6, image_scale=1), 1)
    two = render_sample(DatasetSpec(3, seed=6, image_scale=2), 1)
    assert one.image.shape == (120, 160, 3) and two.image.shape == (240, 320, 3)
    np.testing.assert_array_equal(resize_image(two.image, 160, 120), one.image)
    np.testing.assert_array_equal(one.target, two.target)
    np.testing.assert_array_equal(one.points, two.points)
    with pytest.raises(ValueError, match="image_scale"):
        DatasetSpec(3, image_scale=3)


def test_targets_peak_on_the_projected_points() -> None:
    spec = DatasetSpec(1, seed=11)
    checked = 0
    for i in range(10):
        s = render_sample(spec, i)
        assert s.image.shape == (240, 320, 3) and s.image.dtype == np.uint8
        assert s.target.shape == (7, 120, 160) and np.isfinite(s.target).all()
        for c in (0, 1, 2):
            if s.visible[c] and 2 < s.points[c, 0] < 157 and 2 < s.points[c, 1] < 117:
                u, v, val = peak(s.target[c])
                assert val > 0.9
                assert np.hypot(u - s.points[c, 0], v - s.points[c, 1]) < 0.2
                checked += 1
            elif not s.visible[c]:
                # a point out of view leaves at most a blob's tail at the border
                assert s.target[c].max() < 0.99 or c == 0
    assert checked >= 5


def test_keypoint_targets_match_the_3d_rendering() -> None:
    s = render_sample(DatasetSpec(1, seed=0), 0)
    vis = s.visible
    maps = render_keypoint_heatmaps(120, 160, [s.points], [vis], sigma_px=1.5)
    for c in range(3):
        if vis[c]:
            np.testing.assert_allclose(maps[c], s.target[c], atol=1e-5)
    if vis[0] and vis[1]:
        np.testing.assert_allclose(maps[4], s.target[4], atol=1e-4)
    # nothing labelled: empty maps; a line needs both ends
    assert not render_keypoint_heatmaps(10, 10, [np.zeros((6, 2))], [np.zeros(6, bool)]).any()
    one = np.zeros(6, bool)
    one[0] = True
    m = render_keypoint_heatmaps(20, 20, [np.full((6, 2), 10.0)], [one])
    assert m[0].max() == pytest.approx(1.0) and not m[4].any()


def test_build_resumes_and_refuses_another_spec(tmp_path: Path) -> None:
    spec = DatasetSpec(4, seed=1)
    d = build_dataset(tmp_path / "d", spec, workers=1, progress=False)
    assert d.complete
    images = np.array(d.images)
    # an interrupted build: two samples not done (and zeroed); the rebuild redoes only them
    done = np.load(tmp_path / "d" / "done.npy", mmap_mode="r+")
    done[[1, 3]] = False
    done.flush()
    del done
    im = np.load(tmp_path / "d" / "images.npy", mmap_mode="r+")
    im[[1, 3]] = 0
    im.flush()
    del im
    d2 = build_dataset(tmp_path / "d", spec, workers=1, progress=False)
    assert d2.complete
    np.testing.assert_array_equal(np.array(d2.images), images)
    # points in sight are visible ones, as rendered
    for i in range(4):
        s = render_sample(spec, i)
        np.testing.assert_array_equal(d2.in_sight[i], s.in_sight)
        assert not (s.in_sight & ~s.visible).any()
    with pytest.raises(InputError, match="another spec"):
        build_dataset(tmp_path / "d", DatasetSpec(5, seed=1), workers=1, progress=False)
    with pytest.raises(InputError, match="another spec"):
        build_dataset(tmp_path / "d", DatasetSpec(4, seed=1, image_scale=1), workers=1,
                      progress=False)


def test_a_folder_of_an_older_data_version_is_refused_by_name(tmp_path: Path) -> None:
    spec = DatasetSpec(4, seed=1)
    check_dataset_folder(tmp_path / "absent", spec)  # nothing there: fine
    old = tmp_path / "old"
    old.mkdir()
    (old / "spec.json").write_text(json.dumps(asdict(replace(spec, version=DATA_VERSION - 1))))
    with pytest.raises(InputError, match=f"data version {DATA_VERSION - 1}; this turbinefit "
                                         f"renders version {DATA_VERSION}"):
        check_dataset_folder(old, spec)
    with pytest.raises(InputError, match="data version"):
        build_dataset(old, spec, workers=1, progress=False)
    assert sorted(p.name for p in old.iterdir()) == ["spec.json"]  # nothing added


def test_closeup_targets_align_with_the_projected_geometry() -> None:
    """Close-up samples (the part fills the frame): deterministic; the line targets lie on
    the projected skeleton, the tip blob on the projected tip when it is in view, and the
    rendered part covers the line target where it fills the frame (the photo shows what
    the target marks)."""
    from turbinefit.sim.images import render_image_and_depth, sample_scene
    from turbinefit.turbine.model import skeleton_segments

    spec = DatasetSpec(6, seed=2, width=40, height=30, image_scale=1, closeup_fraction=1.0)
    assert render_sample(spec, 0).image.tobytes() == render_sample(spec, 0).image.tobytes()
    filled: list[int] = []
    tips = 0
    for i in range(6):
        s = render_sample(spec, i)
        view = sample_view(np.random.default_rng(np.random.SeedSequence([spec.seed, i])),
                           spec.width, spec.height, 1.0)
        assert view.closeup
        cam, T = view.camera, view.world_T_cam
        lines = s.target[4:].max(axis=0)
        assert lines.max() > 0.9
        # every ridge pixel (value > 0.9) lies within a pixel of a projected skeleton segment
        segs = T.inverse().apply(skeleton_segments(view.turbine, view.geometry).reshape(-1, 3))
        t = np.linspace(0.0, 1.0, 400)[:, None, None]
        segs = segs.reshape(-1, 2, 3)
        pts = (segs[None, :, 0] + t * (segs[None, :, 1] - segs[None, :, 0])).reshape(-1, 3)
        uv, _, _ = cam.project_unbounded(pts[pts[:, 2] > 0.05])
        vv, uu = np.nonzero(lines > 0.9)
        d = np.min(np.hypot(uu[:, None] - uv[None, :, 0], vv[:, None] - uv[None, :, 1]), axis=1)
        assert d.max() < 1.0
        for k in np.flatnonzero(s.visible[3:]):
            u, v = s.points[3 + k]
            j, ii = round(float(u)), round(float(v))
            assert s.target[3, ii, j] > 0.6
            tips += 1
        # the photo's turbine (finite depth) covers the line target
        big = cam.resized(2 * spec.width, 2 * spec.height)
        scene = sample_scene(np.random.default_rng(0), view.turbine)
        _, depth = render_image_and_depth(big, T, view.turbine.to_vector(), scene,
                                          np.random.default_rng(0), view.geometry)
        solid = np.isfinite(depth).reshape(spec.height, 2, spec.width, 2).any(axis=(1, 3))
        if solid.mean() > 0.05:  # not a thin tip far out
            assert solid[lines > 0.5].mean() > 0.8
            filled.append(i)
    assert len(filled) >= 2
    assert tips >= 1


def test_closeup_fraction() -> None:
    with pytest.raises(ValueError, match="closeup_fraction"):
        DatasetSpec(3, closeup_fraction=1.5)
    rng = np.random.default_rng(3)
    kinds = [sample_view(rng, closeup_fraction=0.3).closeup for _ in range(200)]
    assert 40 <= sum(kinds) <= 80
    assert not any(sample_view(rng, closeup_fraction=0.0).closeup for _ in range(20))
