"""The cases of the fault corpus (``tests/faults.py`` runs them): one per fault class,
each a mutation of the base flight and a command line."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
from faults import (
    Case,
    Mutation,
    both,
    camera,
    cmd,
    column,
    cut,
    directory,
    fifo,
    fit,
    k_entry,
    npy,
    png_header,
    set_value,
    simulate,
    sparse,
    sub,
    symlink,
    track,
    tum,
    unlink,
    write,
)

from turbinefit.sim.scenario import SimConfig, true_turbine
from turbinefit.turbine.model import model_points

# ------------------------------------------------------------------ the cases

CAM, KF, TURB = r"camera\.yaml", r"keyframes\.txt", r"turbine\.yaml"
ODO, GT, GTT = r"odometry\.txt", r"groundtruth\.txt", r"turbine_groundtruth\.yaml"
HM = r"heatmaps/2\.000000\.npy"
PHOTO = r"images/2\.000000\.png"
BIG = 300 << 20  # a sparse file above every text limit
#: The hub of the true turbine of ``simulate``'s default seed (a pose inside the turbine).
_HUB = " ".join(f"{v:.3f}" for v in model_points(
    true_turbine(SimConfig()).to_vector())[0][2])
OK_ODOMETRY: Mutation = lambda f: shutil.copy(f / "keyframes.txt", f / "odometry.txt")  # noqa: E731


def _blank_heatmaps(folder: Path) -> None:
    """Every heat-map of the flight zero: the turbine is never seen."""
    import numpy as np

    for p in (folder / "heatmaps").glob("*.npy"):
        np.save(p, np.zeros_like(np.load(p)))


def dji(k: int | None = None, *, links: str | None = None, every: bool = False,
        **meta: object) -> Mutation:
    """Four DJI-style photos in ``flight/dji`` (an orbit about DJI_ORIGIN, 2 s apart),
    photo ``k`` (``every``: each photo) written with other metadata: ``latitude``,
    ``longitude``, ``altitude``, ``time``, ``pitch``, ``roll`` override its pose; the rest are options of
    :func:`turbinefit.sim.dji_photos.dji_metadata`. ``links``: ``dangling``, ``loop`` or
    ``relative`` adds symbolic links."""
    def m(f: Path) -> None:
        import os
        from dataclasses import replace

        from support import DJI_ORIGIN, dji_test_poses

        from turbinefit.io.georef import Georef
        from turbinefit.sim.dji_photos import dji_poses, write_dji_photo

        folder = f / "dji"
        folder.mkdir()
        poses = dji_poses(Georef(*DJI_ORIGIN), dji_test_poses(4), [0.0, 2.0, 4.0, 6.0])
        for i, pose in enumerate(poses):
            kw = dict(meta) if i == k or every else {}
            over = {key: kw.pop(key) for key in ("latitude", "longitude", "altitude", "time",
                                                 "pitch", "roll") if key in kw}
            write_dji_photo(folder / f"DJI_{i:04d}.JPG", np.full((48, 64, 3), 100, np.uint8),
                            replace(pose, **over), **kw)  # type: ignore[arg-type]
        if links == "dangling":
            os.symlink("gone.JPG", folder / "DJI_0009.JPG")
        elif links == "loop":
            os.symlink("DJI_0009.JPG", folder / "DJI_0009.JPG")
    return m


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
        add(f"huge-{name}", fit(), sparse(name, BIG), pat, r"\(300 MiB\), larger than the")
    add("big-camera.yaml", fit(), sparse("camera.yaml", 2 << 20), CAM,
        r"2097152 bytes \(2 MiB\), larger than the 1 MiB")
    add("dir-camera.yaml", fit(), directory("camera.yaml"), CAM, "directory")
    add("dir-heatmap", fit(), both(unlink("heatmaps/2.000000.npy"),
                                   lambda f: (f / "heatmaps/2.000000.npy").mkdir()), HM, "directory")
    add("heatmaps-is-a-file", fit(), both(unlink("heatmaps"), write("heatmaps", "x")),
        r"heatmaps", "not a directory")
    add("loop-camera.yaml", fit(), symlink("camera.yaml", "camera.yaml"), CAM, "cannot access")

    # -- missing files
    for name, pat in (("camera.yaml", CAM), ("keyframes.txt", KF)):
        add(f"missing-{name}", fit(), unlink(name), pat, "missing")
    # without turbine.yaml fit estimates it (turbinefit init): a turbine never seen is refused
    add("missing-turbine.yaml-unseen", fit(), both(unlink("turbine.yaml"), _blank_heatmaps),
        r"flight", r"cannot determine turbine: it is seen in 0 keyframe\(s\).*--near")
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
    for bad, pat in ((1.5, r"holds 1\.5, outside \[0, 1\]"), (-1.0, r"holds -1\.0"),
                       (1e30, r"outside"), (np.inf, r"holds inf"), (-np.inf, r"holds -inf"),
                       (np.nan, r"NaN"), (1.002, r"1\.00")):
        add(f"heatmap-value-{bad}", fit(), npy(2, set_value(5, bad)), HM,
            r"channel 5 \(line_nacelle\)", pat)
    add("heatmaps-all-minus-1", fit(), npy(None, lambda a: np.full_like(a, -1.0)),
        r"heatmaps/0\.000000\.npy", r"holds -1\.0")
    add("heatmaps-all-255", fit(), npy(None, lambda a: a * 255), r"heatmaps/0\.000000\.npy",
        r"outside \[0, 1\]")
    add("track-heatmap-value", track(), npy(2, set_value(0, 2.0)), HM, r"point_base")
    # fit checks the values as its solver first reads them: the first bad file is named,
    # also when two are, and when init reads them first (no turbine.yaml)
    add("heatmap-values-two-files", fit(), both(npy(3, set_value(0, 2.0)),
                                                npy(2, set_value(6, -0.5))), HM,
        r"channel 6 \(line_blade\)", r"holds -0\.5")
    add("heatmap-value-no-turbine", fit(), both(unlink("turbine.yaml"),
                                                npy(2, set_value(5, np.nan))), HM,
        r"channel 5 \(line_nacelle\)", r"NaN")
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
                      (["--lambda-points", "-1"], r"lambda_points"),
                      (["--points", "none", "--lines", "none"], r"both be none")):
        add(f"fit-option-{'-'.join(opts)}", fit(*opts), None, pat)
    add("fit-option-lambda-points-nan", fit("--lambda-points", "nan"), None,
        r"--lambda-points: expected a finite number", usage=True)
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
                             (["--drift-m", "nan"], r"--drift-m: expected a finite", True),
                             (["--drift-m", "-1"], r"drift", False),
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
    labels = json.dumps({
        "images": [{"id": 1, "file_name": "2.000000.png", "width": 64, "height": 48}],
        "annotations": [{"image_id": 1, "category_id": 1,
                         "keypoints": [1e9, 100, 2] + [0, 0, 0] * 5}],
        "categories": [{"id": 1, "name": "turbine",
                        "keypoints": ["base", "tower_top", "hub", "tip_1", "tip_2", "tip_3"]}]})
    add("evaluate-keypoint-far-outside", cmd("evaluate", "--labels", "{w}/flight/l.json",
                                             "--images-dir", "{w}/flight/images", "--quiet"),
        write("l.json", labels), r"l\.json", r"annotations\[0\]\.keypoints\[0\]",
        r"x 1000000000.0 px is out of range")
    add("evaluate-labels-fifo", cmd("evaluate", "--labels", "{w}/flight/l.json", "--images-dir",
                                    "{w}/flight/images", "--quiet"), fifo("l.json"), r"l\.json",
        r"named pipe", hang=True)
    add("evaluate-labels-devzero", cmd("evaluate", "--labels", "/dev/zero", "--images-dir",
                                       "{w}/flight/images", "--quiet"), None, r"/dev/zero",
        r"character device")
    add("evaluate-labels-not-json", cmd("evaluate", "--labels", "{w}/flight/camera.yaml",
                                        "--images-dir", "{w}/flight/images", "--quiet"), None,
        r"camera\.yaml", r"JSON")
    def outline(seg: object) -> Mutation:
        """A COCO file o.json outlining the flight's 64x48 photo 2.000000.png by ``seg``."""
        return write("o.json", json.dumps({
            "images": [{"id": 1, "file_name": "2.000000.png", "width": 64, "height": 48}],
            "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "bbox": [0, 0, 8, 8],
                             "segmentation": seg}],
            "categories": [{"id": 1, "name": "turbine"}]}))

    boxes = cmd("evaluate", "--boxes", "{w}/flight/o.json", "--images-dir", "{w}/flight/images",
                "--quiet")
    add("evaluate-rle-size", boxes, outline({"size": [48, 48], "counts": [2304]}), r"o\.json",
        r"annotations\[0\]\.segmentation", r"RLE size")
    add("evaluate-rle-counts", boxes, outline({"size": [48, 64], "counts": [3000, 1]}),
        r"o\.json", r"add up to 3001")
    add("evaluate-polygon-outside", boxes, outline([[0, 0, 70, 0, 0, 40]]), r"o\.json",
        r"reaches outside its 64x48 image")
    add("evaluate-polygon-two-points", boxes, outline([[0, 0, 10, 10]]), r"o\.json",
        r"three or more points")
    # -- train from boxes and turbine-free photos (issue 50)
    train = ("train", "--out", "{w}/out", "--images", "4", "--val-images", "2", "--quiet")
    add("train-boxes-without-images", cmd(*train, "--boxes", "{w}/flight/b.csv"),
        write("b.csv", "2.000000.png,64,48,turbine,1,1,30,40\n"), r"boxes",
        r"--boxes and --boxes-images go together")
    add("train-boxes-photo-missing", cmd(*train, "--boxes", "{w}/flight/b.csv",
                                         "--boxes-images", "{w}/flight/images"),
        write("b.csv", "nothing.png,64,48,turbine,1,1,30,40\n"), r"b\.csv:1",
        r"photo not found")
    add("train-boxes-outside", cmd(*train, "--boxes", "{w}/flight/b.csv",
                                   "--boxes-images", "{w}/flight/images"),
        write("b.csv", "2.000000.png,64,48,turbine,1,1,70,40\n"), r"b\.csv:1",
        r"outside its 64x48 image")
    add("train-hold-out-above-1", cmd(*train, "--negatives", "{w}/flight/images",
                                      "--hold-out", "1.5"), None, r"--hold-out", usage=True)
    add("train-negatives-empty", cmd(*train, "--negatives", "{w}/flight/empty"),
        lambda f: (f / "empty").mkdir(), r"empty", r"no image files")
    add("report-rows-fifo", cmd("report", "{w}/flight/exp"),
        both(write("exp/sweep.yaml", "study: unary\n"), fifo("exp/rows.csv")), r"exp",
        hang=True)
    add("report-missing", cmd("report", "{w}/flight/nothing"), None, r"nothing")

    # -- import: DJI photos, ROS bags
    dji_cmd = ("import", "dji", "{w}/flight/dji", "--out", "{w}/out")
    add("dji-not-jpeg", cmd("import", "dji", "{w}/flight/images/2.000000.png", "--out",
                            "{w}/out"), None, PHOTO, r"JPEG")
    add("dji-fifo", cmd("import", "dji", "{w}/flight/a.jpg", "--out", "{w}/out"),
        fifo("a.jpg"), r"a\.jpg", r"named pipe", hang=True)
    add("dji-fake-jpeg", cmd(*dji_cmd), write("dji/a.jpg", "not a photo"), r"dji/a\.jpg",
        r"not a JPEG")
    add("dji-no-photos", cmd(*dji_cmd), lambda f: (f / "dji").mkdir(), r"dji", r"no")
    # issue 49: impossible positions, angles, cameras and times in photo metadata
    from datetime import timedelta

    from turbinefit.sim.dji_photos import DEFAULT_START

    for name, mutation, pats in (
            ("zero-position", dji(2, latitude=0.0, longitude=0.0),
             (r"DJI_0002\.JPG", r"latitude 0, longitude 0")),
            ("latitude-sign", dji(1, latitude=-51.4545), (r"DJI_0001\.JPG", r"993\d km")),
            ("east-west", dji(3, longitude=2.5879), (r"DJI_0003\.JPG", r"3[56]\d km")),
            ("altitude-1e7", dji(0, altitude=1e7), (r"DJI_0000\.JPG", r"AbsoluteAltitude",
                                                    r"out of range")),
            ("all-at-zero", dji(every=True, latitude=0.0, longitude=0.0),
             (r"every photo of the flight \(4\) is at latitude 0",)),
            ("pitch-200", dji(1, pitch=200.0), (r"GimbalPitchDegree", r"gimbal pitch 200")),
            ("roll-1e6", dji(2, roll=1e6), (r"GimbalRollDegree", r"1000000")),
            ("clock-5-years", dji(0, time=DEFAULT_START - timedelta(days=5 * 365)),
             (r"DJI_0000\.JPG", r"1825\.\d days", r"wrong clock")),
            ("focal35-60000", dji(0, focal_35mm=60000.0), (r"FocalLengthIn35mmFilm",)),
            ("principal-point-1e6", dji(0, extra_xmp={"CalibratedFocalLength": "50",
                                                      "CalibratedOpticalCenterX": "1e6"}),
             (r"principal point cx = 1000000",)),
            ("relative-altitude-1e9", dji(0, extra_xmp={"RelativeAltitude": "-1e9"}),
             (r"RelativeAltitude", r"out of range")),
            ("dangling-link", dji(links="dangling"), (r"DJI_0009\.JPG", r"does not exist")),
            ("link-loop", dji(links="loop"), (r"DJI_0009\.JPG", r"symbolic link loop")),
            ("dewarp-short", dji(0, extra_xmp={"DewarpData": "2020-01-01;1,2,3"}),
             (r"DewarpData", r"expected")),
            ("rtk-flag-text", dji(0, extra_xmp={"RtkFlag": "fixed"}), (r"RtkFlag",)),
    ):
        add(f"dji-{name}", cmd(*dji_cmd), mutation, *pats)
    add("georef-altitude-1e9", fit(), write("georef.yaml", "latitude: 51.45\nlongitude: -2.58\n"
                                             "altitude: 1e9\nframe: enu\n"),
        r"georef\.yaml", r"altitude", r"out of range")
    add("dji-origin-far", cmd(*dji_cmd, "--origin", "0,0,0"), dji(), r"--origin",
        r"km from the photos")
    add("dji-origin-altitude-1e9", cmd(*dji_cmd, "--origin", "51.45,-2.58,1e9"), dji(),
        r"--origin", r"altitude", usage=True)
    add("dji-max-gap-zero", cmd(*dji_cmd, "--max-gap", "0"), dji(), r"--max-gap", usage=True)
    add("dji-camera-unknown", cmd(*dji_cmd, "--camera", "zoom"), dji(), r"--camera",
        r"no photos of camera 'zoom'")
    bag = ("import", "rosbag", "{w}/flight/b.bag", "--out", "{w}/out", "--image-topic", "/i",
           "--odometry-topic", "/o")
    add("rosbag-fifo", cmd(*bag), fifo("b.bag"), r"b\.bag", r"named pipe", hang=True)
    add("rosbag-devzero", cmd(*bag), symlink("b.bag", "/dev/zero"), r"b\.bag",
        r"character device")
    add("rosbag-missing", cmd(*bag), None, r"b\.bag", r"not found")
    add("rosbag-not-a-bag", cmd(*bag), write("b.bag", "not a bag"), r"b\.bag", r"ROS bag")

    # -- coverage (a flight folder stands in for a fit folder: poses, turbine, camera)
    cov = ("coverage", "{w}/flight", "--flight", "{w}/flight", "--out", "{w}/out", "--quiet")
    add("coverage-no-turbine", cmd(*cov), unlink("turbine.yaml"), TURB, r"without fitted turbine")
    add("coverage-no-poses", cmd(*cov), unlink("keyframes.txt"), KF, r"without fitted poses")
    # a folder with poses and a turbine but neither a camera nor a summary naming its flight
    add("coverage-no-summary", cmd("coverage", "{w}/flight", "--out", "{w}/out"),
        unlink("camera.yaml"), r"summary\.json", r"--flight")
    add("coverage-fifo-turbine", cmd(*cov), fifo("turbine.yaml"), TURB, "named pipe", hang=True)
    for value, pat in (("1e-4", r"step 0.0001 m is out of range"), ("1e-5", r"--step"),
                       ("1e9", r"between 0.01 and 5 m"), ("nan", r"step must be a number")):
        add(f"coverage-step-{value}", cmd(*cov, "--step", value), None, pat, usage=True)
    add("coverage-gsd-inf", cmd(*cov, "--gsd", "inf"), None, r"--gsd", usage=True)
    add("coverage-blade-pitch", cmd(*cov, "--blade-pitch", "-91"), None,
        r"blade angle -91.0 deg", usage=True)
    # -- simulate --path, --defects-file, --photo-scale; coverage --truth
    sim_path = ("simulate", "{w}/out", "--quiet", "--path", "{w}/flight/p.txt")
    pose = "0 0 -120 60 0 0 0 1\n"
    add("simulate-path-nan", cmd(*sim_path), write("p.txt", pose + "1 0 -120 nan 0 0 0 1\n"),
        r"p\.txt:2", r"non-finite value 'nan'")
    add("simulate-path-inside-turbine", cmd(*sim_path),
        write("p.txt", pose + f"1 {_HUB} 0 0 0 1\n"), r"p\.txt:2",
        r"inside the simulated turbine")
    add("simulate-path-underground", cmd(*sim_path), write("p.txt", pose + "1 0 -120 -2 0 0 0 1\n"),
        r"p\.txt:2", r"below the ground")
    add("simulate-path-fifo", cmd(*sim_path), fifo("p.txt"), r"p\.txt", r"named pipe",
        hang=True)
    sim_defects = ("simulate", "{w}/out", "--quiet", "--defects-file", "{w}/flight/d.csv")
    head = "defect,part,side,span_m,chord,size_m,kind\n"
    for name, row, pat in (
            ("span", "D1,blade_A,pressure_side,64,0,0.2,crack", r"d\.csv:2 \[span_m\].*blade"),
            ("chord", "D1,blade_A,pressure_side,30,-1.5,0.2,crack", r"d\.csv:2 \[chord\]"),
            ("blade", "D1,blade_Q,pressure_side,30,0,0.2,crack", r"d\.csv:2 \[part\]"),
            ("side", "D1,blade_A,root,30,0,0.2,crack", r"d\.csv:2 \[side\]"),
            ("size", "D1,blade_A,pressure_side,30,0,inf,crack", r"d\.csv:2 \[size_m\]")):
        add(f"simulate-defect-{name}", cmd(*sim_defects), write("d.csv", head + row + "\n"),
            pat)
    add("simulate-photo-scale-0", cmd("simulate", "{w}/out", "--photo-scale", "0"), None,
        r"--photo-scale", r"photo scale 0\.0 is out of range", usage=True)
    add("coverage-truth-without-damage", cmd(*cov, "--truth", "{w}/flight/d.csv"),
        write("d.csv", head), r"--truth", r"needs --damage")
    add("coverage-damage-defect-column", cmd(*cov, "--damage", "{w}/flight/b.csv"),
        write("b.csv", "2.000000.png,64,48,crack,1,2,3,4,D1\n2.000000.png,64,48,c,1,2,3,4\n"),
        r"b\.csv:2", r"8 columns, expected 9")
    # -- init: numbers of the prior
    init = ("init", "{w}/flight", "--quiet")
    for opts, pat in ((("--near", "nan,0"), r"--near: X must be a number, got nan"),
                      (("--near-wgs84", "nan,nan"), r"latitude must be a number"),
                      (("--near-wgs84", "91,0"), r"latitude 91.0 deg is out of range"),
                      (("--near", "1e9,0"), r"X 1000000000.0 m is out of range"),
                      (("--near", "5"), r"expected X,Y")):
        add(f"init{'-'.join(opts)}", cmd(*init, *opts), None, pat, usage=True)
    add("init-hub-height", cmd(*init, "--hub-height", "5"), None, r"--hub-height",
        r"hub height 5.0 m")
    plan = ("plan", "{w}/flight", "--flight", "{w}/flight", "--out", "{w}/out", "--quiet")
    add("plan-no-turbine", cmd(*plan, "--standoff", "10"), unlink("turbine.yaml"), TURB,
        r"without fitted turbine")
    add("plan-no-poses", cmd(*plan, "--standoff", "10"), unlink("keyframes.txt"), KF,
        r"without fitted poses")
    add("plan-standoff-meets-rotor", cmd(*plan, "--standoff", "99"), None, r"--standoff",
        r"meets the rotor")
    # issue 49's audit: stand-offs below the least safe one were planned into the blades;
    # the gimbal's range took nan and 1000, and -1000 failed naming a hidden temporary file
    for value in ("0.5", "1e-6", "1"):
        add(f"plan-standoff-{value}", cmd(*plan, "--standoff", value), None,
            r"--standoff", r"out of range: it must be between 3 and 100 m", usage=True)
    for value, words in (("nan", r"must be a number, got nan"), ("1000", r"out of range"),
                         ("-1000", r"out of range")):
        add(f"plan-gimbal-{value}", cmd(*plan, "--standoff", "10", "--max-gimbal-up", value),
            None, r"--max-gimbal-up", words, usage=True)
    add("plan-gsd-unreachable", cmd(*plan, "--standoff", "10", "--gsd", "0.01"), None,
        r"--gsd", r"mm/px at a stand-off of 10 m")
    # the blades' shape and the position margin
    for opt, value, words in (("--blade-pitch", "nan", r"must be a number, got nan"),
                              ("--blade-twist", "91", r"blade angle 91.0 deg is out of range"),
                              ("--position-margin", "-1", r"position margin -1.0 m is out"),
                              ("--position-margin", "inf", r"must be a number|out of range")):
        add(f"plan-{opt[2:]}-{value}", cmd(*plan, "--standoff", "10", opt, value), None, opt, words,
            usage=True)
    add("plan-position-margin-beyond-standoff",
        cmd(*plan, "--standoff", "10", "--position-margin", "11"), None, r"--position-margin",
        r"between 0 and the stand-off \(10 m\)")
    # issue 47: mission files, platforms (the flight folder has no georef.yaml)
    origin = ("--standoff", "10", "--origin", "51.45,-2.51,40")
    add("plan-unknown-platform", cmd(*plan, *origin, "--platform", "m31t"), None,
        r"--platform: unknown platform 'm31t'; known: generic")
    add("plan-unknown-format", cmd(*plan, *origin, "--format", "kml,dji"), None,
        r"--format: unknown mission format 'dji'", usage=True)
    add("plan-format-not-flown", cmd(*plan, *origin, "--format", "dji-wpml"), None,
        r"--format: platform generic does not fly dji-wpml missions")
    add("plan-format-platform", cmd(*plan, *origin, "--format", "litchi", "--platform", "m30t"),
        None, r"--format: platform m30t does not fly litchi missions")
    add("plan-mission-without-georef", cmd(*plan, "--standoff", "10", "--format", "qgc"), None,
        r"--format: qgc need a georeferenced fit", r"--origin")
    add("plan-gimbal-beyond-platform", cmd(*plan, *origin, "--max-gimbal-up", "45"), None,
        r"--max-gimbal-up: 45 deg is beyond the gimbal of platform generic")
    add("plan-speed-beyond-platform", cmd(*plan, *origin, "--platform", "px4", "--speed", "14"),
        None, r"--speed: 14 m/s is faster than platform px4")
    add("plan-origin-nan", cmd(*plan, "--standoff", "10", "--origin", "nan,0,0"), None,
        r"--origin", r"latitude must be a number", usage=True)
    add("plan-origin-on-georef", cmd(*plan, *origin), write("georef.yaml",
        "latitude: 51.4\nlongitude: -2.5\naltitude: 40\nframe: enu\n"), r"--origin: the "
        r"flight is georeferenced")
    # -- view: a folder that is neither a fit nor a mission; bad numbers; bad plan and
    # coverage files (the fit: the flight's own poses and turbine, in flight/fit)
    add("view-flight-folder", cmd("view", "{w}/flight", "--out", "{w}/out"), None,
        r"flight: is neither a fit output", r"it is a flight folder")
    add("view-empty-folder", cmd("view", "{w}/flight/empty", "--out", "{w}/out"),
        lambda f: (f / "empty").mkdir(), r"empty: is neither a fit output \(keyframes")
    add("view-missing", cmd("view", "{w}/flight/none", "--out", "{w}/out"), None,
        r"flight/none: not found")
    vfit = ("view", "{w}/flight/fit", "--flight", "{w}/flight", "--out", "{w}/out")
    add("view-sides-bad-gsd", cmd(*vfit, "--coverage", "{w}/flight/cov"),
        both(_view_fit, _view_coverage("blade_A,leading_edge,1.00,1.50,-1,")),
        r"cov/sides\.csv:2 \[best_gsd_mm_px\]", r"out of range")
    add("view-sides-bad-side", cmd(*vfit, "--coverage", "{w}/flight/cov"),
        both(_view_fit, _view_coverage("blade_A,front,1.00,1.50,3.2,")),
        r"cov/sides\.csv:2 \[side\]", r"unknown side 'front' of blade_A")
    add("view-waypoints-nan", cmd(*vfit, "--plan", "{w}/flight/plan"),
        both(_view_fit, _view_plan("0,nan,1,40,0,0,0,,,")), r"plan/waypoints\.csv:2 \[x\]",
        r"must be a number")
    add("view-plan-photos-mismatch", cmd(*vfit, "--plan", "{w}/flight/plan"),
        both(_view_fit, _view_plan("0,1,1,40,0,0,1,blade_A,leading_edge,20.00")),
        r"plan/keyframes\.txt", r"6 photo poses, but waypoints\.csv has 1 photos")
    add("view-flight-mismatch", cmd(*vfit), both(_view_fit, cut("fit/keyframes.txt", "3.0")),
        r"flight/keyframes\.txt", r"not the fit's 3")
    for opt, value in (("--thumbnail", "10"), ("--thumbnail", "64.5"), ("--photos", "-1"),
                       ("--gsd", "nan")):
        add(f"view{opt}-{value}", cmd(*vfit, opt, value), _view_fit, opt, usage=True)
    # -- mission: what cannot be flown is refused before flying
    mission = ("mission", "{w}/out", "--maps", "ideal", "--max-photos", "1", "--quiet")
    add("mission-gsd-unreachable", cmd(*mission, "--camera", "{w}/flight/camera.yaml"), None,
        r"--camera: the camera \(focal length \d+ px\) reaches", r"a focal length of at least")
    add("mission-unknown-type", cmd(*mission, "--turbine-type", "v90"), None,
        r"--turbine-type: unknown turbine type 'v90'")
    for opt, value in (("--standoff", "1"), ("--gsd", "0"), ("--defects", "-1"),
                       ("--photo-width", "10"), ("--max-gimbal-up", "nan")):
        add(f"mission{opt}-{value}", cmd(*mission, opt, value), None, opt, usage=True)
    return c


def _view_fit(flight: Path) -> None:
    """A fit folder in ``flight/fit``: the flight's poses and turbine."""
    (flight / "fit").mkdir()
    for name in ("keyframes.txt", "turbine.yaml"):
        shutil.copy(flight / name, flight / "fit" / name)


def _view_coverage(row: str) -> Mutation:
    """A coverage folder ``flight/cov`` whose ``sides.csv`` holds ``row``."""
    def m(flight: Path) -> None:
        (flight / "cov").mkdir()
        (flight / "cov" / "summary.json").write_text(json.dumps({"max_gsd_mm_px": 2.0}))
        (flight / "cov" / "sides.csv").write_text(
            "part,side,span_from_m,span_to_m,best_gsd_mm_px,timestamp\n" + row + "\n")
    return m


def _view_plan(row: str) -> Mutation:
    """A plan folder ``flight/plan`` whose ``waypoints.csv`` holds a good first row then
    ``row``, with the flight's poses as its photos'."""
    def m(flight: Path) -> None:
        (flight / "plan").mkdir()
        for name in ("keyframes.txt", "turbine.yaml"):
            shutil.copy(flight / name, flight / "plan" / name)
        (flight / "plan" / "waypoints.csv").write_text(
            "index,x,y,z,yaw_deg,gimbal_pitch_deg,photo,part,side,span_m\n" + row
            + "\n1,2,2,40,0,0,0,,,\n")
    return m


CASES: list[Case] = _cases()

