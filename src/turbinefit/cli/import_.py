"""``turbinefit import``: make a flight folder from what a drone records.

``import dji`` (:mod:`turbinefit.cli.import_dji`) reads DJI photos' EXIF/XMP metadata;
``import rosbag`` (:mod:`turbinefit.cli.import_rosbag`) reads a ROS 1/ROS 2 bag. Each
sub-command's module has ``add_parser(subparsers)`` and ``run(args)``.
"""

from __future__ import annotations

import argparse
import importlib
from typing import Any

#: sub-command -> module under turbinefit.cli
SOURCES = {"dji": "import_dji", "rosbag": "import_rosbag"}


def add_parser(sub: Any, help: str) -> argparse.ArgumentParser:
    p: argparse.ArgumentParser = sub.add_parser(
        "import", help=help,
        description="Make a flight folder (camera.yaml, keyframes.txt, images/, ...) from "
        "DJI photos or a ROS bag, ready for 'turbinefit fit'.")
    kinds = p.add_subparsers(dest="source", metavar="SOURCE", required=True)
    for module in SOURCES.values():
        importlib.import_module(f"turbinefit.cli.{module}").add_parser(kinds)
    return p


def run(args: argparse.Namespace) -> int:
    module = importlib.import_module(f"turbinefit.cli.{SOURCES[args.source]}")
    return int(module.run(args))
