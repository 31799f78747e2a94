"""The edge term in the problem: photos at twice the maps' size in which the tower is
drawn as the solid's tapered silhouette round its true skeleton line give edge
correspondences on the true tower line (within a tenth of a map pixel) at the true poses,
an ``edges`` term in the cost, and none without photos, with lambda_edges 0, or for
maps without evidence."""

import dataclasses

import numpy as np
import pytest
from support import simulated_flight

from turbinefit.costs.edges import PhotoStack
from turbinefit.costs.projection import project_points
from turbinefit.flight import Flight
from turbinefit.solver import FitConfig
from turbinefit.solver.problem import FitProblem
from turbinefit.turbine.model import model_points
from turbinefit.turbine.solid import TurbineSolid

cv2 = pytest.importorskip("cv2")

N = 6
S = 2  # photo px per map px
CONFIG = FitConfig(lines="corr", line_residual="normal", robust="cauchy", lambda_edges=1.0)


def tower_photos(flight: Flight) -> PhotoStack:
    """Grey photos of the true tower (a bright quad of the solid's radii at base and top)
    over a textured dark background."""
    gt, gt_t = flight.gt_world_T_cam, flight.gt_turbine
    assert gt is not None and gt_t is not None
    cam = flight.camera.scaled(S)
    solid = TurbineSolid(gt_t.to_vector())
    P, _ = model_points(gt_t.to_vector())
    rng = np.random.default_rng(0)
    out = []
    for k in range(flight.num_keyframes):
        img = cv2.GaussianBlur(rng.uniform(40, 90, (cam.height, cam.width)), (0, 0), 2.0)
        pr = project_points(cam, gt[k:k + 1], P[:2], None, with_jacobian=False)
        (b, t), depth = pr.uv[0], (gt[k].inverse().apply(P[:2]))[:, 2]
        axis = (t - b) / np.linalg.norm(t - b)
        n = np.array([-axis[1], axis[0]])
        rb, rt = solid.r0 * cam.fx / depth[0], solid.r1 * cam.fx / depth[1]
        quad = np.array([b + rb * n, t + rt * n, t - rt * n, b - rb * n])
        mask = np.zeros((cam.height * 8, cam.width * 8), np.uint8)  # anti-aliased by 8x
        cv2.fillConvexPoly(mask, np.round((quad + 0.5) * 8 - 0.5).astype(np.int32), 255)
        cover = cv2.resize(mask.astype(np.float32) / 255, (cam.width, cam.height),
                           interpolation=cv2.INTER_AREA)
        out.append(np.clip(img * (1 - cover) + 230 * cover, 0, 255).astype(np.uint8))
    return PhotoStack(np.stack(out), float(S))


@pytest.fixture(scope="module")
def flight() -> Flight:
    f = simulated_flight(N, seed=3, width=160)
    return dataclasses.replace(f, photos=tower_photos(f))


def test_edges_lie_on_the_true_tower_line(flight: Flight) -> None:
    gt, gt_t = flight.gt_world_T_cam, flight.gt_turbine
    assert gt is not None and gt_t is not None
    prob = FitProblem(flight, CONFIG)
    th = gt_t.to_vector()
    corr = prob.find_correspondences(gt, th)
    assert corr.edge_found is not None and corr.edge_target is not None
    assert corr.line_normal is not None
    tower = prob._line_index == 0
    found = corr.edge_found[:, tower]
    assert found.sum() >= 0.5 * corr.line_found[:, tower].sum() > 0
    assert not corr.edge_found[:, ~tower & (prob._line_index == 1)].any()  # no nacelle
    _, lns = prob.model(th, False, corr.line_fractions)
    uv = project_points(flight.camera, gt, lns.points(), None, with_jacobian=False).uv
    d = np.sum((corr.edge_target - uv) * corr.line_normal, axis=-1)[:, tower][found]
    assert np.max(np.abs(d)) < 0.1
    lin = prob.linearize(gt, th, corr)
    assert lin.terms["edges"] >= 0 and lin.in_view["edges"] == int(corr.edge_found.sum())


def test_no_edges_without_photos_weight_or_evidence(flight: Flight) -> None:
    gt, gt_t = flight.gt_world_T_cam, flight.gt_turbine
    assert gt is not None and gt_t is not None
    th = gt_t.to_vector()
    for f, cfg in ((dataclasses.replace(flight, photos=None), CONFIG),
                   (flight, dataclasses.replace(CONFIG, lambda_edges=0.0))):
        prob = FitProblem(f, cfg)
        corr = prob.find_correspondences(gt, th)
        assert corr.edge_found is None
        assert "edges" not in prob.linearize(gt, th, corr).terms
    empty = dataclasses.replace(flight, heatmaps=type(flight.heatmaps)(
        np.zeros_like(np.asarray(flight.heatmaps[0]))[None].repeat(N, axis=0)))
    corr = FitProblem(empty, CONFIG).find_correspondences(gt, th)
    assert corr.edge_found is not None and not corr.edge_found.any()


def test_tower_width_gives_its_depth(flight: Flight) -> None:
    """The width term (lambda_width, edge term off): at the true poses the tower's depths
    measured from its silhouette's width are its true depths (to 3 %); moved 10 % back
    along their optical axes, the cameras' width depths stay the true ones (to 5 %), and
    the term's gradient pushes every camera forward; no blade widths without a pitch."""
    gt, gt_t = flight.gt_world_T_cam, flight.gt_turbine
    assert gt is not None and gt_t is not None
    cfg = dataclasses.replace(CONFIG, lambda_edges=0.0, lambda_width=1.0)
    prob = FitProblem(flight, cfg)
    th = gt_t.to_vector()
    corr = prob.find_correspondences(gt, th)
    w = corr.width
    assert w is not None
    tower = prob._line_index == 0
    assert w.found[:, tower].sum() >= 0.5 * corr.line_found[:, tower].sum() > 0
    assert not w.found[:, ~tower].any()  # blades: no pitch given; nacelle: never
    _, lns = prob.model(th, False, corr.line_fractions)
    R = gt.rotation_matrix()
    z = np.einsum("nk,nmk->nm", R[:, :, 2], lns.points() - gt.translation[:, None])
    ratio = w.depth[w.found] / z[w.found]
    assert np.median(np.abs(ratio - 1)) < 0.03
    lin = prob.linearize(gt, th, corr)
    assert "edges" not in lin.terms and lin.in_view["width"] == int(w.found.sum())

    back = gt.retract(np.concatenate([-0.1 * z.mean(axis=1, keepdims=True) * R[:, :, 2],
                                      np.zeros((N, 3))], axis=1))
    corr_b = prob.find_correspondences(back, th)
    assert corr_b.width is not None
    both = corr_b.width.found & w.found
    assert both.sum() >= 0.5 * w.found.sum()
    np.testing.assert_allclose(np.median(corr_b.width.depth[both] / z[both]), 1.0, atol=0.05)
    lin_b = prob.linearize(back, th, corr_b)
    no_width = FitProblem(flight, dataclasses.replace(cfg, lambda_width=0.0))
    lin_0 = no_width.linearize(back, th, corr_b)
    assert lin_b.g_p is not None and lin_0.g_p is not None
    # the width term's cost falls moving each camera forward along its axis: g . axis < 0
    forward = np.einsum("ni,ni->n", lin_b.g_p[:, :3] - lin_0.g_p[:, :3], R[:, :, 2])
    has = corr_b.width.found.any(axis=1) & ~prob.fixed
    assert has.any() and np.all(forward[has] < 0)


def test_tracker_takes_photos_for_the_width_term(flight: Flight) -> None:
    """Photo by photo, the tracker's window holds the photos and its estimates use the
    tower's width; a photo of the wrong size, or given for some keyframes only, is
    refused and changes nothing."""
    from turbinefit.solver.tracker import KeyframeError, Tracker, TrackerConfig

    assert flight.photos is not None
    cfg = TrackerConfig(fit=dataclasses.replace(CONFIG, lambda_edges=0.0, lambda_width=1.0))
    tr = Tracker(flight.camera, flight.turbine, cfg)
    photos = flight.photos.images
    for k in range(N):
        est = tr.update(float(flight.timestamps[k]), flight.world_T_cam[k], flight.heatmaps[k],
                        photo=photos[k])
    assert est.in_view.get("width", 0) > 0
    assert tr._window is not None and tr._window.data.photos is not None
    assert len(tr._window.data.photos) == len(tr._window)

    fresh = Tracker(flight.camera, flight.turbine, cfg)
    t, pose, maps = float(flight.timestamps[0]), flight.world_T_cam[0], flight.heatmaps[0]
    for bad, why in ((photos[0][:, :-3], "aspect"), (photos[0][None], "grey"),
                     (np.full(photos[0].shape, np.nan, np.float32), "NaN")):
        with pytest.raises(KeyframeError, match=why):
            fresh.update(t, pose, maps, photo=bad)
        assert fresh.num_keyframes == 0
    fresh.update(t, pose, maps, photo=photos[0])
    t1, pose1, maps1 = float(flight.timestamps[1]), flight.world_T_cam[1], flight.heatmaps[1]
    with pytest.raises(KeyframeError, match="no photo"):
        fresh.update(t1, pose1, maps1)
    small = photos[1][::2, ::2]
    with pytest.raises(KeyframeError, match="px wide"):
        fresh.update(t1, pose1, maps1, photo=small)
    assert fresh.num_keyframes == 1
    without = Tracker(flight.camera, flight.turbine, cfg)
    without.update(t, pose, maps)
    with pytest.raises(KeyframeError, match="photo given"):
        without.update(t1, pose1, maps1, photo=photos[1])


def test_fit_and_track_folders_read_the_photos_for_the_width_term(flight: Flight,
                                                                    tmp_path) -> None:
    """``turbinefit fit`` and ``track`` of a flight folder with photos twice the maps'
    size: with ``lambda_width`` in the options the photos are read (grey, the maps'
    aspect) and the width term is in the fit's final cost and the tracker's estimates;
    without the option, or without photos, it is not."""
    from turbinefit.io.flight_folder import write_flight
    from turbinefit.jobs.fit import fit_folder
    from turbinefit.jobs.track import track_folder

    assert flight.photos is not None
    rgb = [np.repeat(g[..., None], 3, axis=-1) for g in flight.photos.images]
    write_flight(dataclasses.replace(flight, photos=None), tmp_path / "f", images=rgb,
                 camera=flight.camera.scaled(S))
    opts = {"lines": "corr", "line_residual": "normal", "robust": "cauchy"}
    on = fit_folder(tmp_path / "f", tmp_path / "on", options={**opts, "lambda_width": 1.0},
                    plots=False)
    assert on.summary.result.final_terms.get("width", 0.0) > 0.0
    off = fit_folder(tmp_path / "f", tmp_path / "off", options=opts, plots=False)
    assert "width" not in off.summary.result.final_terms
    write_flight(dataclasses.replace(flight, photos=None), tmp_path / "bare")
    bare = fit_folder(tmp_path / "bare", tmp_path / "b", options={**opts, "lambda_width": 1.0},
                      plots=False)
    assert "width" not in bare.summary.result.final_terms
    tracked = track_folder(tmp_path / "f", tmp_path / "t", options={**opts, "lambda_width": 1.0},
                           plots=False)
    assert tracked.estimates[-1].in_view.get("width", 0) > 0
    untracked = track_folder(tmp_path / "f", tmp_path / "u", options=opts, plots=False)
    assert "width" not in untracked.estimates[-1].in_view
