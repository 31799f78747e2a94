"""The ``turbinefit`` command line: one module per command, a thin layer over
:mod:`turbinefit.jobs` (and :mod:`turbinefit.experiments`, :mod:`turbinefit.train`).

Each command module has ``add_parser(subparsers, help)`` and ``run(args) -> int``, and
imports what it runs only inside ``run``: ``turbinefit --help`` builds every command as a
stub and loads no command module; ``turbinefit COMMAND ...`` builds and loads that one.
Every command prints one clear line and exits with status 2 on bad input (no traceback),
and on SIGINT, SIGTERM or SIGHUP cleans up, prints one line and exits with status 130, 143
or 129 (:mod:`turbinefit.cli.signals`, set up before anything else is imported);
``fit`` and ``track`` exit with status 3 when their verdict is ``failed`` (outputs written).
"""

from __future__ import annotations

from turbinefit.cli import signals

signals.exit_quietly_on_signals()

import argparse  # noqa: E402 - after the signal handlers: an early Ctrl-C prints no traceback
import importlib  # noqa: E402
import sys  # noqa: E402
from collections.abc import Collection, Sequence  # noqa: E402
from types import ModuleType  # noqa: E402

EXIT_BAD_INPUT = 2
#: ``fit`` or ``track`` ran and wrote its outputs, but its verdict is ``failed``.
EXIT_FIT_FAILED = 3
#: The status of Ctrl-C; SIGTERM gives 143 and SIGHUP 129 (128 + the signal's number).
EXIT_INTERRUPTED = 130

#: Every command: name -> one line of help (the module is ``turbinefit.cli.<name>``).
COMMANDS: dict[str, str] = {
    "simulate": "write a simulated flight folder with ground truth",
    "init": "estimate the initial turbine.yaml of a flight from its images",
    "fit": "optimise poses and turbine of a flight folder",
    "track": "replay a flight keyframe by keyframe (in-flight tracking)",
    "coverage": "what each keyframe of a fit shows of each blade and the tower, at what mm/px",
    "plan": "waypoints of the next inspection flight round a fitted turbine",
    "mission": "simulate an inspection mission in the loop (fly, track, replan, find defects)",
    "view": "one interactive HTML page of a fit: turbine, cameras, photos, plan, coverage",
    "experiment": "Monte Carlo studies of the paper (simulated flights)",
    "report": "rebuild an experiment's figures and report from its rows",
    "import": "make a flight folder from DJI photos or a ROS bag",
    "detect": "heat-maps of photos with the CNN (onnxruntime)",
    "evaluate": "detection metrics of the CNN on labelled photos (keypoints, boxes, masks)",
    "train": "train the heat-map CNN on rendered photos (needs turbinefit[train])",
}

FLIGHT_FOLDER_HELP = """\
Flight folder (input of fit and track, output of simulate):
  camera.yaml                 ROS/OpenCV camera_info (image size, camera_matrix, plumb_bob)
  keyframes.txt               TUM 'timestamp tx ty tz qx qy qz qw', initial world_T_cam
  odometry.txt                optional TUM; its consecutive relative poses are the
                              pairwise measurements (default: those of keyframes.txt)
  turbine.yaml                initial turbine parameters (metres, radians)
  heatmaps/<t %.6f>.npy       float16 or float32 (7, H, W) in [0, 1]: point_base,
                              point_tower_top, point_hub, point_blade_tip, line_tower,
                              line_nacelle, line_blade
  images/<t %.6f>.png|.jpg    optional photos; fit detects heat-maps from them when
                              heatmaps/ is absent (or with --from-images)
  groundtruth.txt, turbine_groundtruth.yaml   optional ground truth
  simulation.yaml             written by simulate (its settings); not read by fit
  georef.yaml                 optional WGS84 origin of an east-north-up world frame
                              (written by import); fit and track then add WGS84 outputs

Run 'turbinefit COMMAND --help' for a command's options.
"""


#: Commands whose module name differs from the command (``import`` is a Python keyword).
_MODULE_NAMES = {"import": "import_"}


def _module(name: str) -> ModuleType:
    return importlib.import_module(f"turbinefit.cli.{_MODULE_NAMES.get(name, name)}")


def build_parser(commands: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The argument parser; ``commands``: those built with all their options (None =
    all), the others as stubs that only name themselves."""
    from turbinefit.cli.common import Parser, version

    p = Parser(
        prog="turbinefit",
        description="Simultaneous drone localisation and wind-turbine model fitting from CNN "
        "heat-maps (Moolan-Feroze et al., IROS 2019).",
        epilog=FLIGHT_FOLDER_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=version())
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, text in COMMANDS.items():
        if commands is None or name in commands:
            _module(name).add_parser(sub, text)
        else:
            sub.add_parser(name, help=text)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``turbinefit`` command."""
    status = _run_command(argv)
    signals.ignore_from_now()  # the work is done (turbinefit.cli.signals)
    return status


def _run_command(argv: Sequence[str] | None) -> int:
    args_in = list(sys.argv[1:] if argv is None else argv)
    # the command is the first word that is not an option (the top level has no option
    # that takes a value)
    command = next((a for a in args_in if not a.startswith("-")), None)
    with signals.RaisingOnSignals() as guard:
        try:
            parser = build_parser({command} if command in COMMANDS else ())
            args = parser.parse_args(args_in)
            status = int(_module(args.command).run(args))
            if guard.caught is not None:  # a library swallowed the signal: it still counts
                return _interrupted(guard.caught)
            return status
        except BaseException as exc:
            # once a signal came, whatever ends the command is its doing (a library may
            # have made another exception of it: numpy's C modules an ImportError)
            if guard.caught is not None:
                return _interrupted(guard.caught)
            if isinstance(exc, KeyboardInterrupt):  # Ctrl-C in a program calling main
                return _interrupted(signals.signal_of(exc))
            from turbinefit.errors import TurbinefitError

            if isinstance(exc, TurbinefitError):
                print(f"turbinefit: error: {exc}", file=sys.stderr)
                return EXIT_BAD_INPUT
            if isinstance(exc, OSError):
                from turbinefit.io.atomic import is_disk_full, write_error

                if is_disk_full(exc):
                    print(f"turbinefit: error: {write_error(exc, exc.filename)}",
                          file=sys.stderr)
                    return EXIT_BAD_INPUT
            raise
        finally:  # a job that failed before writing still holds its output's reservation
            atomic = sys.modules.get("turbinefit.io.atomic")
            if atomic is not None:
                atomic.release_all_outputs()


def _interrupted(signum: int) -> int:
    """Print the line of a command stopped by ``signum``; its exit status."""
    print(signals.message(signum), file=sys.stderr)
    return signals.exit_status(signum)
