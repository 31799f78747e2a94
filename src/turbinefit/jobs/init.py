"""The ``init`` job: the initial turbine of a flight from its heat-maps (or photos) and
poses, with no angle given (:func:`turbinefit.solver.init.initial_turbine`).

:func:`init_folder` writes ``turbine.yaml`` (or returns its text) with each parameter's
spread; :func:`estimate_flight_turbine` is what ``fit`` and ``track`` call on a flight
without ``turbine.yaml``; :func:`turbine_prior` turns the command line's ``--near``,
``--near-wgs84``, ``--type``, ``--hub-height`` and ``--rotor-diameter`` into a prior.
A parameter neither the images nor the prior determine is an :class:`InputError` naming
it and what to add; nothing is written then.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from turbinefit.errors import InputError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import HeatmapStack
from turbinefit.io.atomic import write_text_atomic
from turbinefit.io.flight_folder import FLIGHT_ENTRIES, TURBINE_FILE, read_flight_folder
from turbinefit.io.quantities import COORDINATE, LATITUDE, LONGITUDE, Quantity, named
from turbinefit.io.turbine_yaml import format_turbine_yaml
from turbinefit.jobs.sources import open_heatmaps
from turbinefit.solver.init import InitOptions, NotDetermined, TurbinePrior, initial_turbine
from turbinefit.turbine.model import TurbineParams, param_errors

if TYPE_CHECKING:
    from turbinefit.detect import DetectOptions

#: ``--hub-height`` [m]: from the smallest turbines inspected by drone to beyond the
#: tallest built (about 170 m).
HUB_HEIGHT = Quantity("hub height", "m", 10.0, 250.0)
#: ``--rotor-diameter`` [m]: the same span of turbines (the largest: about 260 m).
ROTOR_DIAMETER = Quantity("rotor diameter", "m", 10.0, 300.0)

#: The comment line of the ``turbine.yaml`` that ``init`` writes.
INIT_TURBINE_COMMENT = "turbinefit init: initial turbine estimated from the images (metres, radians)"


@dataclass
class InitSummary:
    """What ``init`` found (``fit`` and ``track`` keep it in ``summary.json`` as
    ``turbine_init``).

    Attributes:
        turbine: the estimate.
        std: spread of each parameter (metres, radians).
        source: where each parameter came from (``images``, ``prior``, ``default``).
        keyframes, keyframes_seen: keyframes used, and those showing the turbine.
        prior: the prior given, in words (None: none).
        seconds: time spent estimating (heat-maps already loaded).
        errors: signed error of each parameter against ground truth (metres, degrees),
            or None without ground truth.
    """

    turbine: TurbineParams
    std: dict[str, float]
    source: dict[str, str]
    keyframes: int
    keyframes_seen: int
    prior: str | None = None
    seconds: float = 0.0
    errors: dict[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"turbine": self.turbine.to_dict(), "std": dict(self.std),
                "source": dict(self.source), "keyframes": self.keyframes,
                "keyframes_seen": self.keyframes_seen, "prior": self.prior,
                "seconds": round(self.seconds, 4), "errors": self.errors}

    def table(self) -> list[str]:
        """How well each parameter is determined, one line each (degrees for angles)."""
        rows = [f"{'parameter':<15}{'estimate':>11}{'spread':>9}  unit  from"
                + ("       error" if self.errors else "")]
        th = self.turbine.to_dict()
        for name, angular in zip(TurbineParams.NAMES, TurbineParams.ANGULAR, strict=True):
            f = math.degrees if angular else float
            row = (f"{name:<15}{f(th[name]):11.2f}{f(self.std[name]):9.2f}  "
                   f"{'deg' if angular else 'm':<4}  {self.source[name]:<10}")
            if self.errors:
                row += f"{self.errors[name]:8.2f}"
            rows.append(row)
        return rows


@dataclass
class InitReport:
    """What :func:`init_folder` did: the summary, the YAML text and where it was written
    (None: not written, the caller prints it)."""

    summary: InitSummary
    yaml: str
    out: Path | None = None
    timings: dict[str, float] = field(default_factory=dict)


def turbine_prior(flight_dir: str | os.PathLike[str], *,
                  near: tuple[float, float] | None = None,
                  near_wgs84: tuple[float, float] | None = None,
                  type_name: str | None = None, hub_height: float | None = None,
                  rotor_diameter: float | None = None) -> TurbinePrior:
    """The prior of the command line: a position (``near`` in the flight's frame, or
    ``near_wgs84`` through the flight's ``georef.yaml``) and sizes (a catalogue ``type_name``,
    or ``hub_height`` and ``rotor_diameter`` [m], which override the type's).

    Raises:
        InputError: for an unknown type, a ``near_wgs84`` on a flight without
            ``georef.yaml``, or implausible sizes.
    """
    prior = TurbinePrior()
    if type_name is not None:
        from turbinefit.io.turbine_types import turbine_type

        prior = turbine_type(type_name).prior()
    if hub_height is not None:
        prior = replace(prior, hub_height=HUB_HEIGHT.check(hub_height, field="--hub-height"))
    if rotor_diameter is not None:
        d = ROTOR_DIAMETER.check(rotor_diameter, field="--rotor-diameter")
        prior = replace(prior, blade_length=d / 2.0)
    if near is not None:
        x = named(COORDINATE, "X").check(near[0], field="--near")
        y = named(COORDINATE, "Y").check(near[1], field="--near")
        prior = replace(prior, near_xy=(x, y))
    elif near_wgs84 is not None:
        from turbinefit.io.georef import GEOREF_FILE, read_flight_georef

        lat = LATITUDE.check(near_wgs84[0], field="--near-wgs84")
        lon = LONGITUDE.check(near_wgs84[1], field="--near-wgs84")
        georef = read_flight_georef(flight_dir)
        if georef is None:
            raise InputError(f"--near-wgs84 needs a georeferenced flight ({GEOREF_FILE}); "
                             "give --near X,Y in the flight's frame", path=flight_dir)
        e = georef.enu(lat, lon, georef.altitude)
        prior = replace(prior, near_xy=(float(e[0]), float(e[1])))
    return prior


def describe_prior(prior: TurbinePrior) -> str | None:
    """The prior in a few words (None if empty)."""
    parts = []
    if prior.near_xy is not None:
        parts.append(f"near ({prior.near_xy[0]:.1f}, {prior.near_xy[1]:.1f}) m")
    if prior.name is not None:
        parts.append(f"type {prior.name}")
    if prior.hub_height is not None:
        parts.append(f"hub height {prior.hub_height:g} m")
    if prior.blade_length is not None:
        parts.append(f"rotor diameter {2 * prior.blade_length:g} m")
    return ", ".join(parts) or None


def estimate_turbine(heatmaps: HeatmapStack, camera: PinholeCamera, world_T_cam: SE3,
                     prior: TurbinePrior | None = None, *, where: object = None,
                     gt_turbine: TurbineParams | None = None,
                     options: InitOptions | None = None) -> InitSummary:
    """:func:`~turbinefit.solver.init.initial_turbine` as a job: its result as an
    :class:`InitSummary`, a parameter it cannot determine as an :class:`InputError` naming
    ``where`` (the flight folder)."""
    prior = prior or TurbinePrior()
    t0 = time.perf_counter()
    try:
        res = initial_turbine(heatmaps, camera, world_T_cam, prior, options)
    except NotDetermined as exc:
        raise InputError(str(exc), path=where) from None
    errors = None
    if gt_turbine is not None:
        e = param_errors(res.turbine, gt_turbine)
        errors = {n: float(math.degrees(v) if a else v) for n, a, v in
                  zip(TurbineParams.NAMES, TurbineParams.ANGULAR, e, strict=True)}
    return InitSummary(res.turbine, res.std, res.source, len(heatmaps), res.keyframes_seen,
                       describe_prior(prior), time.perf_counter() - t0, errors)


def _check_out(out: Path, flight_dir: Path, overwrite: bool) -> None:
    """Refuse an ``--out`` that is an input of the flight (any of its files but
    ``turbine.yaml``), a directory, or an existing file without ``overwrite``."""
    o = out.resolve()
    root = flight_dir.resolve()
    if (o.parent == root and o.name in FLIGHT_ENTRIES - {TURBINE_FILE}) or root in o.parents[1:]:
        raise InputError("is an input of the flight; choose another --out", path=out)
    if o == root or out.is_dir():
        raise InputError("is a directory; --out names the turbine.yaml to write", path=out)
    if out.exists() and not overwrite:
        raise InputError("exists; use --overwrite to replace it", path=out)


def init_folder(flight_dir: str | os.PathLike[str], out: str | os.PathLike[str] | None = None,
                prior: TurbinePrior | None = None, *, overwrite: bool = False,
                from_images: bool | None = None, model: str | os.PathLike[str] | None = None,
                detect_options: DetectOptions | None = None) -> InitReport:
    """Estimate the initial turbine of the flight in ``flight_dir`` (its ``turbine.yaml``,
    if any, is not read) and write it to ``out`` (None: only return the text).

    Heat-maps come from ``heatmaps/`` or are detected from ``images/`` as ``fit`` reads
    them (:func:`turbinefit.jobs.sources.open_heatmaps`).

    Raises:
        InputError: bad input, a bad ``out`` (checked before any work), or a parameter
            neither the images nor ``prior`` determine (nothing is written).
    """
    flight_dir = Path(flight_dir)
    out_path = None if out is None else Path(out)
    if out_path is not None:
        _check_out(out_path, flight_dir, overwrite)
    t0 = time.perf_counter()
    folder = read_flight_folder(flight_dir)
    source = open_heatmaps(folder, from_images, model, detect_options)
    stack = source.stack()
    load = time.perf_counter() - t0
    summary = estimate_turbine(stack, source.camera, folder.keyframes.poses, prior,
                               where=flight_dir, gt_turbine=folder.gt_turbine)
    text = format_turbine_yaml(summary.turbine, INIT_TURBINE_COMMENT, out_path,
                               std=summary.std)
    if out_path is not None:
        write_text_atomic(out_path, text)
    return InitReport(summary, text, out_path,
                      {"load": load, "init": summary.seconds,
                       "total": time.perf_counter() - t0})
