"""The fault corpus: malformed inputs of every command, generated from one small flight.

Each :class:`Case` is a mutation of a fresh copy of a small simulated flight with photos
(:func:`make_base`) and the command line to run on it; :func:`run_case` runs it and
reports what happened (:class:`Outcome`): the exit status, the stderr lines, whether a
traceback escaped, whether it hung, whether anything was written to the output path or
left in the work folder, and whether an input changed. Every case is bad input, so the
answer must be exit status 2, one line ``turbinefit: error: ...`` matching the case's
patterns (the file or option named), no traceback, nothing written, inputs unchanged.

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

Mutation = Callable[[Path], None]


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
            if not re.match(r"turbinefit \w+: error: ", lines[0]):
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
        a = a.copy()
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


# ------------------------------------------------------------------ the cases

CAM, KF, TURB = r"camera\.yaml", r"keyframes\.txt", r"turbine\.yaml"
ODO, GT, GTT = r"odometry\.txt", r"groundtruth\.txt", r"turbine_groundtruth\.yaml"
HM = r"heatmaps/2\.000000\.npy"
PHOTO = r"images/2\.000000\.png"
BIG = 300 << 20  # a sparse file above every text limit
OK_ODOMETRY: Mutation = lambda f: shutil.copy(f / "keyframes.txt", f / "odometry.txt")  # noqa: E731


def _cases() -> list[Case]:
    c: list[Case] = []

    def add(name: str, argv: Callable[[Path], list[str]], mutate: Mutation | None,
            *patterns: str, hang: bool = False, usage: bool = False) -> None:
        c.append(Case(name, argv, mutate, patterns, hang, usage))

    # -- files that are not regular files, or too large (every reader)
    for name, pat in (("camera.yaml", CAM), ("keyframes.txt", KF), ("turbine.yaml", TURB),
                      ("groundtruth.txt", GT), ("turbine_groundtruth.yaml", GTT),
                      ("heatmaps/2.000000.npy", HM)):
        add(f"fifo-{name}", fit(), fifo(name), pat, "named pipe", hang=True)
        add(f"devzero-{name}", fit(), symlink(name, "/dev/zero"), pat, "character device")
    add("fifo-odometry.txt", fit(), fifo("odometry.txt"), ODO, "named pipe", hang=True)
    add("fifo-camera.yaml-track", track(), fifo("camera.yaml"), CAM, "named pipe", hang=True)
    add("fifo-photo", fit("--from-images"), fifo("images/2.000000.png"), PHOTO, "named pipe",
        hang=True)
    add("fifo-config", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config", "{w}/flight/c.yaml"),
        fifo("c.yaml"), r"c\.yaml", "named pipe", hang=True)
    add("devnull-model", fit("--from-images", "--model", "/dev/null"), None, r"/dev/null",
        "character device")
    for name, pat in (("camera.yaml", CAM), ("turbine.yaml", TURB), ("keyframes.txt", KF)):
        add(f"huge-{name}", fit(), sparse(name, BIG), pat, r"300 MiB, larger than the")
    add("big-camera.yaml", fit(), sparse("camera.yaml", 2 << 20), CAM, r"2 MiB, larger than the 1 MiB")
    add("dir-camera.yaml", fit(), directory("camera.yaml"), CAM, "directory")
    add("dir-heatmap", fit(), both(unlink("heatmaps/2.000000.npy"),
                                   lambda f: (f / "heatmaps/2.000000.npy").mkdir()), HM, "directory")
    add("heatmaps-is-a-file", fit(), both(unlink("heatmaps"), write("heatmaps", "x")),
        r"heatmaps", "not a directory")
    add("loop-camera.yaml", fit(), symlink("camera.yaml", "camera.yaml"), CAM, "cannot access")

    # -- missing files
    for name, pat in (("camera.yaml", CAM), ("keyframes.txt", KF), ("turbine.yaml", TURB)):
        add(f"missing-{name}", fit(), unlink(name), pat, "missing")
    add("missing-heatmap", fit(), unlink("heatmaps/2.000000.npy"), HM, r"missing", r"line 5")
    add("missing-folder", cmd("fit", "{w}/nothing", "--out", "{w}/out"), None, r"nothing",
        "not found")
    add("missing-photo", fit("--from-images"), unlink("images/2.000000.png"), r"images",
        r"no photo for keyframe 2")
    add("missing-config", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config", "{w}/no.yaml"),
        None, r"no\.yaml", "not found")

    # -- camera.yaml
    add("camera-cut-before-distortion", fit(), cut("camera.yaml", "distortion_model"), CAM,
        r"distortion_coefficients", r"cut short")
    add("camera-cut-after-model", fit(), cut("camera.yaml", "distortion_coefficients"), CAM,
        r"distortion_coefficients", "missing")
    add("camera-3-coefficients", fit(),
        camera(lambda d: d["distortion_coefficients"].update(cols=3, data=[0.1, 0.0, 0.0])),
        CAM, r"3 distortion coefficients")
    add("camera-rational-5", fit(), camera(lambda d: d.update(distortion_model="rational_polynomial")),
        CAM, r"has 0 or 8")
    add("camera-equidistant", fit(), camera(lambda d: d.update(distortion_model="equidistant")),
        CAM, r"unsupported distortion model")
    add("camera-distortion-1e6", fit(),
        camera(lambda d: d["distortion_coefficients"]["data"].__setitem__(0, 1e6)), CAM,
        r"coefficient 0 is 1000000\.0")
    add("camera-skew-1e12", fit(), camera(k_entry(1, 1e12)), CAM, r"skew 1000000000000\.0")
    add("camera-fx-zero", fit(), camera(k_entry(0, 0.0)), CAM, r"got 0\.0")
    add("camera-fx-negative", fit(), camera(k_entry(0, -50.0)), CAM, r"got -50\.0")
    add("camera-fx-1e9", fit(), camera(k_entry(0, 1e9)), CAM, r"not a focal length")
    add("camera-fy-tiny", fit(), camera(k_entry(4, 0.5)), CAM, r"fy / fx")
    add("camera-cx-far", fit(), camera(k_entry(2, 1e6)), CAM, r"principal point cx")
    add("camera-cy-far", fit(), camera(k_entry(5, -1e6)), CAM, r"principal point cy")
    add("camera-fx-nan", fit(), sub("camera.yaml", r"data: \[[0-9.]+,", "data: [.nan,"), CAM,
        r"finite")
    add("camera-width-7", fit(), camera(lambda d: d.update(image_width=7)), CAM, r"7x48 px")
    add("camera-width-huge", fit(), camera(lambda d: d.update(image_width=10**7)), CAM,
        r"200 MP limit")
    add("camera-width-text", fit(), camera(lambda d: d.update(image_width="wide")), CAM,
        r"not a number")
    add("camera-width-float", fit(), camera(lambda d: d.update(image_width=64.5)), CAM,
        r"integer")
    add("camera-K-2x3", fit(), camera(lambda d: d["camera_matrix"].update(rows=2, cols=3,
                                                                         data=[1] * 6)),
        CAM, r"3x3")
    add("camera-K-rows-mismatch", fit(), camera(lambda d: d["camera_matrix"].update(rows=4)),
        CAM, r"rows \* cols")
    add("camera-K-bottom-row", fit(), camera(k_entry(8, 2.0)), CAM, r"not a camera matrix")
    add("camera-no-matrix", fit(), camera(lambda d: d.pop("camera_matrix")), CAM, r"missing")
    add("camera-duplicate-key", fit(), write("camera.yaml", "image_width: 64\nimage_width: 64\n"),
        CAM, r"duplicate key")
    add("camera-malformed", fit(), write("camera.yaml", "image_width: [64\n"), CAM, r"invalid YAML")
    add("camera-empty", fit(), write("camera.yaml", ""), CAM, r"empty")
    add("camera-list", fit(), write("camera.yaml", "- 1\n"), CAM, r"mapping")
    add("camera-not-utf8", fit(), write("camera.yaml", b"\xff\xfe\x00"), CAM, r"UTF-8")
    add("camera-model-not-string", fit(), camera(lambda d: d.update(distortion_model=5)), CAM,
        r"distortion_model", r"string")

    # -- keyframes.txt and the other trajectories
    add("tum-translation-1e300", fit(), tum("keyframes.txt", 2, column(1, "1e300")), KF + r":5:",
        r"tx = 1e300 m is beyond")
    add("tum-translation-1e9", fit(), tum("keyframes.txt", 4, column(3, "-1e9")), KF + r":7:",
        r"tz")
    add("tum-timestamp-1e300", fit(), tum("keyframes.txt", 5, column(0, "1e300")), KF + r":8:",
        r"timestamp 1e300")
    add("tum-columns", fit(), tum("keyframes.txt", 1, lambda t: t[:-1]), KF + r":4:",
        r"expected 8 columns")
    add("tum-nine-columns", fit(), tum("keyframes.txt", 1, lambda t: [*t, "0"]), KF, r"got 9")
    add("tum-zero-quaternion", fit(), tum("keyframes.txt", 2, lambda t: t[:4] + ["0"] * 4),
        KF + r":5:", r"zero norm")
    add("tum-long-quaternion", fit(), tum("keyframes.txt", 2, lambda t: t[:4] + ["1"] * 4),
        KF + r":5:", r"norm 2")
    add("tum-nan", fit(), tum("keyframes.txt", 3, column(2, "nan")), KF + r":6:", r"non-finite")
    add("tum-inf", fit(), tum("keyframes.txt", 3, column(2, "-inf")), KF + r":6:", r"non-finite")
    add("tum-text", fit(), tum("keyframes.txt", 3, column(2, "one")), KF + r":6:", r"not a number")
    add("tum-underscore", fit(), tum("keyframes.txt", 3, column(2, "1_0")), KF, r"not a number")
    add("tum-order", fit(), tum("keyframes.txt", 3, column(0, "0.5")), KF + r":6:", r"not after")
    add("tum-duplicate-time", fit(), tum("keyframes.txt", 3, column(0, "1.0")), KF, r"not after")
    add("tum-empty", fit(), write("keyframes.txt", "# nothing\n"), KF, r"no poses")
    add("tum-not-utf8", fit(), write("keyframes.txt", b"0 \xff\n"), KF, r"UTF-8")
    add("tum-extra-keyframe", fit(),
        both(sub("keyframes.txt", r"\Z", "6.000000 0 0 0 0 0 0 1\n"), unlink("groundtruth.txt")),
        r"heatmaps/6\.000000\.npy",
        r"missing")
    add("odometry-shifted", fit(), both(OK_ODOMETRY, tum("odometry.txt", 2, column(0, "1.5"))),
        ODO + r":5:", r"differs from keyframe 2")
    add("odometry-short", fit(), both(OK_ODOMETRY, sub("odometry.txt", r"^5\.000000 .*\n", "")),
        ODO, r"5 poses but keyframes\.txt has 6")
    add("odometry-bad-line", fit(), both(OK_ODOMETRY, tum("odometry.txt", 1, lambda t: t[:3])),
        ODO + r":4:", r"columns")
    add("odometry-1e300", fit(), both(OK_ODOMETRY, tum("odometry.txt", 1, column(2, "1e300"))),
        ODO + r":4:", r"ty")
    add("groundtruth-shifted", fit(), tum("groundtruth.txt", 3, column(0, "2.5")), GT,
        r"2\.5 differs")
    add("groundtruth-short", fit(), sub("groundtruth.txt", r"^5\.000000 .*\n", ""), GT,
        r"5 poses")
    add("groundtruth-1e300", fit(), tum("groundtruth.txt", 3, column(1, "1e300")), GT + r":6:",
        r"beyond")
    add("track-tum-1e300", track(), tum("keyframes.txt", 2, column(1, "1e300")), KF + r":5:",
        r"beyond")

    # -- turbine.yaml and turbine_groundtruth.yaml
    for key, value, pat in (("tower_height", "1e300", r"1e\+300 m is beyond"),
                            ("blade_length", "5000", r"5000\.0 m is beyond the plausible 1000"),
                            ("nacelle_length", "2e3", r"beyond"),
                            ("base_x", "-1e300", r"beyond"), ("heading", "1e300", r"rad"),
                            ("blade_rotation", "-1e5", r"rad"),
                            ("tower_height", "-5", r"> 0, got -5\.0"),
                            ("blade_length", "0", r"> 0, got 0\.0"),
                            ("nacelle_length", "-1", r">= 0"),
                            ("tower_height", ".nan", r"finite"), ("heading", "north", r"number"),
                            ("base_y", "[1, 2]", r"number"), ("base_y", "null", r"number")):
        add(f"turbine-{key}-{value}", fit(), sub("turbine.yaml", rf"^{key}:.*$", f"{key}: {value}"),
            TURB + rf" \[{key}\]", pat)
    add("turbine-missing-key", fit(), sub("turbine.yaml", r"^heading:.*$", ""), TURB, r"missing")
    add("turbine-unknown-key", fit(), sub("turbine.yaml", r"\Z", "rotor: 3\n"), TURB,
        r"unknown key")
    add("turbine-duplicate-key", fit(), sub("turbine.yaml", r"\Z", "heading: 3\n"), TURB,
        r"duplicate key")
    add("turbine-malformed", fit(), sub("turbine.yaml", r"^heading:.*$", "heading: [1"), TURB,
        r"invalid YAML")
    add("turbine-gt-1e300", fit(), sub("turbine_groundtruth.yaml", r"^tower_height:.*$",
                                       "tower_height: 1e300"), GTT, r"beyond")
    add("track-turbine-1e300", track(), sub("turbine.yaml", r"^tower_height:.*$",
                                            "tower_height: 1e300"), TURB, r"beyond")

    # -- heat-maps
    for value, pat in ((1.5, r"holds 1\.5, outside \[0, 1\]"), (-1.0, r"holds -1\.0"),
                       (1e30, r"outside"), (np.inf, r"holds inf"), (-np.inf, r"holds -inf"),
                       (np.nan, r"NaN"), (1.002, r"1\.00")):
        add(f"heatmap-value-{value}", fit(), npy(2, set_value(5, value)), HM,
            r"channel 5 \(line_nacelle\)", pat)
    add("heatmaps-all-minus-1", fit(), npy(None, lambda a: np.full_like(a, -1.0)),
        r"heatmaps/0\.000000\.npy", r"holds -1\.0")
    add("heatmaps-all-255", fit(), npy(None, lambda a: a * 255), r"heatmaps/0\.000000\.npy",
        r"outside \[0, 1\]")
    add("track-heatmap-value", track(), npy(2, set_value(0, 2.0)), HM, r"point_base")
    add("heatmap-shape", fit(), npy(2, lambda a: a[:, ::2, ::2].copy()), HM,
        r"shape \(7, 24, 32\), expected \(7, 48, 64\)")
    add("heatmap-channels", fit(), npy(2, lambda a: a[:6].copy()), HM, r"shape \(6, 48, 64\)")
    add("heatmap-2d", fit(), npy(0, lambda a: a[0].copy()), r"heatmaps/0\.000000\.npy",
        r"expected \(7, height, width\)")
    add("heatmaps-tiny", fit(), npy(None, lambda a: a[:, :10, :12].copy()),
        r"heatmaps/0\.000000\.npy", r"12x10 px; each side must be at least 24")
    add("heatmaps-not-a-scale", fit(), npy(None, lambda a: a[:, :, :40].copy()),
        r"heatmaps/0\.000000\.npy", r"do not fit the photos")
    add("heatmap-float64", fit(), npy(2, lambda a: a.astype(np.float64)), HM, r"dtype <f8")
    add("heatmap-big-endian", fit(), npy(2, lambda a: a.astype(">f4")), HM, r"dtype >f4")
    add("heatmap-fortran", fit(), npy(2, np.asfortranarray), HM, r"Fortran")
    add("heatmap-text", fit(), write("heatmaps/2.000000.npy", "hello"), HM, r"not a \.npy")
    add("heatmap-truncated", fit(), lambda f: (f / "heatmaps/2.000000.npy").write_bytes(
        (f / "heatmaps/2.000000.npy").read_bytes()[:500]), HM, r"truncated")
    add("heatmap-bad-header", fit(), lambda f: (f / "heatmaps/2.000000.npy").write_bytes(
        b"\x93NUMPY\x01\x00\x10\x00{'descr': <f4}  \n"), HM, r"header")
    add("heatmap-version-9", fit(), lambda f: (f / "heatmaps/2.000000.npy").write_bytes(
        b"\x93NUMPY\x09\x00" + b"\0" * 100), HM, r"version")
    add("heatmaps-missing-dir", fit(), both(unlink("heatmaps"), unlink("images")), r"heatmaps",
        r"missing")

    # -- photos (fit from images)
    add("photo-30000px", fit("--from-images"), write("images/2.000000.png", png_header(30000, 30000)),
        PHOTO, r"30000x30000 px \(900 MP\), more than the 200 MP limit")
    add("photo-100000px", fit("--from-images"),
        write("images/2.000000.png", png_header(100000, 100000)), PHOTO, r"200 MP limit")
    add("photo-size-mismatch", fit("--from-images"),
        write("images/2.000000.png", png_header(128, 96)), PHOTO, r"128x96 but camera\.yaml is 64x48")
    add("photo-not-an-image", fit("--from-images"), write("images/2.000000.png", "text"), PHOTO,
        r"not an image")
    add("photo-devzero", fit("--from-images"), symlink("images/2.000000.png", "/dev/zero"), PHOTO,
        r"character device")
    add("model-missing", fit("--from-images", "--model", "/nonexistent.onnx"), None,
        r"nonexistent\.onnx", r"not found")

    # -- fit and track options and config files
    add("config-devzero", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config", "/dev/zero"),
        None, r"/dev/zero", r"character device")
    add("config-huge", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config", "{w}/flight/c.yaml"),
        both(write("c.yaml", "mode: joint\n"), sparse("c.yaml", 2 << 20)), r"c\.yaml", r"1 MiB")
    add("config-unknown", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config", "{w}/flight/c.yaml"),
        write("c.yaml", "bogus: 1\n"), r"c\.yaml", r"bogus")
    add("config-bad-value", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config",
                                "{w}/flight/c.yaml"),
        write("c.yaml", "max_iterations: 0\n"), r"max_iterations")
    add("config-nan", cmd("fit", "{w}/flight", "--out", "{w}/out", "--config", "{w}/flight/c.yaml"),
        write("c.yaml", "lambda_pair: .nan\n"), r"lambda_pair")
    for opts, pat in ((["--preset", "nope"], r"--preset"), (["--max-iterations", "0"], r">= 1"),
                      (["--pixel-sigma", "-1"], r"pixel_sigma"),
                      (["--lambda-points", "nan"], r"lambda_points"),
                      (["--points", "none", "--lines", "none"], r"both be none")):
        add(f"fit-option-{'-'.join(opts)}", fit(*opts), None, pat)
    add("fit-out-is-input", cmd("fit", "{w}/flight", "--out", "{w}/flight"), None, r"input")
    add("fit-out-in-file", cmd("fit", "{w}/flight", "--out", "{w}/camera.yaml/x"),
        lambda f: (f.parent / "camera.yaml").write_text("x"), r"camera\.yaml", r"not a directory")
    add("track-option-window", track("--window", "1"), None, r"window")

    # -- simulate options
    # the last ones argparse's own types refuse (its usage, then one error line)
    for opts, pat, usage in ((["--keyframes", "100000000000"], r"at most 1000000", False),
                             (["--width", "100000", "--height", "100000"], r"200 MP limit", False),
                             (["--width", "7"], r"7x240 px", False),
                             (["--height", "10"], r"320x10 px", False),
                             (["--heatmap-size", "20"], r"20x15 px", False),
                             (["--heatmap-size", "16x12"], r"16x12 px", False),
                             (["--heatmap-size", "100x10"], r"heatmap", False),
                             (["--width", "8000", "--height", "240"], r"320x10", False),
                             (["--keyframes", "900000"], r"need about .* of memory", False),
                             (["--width", "20000", "--height", "9999", "--images"], r"memory",
                              False),
                             (["--preset", "nope"], r"--preset", False),
                             (["--turbine", "nope"], r"turbine", False),
                             (["--drift-m", "nan"], r"drift", False),
                             (["--heatmap-noise", "-1"], r"--heatmap-noise", False),
                             (["--heatmap-size", "axb"], r"WIDTHxHEIGHT", True),
                             (["--keyframes", "0"], r"keyframes", True),
                             (["--seed", "-1"], r"seed", True),
                             (["--width", "-3"], r"--width", True)):
        add(f"simulate-{'-'.join(opts)}", simulate(*opts), None, pat, usage=usage)

    # -- detect, evaluate, report
    add("detect-fifo", cmd("detect", "{w}/flight/images/2.000000.png", "--out", "{w}/out",
                           "--quiet"), fifo("images/2.000000.png"), PHOTO, r"named pipe",
        hang=True)
    add("detect-huge", cmd("detect", "{w}/flight/images", "--out", "{w}/out", "--quiet"),
        write("images/2.000000.png", png_header(30000, 30000)), PHOTO, r"200 MP limit")
    add("detect-tiny", cmd("detect", "{w}/flight/images/2.000000.png", "--out", "{w}/out",
                           "--quiet"),
        write("images/2.000000.png", png_header(20, 20)), PHOTO, r"at least 24")
    add("detect-elongated", cmd("detect", "{w}/flight/images/2.000000.png", "--out", "{w}/out",
                                "--quiet"),
        write("images/2.000000.png", png_header(4000, 30)), PHOTO, r"heat-maps of 160x1 px")
    add("detect-missing", cmd("detect", "{w}/flight/nothing.png", "--out", "{w}/out", "--quiet"),
        None, r"nothing\.png")
    add("detect-model-fifo", cmd("detect", "{w}/flight/images", "--out", "{w}/out", "--quiet",
                                 "--model", "{w}/flight/m.onnx"), fifo("m.onnx"), r"m\.onnx",
        r"named pipe", hang=True)
    add("detect-model-not-onnx", cmd("detect", "{w}/flight/images", "--out", "{w}/out", "--quiet",
                                     "--model", "{w}/flight/camera.yaml"), None, r"camera\.yaml",
        r"ONNX")
    add("evaluate-labels-fifo", cmd("evaluate", "--labels", "{w}/flight/l.json", "--images-dir",
                                    "{w}/flight/images", "--quiet"), fifo("l.json"), r"l\.json",
        r"named pipe", hang=True)
    add("evaluate-labels-devzero", cmd("evaluate", "--labels", "/dev/zero", "--images-dir",
                                       "{w}/flight/images", "--quiet"), None, r"/dev/zero",
        r"character device")
    add("evaluate-labels-not-json", cmd("evaluate", "--labels", "{w}/flight/camera.yaml",
                                        "--images-dir", "{w}/flight/images", "--quiet"), None,
        r"camera\.yaml", r"JSON")
    add("report-rows-fifo", cmd("report", "{w}/flight/exp"),
        both(write("exp/sweep.yaml", "study: unary\n"), fifo("exp/rows.csv")), r"exp",
        hang=True)
    add("report-missing", cmd("report", "{w}/flight/nothing"), None, r"nothing")
    return c


CASES: list[Case] = _cases()
