"""``turbinefit fit`` on bad input: broken flight folders, unusable output folders,
permissions, bad configuration files and options. Each is one error line, exit status 2,
and nothing written."""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml
from support import assert_one_line_error, digest, entries, heatmap, run

# keyframes.txt as simulate writes it: a comment, the column header, then keyframe k on line k + 3
FIRST_POSE_LINE = 3


def edit_line(path: Path, lineno: int, edit: Callable[[list[str]], list[str]]) -> None:
    """Replace whitespace-separated line ``lineno`` (1-based) of a text file by edit(tokens)."""
    lines = path.read_text().splitlines()
    lines[lineno - 1] = " ".join(edit(lines[lineno - 1].split()))
    path.write_text("\n".join(lines) + "\n")


def _missing_folder(f: Path) -> Path:
    return f.parent / "no_such_flight"


def _unlink(name: str) -> Callable[[Path], None]:
    return lambda f: (f / name).unlink()


def _no_turbine_no_tips(f: Path) -> None:
    """No turbine.yaml, and no blade tip in any heat-map."""
    (f / "turbine.yaml").unlink()
    for p in (f / "heatmaps").glob("*.npy"):
        m = np.load(p)
        m[3] = 0.0
        np.save(p, m)


def _tum(k: int, edit: Callable[[list[str]], list[str]]) -> Callable[[Path], None]:
    """Edit the line of keyframe ``k`` in keyframes.txt."""
    return lambda f: edit_line(f / "keyframes.txt", FIRST_POSE_LINE + k, edit)


def _scale_quat(tokens: list[str], s: float) -> list[str]:
    return tokens[:4] + [repr(float(x) * s) for x in tokens[4:]]


def _save_heatmap(k: int, make: Callable[[np.ndarray], np.ndarray]) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        path = heatmap(f, k)
        np.save(path, make(np.load(path)))
    return mutate


def _all_nan(a: np.ndarray) -> np.ndarray:
    return np.full_like(a, np.nan)


def _camera_fx(value: float) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        data = yaml.safe_load((f / "camera.yaml").read_text())
        data["camera_matrix"]["data"][0] = value
        (f / "camera.yaml").write_text(yaml.safe_dump(data))
    return mutate


def _append(name: str, text: str) -> Callable[[Path], None]:
    return lambda f: (f / name).write_text((f / name).read_text() + text)


def _replace_in(name: str, old: str, new: str) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        text = (f / name).read_text()
        assert re.search(old, text, re.M)
        (f / name).write_text(re.sub(old, new, text, count=1, flags=re.M))
    return mutate


def _drop_last_line(name: str) -> Callable[[Path], None]:
    def mutate(f: Path) -> None:
        lines = (f / name).read_text().splitlines()
        (f / name).write_text("\n".join(lines[:-1]) + "\n")
    return mutate


KF = r"keyframes\.txt"


BAD_FLIGHTS: dict[str, tuple[Callable[[Path], object], list[str]]] = {
    "missing-folder": (_missing_folder, [r"no_such_flight", r"not found"]),
    "missing-camera": (_unlink("camera.yaml"), [r"camera\.yaml", r"missing"]),
    # without turbine.yaml fit estimates it: heat-maps without blade tips cannot give one
    "missing-turbine-no-tips": (_no_turbine_no_tips,
                                [r"flight: cannot determine blade_length", r"--type"]),
    "tum-columns": (_tum(4, lambda t: t[:-1]), [KF + r":7:", r"expected 8 columns", r"got 7"]),
    "tum-zero-quaternion": (_tum(2, lambda t: _scale_quat(t, 0.0)), [KF + r":5:", r"zero norm"]),
    "tum-non-unit-quaternion": (_tum(3, lambda t: _scale_quat(t, 1.5)), [KF + r":6:", r"norm 1\.5"]),
    "tum-nan": (_tum(5, lambda t: [t[0], "nan", *t[2:]]), [KF + r":8:", r"non-finite", r"nan"]),
    "tum-not-a-number": (_tum(1, lambda t: [t[0], "1,5", *t[2:]]), [KF + r":4:", r"not a number"]),
    "tum-timestamp-order": (_tum(1, lambda t: ["0.0", *t[1:]]), [KF + r":4:", r"not after"]),
    "groundtruth-short": (_drop_last_line("groundtruth.txt"),
                          [r"groundtruth\.txt", r"11 poses", r"keyframes\.txt has 12"]),
    "heatmap-missing": (_unlink("heatmaps/3.000000.npy"),
                        [r"heatmaps/3\.000000\.npy", r"missing", r"keyframes\.txt, line 6"]),
    "heatmap-shape": (_save_heatmap(2, lambda a: a[:, ::2, ::2].copy()),
                      [r"heatmaps/2\.000000\.npy", r"shape \(7, 60, 80\)", r"\(7, 120, 160\)"]),
    "heatmap-dtype": (_save_heatmap(4, lambda a: a.astype(np.float64)),
                      [r"heatmaps/4\.000000\.npy", r"dtype", r"float32"]),
    "heatmap-nan": (_save_heatmap(5, _all_nan), [r"heatmaps/5\.000000\.npy", r"NaN"]),
    "heatmap-not-npy": (lambda f: heatmap(f, 6).write_text("hello"),
                        [r"heatmaps/6\.000000\.npy", r"not a \.npy"]),
    "camera-fx-zero": (_camera_fx(0.0), [r"camera\.yaml", r"camera_matrix", r"fx must be positive"]),
    "camera-fx-negative": (_camera_fx(-100.0), [r"camera\.yaml", r"fx must be positive", r"-100"]),
    "turbine-malformed-yaml": (_replace_in("turbine.yaml", r"^tower_height:.*$", "tower_height: [86.0"),
                               [r"turbine\.yaml:\d+:", r"invalid YAML"]),
    "turbine-unknown-key": (_append("turbine.yaml", "rotor_diameter: 120.0\n"),
                            [r"turbine\.yaml \[rotor_diameter\]", r"unknown key"]),
    "turbine-missing-key": (_replace_in("turbine.yaml", r"^blade_length:.*$", ""),
                            [r"turbine\.yaml \[blade_length\]", r"missing"]),
    "turbine-negative-height": (_replace_in("turbine.yaml", r"^tower_height:.*$", "tower_height: -5"),
                                [r"turbine\.yaml \[tower_height\]", r"> 0"]),
}


@pytest.mark.parametrize("quiet", [True, False], ids=["quiet", "verbose"])
@pytest.mark.parametrize("case", list(BAD_FLIGHTS))
def test_fit_bad_flight(case: str, quiet: bool, flight_copy: Path, tmp_path: Path,
                        capsys: pytest.CaptureFixture[str]) -> None:
    mutate, patterns = BAD_FLIGHTS[case]
    result = mutate(flight_copy)
    target = result if isinstance(result, Path) else flight_copy
    before = digest(flight_copy)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(target), "--out", str(out_dir), "--no-plots",
                       *(["--quiet"] if quiet else []))
    assert_one_line_error(rc, out, err, *patterns)
    assert not out_dir.exists()
    assert entries(tmp_path) == ["flight"]  # no temporary output left behind
    assert digest(flight_copy) == before


@pytest.mark.parametrize(("where", "overwrite"), [
    ("same", False), ("same", True), ("inside", False), ("parent", True)])
def test_fit_refuses_output_over_its_input(where: str, overwrite: bool, flight_copy: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out_dir = {"same": flight_copy, "inside": flight_copy / "fit", "parent": tmp_path}[where]
    before = digest(flight_copy)
    rc, out, err = run(capsys, "fit", str(flight_copy), "--out", str(out_dir), "--no-plots", "--quiet",
                       *(["--overwrite"] if overwrite else []))
    assert_one_line_error(rc, out, err, re.escape(str(out_dir)), r"input")
    assert digest(flight_copy) == before
    assert entries(tmp_path) == ["flight"]


def test_fit_out_is_an_existing_file(sim_flight_dir: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "afile"
    dest.write_text("x")
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(dest), "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)))
    assert dest.read_text() == "x"


def test_fit_out_under_an_existing_file(sim_flight_dir: Path, tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    import turbinefit.jobs.fit

    def fail(*args: object, **kwargs: object) -> None:
        raise AssertionError("read the flight although --out is unusable")

    monkeypatch.setattr(turbinefit.jobs.fit, "read_flight_folder", fail)  # refused before any work
    dest = tmp_path / "afile"
    dest.write_text("x")
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(dest / "sub" / "fit"),
                       "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(dest)), r"not a directory")
    assert dest.read_text() == "x"
    assert entries(tmp_path) == ["afile"]


def test_fit_out_is_a_symlink_loop(sim_flight_dir: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(loop), "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(loop)), r"[Ss]ymlink loop")
    assert loop.is_symlink()


def test_fit_out_parent_not_writable(sim_flight_dir: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # as root, a chmod does not deny anything: make os.access say what it says to a user
    import turbinefit.io.atomic

    real_access = os.access
    parent = tmp_path / "readonly"
    parent.mkdir()

    def access(path: object, mode: int, **kwargs: object) -> bool:
        if Path(str(path)) == parent:
            return False
        return real_access(path, mode, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(turbinefit.io.atomic.os, "access", access)
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(parent / "new" / "fit"),
                       "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(parent)), r"no permission")
    assert entries(tmp_path) == ["readonly"] and entries(parent) == []


def _permissions_apply(folder: Path) -> bool:
    """Whether a mode-000 file is unreadable here (not for root with CAP_DAC_OVERRIDE)."""
    probe = folder / ".probe"
    probe.write_text("x")
    probe.chmod(0)
    try:
        probe.read_text()
    except PermissionError:
        return True
    else:
        return False
    finally:
        probe.chmod(0o600)
        probe.unlink()


@pytest.mark.parametrize("what", ["config", "out-parent", "flight"])
def test_fit_permission_denied(what: str, flight_copy: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    if not _permissions_apply(tmp_path):
        pytest.skip("file permissions do not apply to this user (root)")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("mode: joint\n")
    ro = tmp_path / "ro"
    ro.mkdir()
    out_dir = ro / "fit" if what == "out-parent" else tmp_path / "fit"
    locked = {"config": cfg, "out-parent": ro, "flight": flight_copy}[what]
    mode = 0o500 if what == "out-parent" else 0o000
    locked.chmod(mode)
    try:
        rc, out, err = run(capsys, "fit", str(flight_copy), "--out", str(out_dir), "--config", str(cfg),
                           "--no-plots", "--quiet")
    finally:
        locked.chmod(0o700 if locked.is_dir() else 0o600)
    assert_one_line_error(rc, out, err, re.escape(str(locked)))
    assert not out_dir.exists()


@pytest.mark.parametrize("overwrite", [False, True])
def test_fit_refuses_output_over_its_config_file(overwrite: bool, sim_flight_dir: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    prev = tmp_path / "prev"
    common = ["fit", str(sim_flight_dir), "--no-plots", "--quiet", "--max-iterations", "1"]
    assert run(capsys, *common, "--out", str(prev))[0] == 0
    before = digest(prev)
    rc, out, err = run(capsys, *common, "--out", str(prev), "--config", str(prev / "config.yaml"),
                       *(["--overwrite"] if overwrite else []))
    assert_one_line_error(rc, out, err, re.escape(str(prev)), r"input", r"config\.yaml")
    assert digest(prev) == before
    assert entries(tmp_path) == ["prev"]


@pytest.mark.parametrize("kind", ["foreign-file", "flight-folder", "sub-folder"])
def test_fit_overwrite_refuses_a_folder_that_is_not_a_fit_output(
        kind: str, sim_flight_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    dest = tmp_path / "dest"
    if kind == "flight-folder":
        shutil.copytree(sim_flight_dir, dest)
        culprit = "camera.yaml|groundtruth.txt|heatmaps|keyframes.txt|simulation.yaml|turbine"
    else:
        dest.mkdir()
        (dest / "summary.json").write_text("{}")  # a fit output, and one thing that is not
        if kind == "foreign-file":
            (dest / "thesis.tex").write_text("mine\n")
            culprit = r"thesis\.tex"
        else:
            (dest / "scene.png").mkdir()
            (dest / "scene.png" / "keep.txt").write_text("mine\n")
            culprit = r"scene\.png"
    before = digest(dest)
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(dest), "--no-plots", "--quiet",
                       "--overwrite")
    assert_one_line_error(rc, out, err, re.escape(str(dest)), r"refusing to overwrite", culprit,
                          r"not an output of turbinefit fit")
    assert digest(dest) == before
    assert entries(tmp_path) == ["dest"]


def test_fit_write_failure_leaves_nothing(sim_flight_dir: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str],
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    import turbinefit.jobs.fit

    def full_disk(out: Path, *args: object) -> None:
        (out / "scene.png").write_bytes(b"half a plot")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(turbinefit.jobs.fit, "write_plots", full_disk)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(out_dir), "--quiet",
                       "--max-iterations", "1")
    assert_one_line_error(rc, out, err, re.escape(str(out_dir)), r"no space left on device writing")
    assert entries(tmp_path) == []  # neither the output nor its temporary folder


BAD_CONFIGS: dict[str, tuple[bytes | None, list[str]]] = {
    "unknown-option": (b"mode: joint\nbogus_option: 3\n", [r"unknown fit option", r"bogus_option"]),
    "bad-value": (b"max_iterations: 0\n", [r"max_iterations", r">= 1"]),
    "bad-choice": (b"points: sideways\n", [r"points", r"interp, corr or none"]),
    "not-a-mapping": (b"- 1\n- 2\n", [r"mapping"]),
    "malformed-yaml": (b"mode: joint\nlines: [interp\n", [r"cfg\.yaml:\d+:", r"malformed YAML"]),
    "missing": (None, [r"not found"]),
    "duplicate-key": (b"mode: joint\nmode: pose\n", [r"cfg\.yaml:2:", r"duplicate key 'mode'"]),
    "key-not-a-string": (b"1: 2\n", [r"option name 1", r"not a string"]),
    "int-option-not-whole": (b"samples_per_line: 2.5\n", [r"samples_per_line", r"whole number"]),
    "int-option-bool": (b"samples_per_line: true\n", [r"samples_per_line", r"whole number"]),
    "float-option-text": (b"lambda_pair: lots\n", [r"lambda_pair", r"must be a number", r"'lots'"]),
    "pair-information-text": (b"pair_information: '" + b"1" * 36 + b"'\n",
                              [r"pair_information", r"list of 36 numbers"]),
    "pair-information-item": (b"pair_information: [1, x]\n", [r"pair_information\[1\]", r"number"]),
    "geometry-not-a-mapping": (b"geometry: 5\n", [r"geometry", r"mapping", r"shaft_tilt"]),
    "geometry-null": (b"geometry: null\n", [r"geometry", r"mapping"]),
    "geometry-nan": (b"geometry: {blade_cone: .nan}\n", [r"geometry\.blade_cone", r"finite"]),
    "geometry-bool": (b"geometry: {hub_offset: yes}\n", [r"geometry\.hub_offset", r"True"]),
    "geometry-unknown": (b"geometry: {rotor_tilt: 0.1}\n", [r"unknown geometry option", r"rotor_tilt"]),
}


@pytest.mark.parametrize("case", [*BAD_CONFIGS, "directory", "not-utf8", "geometry-not-a-number"])
def test_fit_bad_config_file(case: str, sim_flight_dir: Path, tmp_path: Path,
                             capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "cfg.yaml"
    patterns = [r"cfg\.yaml"]
    if case == "directory":
        cfg.mkdir()
    elif case == "not-utf8":
        cfg.write_bytes(b"\xff\xfe mode: joint\n")
    elif case == "geometry-not-a-number":
        cfg.write_bytes(b"geometry: {shaft_tilt: abc}\n")
        patterns = [r"shaft_tilt", r"cfg\.yaml", r"geometry\.shaft_tilt", r"finite real number", r"'abc'"]
    else:
        content, more = BAD_CONFIGS[case]
        if content is not None:
            cfg.write_bytes(content)
        patterns += more
    existing = entries(tmp_path)
    out_dir = tmp_path / "fit"
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(out_dir), "--config", str(cfg),
                       "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, *patterns)
    assert entries(tmp_path) == existing  # out_dir not created


def test_fit_unreadable_config_file(sim_flight_dir: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str],
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("mode: joint\n")
    real_open = os.open

    def os_open(path: object, *args: object, **kwargs: object) -> int:
        if Path(str(path)) == cfg:
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "open", os_open)
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(tmp_path / "fit"),
                       "--config", str(cfg), "--no-plots", "--quiet")
    assert_one_line_error(rc, out, err, re.escape(str(cfg)), r"cannot read", r"Permission denied")
    assert entries(tmp_path) == ["cfg.yaml"]


@pytest.mark.parametrize(("args", "patterns"), [
    (["--preset", "nope"], [r"--preset", r"'nope'", r"paper-best"]),
    (["--lambda-points", "-1"], [r"lambda_points", r"non-negative"]),
    (["--pixel-sigma", "-1"], [r"pixel_sigma", r"positive"]),
    (["--max-iterations", "0"], [r"max_iterations", r">= 1"]),
    (["--points", "none", "--lines", "none"], [r"both be none"]),
])
def test_fit_bad_options(args: list[str], patterns: list[str], sim_flight_dir: Path, tmp_path: Path,
                         capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = run(capsys, "fit", str(sim_flight_dir), "--out", str(tmp_path / "fit"), "--quiet", *args)
    assert_one_line_error(rc, out, err, *patterns)
    assert entries(tmp_path) == []
