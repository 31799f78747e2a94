"""Heat-map files of a flight folder (turbinefit.io.heatmap_files): maps smaller than the
photos fix the scale of the flight's camera; bad sizes are refused naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import assert_one_line_error, raises_input_error, run

from turbinefit.io.camera_yaml import format_camera_yaml
from turbinefit.io.flight_folder import read_flight, read_flight_folder, write_flight
from turbinefit.jobs.sources import FileHeatmaps
from turbinefit.sim.scenario import SimConfig, simulate_flight
from turbinefit.solver import FitConfig, fit


def _reduced_flight(tmp_path: Path) -> tuple[SimConfig, Path]:
    cfg = SimConfig(n_keyframes=12, seed=3, width=640, height=480, heatmap_size=(160, 120))
    folder = tmp_path / "flight"
    write_flight(simulate_flight(cfg), folder, camera=cfg.camera(), heatmap_dtype="float32")
    return cfg, folder


def test_reduced_maps_round_trip_with_the_scaled_camera_and_fit(tmp_path: Path) -> None:
    cfg, folder = _reduced_flight(tmp_path)
    flight = simulate_flight(cfg)
    assert (flight.heatmaps.width, flight.heatmaps.height) == (160, 120)
    assert flight.camera == cfg.camera().resized(160, 120)
    # camera.yaml is the photos' camera; the maps keep their own size
    assert (folder / "camera.yaml").read_text() == format_camera_yaml(cfg.camera())
    assert np.load(folder / "heatmaps" / "0.000000.npy").shape == (7, 120, 160)
    assert read_flight_folder(folder).camera == cfg.camera()
    for mmap in (True, False):
        back = read_flight(folder, mmap=mmap)
        assert back.camera == flight.camera
        for k in range(flight.num_keyframes):
            np.testing.assert_array_equal(back.heatmaps[k], flight.heatmaps[k])
    assert FileHeatmaps(read_flight_folder(folder)).camera == flight.camera
    # written again, the same folder
    write_flight(back, tmp_path / "again", camera=read_flight_folder(folder).camera)
    assert (tmp_path / "again" / "camera.yaml").read_text() == format_camera_yaml(cfg.camera())
    # the fit works in the maps' pixels: the same result as in memory, and it improves
    cfg_fit = FitConfig()
    a, b = fit(back, cfg_fit), fit(flight, cfg_fit)
    np.testing.assert_allclose(a.turbine.to_vector(), b.turbine.to_vector(), rtol=1e-8)
    assert a.final_cost < a.initial_cost


@pytest.mark.parametrize("native", ["1", "0"])
def test_float16_files_read_as_their_values_and_fit_as_float32_ones(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, native: str) -> None:
    monkeypatch.setenv("TURBINEFIT_NATIVE", native)
    cfg = SimConfig(n_keyframes=12, seed=4)
    flight = simulate_flight(cfg)
    write_flight(flight, tmp_path / "half")  # float16 by default
    write_flight(flight, tmp_path / "full", heatmap_dtype="float32")
    name = "heatmaps/0.000000.npy"
    assert np.load(tmp_path / "half" / name).dtype == np.float16
    assert (tmp_path / "half" / name).stat().st_size * 2 - 128 == \
        (tmp_path / "full" / name).stat().st_size
    half, full = read_flight(tmp_path / "half"), read_flight(tmp_path / "full")
    assert half.heatmaps.half and not full.heatmaps.half
    for k in range(flight.num_keyframes):
        assert half.heatmaps[k].dtype == np.float16  # memory-mapped as stored
        np.testing.assert_array_equal(
            half.heatmaps[k], full.heatmaps[k].astype(np.float16).astype(np.float32))
        np.testing.assert_allclose(half.heatmaps[k], full.heatmaps[k], rtol=0, atol=2.5e-4)
    # the fit of rounded maps: the same as of the exact ones, to well within its accuracy
    a, b = fit(half, FitConfig()), fit(full, FitConfig())
    np.testing.assert_allclose(a.world_T_cam.translation, b.world_T_cam.translation,
                               rtol=0, atol=0.01)
    np.testing.assert_allclose(a.turbine.to_vector(), b.turbine.to_vector(), rtol=0, atol=0.01)
    assert a.final_cost < a.initial_cost


@pytest.mark.parametrize("native", ["1", "0"])
def test_a_flight_may_mix_float16_and_float32_files_and_a_bad_float16_value_is_named(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, native: str) -> None:
    monkeypatch.setenv("TURBINEFIT_NATIVE", native)
    flight = simulate_flight(SimConfig(n_keyframes=5, seed=2))
    folder = tmp_path / "f"
    write_flight(flight, folder, heatmap_dtype="float32")
    f3 = folder / "heatmaps" / "3.000000.npy"
    np.save(f3, np.load(f3).astype(np.float16))
    for mmap in (True, False):
        back = read_flight(folder, mmap=mmap)  # one storage: float32
        assert not back.heatmaps.half and back.heatmaps.pointers() is not None
        for k in range(5):
            want = np.asarray(flight.heatmaps[k], dtype=np.float16 if k == 3 else np.float32)
            np.testing.assert_array_equal(back.heatmaps[k], want.astype(np.float32))
    bad = np.load(f3)
    bad[6, 10, 20] = np.float16(1.5)
    np.save(f3, bad)
    with raises_input_error(f3) as e:
        read_flight(folder)
    assert "channel 6 (line_blade) holds 1.5, outside [0, 1]" in str(e.value)


def test_write_flight_refuses_a_camera_that_is_not_the_maps_scale(tmp_path: Path) -> None:
    cfg = SimConfig(n_keyframes=2, width=640, height=480, heatmap_size=(160, 120))
    flight = simulate_flight(cfg)
    with pytest.raises(ValueError, match="not the 640x480 photo camera scaled"):
        write_flight(flight, tmp_path / "f", camera=SimConfig(width=640, height=480,
                                                              hfov_deg=60.0).camera())
    assert not (tmp_path / "f").exists()


@pytest.mark.parametrize("case", ["one_other_size", "other_aspect", "larger"])
def test_bad_heatmap_sizes_are_refused_naming_the_file(
        tmp_path: Path, case: str, capsys: pytest.CaptureFixture[str]) -> None:
    _, folder = _reduced_flight(tmp_path)
    files = sorted((folder / "heatmaps").iterdir())
    if case == "one_other_size":
        bad = files[5]
        np.save(bad, np.zeros((7, 240, 320), np.float32))
        pattern = r"shape \(7, 240, 320\), expected \(7, 120, 160\).*0\.000000\.npy"
    else:
        bad = files[0]
        size = (7, 120, 120) if case == "other_aspect" else (7, 960, 1280)
        for f in files:
            np.save(f, np.zeros(size, np.float32))
        pattern = ("not the camera's 640x480 scaled" if case == "other_aspect"
                   else "not inside the camera's 640x480")
    with raises_input_error(bad):
        read_flight(folder)
    rc, out, err = run(capsys, "fit", str(folder), "--out", str(tmp_path / "fit"), "--no-plots")
    assert_one_line_error(rc, out, err, "^turbinefit: error: " + str(bad), pattern)
    assert not (tmp_path / "fit").exists()
