"""Heat-map files as the compiled kernels read them (turbinefit._native.FileMaps): the same
results as the same maps in memory, bit for bit; the process holds only the pages the
kernels read; the value check keeps the verdict's coarse grid."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from turbinefit import _native
from turbinefit.heatmaps import HeatmapStack
from turbinefit.io.flight_folder import read_flight, write_flight
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver import FitConfig, fit
from turbinefit.solver.config import FILE_FIT_DEFAULTS
from turbinefit.solver.problem import FitProblem

pytestmark = pytest.mark.skipif(not _native.files_supported(),
                                reason="compiled kernels not built, or no mmap")


@pytest.fixture(scope="module", params=["float16", "float32"])
def flights(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):
    """A simulated flight written as heat-map files, read back (FileMaps), and the same
    maps in memory."""
    folder = tmp_path_factory.mktemp("flight") / request.param
    write_flight(simulate_flight(SimConfig(n_keyframes=40, seed=5)), folder,
                 heatmap_dtype=request.param)
    files = read_flight(folder)
    maps = files.heatmaps
    assert maps.files is not None and maps.pointers() is None
    memory = type(files)(**{**files.__dict__, "heatmaps": HeatmapStack(
        np.stack([maps[k] for k in range(maps.num_keyframes)]))})
    assert memory.heatmaps.files is None and memory.heatmaps.half == maps.half
    return folder, files, memory


def test_a_fit_from_files_is_the_fit_in_memory(flights) -> None:
    _, files, memory = flights
    cfg = FitConfig(**FILE_FIT_DEFAULTS)
    a, b = fit(files, cfg), fit(memory, cfg)
    np.testing.assert_array_equal(a.world_T_cam.wxyz_xyz, b.world_T_cam.wxyz_xyz)
    np.testing.assert_array_equal(a.turbine.to_vector(), b.turbine.to_vector())
    assert (a.verdict, a.reasons, a.iterations) == (b.verdict, b.reasons, b.iterations)
    assert a.signals is not None and b.signals is not None
    assert a.signals.to_dict() == b.signals.to_dict()


@pytest.mark.parametrize("kw", [
    {"lines": "corr", "line_residual": "normal", "robust": "cauchy"},
    {"points": "interp", "lines": "interp", "line_sampling": "uniform"},
])
def test_kernels_read_files_as_memory_and_numpy_reads_them_too(
        flights, monkeypatch: pytest.MonkeyPatch, kw: dict) -> None:
    """Correspondences and normal equations from the files: those of the maps in memory
    (the same kernels), and with numpy (each keyframe read anew) its own in memory."""
    _, files, memory = flights
    poses, theta = files.world_T_cam, files.turbine.to_vector()
    out = {}
    for native in ("1", "0"):
        monkeypatch.setenv("TURBINEFIT_NATIVE", native)
        for name, flight in (("files", files), ("memory", memory)):
            prob = FitProblem(flight, FitConfig(**kw))
            corr = prob.find_correspondences(poses, theta)
            out[native, name] = corr, prob.linearize(poses, theta, corr)
    for native in ("1", "0"):
        (ca, la), (cb, lb) = out[native, "files"], out[native, "memory"]
        for field in ("point_target", "point_found", "line_target", "line_found"):
            x, y = getattr(ca, field), getattr(cb, field)
            assert (x is None) == (y is None)
            if x is not None:
                np.testing.assert_array_equal(x, y)
        assert la.cost == lb.cost
        np.testing.assert_array_equal(la.D, lb.D)
        np.testing.assert_array_equal(la.g_p, lb.g_p)


def test_the_coarse_grid_kept_by_the_check_is_that_of_the_maps(flights) -> None:
    _, files, memory = flights
    kf = np.array([3, 0, 39, 17])
    assert files.heatmaps.files.grid is not None
    grid = files.heatmaps.coarse_grid(kf)
    np.testing.assert_array_equal(grid, memory.heatmaps.coarse_grid(kf))
    assert grid.dtype == memory.heatmaps[0].dtype and grid.shape[:2] == (4, 7)
    sub = files.heatmaps.subset(np.array([5, 9]))
    np.testing.assert_array_equal(sub.coarse_grid(np.array([1])),
                                  memory.heatmaps.coarse_grid(np.array([9])))
    np.testing.assert_array_equal(sub[0], memory.heatmaps[5])
    assert not sub[0].flags.writeable


def _mapped_kb(folder: Path) -> int:
    """kB of the files below ``folder`` mapped into this process (/proc/self/smaps)."""
    total, inside = 0, False
    prefix = str(folder.resolve())
    for line in Path("/proc/self/smaps").read_text().splitlines():
        head = re.match(r"^[0-9a-f]+-[0-9a-f]+ ", line)
        if head:
            inside = line.split(maxsplit=5)[-1].startswith(prefix)
        elif inside and line.startswith("Rss:"):
            total += int(line.split()[1])
    return total


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/smaps")
def test_a_fit_holds_only_the_pages_it_reads(tmp_path: Path) -> None:
    """After the value check no page of the files stays mapped; after a fit, the pages the
    kernels read (a third of the files at most, those round the projected model) and short
    gaps between them, not all of them as memory maps of the files would hold."""
    folder = tmp_path / "flight"
    write_flight(simulate_flight(SimConfig(n_keyframes=60, seed=2, width=640, height=480)),
                 folder, heatmap_dtype="float32")
    total_kb = sum(p.stat().st_size for p in (folder / "heatmaps").iterdir()) // 1024
    flight = read_flight(folder)
    maps = flight.heatmaps.files
    assert maps is not None and maps.used_bytes() == 0
    assert _mapped_kb(folder / "heatmaps") == 0  # checked, and let go
    result = fit(flight, FitConfig(**FILE_FIT_DEFAULTS))
    assert result.verdict == "ok"
    used_kb = maps.used_bytes() // 1024
    assert 0 < used_kb < 0.35 * total_kb
    mapped_kb = _mapped_kb(folder / "heatmaps")
    assert mapped_kb < 0.5 * total_kb
    # a keyframe read whole (a plot, init) is let go again
    np.testing.assert_array_equal(flight.heatmaps[7], np.load(folder / "heatmaps" / "7.000000.npy"))
    assert _mapped_kb(folder / "heatmaps") <= mapped_kb


def test_values_checked_on_first_read(tmp_path: Path) -> None:
    """Maps read with ``check="first read"``: the solver's first search checks every
    keyframe it reads (no pass of its own), a value out of range stops it naming the first
    bad file, and ``check()`` covers those nothing read."""
    from turbinefit.heatmaps import HeatmapValueError
    from turbinefit.io.flight_folder import read_flight_folder
    from turbinefit.io.heatmap_files import value_error

    folder = tmp_path / "flight"
    write_flight(simulate_flight(SimConfig(n_keyframes=12, seed=3)), folder)
    flight_folder = read_flight_folder(folder)
    stack = flight_folder.read_heatmaps(check="first read")
    files = stack.files
    assert files is not None and not any(files.checked(k) for k in range(12))
    flight = flight_folder.flight(stack)
    fit(flight, FitConfig(**FILE_FIT_DEFAULTS))
    assert all(files.checked(k) for k in range(12)) and files.first_bad() == 12
    stack.check()  # nothing left
    np.testing.assert_array_equal(
        stack.coarse_grid(np.arange(12)),
        read_flight(folder).heatmaps.coarse_grid(np.arange(12)))

    for k, value in ((7, 1.5), (4, np.nan)):
        path = folder / "heatmaps" / f"{k}.000000.npy"
        maps = np.load(path)
        maps[3, 5, 6] = value
        np.save(path, maps)
    stack = read_flight_folder(folder).read_heatmaps(check="first read")
    with pytest.raises(HeatmapValueError) as info:
        fit(flight_folder.flight(stack), FitConfig(**FILE_FIT_DEFAULTS))
    assert info.value.keyframe == 4
    assert "NaN" in str(value_error(stack, 4, folder / "heatmaps" / "4.000000.npy"))
    stack = read_flight_folder(folder).read_heatmaps(check="first read")
    stack[0]
    for k in (7, 4, 7):  # each bad keyframe read raises, whichever was found first
        with pytest.raises(HeatmapValueError) as info:
            stack[k]
        assert info.value.keyframe == k
    with pytest.raises(HeatmapValueError) as info:
        stack.check()
    assert info.value.keyframe == 4
