"""The fault corpus: malformed inputs of every command, generated from one small flight.

The cases are in ``tests/fault_cases.py``; this module runs them. Each :class:`Case` is
a mutation of a fresh copy of a small simulated flight with photos (:func:`make_base`) and
the command line to run on it; :func:`run_case` runs it and reports what happened
(:class:`Outcome`): the exit status, the stderr lines, whether a traceback escaped,
whether it hung, whether anything was written to the output path or left in the work
folder, and whether an input changed. Every case is bad input, so the answer must be exit
status 2, one line ``turbinefit: error: ...`` matching the case's patterns (the file or
option named), no traceback, nothing written, inputs unchanged.

``tests/cli/test_fault_corpus.py`` asserts that on every case;
``benchmarks/bench_faults.py`` counts tracebacks, hangs, silent accepts and files left
behind over the whole corpus. Cases that could hang (named pipes) run in a subprocess with
a timeout; the others in-process through :func:`turbinefit.cli.main`.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import re
import shutil
import struct
import subprocess
import sys
import traceback
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

#: ``turbinefit simulate`` options of the corpus's base flight: 6 keyframes at t = 0..5 s,
#: 64 x 48 photos and heat-maps.
BASE_ARGS = ["--keyframes", "6", "--seed", "1", "--width", "64", "--height", "48", "--images"]
#: Seconds a subprocess case may take before it counts as a hang.
HANG_TIMEOUT = 60.0
#: keyframes.txt as simulate writes it: two comment lines, then keyframe k on line k + 3.
FIRST_POSE_LINE = 3

#: Changes a copy of a flight folder in place; what it returns is ignored.
Mutation = Callable[[Path], object]


@dataclass(frozen=True)
class Case:
    """One bad input: ``mutate`` the flight copy ``work/flight``, run ``argv(work)`` (the
    output path is ``work/out``), expect one error line matching every regex of
    ``patterns``. ``subprocess``: the input could make a reader hang (a FIFO). ``usage``:
    the command line itself is wrong, so argparse answers (its usage, then one error line;
    exit status 2)."""

    name: str
    argv: Callable[[Path], list[str]]
    mutate: Mutation | None = None
    patterns: tuple[str, ...] = ()
    subprocess: bool = False
    usage: bool = False


@dataclass
class Outcome:
    """What running a case did."""

    status: int | None
    stderr: str
    stdout: str
    traceback: bool = False
    hung: bool = False
    written: list[str] = field(default_factory=list)  # entries added to the work folder
    changed: list[str] = field(default_factory=list)  # input files changed or removed

    @property
    def accepted(self) -> bool:
        return self.status == 0

    def problems(self, case: Case) -> list[str]:
        """Why this outcome is not the one-line refusal the case expects (empty: fine)."""
        out = []
        if self.hung:
            out.append("hung")
        if self.traceback:
            out.append("traceback")
        if self.accepted:
            out.append("accepted silently (exit 0)")
        elif self.status != 2 and not self.hung:
            out.append(f"exit status {self.status}")
        lines = self.stderr.splitlines()
        if case.usage and lines and lines[0].startswith("usage: turbinefit"):
            lines = lines[-1:]  # argparse: usage lines, then "turbinefit CMD: error: ..."
            if not re.match(r"turbinefit \w+( \w+)?: error: ", lines[0]):
                out.append(f"not a usage error: {lines!r}")
        elif not self.hung and (len(lines) != 1 or not lines[0].startswith("turbinefit: error: ")):
            out.append(f"stderr is not one error line: {lines!r}")
        elif lines:
            out += [f"{p!r} not in {lines[0]!r}" for p in case.patterns
                    if not re.search(p, lines[0])]
        if self.stdout:
            out.append(f"stdout: {self.stdout!r}")
        if self.written:
            out.append(f"left behind: {self.written}")
        if self.changed:
            out.append(f"inputs changed: {self.changed}")
        return out


# ------------------------------------------------------------------ the base flight


def make_base(folder: Path) -> Path:
    """The base flight ``folder/flight`` (``simulate`` with :data:`BASE_ARGS`)."""
    from turbinefit.cli import main

    flight = folder / "flight"
    assert main(["simulate", str(flight), *BASE_ARGS, "--quiet"]) == 0
    return flight


def _snapshot(work: Path) -> dict[str, str]:
    """{relative path: sha256 or link target} of everything under ``work`` (no FIFO or
    device is opened)."""
    out = {}
    for p in sorted(work.rglob("*")):
        rel = str(p.relative_to(work))
        if p.is_symlink():
            out[rel] = "-> " + os.readlink(p)
        elif p.is_file() and p.stat().st_size > 16 << 20:  # the sparse files: no reading
            out[rel] = f"{p.stat().st_size} bytes, mtime {p.stat().st_mtime_ns}"
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[rel] = "dir" if p.is_dir() else "special"
    return out


def prepare(case: Case, base: Path, work: Path) -> None:
    """``work/flight``: a copy of ``base`` mutated by the case."""
    shutil.copytree(base, work / "flight", symlinks=True)
    if case.mutate is not None:
        case.mutate(work / "flight")


def run_case(case: Case, base: Path, work: Path) -> Outcome:
    """Run ``case`` in the empty folder ``work`` (see the module docstring)."""
    prepare(case, base, work)
    before = _snapshot(work)
    argv = [str(a) for a in case.argv(work)]
    if case.subprocess:
        outcome = _run_subprocess(argv)
    else:
        outcome = _run_in_process(argv)
    after = _snapshot(work)
    outcome.written = sorted(set(after) - set(before))
    outcome.changed = sorted(k for k in before if after.get(k) != before[k])
    return outcome


def _run_in_process(argv: list[str]) -> Outcome:
    from turbinefit.cli import main

    out, err = io.StringIO(), io.StringIO()
    tb = False
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            status: int | None = main(argv)
        except SystemExit as e:  # argparse
            status = e.code if isinstance(e.code, int) else 1
        except BaseException:
            traceback.print_exc()
            status, tb = None, True
    text = err.getvalue()
    return Outcome(status, text, out.getvalue(), traceback=tb or "Traceback" in text)


def _run_subprocess(argv: list[str]) -> Outcome:
    env = dict(os.environ)
    src = str(Path(__file__).resolve().parents[1] / "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    try:
        proc = subprocess.run([sys.executable, "-m", "turbinefit.cli", *argv], env=env,
                              capture_output=True, text=True, timeout=HANG_TIMEOUT,
                              stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired as e:
        return Outcome(None, str(e.stderr or ""), str(e.stdout or ""), hung=True)
    return Outcome(proc.returncode, proc.stderr, proc.stdout,
                   traceback="Traceback" in proc.stderr)


# ------------------------------------------------------------------ command lines


def fit(*extra: str) -> Callable[[Path], list[str]]:
    return lambda w: ["fit", str(w / "flight"), "--out", str(w / "out"), "--no-plots",
                      "--quiet", *extra]


def track(*extra: str) -> Callable[[Path], list[str]]:
    return lambda w: ["track", str(w / "flight"), "--out", str(w / "out"), "--no-plots",
                      "--quiet", *extra]


def simulate(*extra: str) -> Callable[[Path], list[str]]:
    return lambda w: ["simulate", str(w / "out"), "--quiet", *extra]


def cmd(*args: str) -> Callable[[Path], list[str]]:
    """Any command line; ``{w}`` in an argument is the work folder."""
    return lambda w: [a.format(w=w) for a in args]


# ------------------------------------------------------------------ mutations


def write(name: str, data: bytes | str) -> Mutation:
    def m(f: Path) -> None:
        p = f / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        elif p.exists() or p.is_symlink():
            p.unlink()
        p.write_bytes(data.encode() if isinstance(data, str) else data)
    return m


def unlink(name: str) -> Mutation:
    def m(f: Path) -> None:
        p = f / name
        shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()
    return m


def fifo(name: str) -> Mutation:
    def m(f: Path) -> None:
        p = f / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if p.exists():
            p.unlink()
        os.mkfifo(p)
    return m


def symlink(name: str, target: str) -> Mutation:
    def m(f: Path) -> None:
        p = f / name
        if p.exists() or p.is_symlink():
            p.unlink()
        p.symlink_to(target)
    return m


def directory(name: str) -> Mutation:
    def m(f: Path) -> None:
        (f / name).unlink()
        (f / name).mkdir()
    return m


def sparse(name: str, size: int) -> Mutation:
    """Grow the file to ``size`` bytes with a hole (fast, takes no disk)."""
    def m(f: Path) -> None:
        with open(f / name, "r+b") as fh:
            fh.truncate(size)
    return m


def sub(name: str, pattern: str, new: str) -> Mutation:
    def m(f: Path) -> None:
        text = (f / name).read_text()
        assert re.search(pattern, text, re.M), (name, pattern)
        (f / name).write_text(re.sub(pattern, new, text, count=1, flags=re.M))
    return m


def cut(name: str, before: str) -> Mutation:
    """Cut the file off where the line starting with ``before`` begins."""
    def m(f: Path) -> None:
        text = (f / name).read_text()
        (f / name).write_text(text[:text.index("\n" + before) + 1])
    return m


def camera(edit: Callable[[dict], object]) -> Mutation:
    def m(f: Path) -> None:
        data = yaml.safe_load((f / "camera.yaml").read_text())
        edit(data)
        (f / "camera.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    return m


def k_entry(i: int, value: object) -> Callable[[dict], object]:
    return lambda d: d["camera_matrix"]["data"].__setitem__(i, value)


def tum(name: str, k: int, edit: Callable[[list[str]], list[str]]) -> Mutation:
    def m(f: Path) -> None:
        lines = (f / name).read_text().splitlines()
        i = FIRST_POSE_LINE + k - 1  # 0-based index of line k + 3, keyframe k
        lines[i] = " ".join(edit(lines[i].split()))
        (f / name).write_text("\n".join(lines) + "\n")
    return m


def column(i: int, value: str) -> Callable[[list[str]], list[str]]:
    return lambda t: [*t[:i], value, *t[i + 1:]]


def npy(k: int | None, make: Callable[[np.ndarray], np.ndarray]) -> Mutation:
    """Rewrite the heat-maps of keyframe ``k`` (None: of every keyframe) as make(maps)."""
    def m(f: Path) -> None:
        for p in sorted((f / "heatmaps").glob("*.npy")):
            if k is None or p.name == f"{float(k):.6f}.npy":
                np.save(p, make(np.load(p)))
    return m


def set_value(c: int, value: float) -> Callable[[np.ndarray], np.ndarray]:
    def make(a: np.ndarray) -> np.ndarray:
        a = a.astype(np.float32)  # a copy; float16 cannot hold every bad value
        a[c, 3, 4] = value
        return a
    return make


def png_header(width: int, height: int) -> bytes:
    """A PNG that claims ``width`` x ``height`` pixels (its data is a few bytes)."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(
            ">I", zlib.crc32(kind + body))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
            + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))


def both(*ms: Mutation) -> Mutation:
    def m(f: Path) -> None:
        for x in ms:
            x(f)
    return m
