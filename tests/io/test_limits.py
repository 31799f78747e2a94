"""Input limits (turbinefit.io.limits): only regular files of sane size are read."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pytest

from turbinefit.errors import InputError, plain_number
from turbinefit.io.atomic import read_text
from turbinefit.io.heatmap_files import check_heatmap_values
from turbinefit.io.limits import (
    MAX_SETTINGS_BYTES,
    check_image_size,
    human_bytes,
    open_input,
    read_input_bytes,
)


def test_a_fifo_is_refused_without_opening_it(tmp_path: Path) -> None:
    pipe = tmp_path / "camera.yaml"
    os.mkfifo(pipe)
    done = threading.Event()
    errors: list[str] = []

    def read() -> None:  # in a thread: a blocking open would hang it, not the test
        try:
            read_text(pipe)
        except InputError as e:
            errors.append(str(e))
        done.set()

    threading.Thread(target=read, daemon=True).start()
    assert done.wait(10), "reading a FIFO blocked"
    assert errors == [f"{pipe}: is a named pipe (FIFO), not a regular file; refusing to read it"]


@pytest.mark.parametrize(("target", "what"), [("/dev/zero", "character device"),
                                              ("/dev/null", "character device")])
def test_a_link_to_a_device_is_refused(tmp_path: Path, target: str, what: str) -> None:
    link = tmp_path / "camera.yaml"
    link.symlink_to(target)
    with pytest.raises(InputError, match=what):
        read_text(link)


def test_a_link_to_a_regular_file_is_fine(tmp_path: Path) -> None:
    (tmp_path / "real.yaml").write_text("a: 1\n")
    (tmp_path / "link.yaml").symlink_to(tmp_path / "real.yaml")
    assert read_text(tmp_path / "link.yaml") == "a: 1\n"


def test_size_limit_refused_before_reading(tmp_path: Path) -> None:
    big = tmp_path / "turbine.yaml"
    with open(big, "wb") as f:
        f.truncate(MAX_SETTINGS_BYTES + 1)
    with pytest.raises(InputError,
                       match=r"turbine\.yaml: file is 1048577 bytes \(1 MiB\), larger than the 1 MiB"):
        read_text(big, MAX_SETTINGS_BYTES)
    big.write_bytes(b"x" * 100)
    assert read_input_bytes(big, 100) == b"x" * 100
    with pytest.raises(InputError, match="larger than the 99 bytes limit"):
        read_input_bytes(big, 99)


def test_a_file_that_reports_no_size_is_still_capped() -> None:
    # /proc files are regular files whose size reads 0: the read stops at the limit
    with pytest.raises(InputError, match="larger than the 10 bytes limit"):
        read_input_bytes("/proc/self/status", 10)


def test_open_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="nothing: gone"):
        open_input(tmp_path / "nothing", missing="gone")
    with pytest.raises(InputError, match="is a directory"):
        open_input(tmp_path)
    (tmp_path / "a").write_bytes(b"abc")
    with open_input(tmp_path / "a") as f:
        assert f.read() == b"abc"


def test_human_bytes() -> None:
    assert [human_bytes(n) for n in (5, 2048, 3 << 20, 23 << 30, 5 << 40, 5000 << 40)] == [
        "5 bytes", "2 KiB", "3 MiB", "23 GiB", "5 TiB", "5e+03 TiB"]


def test_image_size_limits() -> None:
    check_image_size(24, 24)
    check_image_size(14204, 10652)  # a 150 MP inspection camera
    with pytest.raises(InputError, match=r"7x48 px; each side must be at least 24"):
        check_image_size(7, 48)
    with pytest.raises(InputError, match=r"30000x30000 px \(900 MP\), more than the 200 MP"):
        check_image_size(30000, 30000)


@pytest.mark.parametrize("dtype", [np.float32, np.float16, np.float64])
def test_heatmap_values_any_dtype(dtype: type) -> None:
    maps = np.zeros((7, 30, 40), dtype=dtype)
    maps[3] = 1.0005  # within the tolerance
    check_heatmap_values(maps, "m.npy")
    maps[6, 2, 2] = -0.5
    with pytest.raises(InputError, match=r"m\.npy: channel 6 \(line_blade\) holds -0\.5"):
        check_heatmap_values(maps, "m.npy")
    maps[1, 0, 0] = np.nan
    with pytest.raises(InputError, match=r"channel 1 \(point_tower_top\) holds NaN"):
        check_heatmap_values(maps, "m.npy")


def test_plain_number() -> None:
    assert [plain_number(x) for x in (np.float64(0.0), np.int64(12), np.float32(0.5), 1e300,
                                      True, "x")] == ["0.0", "12", "0.5", "1e+300", "True", "'x'"]


@pytest.mark.parametrize("native", ["1", "0"])
@pytest.mark.parametrize(("value", "message"), [
    (np.nan, r"channel 4 \(line_tower\) holds NaN"),
    (np.inf, r"channel 4 \(line_tower\) holds inf"),
    (1.002, r"channel 4 \(line_tower\) holds 1\.002"),
    (-0.0011, r"channel 4 \(line_tower\) holds -0\.0011"),
])
def test_mapped_heatmap_values_name_the_first_bad_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, native: str, value: float,
        message: str) -> None:
    """The memory-mapped check (compiled one-pass kernel, or numpy reading each file) names
    the first bad keyframe's file, whichever bad files follow; values within the tolerance
    pass."""
    from turbinefit import _native
    from turbinefit.io.heatmap_files import read_heatmaps

    if native == "1" and _native._LIB is None:
        pytest.skip("compiled kernels not built")
    monkeypatch.setenv("TURBINEFIT_NATIVE", native)
    t = np.arange(9, dtype=float)
    for k in range(9):
        maps = np.full((7, 24, 32), 0.5, dtype=np.float32)
        maps[0, 0, 0], maps[1, -1, -1] = -0.00099, 1.00099  # inside the tolerance
        np.save(tmp_path / f"{t[k]:.6f}.npy", maps)
    read_heatmaps(tmp_path, t)  # all good
    for k in (6, 3, 8):  # bad files at 3, 6 and 8: 3 is named
        maps = np.load(tmp_path / f"{t[k]:.6f}.npy")
        maps[4, 5, 7] = value
        np.save(tmp_path / f"{t[k]:.6f}.npy", maps)
    with pytest.raises(InputError, match=r"3\.000000\.npy: " + message):
        read_heatmaps(tmp_path, t)
