"""What several commands share: argument types, the help formatter, the options of photo
detection and of the fit (generated from :class:`~turbinefit.solver.config.FitConfig`),
and progress output.

Imports only the standard library at module level; the fit options import
:mod:`turbinefit.solver.config` when a parser that has them is built.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import itertools
import math
import re
import textwrap
import typing
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from turbinefit.detect import DetectOptions
    from turbinefit.io.quantities import Quantity
    from turbinefit.solver.config import FitConfig


# ---- the parser ---------------------------------------------------------------------------

#: An argument that starts with a minus and then a digit, a point and a digit, ``inf`` or
#: ``nan`` is a value (``--origin -5.2,-35.6,12``, ``--near -40,-3``), never an option: no
#: option of turbinefit looks like that. argparse's own rule takes only a plain negative
#: number (``-5.2``) as a value, so a list of numbers starting with a minus was refused
#: as an unknown option ("expected one argument").
NEGATIVE_VALUE = re.compile(r"^-(\.?\d|inf|nan)", re.IGNORECASE)


class Parser(argparse.ArgumentParser):
    """The command line's argument parser (and its subcommands'): argparse's, with
    :data:`NEGATIVE_VALUE` as its rule for values that start with a minus."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_VALUE


# ---- argument types ----------------------------------------------------------------------

def option(quantity: Quantity) -> Callable[[str], float]:
    """The argparse type of an option holding one ``quantity``
    (:mod:`turbinefit.io.quantities`): its range checked as in files and photo metadata."""
    def parse(text: str) -> float:
        from turbinefit.errors import InputError

        try:
            return quantity.parse(text)
        except InputError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    parse.__name__ = quantity.what
    return parse


def job_option(job: str, name: str) -> Callable[[str], float]:
    """:func:`option` of the quantity ``name`` of :mod:`turbinefit.jobs`'s module ``job``
    (a quantity only that job has), loaded when the option is given, so that the
    command's ``--help`` loads no job."""
    def parse(text: str) -> float:
        import importlib

        return option(getattr(importlib.import_module(f"turbinefit.jobs.{job}"), name))(text)
    parse.__name__ = name.lower()
    return parse


def option_tuple(*quantities: Quantity, what: str) -> Callable[[str], tuple[float, ...]]:
    """The argparse type of an option holding comma-separated numbers, one per quantity
    (``what`` names the form in messages: ``"LAT,LON in degrees"``)."""
    def parse(text: str) -> tuple[float, ...]:
        from turbinefit.errors import InputError

        parts = text.split(",")
        if len(parts) != len(quantities):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        try:
            return tuple(q.parse(x) for q, x in zip(quantities, parts, strict=True))
        except InputError as e:
            raise argparse.ArgumentTypeError(f"{e} (in {text!r})") from None
    parse.__name__ = what
    return parse


def latlonalt(text: str) -> tuple[float, ...]:
    """The argparse type of ``LAT,LON,ALT`` (WGS84 degrees, altitude in metres), loading
    the quantities only when the option is given."""
    from turbinefit.io.quantities import ALTITUDE, LATITUDE, LONGITUDE

    return option_tuple(LATITUDE, LONGITUDE, ALTITUDE,
                        what="LAT,LON,ALT (degrees, degrees, metres)")(text)


def whole_number(text: str, minimum: int, why: str) -> int:
    v = _integer(text)
    if v < minimum:
        raise argparse.ArgumentTypeError(f"{why}, got {v}")
    return v


def positive_int(text: str) -> int:
    return whole_number(text, 1, "must be at least 1")


def whole_nonneg(text: str) -> int:
    return whole_number(text, 0, "must be >= 0")


def seed(text: str) -> int:
    return whole_number(text, 0, "must be a non-negative whole number")


def number(text: str) -> float:
    """A finite number (any option's: none takes nan or inf)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def positive_number(text: str) -> float:
    v = number(text)
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return v


class DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends an option's default to its help, unless the help already says it or the
    default is None or a flag's False (nothing worth saying)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.default is None or action.default is False or "(default" in text:
            return text
        return super()._get_help_string(action) or text


def version() -> str:
    from turbinefit import __version__

    return f"turbinefit {__version__}"


def degrees(x: float) -> float:
    return math.degrees(x)


def turbine_line(th: Any) -> str:
    """One line describing a :class:`~turbinefit.turbine.model.TurbineParams`."""
    return (f"turbine: base ({th.base_x:.2f}, {th.base_y:.2f}) m, tower {th.tower_height:.2f} m, "
            f"heading {degrees(th.heading):.2f} deg, nacelle {th.nacelle_length:.2f} m, "
            f"blade rotation {degrees(th.blade_rotation):.2f} deg, blades "
            f"{th.blade_length:.2f} m")


def init_line(init: Any) -> str:
    """The line ``fit`` and ``track`` print when they estimated the initial turbine
    (an :class:`~turbinefit.jobs.init.InitSummary`)."""
    return (f"no turbine.yaml: initial turbine estimated from the images (turbinefit init) "
            f"from {init.keyframes_seen} of {init.keyframes} keyframes in {init.seconds:.2f} s; "
            f"{turbine_line(init.turbine).removeprefix('turbine: ')}")


def verdict_line(verdict: str, std: Any) -> str:
    """The verdict and theta's standard deviations (``std``: (7,) or None), in one line."""
    if std is None:
        return f"verdict: {verdict}"
    sd = [float(x) for x in std]
    return (f"verdict: {verdict}; standard deviations: base ({sd[0]:.2f}, {sd[1]:.2f}) m, "
            f"tower {sd[2]:.2f} m, heading {degrees(sd[3]):.2f} deg, nacelle {sd[4]:.2f} m, "
            f"blade rotation {degrees(sd[5]):.2f} deg, blades {sd[6]:.2f} m")


# ---- photo detection ---------------------------------------------------------------------

def _tip_shift(text: str) -> float:
    from turbinefit.heatmaps.model_info import TIP_SHIFT_TAPER_PX, valid_tip_shift

    v = number(text)
    if not valid_tip_shift(v):
        raise argparse.ArgumentTypeError(
            f"must be a number of pixels between -{TIP_SHIFT_TAPER_PX:g} and "
            f"{TIP_SHIFT_TAPER_PX:g}, got {text!r}")
    return v


def add_detect_options(parser: argparse.ArgumentParser) -> None:
    """--no-flip, --tip-shift, --no-zoom and --refine/--no-refine: args.flip and args.zoom
    are False when given, else None; args.tip_shift a number when given, else None;
    args.refine True or False when given, else None (the model's metadata, or for refine
    the job, decides what is None; :func:`detect_options` gathers them)."""
    parser.add_argument("--no-flip", dest="flip", action="store_false", default=None,
                        help="run the CNN once per photo instead of averaging its maps with "
                        "those of the mirror image (faster, less accurate; default: as the "
                        "model's metadata says, flip averaging for the shipped model)")
    parser.add_argument("--tip-shift", type=_tip_shift, default=None, metavar="PX",
                        help="move the blade-tip heat-map this many pixels (at the model's "
                        "input width) outward from the detected hub, undoing the net's "
                        "inboard bias; 0 keeps the net's own (default: the value "
                        "calibrated for the model, turbinefit.tip_shift_px in its "
                        "metadata)")
    parser.add_argument("--no-zoom", dest="zoom", action="store_false", default=None,
                        help="no second pass of the CNN on an enlarged crop around small "
                        "turbines to find their blade tips (faster on far views, fewer tips "
                        "found; default: as the model's metadata says, zoom for the shipped "
                        "model)")
    parser.add_argument("--refine", action=argparse.BooleanOptionalAction, default=None,
                        help="coarse to fine: look again at each tower top, hub and blade "
                        "tip found in a photo at least twice the CNN's input size (640 px "
                        "wide for the shipped model) on a crop read at the photo's own "
                        "resolution (up to 4x), and move its blob there: points placed more "
                        "precisely, for about twice the detection time (default: on for fit, "
                        "track and init from photos; off for detect and evaluate)")


def detect_options(args: argparse.Namespace) -> DetectOptions | None:
    """The :class:`~turbinefit.detect.DetectOptions` of :func:`add_detect_options`; None
    when none was given (the jobs then use ``DetectOptions()``, the same thing), so that a
    command fitting heat-map files does not import the detector (onnxruntime, scipy)."""
    if args.flip is None and args.tip_shift is None and args.zoom is None \
            and args.refine is None:
        return None
    from turbinefit.detect import DetectOptions

    return DetectOptions(flip=args.flip, tip_shift=args.tip_shift, zoom=args.zoom,
                         refine=args.refine)


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """--model, --threads and the detection options (``detect`` and ``evaluate``)."""
    parser.add_argument("--model", type=Path, default=None,
                        help="ONNX model (default: the shipped model)")
    parser.add_argument("--threads", type=positive_int, default=None,
                        help="photos detected at once, one inference thread each "
                        "(default: one per core)")
    add_detect_options(parser)


def add_photo_options(parser: argparse.ArgumentParser, what: str) -> None:
    """--from-images, --model, the detection options and --no-plots (``fit``, ``track``)."""
    parser.add_argument("--from-images", action="store_true", default=None,
                        help=f"{what} even if heatmaps/ exists (default: only when heatmaps/ "
                        "is absent)")
    parser.add_argument("--model", type=Path, default=None,
                        help="ONNX heat-map model for detection (default: the shipped one)")
    add_detect_options(parser)
    parser.add_argument("--no-plots", action="store_true", help="skip the figures")


# ---- fit options, generated from FitConfig ------------------------------------------------

#: FitConfig fields with no command-line option (set them in a --config YAML file).
#: (The tie-point and edge terms need data no command gives the fit yet: library only.)
_YAML_ONLY = frozenset({"geometry", "pair_information", "lambda_motion", "motion_robust_scale",
                        "lambda_edges", "edge_sigma", "edge_reach"})
#: FitConfig fields the tracker does not use (the batch fit's limits and warm-up stages).
_BATCH_ONLY = frozenset({"max_iterations", "max_rounds", "warmup", "warmup_stiffness",
                         "warmup_align_rounds", "warmup_match_rounds",
                         "warmup_function_tolerance"})
#: Further option strings of a field (shorter names kept from earlier versions).
_ALIASES = {"pair_sigma_r_deg": ("--pair-sigma-r",)}
#: Fields shown first, in the plain group; the rest are listed as advanced.
_MAIN = ("mode", "points", "lines", "line_residual", "pair_frame", "robust", "gauge",
         "warmup", "max_iterations", "max_rounds")


def field_docs(cls: type) -> dict[str, str]:
    """The docstring written under each field of the dataclass ``cls``, whitespace
    normalised (read from its source, where Python keeps no record of them)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    docs: dict[str, str] = {}
    for prev, node in itertools.pairwise(body):
        if (isinstance(prev, ast.AnnAssign) and isinstance(prev.target, ast.Name)
                and isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
                and isinstance(node.value.value, str)):
            docs[prev.target.id] = " ".join(node.value.value.split())
    return docs


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def add_fit_options(parser: argparse.ArgumentParser, *, batch: bool = True) -> None:
    """One option per field of :class:`~turbinefit.solver.config.FitConfig` (name, type,
    choices, help and default from the dataclass and its field docstrings), except those
    only a YAML file sets; ``batch=False`` (``track``) leaves out those the tracker does
    not use. Every option defaults to None: unset, the --config or --preset value holds;
    values are checked by FitConfig itself when the job applies them. Each help says the
    default the job starts from without --config or --preset (that for its kind of
    heat-maps where the two differ) and, where it differs, FitConfig's."""
    from turbinefit.solver.config import FILE_FIT_DEFAULTS, PHOTO_FIT_DEFAULTS, FitConfig

    default = FitConfig()
    docs = field_docs(FitConfig)
    hints = typing.get_type_hints(FitConfig)
    main = parser.add_argument_group(
        "fit options (as in turbinefit.FitConfig; any of them can also be set in a --config "
        "YAML file)",
        textwrap.fill("With neither --config nor --preset, a job starts from the options "
                      "measured best for its kind of heat-maps (files, or detected from "
                      "photos): the defaults below. With --preset, from that preset (a few "
                      "options set over FitConfig's defaults, shown as 'FitConfig'); with "
                      "--config, from the file.", 76))
    advanced = parser.add_argument_group("advanced fit options")
    fields = sorted(dataclasses.fields(FitConfig),
                    key=lambda f: _MAIN.index(f.name) if f.name in _MAIN else len(_MAIN))
    for f in fields:
        if f.name in _YAML_ONLY or (not batch and f.name in _BATCH_ONLY):
            continue
        group = main if f.name in _MAIN else advanced
        value = getattr(default, f.name)
        flags = (f"--{f.name.replace('_', '-')}", *_ALIASES.get(f.name, ()))
        text = docs.get(f.name, "").replace("%", "%%")
        kind = hints[f.name]
        shown = _default_text(value, FILE_FIT_DEFAULTS.get(f.name, value),
                              PHOTO_FIT_DEFAULTS.get(f.name, value))
        if kind is bool:
            group.add_argument(*flags, dest=f.name, action=argparse.BooleanOptionalAction,
                               default=None, help=f"{text} ({shown})")
            continue
        kw: dict[str, Any] = {}
        if typing.get_origin(kind) is typing.Literal:
            choices = list(typing.get_args(kind))
            if not batch and f.name == "mode":
                choices.remove("turbine")
            kw["choices"] = choices
        else:
            kw["type"] = _integer if kind is int else number
            kw["metavar"] = "N" if kind is int else "X"
        group.add_argument(*flags, dest=f.name, default=None, help=f"{text} ({shown})", **kw)


def _default_text(config: Any, files: Any, photos: Any) -> str:
    """'default: X' for a fit option whose value is ``config`` in FitConfig, and ``files``
    and ``photos`` in the defaults per kind of heat-maps."""
    def show(v: Any) -> str:
        if v is None:
            return "auto"  # unset: resolved from the data
        return f"{v:g}" if isinstance(v, float) else str(v)

    if files == photos:
        text = f"default: {show(files)}"
    else:
        text = f"default: {show(files)} on heat-map files, {show(photos)} from photos"
    if config not in (files, photos):
        text += f"; FitConfig: {show(config)}"
    return text


def fit_option_names(args: argparse.Namespace) -> dict[str, Any]:
    """The fit options given on the command line: {field: value}."""
    from turbinefit.solver.config import FitConfig

    names = {f.name for f in dataclasses.fields(FitConfig)}
    return {k: v for k, v in vars(args).items() if k in names and v is not None}


def add_flight_job_options(parser: argparse.ArgumentParser, batch: bool = True) -> None:
    """--out, --config | --preset and the fit options (``fit`` and ``track``; ``batch=False``:
    the tracker, whose help leaves out the presets of a mode it does not run)."""
    from turbinefit.solver.config import PRESETS

    presets = ", ".join(name + (" (the paper's best)" if name == "paper-best" else "")
                        for name, cfg in PRESETS.items() if batch or cfg.mode != "turbine")
    parser.add_argument("--out", dest="out_dir", metavar="OUT_DIR", type=Path, required=True,
                        help="output folder (written atomically; never the input folder)")
    base = parser.add_mutually_exclusive_group()
    base.add_argument("--config", type=Path, default=None,
                      help="YAML file of fit options (e.g. a previous fit's config.yaml)")
    base.add_argument("--preset", default=None,
                      help=f"start from a named configuration instead of the defaults for the "
                      f"flight's kind of heat-maps: {presets}")
    add_fit_options(parser, batch=batch)


def fit_base_and_options(args: argparse.Namespace) -> tuple[FitConfig | None, dict[str, Any]]:
    """The FitConfig of --config or --preset (None when neither is given: the job then
    starts from the defaults for its kind of heat-maps) and the fit options given on the
    command line, to set on top."""
    from turbinefit.errors import InputError
    from turbinefit.io.fit_config import read_fit_config
    from turbinefit.solver.config import PRESETS

    base = None
    if args.config is not None:
        base = read_fit_config(args.config)
    if args.preset is not None:
        if args.preset not in PRESETS:
            raise InputError(f"unknown preset {args.preset!r} (choose from "
                             f"{', '.join(PRESETS)})", field="--preset")
        base = PRESETS[args.preset]
    return base, fit_option_names(args)


def pair_frame_report(base: FitConfig | None, options: dict[str, Any], used: FitConfig) -> str:
    """The line a command prints about the pairwise frame ``used`` and why (asked for on
    the command line or in --config / --preset, or chosen from the flight's data)."""
    from turbinefit.solver.config import pair_frame_line

    requested = options.get("pair_frame", "auto" if base is None else base.pair_frame)
    return pair_frame_line(dataclasses.replace(used, pair_frame=requested), used)


#: The exit statuses of ``fit`` and ``track``, for their ``--help``.
VERDICT_EPILOG = """\
Every result is judged (summary.json: verdict, reasons, signals; docs/method.md):
ok, doubtful (a warning line, exit status 0) or failed (a warning line, exit
status 3; the outputs are still written, for inspection).

Exit status: 0 done (verdict ok or doubtful), 2 bad input (nothing written),
3 verdict failed (outputs written), 130 interrupted."""


def verdict_status(command: str, verdict: str, reasons: list[str], out_dir: Path) -> int:
    """Print the warning line of a ``doubtful`` or ``failed`` verdict (to stderr, also
    with --quiet) and return the exit status: 3 for ``failed``, else 0."""
    import sys

    from turbinefit.cli import EXIT_FIT_FAILED

    if verdict == "ok":
        return 0
    print(f"turbinefit: warning: {command} {verdict}: {'; '.join(reasons)} (outputs in "
          f"{out_dir})", file=sys.stderr)
    return EXIT_FIT_FAILED if verdict == "failed" else 0
