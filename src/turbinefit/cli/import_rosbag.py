"""``turbinefit import rosbag``: not built yet (issue 29)."""

from __future__ import annotations

import argparse
from typing import Any


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p: argparse.ArgumentParser = sub.add_parser("rosbag", help="(not built yet)")
    return p


def run(args: argparse.Namespace) -> int:
    from turbinefit.errors import InputError

    raise InputError("turbinefit import rosbag is not built yet")
