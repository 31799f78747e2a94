"""Fit and tracker configuration: frozen dataclasses, every field documented, with named
fit presets."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Literal

from turbinefit.turbine.model import TurbineGeometry

Mode = Literal["joint", "pose", "turbine"]
UnaryKind = Literal["interp", "corr", "none"]
Gauge = Literal["first", "gps"]
PairFrame = Literal["auto", "measured", "estimated"]

#: Width [px] of the heat-maps the pixel settings of :class:`FitConfig` are stated for
#: (``[px of maps 320 px wide]``; the net's and the simulator's maps).
REFERENCE_WIDTH = 320
#: The settings in pixels at :data:`REFERENCE_WIDTH`, which follow the maps' scale
#: (:attr:`FitConfig.pixel_scale`); ``robust_scale`` is in units of the whitened residual,
#: so it follows ``pixel_sigma``.
PIXEL_FIELDS = ("pixel_sigma", "corr_radius", "line_search", "border_margin",
                "warmup_pixel_sigma", "edge_reach")


def pixel_scale_for(width: int) -> float:
    """The automatic :attr:`FitConfig.pixel_scale` of heat-maps ``width`` px wide: their
    width over :data:`REFERENCE_WIDTH`, at least 1."""
    return max(1.0, width / REFERENCE_WIDTH)


@dataclass(frozen=True)
class FitConfig:
    """How a flight is fitted. Units: metres [m], degrees [deg] as named; pixel settings in
    [px of maps 320 px wide], multiplied by ``pixel_scale`` into the maps' pixels
    (maps four times as wide are searched over the same part of the view, in the same
    angle)."""

    mode: Mode = "joint"
    """joint: poses and turbine; pose: poses only (turbine fixed); turbine: turbine only."""
    points: UnaryKind = "corr"
    """Unary cost of the 6 model points: corr (window search, paper E_unary(1)), interp
    (bicubic heat-map, E_unary(2)) or none. The paper found points=corr, lines=interp best."""
    lines: UnaryKind = "interp"
    """Unary cost of the line samples (same choices)."""
    samples_per_line: int = 10
    """Points sampled on each of the 5 model lines (interior, evenly spaced)."""
    line_sampling: Literal["visible", "uniform"] = "visible"
    """visible: each keyframe spreads its samples over the part of each line in its view
    (re-chosen every round), so close-up views of a blade or the tower keep all of them;
    uniform: fixed fractions along the whole line (the paper's split)."""
    lambda_points: float = 1.0
    """Weight lambda_P of the point-model term."""
    lambda_lines: float = 1.0
    """Weight lambda_L of the line-model term."""
    lambda_pair: float = 1.0
    """Weight lambda of the pairwise (relative-pose) term."""
    pixel_sigma: float = 0.5
    """Correspondence noise [px of maps 320 px wide]: correspondence residuals are divided
    by it (sub-pixel peaks of sharp heat-maps; raise it for a coarse CNN)."""
    pair_sigma_t: float = 0.1
    """Default information matrix: std. dev. of a relative translation [m] per axis."""
    pair_sigma_r_deg: float = 0.1
    """Default information matrix: std. dev. of a relative rotation [deg] per axis."""
    pair_sigma_t_per_m: float = 0.02
    """Added relative-translation std. dev. per metre of the measured step [m/m]: long
    steps are less certain (sigma_t^2 = pair_sigma_t^2 + (pair_sigma_t_per_m * |step|)^2;
    0 = the paper's fixed C)."""
    pair_frame: PairFrame = "auto"
    """Frame of the relative translation in the pairwise term: measured (the GPS/IMU
    attitude of the first keyframe of each pair: the world-frame GPS step is compared, so
    the IMU's attitude drift does not leak into the positions), estimated (the current
    estimate's attitude: the paper's residual, right for body-frame odometry such as VIO)
    or auto: estimated when the flight has odometry (odometry.txt: body-frame steps),
    measured when it has GPS/IMU keyframes only. fit, FitProblem and the Tracker resolve
    auto from their data (resolve_pair_frame); results record the frame used. See
    turbinefit.costs.pairwise."""
    lambda_motion: float = 0.0
    """Weight of the tie-point term (turbinefit.costs.relative_motion): the relative
    rotation and direction of motion between consecutive photos measured from their tie
    points, where the keyframes come with such measurements (``Flight.motions``, measured
    by turbinefit.tiepoints); 0 = off, the default: on the benchmark flights it made the
    fits worse (docs/benchmarks.md, "Precision beyond the net")."""
    motion_robust_scale: float = 3.0
    """Scale of the Cauchy loss on each tie-point edge's whitened residual (5 values)."""
    lambda_edges: float = 0.0
    """Weight of the edge term (turbinefit.costs.edges): the tower's and blades'
    silhouette edges searched in the photo at its own resolution along the normals of
    the projected lines, where the keyframes come with their grey photos
    (``Flight.photos``) and lines=corr; 0 = off, the default: on the benchmark flights it
    made the fits worse (docs/benchmarks.md, "Precision beyond the net")."""
    edge_sigma: float = 2.0
    """Noise of an edge midpoint [px of the photo as the edge term reads it] (of 0.5, 1
    and 2, 2 fitted three 1280 x 960 photo flights best)."""
    edge_reach: float = 2.0
    """How far the edge midpoint may lie from the net's line correspondence [px of maps
    320 px wide]."""
    lambda_width: float = 0.0
    """Weight of the width term (turbinefit.costs.silhouette_width): each line sample's
    depth measured from the separation of the silhouette edges the edge search finds in
    the photo (the tower's always; the blades' where ``blade_pitch_deg`` is known), what
    holds the camera's distance to a blade in a close-up; needs the keyframes' grey
    photos and lines=corr, as the edge term does; 0 = off."""
    blade_pitch_deg: float | None = None
    """The blades' pitch [deg] as the photos show them (0: the chord in the rotor plane,
    about 90 feathered; the renderer's convention, turbinefit.turbine.solid), for the
    width term's blade sections; None: unknown, the blades' widths are not used."""
    blade_pitch_sigma_deg: float = 2.0
    """How well ``blade_pitch_deg`` is known [deg]: its share of the width term's
    noise."""
    pair_information: tuple[float, ...] | None = None
    """Full 6x6 information matrix C (row-major, 36 values; translation first, 1/m^2 and
    1/rad^2); overrides the two sigmas above."""
    corr_radius: float = 20.0
    """Radius of the circular window searched for point correspondences [px of maps 320 px
    wide]."""
    line_search: float = 20.0
    """Half-length of the perpendicular search for line correspondences [px of maps 320 px
    wide]."""
    line_residual: Literal["point", "normal"] = "point"
    """Residual of a line correspondence (lines=corr): point, the 2-D distance to the
    point found by the perpendicular search (the paper's E_unary(1), which also resists
    sliding along the line), or normal, the distance along the search normal only."""
    corr_threshold: float = 0.3
    """Minimum heat-map value accepted as a correspondence."""
    heatmap_floor: float = 0.05
    """Floor eps of the interp cost -log((G + eps) / (1 + eps)): heat-map values below it
    count as background (robustness to low-level CNN noise); >= 1e-4."""
    border_margin: float = 8.0
    """Width over which heat-map evidence fades out at the image border [px of maps 320 px
    wide]."""
    robust: Literal["none", "huber", "cauchy"] = "huber"
    """Robust loss on the image terms."""
    robust_scale: float = 2.0
    """Scale of the robust loss, in units of the whitened residual."""
    gauge: Gauge = "first"
    """first: hold the first keyframe's pose; gps: weak absolute position priors instead."""
    gps_sigma: float = 3.0
    """Std. dev. of the absolute position priors when gauge=gps [m]."""
    initial_damping: float = 1e-4
    """Initial LM damping mu (relative to diag(J^T J)); larger = shorter first steps."""
    warmup: bool = True
    """Start with two correspondence stages (see turbinefit.solver.fit): *align*, on a
    pose graph stiffened ``warmup_stiffness`` times, where the trajectory moves nearly
    rigidly, with the turbine, onto the heat-maps; then *match*, on the normal graph.
    Both use point and line correspondences (wide basins) with a Huber loss; the
    configured cost then refines. Off: the configured cost from the start."""
    warmup_stiffness: float = 1000.0
    """Pairwise weight multiplier of the align stage."""
    warmup_align_rounds: int = 3
    """Correspondence rounds of the align stage (0 = skip it)."""
    warmup_match_rounds: int = 6
    """Correspondence rounds of the match stage (0 = skip it)."""
    warmup_iterations: int = 4
    """Levenberg-Marquardt iterations per warm-up round."""
    warmup_pixel_sigma: float = 2.0
    """Correspondence noise of the warm-up stages [px of maps 320 px wide] (their Huber loss
    bends at 2x it)."""
    warmup_function_tolerance: float = 1e-2
    """A warm-up round stops at the first accepted step that lowers its cost by less than
    this fraction (the warm-up only has to reach the configured cost's basin: measured on
    20 simulated flights, 1e-2 gives the same final accuracy as 1e-3 in 2/3 of the
    iterations)."""
    max_iterations: int = 15
    """Levenberg-Marquardt iterations per round of the configured cost."""
    max_rounds: int = 3
    """Rounds: correspondences and visible-part line samples are re-found after each."""
    function_tolerance: float = 1e-3
    """Stop when the cost fell by less than this fraction over the last
    ``stall_iterations`` accepted steps."""
    stall_iterations: int = 3
    """Window of the function-tolerance test [accepted steps]."""
    gradient_tolerance: float = 1e-10
    """Stop when the max-norm of the gradient falls below this."""
    parameter_tolerance: float = 1e-8
    """Stop when the step is below this fraction of the state's norm."""
    geometry: TurbineGeometry = field(default_factory=TurbineGeometry)
    """Fixed shape details (shaft tilt, blade cone, hub offset); zeros = the paper's model."""
    pixel_scale: float | None = None
    """Factor from the settings in [px of maps 320 px wide] to the heat-maps' own pixels
    (the searches' sample spacing grows with it too); unset (auto): the maps' width / 320,
    at least 1 (maps up to 320 px wide use the values as written). fit, FitProblem and
    the Tracker resolve it and record the factor used (config.yaml)."""

    def __post_init__(self) -> None:
        def bad(name: str, why: str) -> ValueError:
            return ValueError(f"{name}: {why} (got {getattr(self, name)!r})")

        if self.mode not in ("joint", "pose", "turbine"):
            raise bad("mode", "must be joint, pose or turbine")
        for name in ("points", "lines"):
            if getattr(self, name) not in ("interp", "corr", "none"):
                raise bad(name, "must be interp, corr or none")
        if self.points == "none" and self.lines == "none":
            raise ValueError("points and lines cannot both be none: no image evidence")
        if self.gauge not in ("first", "gps"):
            raise bad("gauge", "must be first or gps")
        if self.line_sampling not in ("visible", "uniform"):
            raise bad("line_sampling", "must be visible or uniform")
        if self.line_residual not in ("point", "normal"):
            raise bad("line_residual", "must be point or normal")
        if self.pair_frame not in ("auto", "measured", "estimated"):
            raise bad("pair_frame", "must be auto, measured or estimated")
        if self.robust not in ("none", "huber", "cauchy"):
            raise bad("robust", "must be none, huber or cauchy")
        for name in ("samples_per_line", "max_iterations", "max_rounds", "stall_iterations",
                     "warmup_iterations"):
            v = getattr(self, name)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 1):
                raise bad(name, "must be a whole number >= 1")
        positive = ("initial_damping", "pixel_sigma", "pair_sigma_t", "pair_sigma_r_deg", "corr_radius",
                    "line_search", "robust_scale", "gps_sigma",
                    "warmup_pixel_sigma", "warmup_function_tolerance", "motion_robust_scale",
                    "edge_sigma", "edge_reach", "blade_pitch_sigma_deg")
        for name in positive:
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise bad(name, "must be a positive number")
        for name in ("lambda_points", "lambda_lines", "lambda_pair", "lambda_motion",
                     "lambda_edges", "lambda_width",
                     "border_margin",
                     "warmup_stiffness",
                     "pair_sigma_t_per_m"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise bad(name, "must be a non-negative number")
        for name in ("warmup_align_rounds", "warmup_match_rounds"):
            v = getattr(self, name)
            if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                raise bad(name, "must be a whole number >= 0")
        if self.blade_pitch_deg is not None and not (
                isinstance(self.blade_pitch_deg, int | float)
                and not isinstance(self.blade_pitch_deg, bool)
                and -180.0 <= self.blade_pitch_deg <= 180.0):
            raise bad("blade_pitch_deg", "must be a number of degrees in [-180, 180] or unset")
        if not isinstance(self.warmup, bool):
            raise bad("warmup", "must be true or false")
        if not (isinstance(self.heatmap_floor, int | float) and 1e-4 <= self.heatmap_floor < 1):
            raise bad("heatmap_floor", "must be in [1e-4, 1)")
        if not 0 < self.corr_threshold < 1:
            raise bad("corr_threshold", "must be in (0, 1)")
        if self.pixel_scale is not None and not (
                isinstance(self.pixel_scale, int | float) and not isinstance(self.pixel_scale, bool)
                and math.isfinite(self.pixel_scale) and self.pixel_scale > 0):
            raise bad("pixel_scale", "must be a positive number or unset (auto)")
        if self.pair_information is not None:
            if len(self.pair_information) != 36:
                raise bad("pair_information", "needs 36 values (a 6x6 matrix)")
            if not all(isinstance(x, int | float) and not isinstance(x, bool)
                       and math.isfinite(x) for x in self.pair_information):
                raise bad("pair_information", "must be 36 finite numbers")

    @property
    def uses_photos(self) -> bool:
        """Whether a term reads the keyframes' grey photos: the edge or the width term,
        with lines=corr."""
        return (self.lambda_edges > 0 or self.lambda_width > 0) and self.lines == "corr"

    @property
    def scale(self) -> float:
        """The resolved ``pixel_scale`` (1 while it is unset: see
        :func:`resolve_pixel_scale`)."""
        return 1.0 if self.pixel_scale is None else float(self.pixel_scale)

    def px(self, name: str) -> float:
        """The setting ``name`` (one of :data:`PIXEL_FIELDS`) in the heat-maps' pixels."""
        if name not in PIXEL_FIELDS:
            raise ValueError(f"{name} is not a pixel setting")
        return float(getattr(self, name)) * self.scale

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["geometry"] = dataclasses.asdict(self.geometry)
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> FitConfig:
        """Build from a (e.g. YAML) mapping; unknown keys raise ValueError."""
        names = {f.name for f in dataclasses.fields(FitConfig)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise ValueError(f"unknown fit option(s): {', '.join(unknown)}")
        d = dict(d)
        if isinstance(d.get("geometry"), dict):
            gnames = {f.name for f in dataclasses.fields(TurbineGeometry)}
            gunk = sorted(set(d["geometry"]) - gnames)
            if gunk:
                raise ValueError(f"unknown geometry option(s): {', '.join(gunk)}")
            d["geometry"] = TurbineGeometry(**d["geometry"])
        if isinstance(d.get("pair_information"), list):
            d["pair_information"] = tuple(float(x) for x in d["pair_information"])
        return FitConfig(**d)


def resolve_pair_frame(config: FitConfig, has_odometry: bool) -> FitConfig:
    """``config`` with ``pair_frame="auto"`` resolved: ``estimated`` when the pairwise
    measurements are body-frame odometry (``has_odometry``: the flight's odometry.txt),
    ``measured`` when they are the GPS/IMU keyframe poses. Other values are kept."""
    if config.pair_frame != "auto":
        return config
    return dataclasses.replace(config, pair_frame="estimated" if has_odometry else "measured")


def resolve_pixel_scale(config: FitConfig, width: int) -> FitConfig:
    """``config`` with an unset ``pixel_scale`` resolved for heat-maps ``width`` px wide
    (:func:`pixel_scale_for`); a set one is kept."""
    if config.pixel_scale is not None:
        return config
    return dataclasses.replace(config, pixel_scale=pixel_scale_for(width))


def pair_frame_line(requested: FitConfig, used: FitConfig) -> str:
    """What a command prints about the pairwise frame: the frame ``used`` (a result's
    resolved config) and why, e.g. ``pairwise frame: estimated (odometry.txt: body-frame
    odometry)``, ``... measured (GPS/IMU keyframes)`` or ``... (set in the options)``."""
    if requested.pair_frame != "auto":
        why = "set in the options"
    elif used.pair_frame == "estimated":
        why = "odometry.txt: body-frame odometry"
    else:
        why = "GPS/IMU keyframes"
    return f"pairwise frame: {used.pair_frame} ({why})"


#: The fit options that measured best on heat-map files (the simulator's maps): line
#: correspondences scored along the search normal and a Cauchy loss
#: (``benchmarks/bench_defaults.py``; the paper's configuration is ``--preset paper-best``).
#: What ``fit`` and ``track`` set over :class:`FitConfig` when neither ``--config`` nor
#: ``--preset`` is given (``turbinefit.jobs.sources``).
FILE_FIT_DEFAULTS: Mapping[str, Any] = MappingProxyType({
    "lines": "corr", "line_residual": "normal", "robust": "cauchy"})
#: The fit options that measured best on heat-maps the CNN detects in photos: as for files,
#: with correspondences trusted less (2 px) and a tight Cauchy loss (scale 0.5: it bends at
#: 1 px), since the net's peaks carry errors and biases of about a pixel and some of its
#: answers are wrong altogether (``benchmarks/bench_defaults.py``).
PHOTO_FIT_DEFAULTS: Mapping[str, Any] = MappingProxyType({
    "lines": "corr", "line_residual": "normal", "robust": "cauchy", "pixel_sigma": 2.0,
    "robust_scale": 0.5})

#: Named configurations: the paper's four unary combinations, the normal-residual variant
#: of corr lines, and the three modes.
PRESETS: dict[str, FitConfig] = {
    "paper-best": FitConfig(points="corr", lines="interp"),
    "all-interp": FitConfig(points="interp", lines="interp"),
    "all-corr": FitConfig(points="corr", lines="corr"),
    "paper-worst": FitConfig(points="interp", lines="corr"),
    # not one of the paper's: line correspondences scored along the search normal only
    # (measured on 200 simulated flights: better than paper-best in position on 66 % of
    # them and in orientation on 89 %; see docs/experiments.md)
    "corr-normal": FitConfig(points="corr", lines="corr", line_residual="normal"),
    "pose-only": FitConfig(mode="pose"),
    "turbine-only": FitConfig(mode="turbine"),
}


#: Default standard deviations of the start-up prior on theta: base x, base y, tower
#: height [m], heading [rad], nacelle length [m], blade rotation [rad], blade length [m]
#: (twice the simulator's initial turbine errors).
DEFAULT_THETA_SIGMA: tuple[float, ...] = (
    2.0, 2.0, 4.0, math.radians(10.0), 1.0, math.radians(10.0), 4.0)


@dataclass(frozen=True)
class TrackerConfig:
    """How the tracker updates. Units as named.

    Attributes:
        fit: the cost and its options (as for the batch fit; warm-up options other than
            ``warmup_pixel_sigma`` are not used).
        window: keyframes in the sliding window (>= 2), or None: keep all (the batch
            problem; per-keyframe work then grows with the flight).
        rounds: correspondence rounds of the configured cost per keyframe.
        iterations: Levenberg-Marquardt iterations per round.
        match_rounds: wide-basin correspondence rounds before them (the batch fit's
            *match* warm-up, with ``fit.warmup_iterations`` iterations) on the first
            ``match_keyframes`` keyframes and whenever the turbine comes back into view.
        match_keyframes: see ``match_rounds``.
        theta_sigma: standard deviations of the start-up prior on theta (7 values, see
            :data:`DEFAULT_THETA_SIGMA`), or None: no prior (theta is then unobservable
            from the first keyframe alone; use with care).
        marginal_terms: how the image terms of a keyframe leaving the window are linearised
            into the prior: ``corr``, as correspondences (points as found by the window
            search, lines along the search normal), whose quadratic model holds over the
            whole search range; or ``same``, as the configured cost, whose interp terms are
            quadratic only within about a pixel of the heat-map's ridge, so that the prior
            of a keyframe marginalised while theta was still off carries a wrong model of
            it (measured: see docs/tracking.md).
        theta_prior_release: the start-up prior is removed once the images alone inform
            every direction of theta this many times more than it does (the smallest
            generalised eigenvalue of data and prior information); None: keep it.
        finish_rounds, finish_iterations: rounds and iterations of
            :meth:`~turbinefit.solver.tracker.Tracker.finish`.
    """

    fit: FitConfig = field(default_factory=FitConfig)
    window: int | None = 20
    rounds: int = 1
    iterations: int = 5
    match_rounds: int = 1
    match_keyframes: int = 5
    theta_sigma: tuple[float, ...] | None = DEFAULT_THETA_SIGMA
    theta_prior_release: float | None = 10.0
    marginal_terms: Literal["corr", "same"] = "corr"
    finish_rounds: int = 3
    finish_iterations: int = 15

    def __post_init__(self) -> None:
        if self.fit.mode not in ("joint", "pose"):
            raise ValueError(f"mode: tracking needs joint or pose (got {self.fit.mode!r})")
        if self.window is not None and (isinstance(self.window, bool)
                                        or not isinstance(self.window, int) or self.window < 2):
            raise ValueError(f"window: must be a whole number >= 2 or None (got {self.window!r})")
        for name in ("rounds", "iterations", "finish_rounds", "finish_iterations"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name}: must be a whole number >= 1 (got {v!r})")
        for name in ("match_rounds", "match_keyframes"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ValueError(f"{name}: must be a whole number >= 0 (got {v!r})")
        if self.marginal_terms not in ("corr", "same"):
            raise ValueError(f"marginal_terms: must be corr or same (got {self.marginal_terms!r})")
        r = self.theta_prior_release
        if r is not None and not (isinstance(r, int | float) and math.isfinite(r) and r > 0):
            raise ValueError(f"theta_prior_release: must be a positive number or None (got {r!r})")
        if self.theta_sigma is not None and (
                len(self.theta_sigma) != 7
                or not all(math.isfinite(s) and s > 0 for s in self.theta_sigma)):
            raise ValueError("theta_sigma: needs 7 positive finite standard deviations")
