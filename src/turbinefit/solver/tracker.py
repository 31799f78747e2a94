"""In-flight tracking: a fixed-lag smoother over the latest keyframes and the turbine.

The paper optimises "successively as the drone navigates around the turbine". The
:class:`Tracker` takes one keyframe at a time (timestamp, GPS/IMU pose, heat-maps) and,
before the next arrives, refines the poses of a sliding window of the last ``window``
keyframes together with theta:

1. the new pose is predicted from the previous estimate and the measured step (the
   pairwise term's residual is zero there): the GPS/IMU keyframes' world-frame step, or,
   with odometry (``update(..., odometry=...)``) and the ``estimated`` pairwise frame, the
   odometry's body-frame step applied to the previous estimate;
2. a few Levenberg-Marquardt rounds (on the first keyframes and when the turbine comes
   back into view, first one *match* round of wide-basin correspondences, as the batch
   warm-up does) refine the window with the configured cost of
   :class:`~turbinefit.solver.config.FitConfig`;
3. when the window is full, its oldest keyframe is marginalised: its image terms
   (linearised as correspondences, ``marginal_terms``), its pairwise edge and the prior
   it carried become a Gaussian prior on the next keyframe and theta
   (:mod:`turbinefit.solver.marginal`). The pose is frozen at its estimate, and its
   linear conditional on the next pose and theta is kept, so that
   :meth:`Tracker.world_T_cam` can move it with later estimates (back-substitution).

Work per keyframe is therefore bounded by the window, not the flight. The latest pose's
and theta's marginal covariances come from the window's Gauss-Newton Hessian (with the
priors): the inverse of the information, in local pose coordinates (m, rad) and theta's
units. They are the in-flight posterior, start-up prior included.

The verdict (:meth:`Tracker.assess`) follows the batch fit's rules
(:mod:`turbinefit.solver.verdict`): the same signals, the same thresholds, and theta's
covariance and its distance from the optimum by the same function
(:func:`~turbinefit.solver.verdict.theta_uncertainty`) on the information the tracker
holds from the flight: the window's terms re-linearised at the end and the marginal prior,
without the start-up prior, which is a regulariser and not evidence (with it, a direction
of theta no image fixes would look known to the prior's sigma; a one-keyframe flight would
be ``ok`` where the fit is ``failed``).

Start-up: theta begins at its initial value with a Gaussian prior (``theta_sigma``), so
the first keyframes, which see the turbine from one side only, cannot move it far. The
prior acts on theta alone, which eliminating poses passes through unchanged, so it is
kept apart from the marginal information and removed exactly once the images outweigh it
(``theta_prior_release``). Keyframes whose heat-maps show nothing carry no image terms.
Gauge: as in the batch fit, the first keyframe is held fixed (``gauge="first"``) or every
keyframe is weakly anchored to its GPS position (``"gps"``).

Pairwise frame: ``pair_frame="auto"`` is resolved by the first keyframe: ``estimated``
if it comes with an odometry pose (body-frame odometry), ``measured`` if not; every later
keyframe must do the same (otherwise a :class:`KeyframeError`). :attr:`Tracker.config`
then holds the resolved options.

With ``window=None`` nothing is marginalised and :meth:`Tracker.finish` runs the batch
problem to convergence: the tracker then ends in a minimum of the batch problem.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from turbinefit.costs.relative_motion import RelativeMotions
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.solver.config import DEFAULT_THETA_SIGMA as DEFAULT_THETA_SIGMA  # re-exported
from turbinefit.solver.config import FitConfig, resolve_pair_frame, resolve_pixel_scale
from turbinefit.solver.config import TrackerConfig as TrackerConfig  # re-exported
from turbinefit.solver.fit import match_config
from turbinefit.solver.keyframe_input import KeyframeError as KeyframeError  # update raises it
from turbinefit.solver.keyframe_input import (
    check_keyframe,
    check_motion,
    check_photo,
    check_position_sigma,
)
from turbinefit.solver.linalg import arrow_covariance, inverse_spd
from turbinefit.solver.marginal import (
    GaussianPrior,
    PoseConditional,
    back_substitute,
    marginalize_pose,
)
from turbinefit.solver.problem import FitProblem, Linearization
from turbinefit.solver.rounds import initial_correspondences, run_rounds
from turbinefit.solver.verdict import (
    ImageEvidence,
    Signals,
    Verdict,
    image_evidence,
    judge,
    measure,
    theta_uncertainty,
)
from turbinefit.solver.window import TrackWindow
from turbinefit.turbine.model import TurbineParams

FloatArray = NDArray[np.float64]

@dataclass(frozen=True)
class TrackEstimate:
    """The tracker's answer to one keyframe, at the moment it was processed.

    Attributes:
        index: keyframe number (0-based, in arrival order).
        timestamp: its time [s].
        world_T_cam: the keyframe's estimated camera-to-world pose.
        turbine: the current turbine estimate (canonical ranges).
        pose_covariance: (6, 6) marginal covariance of the pose in the local coordinates
            of :meth:`SE3.retract` (translation [m^2] first, rotation [rad^2] in the camera
            frame); zeros if the pose is held fixed (the gauge keyframe); None if the
            information is singular.
        theta_covariance: (7, 7) marginal covariance of theta (units of
            :class:`TurbineParams`), the in-flight posterior: with the start-up prior
            while it acts, so never wider than ``theta_sigma``; None with the turbine fixed
            (``mode="pose"``) or singular information. The verdict's covariance, by the
            batch fit's rule without the start-up prior, is
            :meth:`Tracker.theta_covariance`.
        cost: the window's cost after the update.
        iterations: LM iterations spent.
        window: keyframes in the window during the update.
        in_view: model points and line samples projected into the image, by term (of
            keyframes with evidence).
        evidence: whether the keyframe's heat-maps showed anything (a value of at least
            ``fit.corr_threshold``); without, its image terms are left out.
        update_s: wall time of the update [s].
    """

    index: int
    timestamp: float
    world_T_cam: SE3
    turbine: TurbineParams
    pose_covariance: FloatArray | None
    theta_covariance: FloatArray | None
    cost: float
    iterations: int
    window: int
    in_view: dict[str, int]
    evidence: bool
    update_s: float

    def position_sigma_m(self) -> float | None:
        """RMS position standard deviation of the pose, sqrt(trace / 3) [m], or None."""
        if self.pose_covariance is None:
            return None
        return float(math.sqrt(max(float(np.trace(self.pose_covariance[:3, :3])), 0.0) / 3.0))


@dataclass(frozen=True)
class TrackAssessment:
    """The verdict on a track (:meth:`Tracker.assess`), as the batch fit's
    (:class:`~turbinefit.solver.fit.FitResult`) holds it.

    Attributes:
        theta_covariance: (7, 7) theta's covariance by the batch fit's rule on the
            information of the flight (no start-up prior); None with the turbine fixed or
            singular information.
        signals, verdict, reasons: see :mod:`turbinefit.solver.verdict`.
    """

    theta_covariance: FloatArray | None
    signals: Signals
    verdict: Verdict
    reasons: list[str]

    @property
    def theta_std(self) -> FloatArray | None:
        """(7,) theta's standard deviations (metres, radians), or None."""
        return self.signals.theta_std


def marginal_config(cfg: FitConfig) -> FitConfig:
    """The cost a keyframe's image terms are linearised with when it leaves the window
    (``marginal_terms="corr"``): correspondences for points and lines, line residuals along
    the search normal, the rest as configured."""
    return dataclasses.replace(
        cfg, points="corr" if cfg.points != "none" else "none",
        lines="corr" if cfg.lines != "none" else "none", line_residual="normal")


def _predict(world_T_prev: SE3, meas_prev: SE3, meas_new: SE3, frame: str = "measured") -> SE3:
    """The new pose at zero pairwise residual: the previous estimate rotated by the
    measured relative rotation and moved by the measured world-frame step (``measured``
    frame), or composed with the measured body-frame step (``estimated``)."""
    rel = meas_prev.inverse() @ meas_new
    if frame == "estimated":
        return world_T_prev @ rel
    q = (world_T_prev @ rel).wxyz
    return SE3(np.concatenate([q, world_T_prev.translation + meas_new.translation
                               - meas_prev.translation]))


class Tracker:
    """Successive joint estimation of keyframe poses and the turbine (fixed-lag smoother).

    Args:
        camera: intrinsics of the heat-maps' pixel grid.
        initial_turbine: the turbine's initial estimate (the centre of the start-up prior).
        config: see :class:`TrackerConfig`.

    The tracker takes heat-maps: photos are turned into them before :meth:`update`
    (e.g. by :class:`turbinefit.jobs.sources.PhotoHeatmaps`); the grey photos themselves
    only for the edge and width terms (``photo=``). Every keyframe passed to
    :meth:`update` must have a later timestamp than the one before. Heat-maps are
    referenced, not copied, while their keyframe is in the window.
    """

    def __init__(self, camera: PinholeCamera, initial_turbine: TurbineParams,
                 config: TrackerConfig | None = None) -> None:
        self.camera = camera
        cfg = config or TrackerConfig()
        # the pixel settings follow the heat-maps' width (recorded in the config)
        self.config = dataclasses.replace(cfg, fit=resolve_pixel_scale(cfg.fit, camera.width))
        self._set_costs()
        #: whether the keyframes come with odometry (decided by the first keyframe)
        self._has_odometry: bool | None = None
        self._theta = initial_turbine.to_vector().astype(np.float64)
        if not np.all(np.isfinite(self._theta)):
            raise ValueError("initial turbine contains NaN or inf")
        #: the sliding window (None until the first keyframe)
        self._window: TrackWindow | None = None
        #: what marginalised keyframes left: a prior on the window's first pose and theta
        self._marginal: GaussianPrior | None = None
        #: per marginalised keyframe: its conditional and the prior its elimination made
        self._conditionals: list[PoseConditional | None] = []
        self._cond_priors: list[GaussianPrior | None] = []
        self._theta0 = self._theta.copy()
        self._theta_sigma = (None if self.config.theta_sigma is None
                             else np.asarray(self.config.theta_sigma, dtype=np.float64))
        # every keyframe so far
        self._times: list[float] = []
        #: Storage of the window's heat-maps: that of the first keyframe's, float32 or
        #: float16 (as a flight's files store them; the kernels read either), one for all.
        self._map_dtype: type[np.floating] | None = None
        self._final: list[SE3 | None] = []
        self.estimates: list[TrackEstimate] = []
        """The causal estimate of every keyframe, in arrival order."""

    def _set_costs(self) -> None:
        cfg = self.config
        self._refine_cfg = cfg.fit
        self._marg_cfg = marginal_config(cfg.fit) if cfg.marginal_terms == "corr" else cfg.fit
        self._match_cfg = match_config(cfg.fit)

    # ------------------------------------------------------------------------------
    @property
    def num_keyframes(self) -> int:
        return len(self._times)

    @property
    def turbine(self) -> TurbineParams:
        """The current turbine estimate (canonical ranges)."""
        return TurbineParams.from_vector(self._theta).canonical()

    @property
    def theta(self) -> FloatArray:
        """(7,) the current turbine vector as the solver holds it (angles not wrapped;
        :attr:`turbine` gives canonical ranges)."""
        return self._theta.copy()

    @property
    def timestamps(self) -> FloatArray:
        return np.asarray(self._times, dtype=np.float64)

    def world_T_cam(self, back_substitution: bool = True) -> SE3:
        """(N,) the current estimate of every keyframe: the window at its latest, and
        marginalised keyframes moved with it through their stored conditionals
        (:func:`~turbinefit.solver.marginal.back_substitute`, linear, O(N)), or, with
        ``back_substitution=False``, frozen at their estimate when they left the window."""
        out: list[SE3 | None] = list(self._final)
        n_old = len(self._conditionals)  # keyframes 0 .. n_old-1 have left the window
        w = self._window
        if w is not None:
            if back_substitution and n_old:
                frozen = [p for p in out[:n_old] if p is not None]
                out[:n_old] = back_substitute(self._conditionals, self._cond_priors, frozen,
                                              w.world_T_cam[0], self._theta)
            for i, k in enumerate(w.index):
                out[k] = w.world_T_cam[i]
        return SE3(np.stack([p.wxyz_xyz for p in out if p is not None]))

    def causal_world_T_cam(self) -> SE3:
        """(N,) each keyframe's estimate right after its own update."""
        return SE3(np.stack([e.world_T_cam.wxyz_xyz for e in self.estimates]))

    # ------------------------------------------------------------------------------
    def _fixed(self) -> NDArray[np.bool_]:
        assert self._window is not None
        fixed = np.zeros(len(self._window), dtype=bool)
        if self.config.fit.gauge == "first" and self._window.index[0] == 0:
            fixed[0] = True
        return fixed

    def _window_prior(self, world_T_first: SE3) -> GaussianPrior | None:
        """The marginal prior plus the start-up prior on theta. The latter acts on theta
        alone, so eliminating poses passes it through unchanged: it is kept apart from the
        marginal and added exactly here."""
        m = self._marginal
        if self._theta_sigma is None:
            return m
        if m is None:
            return GaussianPrior.on_theta(world_T_first, self._theta0, self._theta_sigma)
        info = 1.0 / self._theta_sigma**2
        H = m.H.copy()
        H[6:, 6:] += np.diag(info)
        g = m.g.copy()
        g[6:] += info * (m.theta - self._theta0)
        return GaussianPrior(m.world_T_cam, m.theta, H, g)

    def _run(self, stages: list[tuple[FitConfig, int, int]]
             ) -> tuple[SE3, FitProblem, Linearization, int]:
        """Rounds of LM on the window: ``stages`` of (config, rounds, iterations). Updates
        theta and the window's estimates."""
        w = self._window
        assert w is not None
        poses = w.world_T_cam
        fixed = self._fixed()
        theta = self._theta
        iterations = 0
        prob: FitProblem | None = None
        lin: Linearization | None = None
        for cfg, rounds, iters in stages:
            prob = FitProblem(w.data, cfg, fixed=fixed, prior=self._window_prior(poses[0]),
                              evidence=w.evidence)
            out = run_rounds(prob, poses, theta, rounds, iters, finish="jacobian")
            poses, theta, lin = out.poses, out.theta, out.linearization
            iterations += out.iterations
        assert prob is not None and lin is not None
        self._theta = theta
        self._window = w.with_estimate(poses)
        return poses, prob, lin, iterations

    def update(self, timestamp: float, world_T_cam: SE3, heatmaps: NDArray[np.floating], *,
               odometry: SE3 | None = None,
               position_sigma: NDArray[np.floating] | None = None,
               motion: RelativeMotions | None = None,
               photo: NDArray[np.generic] | None = None) -> TrackEstimate:
        """Add one keyframe and refine; returns the estimate for it.

        Args:
            timestamp: keyframe time [s], later than the previous keyframe's.
            world_T_cam: its GPS/IMU (initial) camera-to-world pose: the measurement
                without odometry; with, the starting point of the first keyframe and
                the anchor of ``gauge="gps"``.
            heatmaps: (7, H, W) heat-maps at the camera's size (kept as float16 if the
                first keyframe's are float16, else as float32).
            odometry: its odometry pose (e.g. the flight's odometry.txt): the relative
                poses of consecutive odometry poses are then the pairwise measurements.
                Given for every keyframe or for none; the first keyframe decides
                ``pair_frame="auto"`` (estimated with odometry, measured without).
            position_sigma: (3,) standard deviations [m] of ``world_T_cam``'s position
                along the world axes (RTK): an absolute position prior on the keyframe
                (:mod:`turbinefit.costs.position_prior`). Given for every keyframe or
                for none.
            motion: the relative motion from the previous keyframe measured by tie
                points (one entry of :class:`~turbinefit.costs.relative_motion.
                RelativeMotions`, e.g. from :class:`turbinefit.tiepoints.MotionMeter`),
                or None: the tie-point term (``lambda_motion``) between the two.
            photo: its grey photo (H, W), uint8 or float, a whole multiple (at least 2)
                of the heat-maps' size, for the edge and width terms (``lambda_edges``,
                ``lambda_width``). Given for every keyframe or for none.

        Raises:
            KeyframeError: on input that is out of order, of the wrong shape or not finite
                (nothing is changed).
        """
        t0 = time.perf_counter()
        k = len(self._times)
        maps, dtype = check_keyframe(
            k, float(timestamp), self._times[-1] if self._times else None, world_T_cam,
            heatmaps, odometry, self._has_odometry, self.camera, self._map_dtype)
        sigma = check_position_sigma(k, position_sigma, self._window)
        motion = check_motion(k, motion)
        photos = check_photo(k, photo, self._window, self.camera)
        self._map_dtype = dtype  # every input checked: the keyframe is taken
        if self._has_odometry is None:  # the first keyframe resolves pair_frame="auto"
            self._has_odometry = odometry is not None
            self.config = dataclasses.replace(
                self.config, fit=resolve_pair_frame(self.config.fit, self._has_odometry))
            self._set_costs()
        index = k
        self._times.append(float(timestamp))
        self._final.append(None)
        evidence = float(maps.max()) >= self.config.fit.corr_threshold
        w = self._window
        if w is None:
            self._window = TrackWindow.first(self.camera, index, float(timestamp), world_T_cam,
                                             maps, world_T_cam, evidence, odometry, sigma,
                                             motion, photos)
        else:
            last = len(w) - 1
            meas = w.data.measurement_poses()[last]
            pred = _predict(w.world_T_cam[last], meas,
                            world_T_cam if odometry is None else odometry,
                            self.config.fit.pair_frame)
            self._window = w.append(index, float(timestamp), world_T_cam, maps, pred, evidence,
                                    odometry, sigma, motion, photos)

        cfg = self.config
        stages = []
        lost = bool(self.estimates) and not self.estimates[-1].evidence
        if cfg.match_rounds > 0 and (index < cfg.match_keyframes or lost):
            stages.append((self._match_cfg, cfg.match_rounds, cfg.fit.warmup_iterations))
        stages.append((self._refine_cfg, cfg.rounds, cfg.iterations))
        poses, prob, lin, iterations = self._run(stages)
        pose_cov, theta_cov = self._covariance(lin, len(poses) - 1)
        self._maybe_release_prior(theta_cov)
        estimate = TrackEstimate(
            index=index, timestamp=float(timestamp), world_T_cam=poses[len(poses) - 1],
            turbine=self.turbine, pose_covariance=pose_cov, theta_covariance=theta_cov,
            cost=lin.cost, iterations=iterations, window=len(poses),
            in_view=dict(lin.in_view), evidence=evidence, update_s=0.0)
        if cfg.window is not None and len(poses) >= cfg.window:
            self._marginalize_oldest(poses, prob)
        estimate = dataclasses.replace(estimate, update_s=time.perf_counter() - t0)
        self.estimates.append(estimate)
        return estimate

    @property
    def theta_prior_active(self) -> bool:
        """Whether the start-up prior on theta still acts."""
        return self._theta_sigma is not None

    def _maybe_release_prior(self, theta_cov: FloatArray | None) -> None:
        """Drop the start-up prior once the data outweigh it (``theta_prior_release``)."""
        ratio = self.config.theta_prior_release
        sig = self._theta_sigma
        if ratio is None or sig is None or theta_cov is None or not np.all(np.isfinite(theta_cov)):
            return
        try:
            info = np.linalg.inv(theta_cov)
        except np.linalg.LinAlgError:
            return
        data = sig[:, None] * info * sig[None, :] - np.eye(7)  # in units of the prior
        if float(np.linalg.eigvalsh(0.5 * (data + data.T))[0]) >= ratio:
            self._theta_sigma = None

    def _covariance(self, lin: Linearization, index: int) -> tuple[FloatArray | None,
                                                                    FloatArray | None]:
        """Marginal covariances of window pose ``index`` and theta; None where the
        information is singular (e.g. no start-up prior and one keyframe)."""
        assert lin.D is not None and lin.B is not None
        if self._fixed()[index]:
            cov_t = None
            if lin.E is not None:
                try:
                    cov_t = inverse_spd(lin.E)
                except np.linalg.LinAlgError:
                    cov_t = None
            return np.zeros((6, 6)), cov_t
        try:
            return arrow_covariance(lin.D, lin.B, lin.C, lin.E, index)
        except np.linalg.LinAlgError:
            return None, None

    def theta_uncertainty(self) -> tuple[FloatArray | None, float | None]:
        """theta's (7, 7) covariance and its distance from the optimum of the data's cost
        [standard deviations], by the batch fit's rule
        (:func:`~turbinefit.solver.verdict.theta_uncertainty`) on the information the
        tracker holds from the flight: the window's configured cost linearised at the
        current estimate with correspondences searched there, and the marginal prior of
        the keyframes that left it; not the start-up prior on theta (a regulariser, not
        evidence: while it acts, the distance includes how far it holds theta from what
        the images say). (None, None) with the turbine fixed, before the first keyframe,
        or with singular information (e.g. one keyframe that leaves a direction of theta
        unfixed). One correspondence search and linearisation of the window: for the end
        of a flight, not for every update."""
        w = self._window
        if w is None or self.config.fit.mode != "joint":
            return None, None
        prob = FitProblem(w.data, self._refine_cfg, fixed=self._fixed(), prior=self._marginal,
                          evidence=w.evidence)
        corr = initial_correspondences(prob, w.world_T_cam, self._theta)
        return theta_uncertainty(prob.linearize(w.world_T_cam, self._theta, corr))

    def theta_covariance(self) -> FloatArray | None:
        """theta's covariance of :meth:`theta_uncertainty`: the verdict's."""
        return self.theta_uncertainty()[0]

    def arrival_evidence(self) -> ImageEvidence:
        """How the heat-maps of the latest keyframe agree with its estimate on arrival and
        the current theta (:func:`~turbinefit.solver.verdict.image_evidence`): the image
        signals of the verdict. Call it right after each :meth:`update` (it is not part
        of the update's work) and pass what it returns to :meth:`assess`."""
        w = self._window
        if w is None:
            raise ValueError("no keyframe yet")
        last = len(w) - 1
        return image_evidence(w.data, w.world_T_cam[last:last + 1], self._theta,
                              self.config.fit, keyframes=np.array([last]))

    def assess(self, image: ImageEvidence, initial: SE3, measurements: SE3
               ) -> TrackAssessment:
        """The verdict on the track so far, by the batch fit's rules (the same signals,
        thresholds and covariance function, :mod:`turbinefit.solver.verdict`).

        Args:
            image: every keyframe's :meth:`arrival_evidence`, in arrival order
                (:meth:`~turbinefit.solver.verdict.ImageEvidence.concat`).
            initial: (N,) the poses the keyframes came with.
            measurements: (N,) the poses whose steps are the pairwise measurements (the
                odometry poses if the keyframes came with them, else ``initial``).
        """
        if not self.estimates:
            raise ValueError("no keyframe yet")
        cov, step = self.theta_uncertainty()
        joint = self.config.fit.mode == "joint"
        signals = measure(image, initial, self.world_T_cam(), measurements,
                          self._theta if joint else None, cov, self.config.fit,
                          sum(e.iterations for e in self.estimates), (self.estimates[-1].cost,),
                          step)
        verdict, reasons = judge(signals)
        return TrackAssessment(cov, signals, verdict, reasons)

    def _marginalize_oldest(self, poses: SE3, prob: FitProblem) -> None:
        """Fold the window's oldest keyframe into the prior and freeze its pose."""
        w = self._window
        assert w is not None
        fixed = self._fixed()
        theta = self._theta
        one = FitProblem(w.data, self._marg_cfg, keyframes=np.array([0]),
                         fixed=fixed[:1], evidence=w.evidence[:1])
        corr = initial_correspondences(one, poses[0:1], theta)
        lin = one.linearize(poses[0:1], theta, corr)
        assert lin.D is not None and lin.g_p is not None
        has_next = len(poses) > 1
        Ji = Jj = r = None
        if has_next:
            r, Ji, Jj = prob.pairwise_edge(poses, 0)
        try:
            self._marginal, cond = marginalize_pose(
                D=lin.D[0], C=None if lin.C is None else lin.C[0], E=lin.E,
                g_p=lin.g_p[0], g_t=lin.g_t, fixed=bool(fixed[0]),
                pair_Ji=Ji, pair_Jj=Jj, pair_r=r, prior=self._marginal,
                world_T_drop=poses[0], world_T_next=poses[1] if has_next else poses[0],
                theta=theta)
        except np.linalg.LinAlgError:
            # keep the old prior: the keyframe's information is dropped, not corrupted
            cond = None
        self._conditionals.append(cond)
        self._cond_priors.append(self._marginal if cond is not None else None)
        self._final[int(w.index[0])] = w.world_T_cam[0]
        self._window = w.drop_oldest()

    def finish(self) -> TurbineParams:
        """Converge the window (configured cost, ``finish_rounds`` x ``finish_iterations``);
        with ``window=None`` this is the batch solve. Returns the turbine."""
        if self._window is None:
            return self.turbine
        cfg = self.config
        self._run([(self._refine_cfg, cfg.finish_rounds, cfg.finish_iterations)])
        return self.turbine
