"""The joint least-squares problem of a flight: residuals, Jacobians, normal equations.

Unknowns: every keyframe pose ``world_T_cam[k]`` (6 local coordinates each, see
:meth:`turbinefit.geometry.se3.SE3.retract`) and theta (7). Cost (Ceres' convention)::

    E = 1/2 sum rho(s_image) + 1/2 sum |r_pair|^2 + 1/2 sum |r_prior|^2
        + 1/2 sum |r_position|^2 + 1/2 sum rho(|r_motion|^2)

with, per projected model point or line sample, ``s`` the heat-map cost of
:mod:`turbinefit.costs.heatmap_cost` (interp) or the squared whitened distance to a
correspondence of :mod:`turbinefit.costs.correspondence` (corr), weighted lambda_P for the
6 model points and lambda_L for the line samples; the pairwise term of
:mod:`turbinefit.costs.pairwise` (lambda) between consecutive keyframes; and, with
``gauge="gps"``, absolute position priors; and, when the keyframes come with position
standard deviations (``position_sigma``, an RTK flight's ``keyframes_sigma.csv``), a
position prior per keyframe with them (:mod:`turbinefit.costs.position_prior`); and, when
the keyframes come with relative motions measured by tie points between consecutive photos
(``motions``), the tie-point term between those keyframes
(:mod:`turbinefit.costs.relative_motion`, weight ``lambda_motion``), which like the
pairwise term only couples consecutive poses.

Each image term gives, per point, the gradient ``g`` and a positive semi-definite Hessian
model ``H`` of its cost w.r.t. the point's pixel (exact Gauss-Newton for corr, see
heatmap_cost for interp; a robust loss scales both by rho'(s)); with ``J = d uv / d x``
the normal equations collect ``J^T H J`` and ``J^T g``. Everything is evaluated for all
keyframes in one vectorised pass, accumulated per keyframe (6x6 pose blocks, 6x7
pose-turbine blocks, one 7x7 turbine block), so that cost and memory grow linearly with
the number of keyframes.

Gauge: the pairwise term is relative only, so with theta free a global x-y shift and yaw
of everything is unobservable (theta's base and heading absorb it). By default the first
keyframe's pose is held fixed; ``gauge="gps"`` instead anchors every keyframe weakly to its
initial (GPS) position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from turbinefit import _native
from turbinefit.costs.correspondence import (
    correspondence_terms,
    find_line_correspondences,
    find_point_correspondences,
)
from turbinefit.costs.edges import PhotoStack
from turbinefit.costs.heatmap_cost import heatmap_terms
from turbinefit.costs.pairwise import pairwise_residuals, relative_poses
from turbinefit.costs.position_prior import position_prior_residuals
from turbinefit.costs.projection import project_points
from turbinefit.costs.relative_motion import RelativeMotions, relative_motion_residuals
from turbinefit.costs.robust import RobustLoss
from turbinefit.costs.silhouette_width import WidthDepths, width_terms
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.solver.config import FitConfig, resolve_pair_frame, resolve_pixel_scale
from turbinefit.solver.marginal import GaussianPrior
from turbinefit.solver.photo_terms import MIN_EDGE_SCALE, silhouette_correspondences
from turbinefit.turbine.model import (
    LINES,
    POINT_CHANNELS,
    line_samples,
    model_points,
)

FloatArray = NDArray[np.float64]

class ProblemData(Protocol):
    """What a :class:`FitProblem` reads of its keyframes: a
    :class:`~turbinefit.flight.Flight`, or :class:`~turbinefit.solver.window.Keyframes`."""

    @property
    def camera(self) -> PinholeCamera:
        """Intrinsics of the heat-maps' pixel grid."""

    @property
    def world_T_cam(self) -> SE3:
        """(N,) initial (GPS/IMU) camera-to-world poses: the anchors of ``gauge="gps"``."""

    @property
    def heatmaps(self) -> HeatmapStack:
        """The N keyframes' heat-maps."""

    @property
    def num_keyframes(self) -> int:
        """N."""

    @property
    def odometry(self) -> SE3 | None:
        """(N,) body-frame odometry poses, or None (the pairwise measurements are then the
        steps of ``world_T_cam``); decides ``pair_frame="auto"``."""

    def measurement_poses(self) -> SE3:
        """(N,) poses whose consecutive relative poses are the pairwise measurements."""

    @property
    def position_sigma(self) -> FloatArray | None:
        """(N, 3) standard deviations [m] of the positions of ``world_T_cam`` (absolute
        position priors), or None: no such priors."""

    @property
    def photos(self) -> PhotoStack | None:
        """(N,) the keyframes' grey photos for the edge term, or None
        (:mod:`turbinefit.costs.edges`)."""

    @property
    def motions(self) -> RelativeMotions | None:
        """(N,) relative motions measured by tie points between consecutive photos, or
        None (:mod:`turbinefit.costs.relative_motion`)."""


@dataclass
class Samples:
    """World points of an image term: ``(1 - f) A + f B`` with per-keyframe fractions
    ``f`` (N, M) along segments A -> B (M, 3), or the shared points A if ``f`` is None;
    ``JA``, ``JB`` (M, 3, 7): the ends' Jacobians w.r.t. theta, or None."""

    A: FloatArray
    B: FloatArray
    JA: FloatArray | None
    JB: FloatArray | None
    f: FloatArray | None = None

    def points(self) -> FloatArray:
        """(M, 3) shared, or (N, M, 3) per-keyframe world points."""
        if self.f is None:
            return self.A
        f = self.f[..., None]
        return self.A[None] * (1.0 - f) + self.B[None] * f


@dataclass
class Correspondences:
    """Fixed 2-D targets of the corr terms: (N, M, 2) pixels and a (N, M) found-mask."""

    point_target: FloatArray | None = None
    point_found: NDArray[np.bool_] | None = None
    line_target: FloatArray | None = None
    line_found: NDArray[np.bool_] | None = None
    line_normal: FloatArray | None = None
    """(N, M, 2) unit image normal each line target was searched along."""
    line_fractions: FloatArray | None = None
    """(N, 5, n) where each keyframe samples each line (visible-part sampling), or None."""
    edge_target: FloatArray | None = None
    """(N, M, 2) silhouette midpoints of the line samples found in the photos (edge term)."""
    edge_found: NDArray[np.bool_] | None = None
    width: WidthDepths | None = None
    """The line samples' depths measured from their apparent widths (width term)."""

    def count(self) -> int:
        n = 0
        for f in (self.point_found, self.line_found, self.edge_found):
            if f is not None:
                n += int(f.sum())
        return n


@dataclass
class Linearization:
    """Cost and (undamped) normal equations at one state (``J^T H J`` and ``J^T g``).

    ``D`` (N, 6, 6) / ``B`` (N-1, 6, 6) are the diagonal / sub-diagonal pose blocks of
    J^T H J, ``C`` (N, 6, 7) the pose-turbine blocks, ``E`` (7, 7) the turbine block,
    ``g_p`` (N, 6) / ``g_t`` (7,) the gradient. Blocks of held variables are zero.
    """

    cost: float
    terms: dict[str, float]
    D: FloatArray | None = None
    B: FloatArray | None = None
    C: FloatArray | None = None
    E: FloatArray | None = None
    g_p: FloatArray | None = None
    g_t: FloatArray | None = None
    num_residuals: int = 0
    in_view: dict[str, int] = field(default_factory=dict)


def pair_sqrt_information(config: FitConfig, measured_rel: SE3) -> FloatArray:
    """(E, 6, 6) square-root information ``L`` (``C = L^T L``) of each pairwise edge whose
    measured relative pose is ``measured_rel`` (E,), times ``sqrt(lambda_pair)``: from
    ``pair_information``, or from the configured sigmas and each step's length."""
    n_edges = measured_rel.batch_shape[0] if measured_rel.batch_shape else 1
    if config.pair_information is not None:
        C = np.asarray(config.pair_information, dtype=np.float64).reshape(6, 6)
        C = 0.5 * (C + C.T)
        try:
            L = np.linalg.cholesky(C).T  # C = L^T L
        except np.linalg.LinAlgError as exc:
            raise ValueError("pair_information must be positive definite") from exc
        sqrt_info = np.broadcast_to(L, (n_edges, 6, 6))
    else:
        step = np.linalg.norm(measured_rel.translation.reshape(-1, 3), axis=-1)
        sig_t = np.sqrt(config.pair_sigma_t**2 + (config.pair_sigma_t_per_m * step) ** 2)
        diag = np.empty((step.size, 6))
        diag[:, :3] = 1.0 / sig_t[:, None]
        diag[:, 3:] = 1.0 / math.radians(config.pair_sigma_r_deg)
        sqrt_info = diag[:, :, None] * np.eye(6)
    return math.sqrt(config.lambda_pair) * np.asarray(sqrt_info)


class FitProblem:
    """The least-squares problem of one flight (or window of keyframes) under one
    :class:`FitConfig`.

    Args:
        data: the keyframes (camera, heat-maps, initial poses, measurements).
        config: the fit options; ``pair_frame="auto"`` is resolved from ``data``
            (estimated with odometry, measured without,
            :func:`~turbinefit.solver.config.resolve_pair_frame`), an unset
            ``pixel_scale`` from the heat-maps' width
            (:func:`~turbinefit.solver.config.resolve_pixel_scale`), and :attr:`config`
            holds the resolved options.
        keyframes: indices into the flight's keyframes to use (default: all), in time order;
            consecutive ones are linked by pairwise edges.
        fixed: (len(keyframes),) poses held at their current values (default: from the
            config: the first with ``gauge="first"``, all with ``mode="turbine"``).
        prior: a Gaussian prior on the first used keyframe's pose and theta (what
            marginalised keyframes left behind, see :mod:`turbinefit.solver.marginal`).
        evidence: (len(keyframes),) False for keyframes whose heat-maps show nothing
            (no detection at all): their image terms are left out, since the interp cost
            of an empty heat-map is lower outside the image than inside and would push
            the turbine out of their view. Default: all True.
    """

    def __init__(self, data: ProblemData, config: FitConfig,
                 keyframes: NDArray[np.int_] | None = None, *,
                 fixed: NDArray[np.bool_] | None = None,
                 prior: GaussianPrior | None = None,
                 evidence: NDArray[np.bool_] | None = None) -> None:
        self.data = data
        self.config = config = resolve_pixel_scale(
            resolve_pair_frame(config, data.odometry is not None), data.camera.width)
        #: sample spacing of the correspondence searches [px of the maps]
        self.search_step = max(1, math.floor(config.scale))
        self.keyframes = (np.arange(data.num_keyframes) if keyframes is None
                          else np.asarray(keyframes, dtype=np.int64))
        self.num_keyframes = int(self.keyframes.size)
        meas = data.measurement_poses()[self.keyframes]
        self._measured_rel = relative_poses(meas[:-1], meas[1:])
        #: (E, 3, 3) fixed frames of the pairwise translation residual, or None (estimated).
        self._pair_frames: FloatArray | None = (
            meas[:-1].rotation_matrix() if config.pair_frame == "measured" else None)
        #: (E, 6, 6) per-edge square-root information L (C = L^T L), times sqrt(lambda).
        self._sqrt_info: FloatArray = pair_sqrt_information(config, self._measured_rel)
        self.prior_position = data.world_T_cam.translation[self.keyframes].copy()
        sigma = data.position_sigma
        #: (N, 3) standard deviations of the keyframes' position priors, or None
        self.position_sigma = (None if sigma is None
                               else np.asarray(sigma, dtype=np.float64)[self.keyframes].copy())
        motions = getattr(data, "motions", None)
        #: the tie-point measurements of the used keyframes (entry k: from k-1 to k), or
        #: None (none measured, or lambda_motion 0)
        self.motions: RelativeMotions | None = (
            None if motions is None or config.lambda_motion == 0.0
            else motions.take(self.keyframes))
        if self.motions is not None and not self.motions.valid.any():
            self.motions = None
        if self.motions is not None:
            self._motion_sqrt_info = math.sqrt(config.lambda_motion) * self.motions.sqrt_info
            self._motion_loss = RobustLoss("cauchy", config.motion_robust_scale)
        #: the flight's photos for the edge term (indexed by ``keyframes``), or None
        photos = getattr(data, "photos", None)
        self.photos: PhotoStack | None = (
            photos if config.uses_photos and photos is not None
            and photos.scale >= MIN_EDGE_SCALE else None)
        n = config.samples_per_line
        self._line_channels = np.repeat(np.array([ln[2] for ln in LINES]), n)
        self._line_index = np.repeat(np.arange(len(LINES)), n)
        self.loss = RobustLoss(config.robust, config.robust_scale)
        self.fixed = np.zeros(self.num_keyframes, dtype=bool)
        if fixed is not None:
            self.fixed[:] = np.asarray(fixed, dtype=bool)
        elif config.mode == "turbine":
            self.fixed[:] = True
        elif config.gauge == "first":
            self.fixed[0] = True
        self.prior = prior
        self.evidence = None if evidence is None else np.asarray(evidence, dtype=bool).copy()
        if self.evidence is not None and self.evidence.shape != (self.num_keyframes,):
            raise ValueError(f"evidence has shape {self.evidence.shape}, expected "
                             f"({self.num_keyframes},)")
        self.optimise_theta = config.mode in ("joint", "turbine")
        #: whether rounds need find_correspondences (corr terms or visible-part sampling)
        self.needs_correspondences = "corr" in (config.points, config.lines) or (
            config.line_sampling == "visible" and config.lines != "none")

    # ------------------------------------------------------------------------------
    def model(self, theta: FloatArray, with_jacobian: bool,
              fractions: FloatArray | None = None) -> tuple[Samples, Samples]:
        """The 6 model points and the line samples, with Jacobians w.r.t. theta.

        Line samples sit at uniform fractions of each line, or at per-keyframe
        ``fractions`` (N, 5, n) (visible-part sampling)."""
        P, JP = model_points(theta, self.config.geometry, with_jacobian)
        points = Samples(P, P, JP, JP)
        if fractions is None:
            S, JS, _ = line_samples(P, JP, self.config.samples_per_line)
            return points, Samples(S, S, JS, JS)
        ends = np.array([[ln[0], ln[1]] for ln in LINES])
        a = ends[self._line_index, 0]
        b = ends[self._line_index, 1]
        f = fractions.reshape(fractions.shape[0], -1)
        return points, Samples(P[a], P[b], None if JP is None else JP[a],
                               None if JP is None else JP[b], f)

    def visible_fractions(self, poses: SE3, theta: FloatArray) -> FloatArray:
        """Per keyframe and line, ``n`` sample fractions spread over the part of the line
        that projects into the image (uniform over the whole line where none does)."""
        n = self.config.samples_per_line
        P, _ = model_points(theta, self.config.geometry, False)
        dense = np.linspace(0.0, 1.0, 65)
        ends = np.array([[ln[0], ln[1]] for ln in LINES])
        pts = (P[ends[:, 0]][:, None] * (1 - dense[:, None])
               + P[ends[:, 1]][:, None] * dense[:, None]).reshape(-1, 3)
        pr = project_points(self.data.camera, poses, pts, None, with_jacobian=False)
        vis = pr.inside.reshape(-1, len(LINES), dense.size)  # (N, 5, 65)
        any_vis = vis.any(axis=-1)
        step = dense[1]
        lo = np.where(any_vis, dense[np.argmax(vis, axis=-1)] - 0.5 * step, 0.0)
        hi = np.where(any_vis, dense[dense.size - 1 - np.argmax(vis[..., ::-1], axis=-1)]
                      + 0.5 * step, 1.0)
        lo = np.maximum(lo, 0.0)
        hi = np.minimum(hi, 1.0)
        u = (np.arange(n) + 0.5) / n
        return lo[..., None] + (hi - lo)[..., None] * u

    def _line_dirs(self, P: FloatArray) -> FloatArray:
        """Unit world direction (5n, 3) of the model line each line sample lies on."""
        ends = np.array([[ln[0], ln[1]] for ln in LINES])
        d = P[ends[:, 1]] - P[ends[:, 0]]
        d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        return d[self._line_index]

    def find_correspondences(self, poses: SE3, theta: FloatArray) -> Correspondences:
        """Per-round data at the current estimate: correspondences of the corr terms
        (searched around the current projections) and the visible-part line sampling."""
        cfg = self.config
        cam = self.data.camera
        out = Correspondences()
        if cfg.line_sampling == "visible" and cfg.lines != "none":
            out.line_fractions = self.visible_fractions(poses, theta)
        pts, lns = self.model(theta, False, out.line_fractions)
        P, S = pts.A, lns.points()
        if cfg.points == "corr":
            pr = project_points(cam, poses, P, None, with_jacobian=False)
            out.point_target, out.point_found = find_point_correspondences(
                self.data.heatmaps, self.keyframes, POINT_CHANNELS, pr.uv, pr.inside,
                cfg.px("corr_radius"), cfg.corr_threshold, self.search_step)
        if cfg.lines == "corr":
            dirs = self._line_dirs(P)
            pr = project_points(cam, poses, S, None, with_jacobian=False)
            pr2 = project_points(cam, poses, S + dirs, None, with_jacobian=False)
            tangent = pr2.uv - pr.uv
            norm = np.linalg.norm(tangent, axis=-1, keepdims=True)
            usable = pr.inside & pr2.front & (norm[..., 0] > 1e-6)
            tangent = tangent / np.maximum(norm, 1e-9)
            normal = np.stack([-tangent[..., 1], tangent[..., 0]], axis=-1)
            out.line_normal = normal
            out.line_target, out.line_found = find_line_correspondences(
                self.data.heatmaps, self.keyframes, self._line_channels, pr.uv, normal,
                usable, cfg.px("line_search"), cfg.corr_threshold, self.search_step)
            if self.photos is not None:
                out.edge_target, out.edge_found, out.width = silhouette_correspondences(
                    cfg, cam, self.photos, self.keyframes, poses, theta, S, dirs,
                    out.line_fractions, self._line_index, out.line_target, out.line_found,
                    normal)
        return out

    def pairwise_edge(self, poses: SE3, edge: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The whitened residual (6,) of pairwise edge ``edge`` (between the problem's
        keyframes ``edge`` and ``edge + 1``) at ``poses`` (the problem's keyframes), and its
        Jacobians (6, 6) w.r.t. the local updates of the two poses."""
        e = slice(edge, edge + 1)
        frames = None if self._pair_frames is None else self._pair_frames[e]
        r, Ji, Jj = pairwise_residuals(poses[e], poses[edge + 1:edge + 2],
                                       self._measured_rel[e], self._sqrt_info[e], True, frames)
        assert Ji is not None and Jj is not None
        if self.motions is not None and self.motions.valid[edge + 1]:
            rm, Jim, Jjm = self._motion_terms(poses, np.array([edge]), True)[1:]
            assert Jim is not None and Jjm is not None
            return (np.concatenate([r[0], rm[0]]), np.concatenate([Ji[0], Jim[0]]),
                    np.concatenate([Jj[0], Jjm[0]]))
        return r[0], Ji[0], Jj[0]

    def _motion_terms(self, poses: SE3, edges: NDArray[np.int_], with_jacobian: bool
                      ) -> tuple[float, FloatArray, FloatArray | None, FloatArray | None]:
        """The tie-point term of ``edges`` (between the problem's keyframes e and e + 1,
        each with a measurement): cost, robustified residuals (E, 5) and Jacobians."""
        assert self.motions is not None
        m = self.motions
        j = edges + 1
        r, rho, Ji, Jj = relative_motion_residuals(
            poses[edges], poses[j], m.i_q_j[j], m.i_dir_j[j], self._motion_sqrt_info[j],
            self._motion_loss, with_jacobian)
        return 0.5 * float(rho.sum()), r, Ji, Jj

    # ------------------------------------------------------------------------------
    def _image_block(self, keyframes: NDArray[np.int_], kind: str, smp: Samples,
                     channels: NDArray[np.int_], lam: float, poses: SE3,
                     target: FloatArray | None, found: NDArray[np.bool_] | None,
                     normal: FloatArray | None,
                     with_jacobian: bool) -> tuple[float, int, tuple[FloatArray, FloatArray,
                                                                     FloatArray] | None]:
        """One image term: cost, points in view, and with the Jacobian
        ``(g, H, J)``: gradient (N, M, 2) and PSD Hessian model (N, M, 2, 2) of the cost
        w.r.t. each point's pixel, and d uv / d x (N, M, 2, 13). Robustified."""
        cfg = self.config
        blend = None
        if smp.f is not None and smp.JA is not None and smp.JB is not None:
            blend = (smp.JA, smp.JB, smp.f)
        pr = project_points(self.data.camera, poses, smp.points(),
                            smp.JA if smp.f is None else None, with_jacobian, blend=blend)
        g: FloatArray | None = None
        H: FloatArray | None = None
        if kind == "interp":
            ht = heatmap_terms(self.data.heatmaps, keyframes, channels, pr, lam,
                               cfg.px("border_margin"), cfg.heatmap_floor, with_jacobian)
            s, g, H = ht.s, ht.g, ht.H
            n_in = int(pr.inside.sum())
        else:
            assert target is not None and found is not None
            ct = correspondence_terms(pr, target, found, normal, lam, cfg.px("pixel_sigma"),
                                      with_jacobian)
            s, g, H = ct.s, ct.g, ct.H
            n_in = int(ct.used.sum())
        rho, drho = self.loss.evaluate(s)
        cost = 0.5 * float(rho.sum())
        if not with_jacobian:
            return cost, n_in, None
        assert g is not None and H is not None and pr.J is not None
        if self.loss.name != "none":  # iteratively reweighted: rho'(s) scales g and H
            g = g * drho[..., None]
            H = H * drho[..., None, None]
        return cost, n_in, (g, H, pr.J)

    def _image_block_native(self, maps: _native.NativeMaps, keyframes: NDArray[np.int_],
                            kind: str, smp: Samples,
                            channels: NDArray[np.int_], lam: float, poses: SE3,
                            target: FloatArray | None, found: NDArray[np.bool_] | None,
                            normal: FloatArray | None, JtHJ: FloatArray | None,
                            g: FloatArray | None) -> tuple[float, int]:
        """:meth:`_image_block` by the compiled kernel, adding into ``JtHJ`` and ``g``
        (when given); returns cost and points in view."""
        cfg = self.config
        cam = self.data.camera
        cost, count = _native.image_terms(
            poses.wxyz_xyz, cam.kernel_params(), cam.width, cam.height, smp.A, smp.B,
            smp.JA, smp.JB, smp.f, channels, maps, keyframes, kind,
            target, found, normal, lam,
            cfg.px("pixel_sigma"), cfg.px("border_margin"), cfg.heatmap_floor, cfg.robust,
            cfg.robust_scale, JtHJ is not None, JtHJ, g)
        return float(cost.sum()), int(count.sum())

    def linearize(self, poses: SE3, theta: FloatArray, corr: Correspondences,
                  with_jacobian: bool = True) -> Linearization:
        """Cost, and normal equations if ``with_jacobian``, at ``(poses, theta)``."""
        cfg = self.config
        pts, lns = self.model(theta, with_jacobian, corr.line_fractions)
        terms: dict[str, float] = {}
        in_view: dict[str, int] = {}
        blocks: list[tuple[str, str, Samples, NDArray[np.int_], float, FloatArray | None,
                           NDArray[np.bool_] | None, FloatArray | None]] = [
            ("points", cfg.points, pts, POINT_CHANNELS, cfg.lambda_points,
             corr.point_target, corr.point_found, None),
            ("lines", cfg.lines, lns, self._line_channels, cfg.lambda_lines,
             corr.line_target, corr.line_found,
             corr.line_normal if cfg.line_residual == "normal" else None),
        ]
        if self.photos is not None and corr.edge_found is not None:
            # whitened by edge_sigma photo px: the corr kernel divides by pixel_sigma map px
            sigma_map = cfg.edge_sigma / self.photos.scale
            blocks.append(("edges", "corr", lns, self._line_channels,
                           cfg.lambda_edges * (cfg.px("pixel_sigma") / sigma_map) ** 2,
                           corr.edge_target, corr.edge_found, corr.line_normal))
        N = self.num_keyframes
        JtHJ = np.zeros((N, 13, 13)) if with_jacobian else None
        g_u = np.zeros((N, 13)) if with_jacobian else None
        # the keyframes with image evidence (all, or a subset whose blocks are scattered)
        sel = (None if self.evidence is None or self.evidence.all()
               else np.flatnonzero(self.evidence))
        n_img = N if sel is None else int(sel.size)
        kf_img = self.keyframes if sel is None else self.keyframes[sel]
        poses_img = poses if sel is None else poses[sel]
        JtHJ_img = JtHJ if sel is None or JtHJ is None else np.zeros((n_img, 13, 13))
        g_img = g_u if sel is None or g_u is None else np.zeros((n_img, 13))

        def rows(a: FloatArray | None) -> FloatArray | None:
            return a if a is None or sel is None else a[sel]

        n_res = 0
        maps = _native.native_maps(self.data.heatmaps) if _native.available() else None
        for name, kind, smp, ch, lam, tgt, fnd, nrm in blocks:
            if kind == "none" or lam == 0.0:
                continue
            if n_img == 0:
                terms[name], in_view[name] = 0.0, 0
                continue
            # residuals per point: 2 for a 2-D correspondence, 1 otherwise
            n_res += n_img * smp.A.shape[0] * (2 if kind == "corr" and nrm is None else 1)
            if sel is not None:
                smp = Samples(smp.A, smp.B, smp.JA, smp.JB, rows(smp.f))
                tgt, nrm = rows(tgt), rows(nrm)
                fnd = None if fnd is None else fnd[sel]
            if maps is not None:
                terms[name], in_view[name] = self._image_block_native(
                    maps, kf_img, kind, smp, ch, lam, poses_img, tgt, fnd, nrm, JtHJ_img,
                    g_img)
                continue
            c, n_in, der = self._image_block(kf_img, kind, smp, ch, lam, poses_img, tgt, fnd,
                                             nrm, with_jacobian)
            terms[name] = c
            in_view[name] = n_in
            if der is not None:
                assert JtHJ_img is not None and g_img is not None
                g, H, J = der
                Jf = J.reshape(n_img, -1, 13)
                HJ = (H @ J).reshape(n_img, -1, 13)
                JtHJ_img += np.swapaxes(Jf, 1, 2) @ HJ
                g_img += np.einsum("nri,nr->ni", Jf, g.reshape(n_img, -1))
        if sel is not None and JtHJ is not None and g_u is not None:
            assert JtHJ_img is not None and g_img is not None
            JtHJ[sel] = JtHJ_img
            g_u[sel] = g_img
        if corr.width is not None and cfg.lambda_width > 0:
            blend = None if lns.JA is None or lns.JB is None else (lns.JA, lns.JB, lns.f)
            terms["width"], in_view["width"], Hw, gw = width_terms(
                poses, np.broadcast_to(lns.points(), (N, *lns.A.shape)), blend,
                corr.width, cfg.lambda_width, with_jacobian)
            n_res += in_view["width"]
            if Hw is not None and gw is not None and JtHJ is not None and g_u is not None:
                JtHJ += Hw
                g_u += gw
        want_pair = N > 1 and cfg.lambda_pair > 0
        if want_pair:
            rp, Ji, Jj = pairwise_residuals(poses[:-1], poses[1:], self._measured_rel,
                                            self._sqrt_info, with_jacobian, self._pair_frames)
            terms["pairwise"] = 0.5 * float(np.sum(rp * rp))
        motion_edges = (np.flatnonzero(self.motions.valid[1:])
                        if self.motions is not None and N > 1 else np.zeros(0, dtype=np.int64))
        if motion_edges.size:
            terms["motion"], rmo, Jim, Jjm = self._motion_terms(poses, motion_edges,
                                                                with_jacobian)
            n_res += rmo.size
        use_prior = cfg.gauge == "gps" and cfg.mode != "turbine"
        if use_prior:
            rg = (poses.translation - self.prior_position) / cfg.gps_sigma
            terms["prior"] = 0.5 * float(np.sum(rg * rg))
        use_position = self.position_sigma is not None and cfg.mode != "turbine"
        if use_position:
            assert self.position_sigma is not None
            rx, Jx = position_prior_residuals(poses, self.prior_position, self.position_sigma,
                                              with_jacobian)
            terms["position"] = 0.5 * float(np.sum(rx * rx))
            n_res += rx.size
        if self.prior is not None:
            dx = self.prior.delta(poses[0], theta)
            Hdx = self.prior.H @ dx
            terms["prior_marginal"] = float(0.5 * dx @ Hdx + self.prior.g @ dx)
        cost = float(sum(terms.values()))
        n_res += 6 * (N - 1) if want_pair else 0
        lin = Linearization(cost=cost, terms=terms, num_residuals=n_res, in_view=in_view)
        if not with_jacobian:
            return lin
        assert JtHJ is not None and g_u is not None
        D = JtHJ[:, :6, :6].copy()
        g_p = g_u[:, :6].copy()
        B = np.zeros((max(N - 1, 0), 6, 6))
        if want_pair:
            assert Ji is not None and Jj is not None
            JiT = np.swapaxes(Ji, 1, 2)
            JjT = np.swapaxes(Jj, 1, 2)
            D[:-1] += JiT @ Ji
            D[1:] += JjT @ Jj
            B = JjT @ Ji
            g_p[:-1] += np.einsum("eij,ei->ej", Ji, rp)
            g_p[1:] += np.einsum("eij,ei->ej", Jj, rp)
        if motion_edges.size:
            assert Jim is not None and Jjm is not None
            e = motion_edges
            JiT = np.swapaxes(Jim, 1, 2)
            JjT = np.swapaxes(Jjm, 1, 2)
            np.add.at(D, e, JiT @ Jim)
            np.add.at(D, e + 1, JjT @ Jjm)
            np.add.at(B, e, JjT @ Jim)
            np.add.at(g_p, e, np.einsum("eij,ei->ej", Jim, rmo))
            np.add.at(g_p, e + 1, np.einsum("eij,ei->ej", Jjm, rmo))
        if use_prior:
            D[:, [0, 1, 2], [0, 1, 2]] += 1.0 / cfg.gps_sigma**2
            g_p[:, :3] += rg / cfg.gps_sigma
        if use_position:
            assert Jx is not None
            JxT = np.swapaxes(Jx, 1, 2)
            D += JxT @ Jx
            g_p += np.einsum("nij,ni->nj", Jx, rx)
        if self.prior is not None:  # gradient H dx + g, Hessian H (first-estimate Jacobians)
            gx = Hdx + self.prior.g
            D[0] += self.prior.H[:6, :6]
            g_p[0] += gx[:6]
            JtHJ[0, :6, 6:] += self.prior.H[:6, 6:]
            JtHJ[0, 6:, 6:] += self.prior.H[6:, 6:]
            g_u[0, 6:] += gx[6:]
        # hold fixed poses: identity blocks, no coupling, no gradient
        fx = self.fixed
        if fx.any():
            D[fx] = np.eye(6)
            g_p[fx] = 0.0
            if N > 1:
                B[fx[1:]] = 0.0
                B[fx[:-1]] = 0.0
        lin.D, lin.B, lin.g_p = D, B, g_p
        if self.optimise_theta:
            C = JtHJ[:, :6, 6:].copy()
            C[fx] = 0.0
            lin.C = C
            lin.E = JtHJ[:, 6:, 6:].sum(axis=0)
            lin.g_t = g_u[:, 6:].sum(axis=0)
        return lin
