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
