"""Output folders of the jobs: the rules in one place.

Every job writes one output folder (or, for ``evaluate``, one file) atomically
(:func:`turbinefit.io.atomic.atomic_output_dir`): into a hidden temporary sibling renamed
into place at the end, so a failure leaves nothing half-written. Before any work, the
destination is checked:

* it must not be, contain or lie inside any input (a flight folder, a config file, photos);
* a file or symbolic link there is refused;
* an existing non-empty folder is refused unless ``overwrite``, and even then unless it
  holds nothing but what the same command writes (:class:`OutputKind`), a guard against
  ``--overwrite`` on a wrong path.

The summaries the jobs write (``summary.json``) are dataclasses with a ``to_dict``;
:func:`summary_json` is their one serialiser (strict JSON: undefined numbers are null).
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from turbinefit.errors import InputError
from turbinefit.io.atomic import (
    atomic_output_dir,
    check_output_dir,
    is_disk_full,
    reserve_output,
    write_error,
)

#: How the command line asks for an existing non-empty output folder to be replaced.
OVERWRITE_HINT = "use --overwrite"


@dataclass(frozen=True)
class OutputKind:
    """What one command writes into its output folder.

    Attributes:
        command: the command's name (for messages).
        entries: the file names it writes, or None to allow any name with ``suffixes``.
        suffixes: the file suffixes it writes (with ``entries=None``).
        patterns: regular expressions of further names it writes (numbered files).
    """

    command: str
    entries: frozenset[str] | None = None
    suffixes: tuple[str, ...] = ()
    patterns: tuple[str, ...] = ()

    def foreign_entry(self, folder: Path) -> str | None:
        """None if ``folder`` holds nothing but files this command writes (safe to
        replace), else why not."""
        for entry in folder.iterdir():
            ok = (entry.name in self.entries if self.entries is not None
                  else entry.suffix in self.suffixes) or any(
                      re.fullmatch(p, entry.name) for p in self.patterns)
            if not ok or not entry.is_file():
                return f"{entry.name!r} is not an output of turbinefit {self.command}"
        return None

    def check(self, out_dir: Path, inputs: Iterable[Path], overwrite: bool) -> None:
        """Refuse ``out_dir`` before any work (see the module docstring), and reserve it
        (:func:`~turbinefit.io.atomic.reserve_output`: a second run into it is refused
        until this one's :meth:`writing` ends)."""
        check_not_input(out_dir, inputs)
        check_output_dir(out_dir, overwrite, self.foreign_entry, OVERWRITE_HINT)
        reserve_output(out_dir)

    @contextmanager
    def writing(self, out_dir: Path, overwrite: bool) -> Iterator[Path]:
        """The temporary folder to fill; renamed to ``out_dir`` when the block succeeds."""
        with atomic_output_dir(out_dir, overwrite=overwrite, may_replace=self.foreign_entry,
                               overwrite_hint=OVERWRITE_HINT) as tmp:
            yield tmp


def check_not_input(out: Path, inputs: Iterable[Path], what: str = "output folder") -> None:
    """Refuse an output path (``what``, in the message) that is, contains or lies inside
    one of ``inputs``."""
    try:
        resolved = out.resolve()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symbolic-link loop
        raise InputError(f"cannot resolve the output path: {exc}", out) from None
    for src in inputs:
        try:
            s = src.resolve()
        except (OSError, RuntimeError) as exc:
            raise InputError(f"cannot resolve the input path: {exc}", src) from None
        if resolved == s or s.is_relative_to(resolved) or resolved.is_relative_to(s):
            raise InputError(f"{what} would overwrite or nest inside the input {src}", out)


def check_output_file(path: Path, inputs: Iterable[Path], overwrite: bool, what: str,
                      ours: Callable[[Path], bool] | None = None) -> None:
    """Refuse ``path`` as a job's one output file before any work, and reserve it
    (:func:`~turbinefit.io.atomic.reserve_output`): it must not be or lie inside an input,
    nor be a symbolic link or a folder; an existing file is replaced only with
    ``overwrite`` and, given ``ours``, only if ``ours(path)`` says this command wrote it
    (a guard against ``--overwrite`` on a wrong path). ``what`` names the file in messages.
    """
    check_not_input(path, inputs, f"the {what}")
    if path.is_symlink():
        raise InputError("output path is a symbolic link; refusing to replace it", path)
    if path.is_dir():
        raise InputError(f"is a folder; the {what} is a file", path)
    if path.exists():
        if not overwrite:
            raise InputError(f"exists ({OVERWRITE_HINT} to replace it)", path)
        if not path.is_file():
            raise InputError("output path exists and is not a regular file", path)
        if ours is not None and not ours(path):
            raise InputError(f"is not a {what} turbinefit wrote; refusing to replace it", path)
    reserve_output(path)


def recorded_path(path: str | Path, out_dir: str | Path) -> str:
    """How an output folder ``out_dir`` records an input ``path`` (in ``summary.json``):
    relative to ``out_dir`` itself, so that the record holds from any working directory
    and when the two folders move together; read back by :func:`recorded_input`."""
    try:
        return os.path.relpath(os.path.abspath(path), os.path.abspath(out_dir))
    except ValueError:  # another drive (Windows): no relative path
        return os.path.abspath(path)


def recorded_input(name: str, out_dir: Path) -> list[Path]:
    """Where a path an output folder records may be, most likely first: relative to the
    folder (as :func:`recorded_path` writes it; an absolute path stays as it is), then,
    for records of older versions, relative to the working directory and to the folder's
    parent."""
    return [out_dir / name, Path(name), out_dir.parent / name]


def flight_inputs(flight_dir: Path, config_path: Path | None) -> list[Path]:
    """The inputs of a job on a flight folder: the folder and the config file, if any."""
    return [flight_dir] + ([] if config_path is None else [config_path])


def plot_error(exc: OSError, out_dir: Path) -> InputError:
    """The error of a figure that could not be written (e.g. no space left: the line names
    the figure, or the folder)."""
    if is_disk_full(exc):
        return write_error(exc, exc.filename or out_dir)
    return InputError(f"cannot write the plots: {exc.strerror or exc}", out_dir)


class Summary(Protocol):
    """A job's summary: a dataclass that gives the JSON it is written as."""

    def to_dict(self) -> dict[str, Any]: ...


def finite_json(obj: Any) -> Any:
    """``obj`` with every non-finite float (NaN, infinity) replaced by None (JSON null),
    recursively through dicts, lists and tuples."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [finite_json(v) for v in obj]
    return obj


def summary_json(summary: Summary | Mapping[str, Any]) -> str:
    """The text of ``summary.json`` of a job's summary, or of the mapping it already is:
    strict JSON (no NaN or Infinity: undefined values are null)."""
    data = summary if isinstance(summary, Mapping) else summary.to_dict()
    return json.dumps(finite_json(dict(data)), indent=2, allow_nan=False) + "\n"


FIT_OUTPUTS = OutputKind("fit", frozenset({
    "keyframes.txt", "turbine.yaml", "turbine.glb", "config.yaml", "summary.json", "scene.png",
    "reprojections.png", "errors.png", "cost.png", "keyframes_wgs84.csv",
    "keyframes_wgs84.csvt", "keyframes_wgs84.prj", "keyframes_wgs84.geojson"}))
TRACK_OUTPUTS = OutputKind("track", frozenset({
    "causal.txt", "keyframes.txt", "turbine.yaml", "turbine.glb", "latency.csv", "latency.png",
    "config.yaml", "summary.json", "scene.png", "errors.png", "keyframes_wgs84.csv",
    "keyframes_wgs84.csvt", "keyframes_wgs84.prj", "keyframes_wgs84.geojson"}))
#: ``detect`` writes ``<stem>.npy`` heat-maps and a ``<stem>.png`` overlay per photo.
DETECT_OUTPUTS = OutputKind("detect", None, (".npy", ".png"))
