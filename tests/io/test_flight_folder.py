"""Flight folders (turbinefit.io.flight_folder): round trips, reading errors named by file,
and atomic writing that never leaves half a flight."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest
from support import (
    H,
    W,
    assert_poses_close,
    leftovers,
    raises_input_error,
    random_flight,
    tiny_turbine,
    tum_timestamps,
)

import turbinefit.io.flight_folder as flight_folder
from turbinefit import _native
from turbinefit.errors import InputError
from turbinefit.flight import Flight
from turbinefit.heatmaps import HeatmapStack
from turbinefit.io import heatmap_filename, read_flight, read_heatmaps, read_tum, write_flight, write_tum


def as_written(maps: np.ndarray, dtype: str = "float16") -> np.ndarray:
    """Heat-maps as a flight folder written as ``dtype`` reads them back (float32)."""
    return np.asarray(maps).astype(dtype).astype(np.float32)


def assert_flights_equal(a: Flight, b: Flight, dtype: str = "float16") -> None:
    """``a`` read back from a folder ``b`` was written to (heat-maps as ``dtype``)."""
    assert a.camera == b.camera
    np.testing.assert_allclose(a.timestamps, b.timestamps, rtol=0, atol=1e-9)
    assert_poses_close(a.world_T_cam, b.world_T_cam)
    assert a.turbine == b.turbine
    assert a.gt_turbine == b.gt_turbine
    for name in ("odometry", "gt_world_T_cam"):
        pa, pb = getattr(a, name), getattr(b, name)
        assert (pa is None) == (pb is None)
        if pa is not None:
            assert_poses_close(pa, pb)
    assert len(a.heatmaps) == len(b.heatmaps)
    for k in range(len(a.heatmaps)):
        np.testing.assert_array_equal(a.heatmaps[k], as_written(b.heatmaps[k], dtype))


@pytest.mark.parametrize("dtype", ["float16", "float32"])
@pytest.mark.parametrize("mmap", [True, False])
def test_flight_round_trip_with_optional_files(tmp_path: Path, mmap: bool, dtype: str) -> None:
    flight = random_flight(optional=True)
    folder = tmp_path / "flight"
    assert write_flight(flight, folder, heatmap_dtype=dtype) == folder  # type: ignore[arg-type]
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["camera.yaml", "groundtruth.txt", "heatmaps", "keyframes.txt",
                     "odometry.txt", "turbine.yaml", "turbine_groundtruth.yaml"]
    assert sorted(p.name for p in (folder / "heatmaps").iterdir()) == sorted(
        heatmap_filename(t) for t in flight.timestamps)
    assert heatmap_filename(flight.timestamps[0]) == "1567000000.123456.npy"
    assert np.load(folder / "heatmaps" / heatmap_filename(flight.timestamps[0])).dtype == dtype

    back = read_flight(folder, mmap=mmap)
    assert_flights_equal(back, flight, dtype)
    assert back.has_ground_truth
    m = back.heatmaps[2]
    # memory maps keep the files' storage (read-only); mmap=False reads into float32
    assert m.dtype == (dtype if mmap else np.float32) and m.shape == (7, H, W)
    assert m.flags.writeable is (not mmap)
    assert back.heatmaps.half is (mmap and dtype == "float16")
    assert _native.native_maps(back.heatmaps) is not None  # the compiled kernels read either
    # the costs' access path works on both storages
    kf = np.array([0, 4])
    idx = np.array([[0, 7 * H * W - 1], [5, 123]])
    written = HeatmapStack([as_written(flight.heatmaps[k], dtype) for k in range(flight.num_keyframes)])
    np.testing.assert_array_equal(back.heatmaps.gather(kf, idx), written.gather(kf, idx))
    if dtype == "float16":  # within float16's rounding of values in [0, 1]
        np.testing.assert_allclose(back.heatmaps.gather(kf, idx),
                                   flight.heatmaps.gather(kf, idx), rtol=0, atol=2.5e-4)
    assert leftovers(tmp_path) == []


def test_flight_round_trip_minimal(tmp_path: Path) -> None:
    flight = random_flight(n=3, optional=False, distortion=False)
    folder = tmp_path / "a" / "b" / "flight"  # parents are created
    write_flight(flight, folder)
    assert sorted(p.name for p in folder.iterdir()) == ["camera.yaml", "heatmaps",
                                                        "keyframes.txt", "turbine.yaml"]
    back = read_flight(folder)
    assert_flights_equal(back, flight)
    assert back.odometry is None and back.gt_world_T_cam is None and back.gt_turbine is None
    assert not back.camera.has_distortion


def test_flight_heatmaps_converted_to_float32(tmp_path: Path) -> None:
    f32 = random_flight(n=2, optional=False)
    f64 = Flight(f32.camera, f32.timestamps, f32.world_T_cam,
                 HeatmapStack([f32.heatmaps[k].astype(np.float64) for k in range(2)]),
                 f32.turbine)
    write_flight(f64, tmp_path / "f", heatmap_dtype="float32")
    back = read_flight(tmp_path / "f")
    assert back.heatmaps[1].dtype == np.float32
    np.testing.assert_array_equal(back.heatmaps[1], f32.heatmaps[1])


def test_read_flight_1000_heatmaps_is_fast(tmp_path: Path) -> None:
    n, h, w = 1000, 6, 8
    hm = tmp_path / "heatmaps"
    hm.mkdir()
    rng = np.random.default_rng(3)
    t = tum_timestamps(n)
    maps = rng.random((n, 7, h, w), dtype=np.float32)
    for k in range(n):
        np.save(hm / heatmap_filename(t[k]), maps[k])
    t0 = time.perf_counter()
    stack = read_heatmaps(hm, t, h, w, mmap=True)
    elapsed = time.perf_counter() - t0
    assert len(stack) == n
    np.testing.assert_array_equal(stack[999], maps[999])
    assert elapsed < 0.5, elapsed  # ~0.02 s on a laptop; generous for slow CI
    loaded = read_heatmaps(hm, t, h, w, mmap=False)
    np.testing.assert_array_equal(loaded[500], maps[500])


@pytest.fixture
def flight_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "flight"
    write_flight(random_flight(optional=True), folder)
    return folder


def test_read_flight_missing_folder_and_files(tmp_path: Path, flight_dir: Path) -> None:
    with raises_input_error(tmp_path / "nope"):
        read_flight(tmp_path / "nope")
    (tmp_path / "file").write_text("x")
    with raises_input_error(tmp_path / "file"):
        read_flight(tmp_path / "file")
    for name in ("camera.yaml", "keyframes.txt", "turbine.yaml"):
        (flight_dir / name).rename(tmp_path / name)
        with raises_input_error(flight_dir / name) as info:
            read_flight(flight_dir)
        assert "missing" in str(info.value)
        (tmp_path / name).rename(flight_dir / name)
    (flight_dir / "heatmaps").rename(tmp_path / "hm")
    with raises_input_error(flight_dir / "heatmaps"):
        read_flight(flight_dir)


def test_read_flight_heatmaps_not_a_directory(tmp_path: Path, flight_dir: Path) -> None:
    hm = flight_dir / "heatmaps"
    hm.rename(tmp_path / "hm")
    hm.write_text("x")
    with raises_input_error(hm) as info:
        read_flight(flight_dir)
    assert "not a directory" in str(info.value)
    with raises_input_error(hm) as info:
        read_heatmaps(hm, [0.0], H, W)
    assert "not a directory" in str(info.value)


@pytest.mark.parametrize("name", ["camera.yaml", "heatmaps", "odometry.txt", "."])
def test_read_flight_inaccessible_path_is_an_input_error(flight_dir: Path, name: str,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    # what os.stat says below a directory without search (x) permission; as root a chmod
    # would not deny anything, so fake it
    target = flight_dir if name == "." else flight_dir / name
    real_stat = os.stat

    def stat(path, *args, **kwargs):
        if isinstance(path, str | os.PathLike) and Path(path) == target:
            raise PermissionError(13, "Permission denied", str(path))
        return real_stat(path, *args, **kwargs)

    monkeypatch.setattr(os, "stat", stat)
    with raises_input_error(target) as info:
        read_flight(flight_dir)
    assert "cannot access: Permission denied" in str(info.value)


def test_read_flight_errors_inside_files_name_them(flight_dir: Path) -> None:
    kf = flight_dir / "keyframes.txt"
    lines = kf.read_text().splitlines()
    lines[3] = lines[3].replace(" ", " x ", 1)
    kf.write_text("\n".join(lines) + "\n")
    with raises_input_error(kf, line=4):
        read_flight(flight_dir)


def test_read_flight_missing_heatmap_names_file(flight_dir: Path) -> None:
    t = read_tum(flight_dir / "keyframes.txt")[0]
    missing = flight_dir / "heatmaps" / heatmap_filename(t[2])
    missing.unlink()
    with raises_input_error(missing) as info:
        read_flight(flight_dir)
    assert "keyframe 2" in str(info.value)
    assert "keyframes.txt, line" in str(info.value)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: np.save(p, np.zeros((7, H, W + 1), np.float32)), "shape (7, 24, 33)"),
        (lambda p: np.save(p, np.zeros((H, W), np.float32)), "shape (24, 32)"),
        (lambda p: np.save(p, np.zeros((7, H, W), np.float64)), "dtype <f8"),
        (lambda p: np.save(p, np.zeros((7, H, W), ">f4")), "dtype >f4"),
        (lambda p: np.save(p, np.asfortranarray(np.zeros((7, H, W), np.float32))), "Fortran"),
        (lambda p: p.write_bytes(b"this is not a numpy file at all"), "not a .npy"),
        (lambda p: p.write_bytes(b""), "not a .npy"),
        (lambda p: p.write_bytes(b"\x93NUMPY\x01\x00\x10\x00{'descr': garbage"), "header"),
        (lambda p: p.write_bytes(_npy_bytes()[:-10]), "truncated"),
    ],
)
@pytest.mark.parametrize("mmap", [True, False])
def test_read_flight_bad_heatmap_names_file(flight_dir: Path, make, message: str,
                                            mmap: bool) -> None:
    t = read_tum(flight_dir / "keyframes.txt")[0]
    bad = flight_dir / "heatmaps" / heatmap_filename(t[3])
    bad.unlink()
    make(bad)
    with raises_input_error(bad) as info:
        read_flight(flight_dir, mmap=mmap)
    assert message in str(info.value)


def _npy_bytes() -> bytes:
    import io
    buf = io.BytesIO()
    np.save(buf, np.zeros((7, H, W), np.float32))
    return buf.getvalue()


@pytest.mark.parametrize("name", ["odometry.txt", "groundtruth.txt"])
def test_read_flight_timestamp_mismatch(flight_dir: Path, name: str) -> None:
    path = flight_dir / name
    t, poses = read_tum(path)
    t_bad = t.copy()
    t_bad[2] += 2e-6
    write_tum(path, t_bad, poses)
    with raises_input_error(path, line=4) as info:  # a header line, then poses 0, 1, 2
        read_flight(flight_dir)
    assert "keyframe 2" in str(info.value)
    # within the tolerance is fine (edit the text: write_tum prints microseconds)
    write_tum(path, t, poses)
    lines = path.read_text().splitlines()
    _stamp, rest = lines[3].split(" ", 1)
    lines[3] = f"{t[2] + 6e-7:.7f} {rest}"
    path.write_text("\n".join(lines) + "\n")
    back = read_flight(flight_dir)
    assert 3e-7 < abs(read_tum(path)[0][2] - t[2]) < 1e-6
    attr = "odometry" if name == "odometry.txt" else "gt_world_T_cam"
    assert_poses_close(getattr(back, attr), poses)
    write_tum(path, t[:-1], poses[:-1])
    with raises_input_error(path) as info:
        read_flight(flight_dir)
    assert "4 poses but keyframes.txt has 5" in str(info.value)


def test_read_flight_bad_optional_turbine(flight_dir: Path) -> None:
    path = flight_dir / "turbine_groundtruth.yaml"
    path.write_text(path.read_text().replace("tower_height", "height"))
    with raises_input_error(path, field="height"):
        read_flight(flight_dir)


def test_write_flight_refuses_non_empty_folder(tmp_path: Path, flight_dir: Path) -> None:
    before = sorted(p.name for p in flight_dir.iterdir())
    with raises_input_error(flight_dir) as info:
        write_flight(random_flight(seed=5), flight_dir)
    assert "overwrite" in str(info.value)
    assert sorted(p.name for p in flight_dir.iterdir()) == before
    assert leftovers(tmp_path) == []
    # an empty folder is fine
    empty = tmp_path / "empty"
    empty.mkdir()
    write_flight(random_flight(n=2), empty)
    assert len(read_flight(empty).timestamps) == 2
    # a file in the way is refused even with overwrite
    (tmp_path / "file").write_text("x")
    with raises_input_error(tmp_path / "file"):
        write_flight(random_flight(), tmp_path / "file", overwrite=True)


def test_write_flight_overwrite_replaces(tmp_path: Path, flight_dir: Path) -> None:
    new = random_flight(n=3, seed=9, optional=False)
    write_flight(new, flight_dir, overwrite=True)
    assert not (flight_dir / "odometry.txt").exists()
    assert len(list((flight_dir / "heatmaps").iterdir())) == 3
    assert_flights_equal(read_flight(flight_dir), new)
    assert leftovers(tmp_path) == []


def test_write_flight_overwrite_in_place_from_memory_maps(tmp_path: Path,
                                                          flight_dir: Path) -> None:
    write_flight(random_flight(optional=True), flight_dir, overwrite=True,
                 heatmap_dtype="float32")  # memory-mapped on reading
    original = read_flight(flight_dir, mmap=True)
    assert not original.heatmaps[0].flags.writeable
    changed = Flight(original.camera, original.timestamps, original.world_T_cam,
                     original.heatmaps, tiny_turbine(offset=7.0), original.odometry)
    write_flight(changed, flight_dir, overwrite=True)
    back = read_flight(flight_dir, mmap=False)
    assert back.turbine.base_x == tiny_turbine().base_x + 7.0
    assert back.gt_turbine is None
    expected = random_flight(optional=True)
    for k in range(len(expected.heatmaps)):
        np.testing.assert_array_equal(back.heatmaps[k], as_written(expected.heatmaps[k]))
    assert leftovers(tmp_path) == []


def test_write_flight_overwrite_refuses_foreign_folder(tmp_path: Path, flight_dir: Path) -> None:
    (flight_dir / "notes.md").write_text("mine")
    with raises_input_error(flight_dir) as info:
        write_flight(random_flight(), flight_dir, overwrite=True)
    assert "notes.md" in str(info.value)
    assert (flight_dir / "notes.md").read_text() == "mine"
    (flight_dir / "notes.md").unlink()
    (flight_dir / "heatmaps" / "readme.txt").write_text("x")
    with raises_input_error(flight_dir):
        write_flight(random_flight(), flight_dir, overwrite=True)


def test_write_flight_extra_texts_are_written_and_replaceable(tmp_path: Path) -> None:
    folder = tmp_path / "flight"
    write_flight(random_flight(n=2), folder, extra_texts={"simulation.yaml": "seed: 1\n"})
    assert (folder / "simulation.yaml").read_text() == "seed: 1\n"
    assert_flights_equal(read_flight(folder), random_flight(n=2))  # ignored on reading
    # a folder write_flight wrote, simulation.yaml included, is a flight folder to replace
    assert "simulation.yaml" in flight_folder.FLIGHT_ENTRIES
    flight_folder.check_flight_destination(folder, overwrite=True)
    write_flight(random_flight(n=3, seed=1), folder, overwrite=True,
                 extra_texts={"simulation.yaml": "seed: 2\n"})
    assert (folder / "simulation.yaml").read_text() == "seed: 2\n"
    write_flight(random_flight(n=3, seed=1), folder, overwrite=True)  # without one: removed
    assert not (folder / "simulation.yaml").exists()
    assert leftovers(tmp_path) == []
    # only names the guard accepts, and not the flight's own files
    for name in ("notes.txt", "camera.yaml", "heatmaps"):
        with pytest.raises(ValueError, match="extra_texts"):
            write_flight(random_flight(n=2), tmp_path / "other", extra_texts={name: "x"})
    assert not (tmp_path / "other").exists()


def test_check_flight_destination(tmp_path: Path, flight_dir: Path) -> None:
    flight_folder.check_flight_destination(tmp_path / "new")  # missing: fine
    with raises_input_error(flight_dir) as info:
        flight_folder.check_flight_destination(flight_dir, overwrite_hint="use --overwrite")
    assert str(info.value).endswith("not empty (use --overwrite)")
    flight_folder.check_flight_destination(flight_dir, overwrite=True)
    (flight_dir / "notes.md").write_text("mine")
    with raises_input_error(flight_dir) as info:
        flight_folder.check_flight_destination(flight_dir, overwrite=True)
    assert "'notes.md' is not part of a flight folder" in str(info.value)


@pytest.mark.parametrize("existing", [False, True])
def test_write_flight_failure_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             existing: bool) -> None:
    folder = tmp_path / "flight"
    if existing:
        write_flight(random_flight(n=2, optional=False), folder)
    calls = {"n": 0}
    real_save = np.save

    def failing_save(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise OSError(28, "No space left on device")
        return real_save(*args, **kwargs)

    monkeypatch.setattr(flight_folder.np, "save", failing_save)
    with pytest.raises(InputError, match=r"no space left on device writing .*heatmaps"):
        write_flight(random_flight(n=5), folder, overwrite=True)
    assert calls["n"] == 3
    assert leftovers(tmp_path) == []
    if existing:
        assert len(read_flight(folder).timestamps) == 2  # old flight untouched
    else:
        assert not folder.exists()


def test_write_flight_rejects_timestamps_closer_than_a_microsecond(tmp_path: Path) -> None:
    f = random_flight(n=2, optional=False)
    bad = Flight(f.camera, np.array([5.0, 5.0000001]), f.world_T_cam, f.heatmaps, f.turbine)
    with raises_input_error(tmp_path / "f" / "keyframes.txt", field="timestamps"):
        write_flight(bad, tmp_path / "f")
    assert list(tmp_path.iterdir()) == []
