"""Plain helpers the tests import (``from support import ...``): cameras and poses, synthetic
heat-maps and flights, finite differences on the pose manifold, and checks of file errors
and of command-line runs. Fixtures live in the ``conftest.py`` files."""

from __future__ import annotations

import hashlib
import math
import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from turbinefit.errors import InputError
from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3, quat_normalize
from turbinefit.heatmaps import HeatmapStack
from turbinefit.turbine.model import TurbineGeometry, TurbineParams, line_samples, model_points

# ------------------------------------------------------------------ cameras, poses, turbines

#: A 320 x 240 pinhole camera without distortion.
CAMERA = PinholeCamera(320, 240, 228.0, 228.0, 159.5, 119.5)
#: The camera of the simulator tests (a slightly longer focal length).
SIM_CAMERA = PinholeCamera(320, 240, 228.5, 228.5, 159.5, 119.5)
#: A turbine of NREL 5 MW size.
NRE = TurbineParams(1.0, -2.0, 87.6, 0.6, 5.0, 0.3, 63.0)


def look_at(eye: np.ndarray, target: np.ndarray) -> SE3:
    """world_T_cam of OpenCV cameras at ``eye`` (N, 3) looking at ``target`` (N, 3), y down."""
    eye = np.atleast_2d(eye).astype(float)
    target = np.atleast_2d(target).astype(float)
    z = target - eye
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    up = np.array([0.0, 0.0, 1.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=-1)
    return SE3.from_rotation_translation(R, eye)


def pose_looking_at(eye: object, target: object) -> SE3:
    """One world_T_cam at ``eye`` (3,) looking at ``target`` (3,)."""
    return look_at(np.asarray(eye, float), np.asarray(target, float))[0]


def orbit_poses(n: int, radius: float = 120.0, height: float = 60.0,
                centre: tuple[float, float, float] = (0.0, 0.0, 70.0)) -> SE3:
    """``n`` cameras on an arc round ``centre``, looking at it."""
    ang = np.linspace(0, 1.2, n)
    eye = np.stack([radius * np.cos(ang), radius * np.sin(ang), np.full(n, height)], -1)
    return look_at(eye, np.tile(np.array(centre), (n, 1)))


def random_poses(rng: np.random.Generator, n: int) -> SE3:
    """``n`` random poses (translations of ~50 m)."""
    q = quat_normalize(rng.normal(size=(n, 4)))
    t = rng.normal(scale=50.0, size=(n, 3))
    return SE3(np.concatenate([q, t], axis=1))


# ------------------------------------------------------------------ heat-maps and flights

def smooth_heatmaps(n: int, h: int = 240, w: int = 320, seed: int = 0) -> np.ndarray:
    """(n, 7, h, w) float32 sums of wide Gaussian bumps in (0.05, 0.95): smooth, no clamping."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    out = np.empty((n, 7, h, w), dtype=np.float32)
    for k in range(n):
        for c in range(7):
            acc = np.zeros((h, w))
            for _ in range(4):
                cu, cv = rng.uniform(0, w), rng.uniform(0, h)
                s = rng.uniform(20, 50)
                acc += rng.uniform(0.2, 1.0) * np.exp(-((u - cu) ** 2 + (v - cv) ** 2) / (2 * s * s))
            out[k, c] = 0.05 + 0.9 * acc / acc.max()
    return out


def simulated_flight(n: int, name: str = "default", seed: int = 0, width: int = 160,
                     **overrides: object) -> Flight:
    """A flight of ``n`` keyframes simulated from the preset ``name``, heat-maps of
    ``width`` x 3/4 ``width`` pixels."""
    from turbinefit.sim.scenario import preset, simulate_flight

    return simulate_flight(preset(name, n_keyframes=n, seed=seed, width=width,
                                  height=width * 3 // 4, **overrides))


#: Heat-map size of :func:`random_flight`.
H, W = 24, 32


def tum_timestamps(n: int, start: float = 1567000000.123456) -> np.ndarray:
    """Timestamps with six decimals, as a TUM file stores them."""
    return np.array([float(f"{start + 0.25 * k + 1e-6 * k:.6f}") for k in range(n)])


def tiny_camera(distortion: bool = True) -> PinholeCamera:
    """A W x H camera, with plumb-bob distortion unless ``distortion`` is False."""
    d = (-0.12, 0.034, 1e-5, -2.5e-4, 0.0012) if distortion else (0.0,) * 5
    return PinholeCamera(W, H, 30.5, 31.25, 15.75, 11.5, 0.0, d)  # type: ignore[arg-type]


def tiny_turbine(offset: float = 0.0) -> TurbineParams:
    """A turbine with many-digit parameters (for exact round trips)."""
    return TurbineParams(12.5 + offset, -3.25, 80.1, 1.2345678901234567, 4.0, 0.3, 40.7)


def random_flight(n: int = 5, seed: int = 0, optional: bool = True,
                  distortion: bool = True) -> Flight:
    """A flight of random poses and heat-maps (for file round trips), with odometry and
    ground truth if ``optional``."""
    rng = np.random.default_rng(seed)
    maps = rng.random((n, 7, H, W), dtype=np.float32)
    return Flight(
        camera=tiny_camera(distortion),
        timestamps=tum_timestamps(n),
        world_T_cam=random_poses(rng, n),
        heatmaps=HeatmapStack(maps),
        turbine=tiny_turbine(),
        odometry=random_poses(rng, n) if optional else None,
        gt_world_T_cam=random_poses(rng, n) if optional else None,
        gt_turbine=tiny_turbine(0.5) if optional else None,
    )


def photo_px(uv: np.ndarray, scale: int) -> np.ndarray:
    """Heat-map pixel coordinates -> photo pixel coordinates (pixel centres aligned)."""
    return (np.asarray(uv, dtype=np.float64) + 0.5) * scale - 0.5


# ------------------------------------------------------------------ finite differences

FD_EPS = 1e-6
#: Turbine parameters the cost derivatives are checked at.
FD_THETA = np.array([0.0, 0.0, 80.0, 0.6, 5.0, 0.3, 50.0])


def perturb(poses: SE3, theta: np.ndarray, k: int, i: int, eps: float) -> tuple[SE3, np.ndarray]:
    """Perturb local coordinate i (0-5 pose k, 6-12 theta) by eps."""
    if i < 6:
        d = np.zeros((len(poses), 6))
        d[k, i] = eps
        return poses.retract(d), theta
    t = theta.copy()
    t[i - 6] += eps
    return poses, t


def model_and_samples(theta: np.ndarray, with_j: bool = True
                      ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The 6 model points and 6 samples per line: (points, d points / d theta, channels)."""
    P, JP = model_points(theta, with_jacobian=with_j)
    S, JS, ch = line_samples(P, JP, 6)
    return np.concatenate([P, S]), (None if JP is None else np.concatenate([JP, JS])), ch


# ------------------------------------------------------------------ files

def raises_input_error(path: Path, line: int | None = None, field: str | None = None):
    """pytest.raises for an InputError whose message names ``path`` (and line/field)."""
    pattern = "^" + re.escape(str(path))
    pattern += re.escape(f":{line}") if line is not None else r"(?::\d+)?"
    pattern += re.escape(f" [{field}]") if field is not None else r"(?: \[[^\]]*\])?"
    return pytest.raises(InputError, match=pattern + ": ")


def assert_poses_close(a: SE3, b: SE3, tol: float = 1e-9) -> None:
    assert a.batch_shape == b.batch_shape
    np.testing.assert_allclose(a.wxyz_xyz, b.wxyz_xyz, rtol=0, atol=tol)


def leftovers(parent: Path) -> list[str]:
    """Hidden temporary entries left in ``parent`` by atomic writes."""
    return sorted(p.name for p in parent.iterdir() if p.name.startswith("."))


def digest(folder: Path) -> dict[str, tuple[str, int]]:
    """{relative path: (sha256, mtime_ns)} of every file below ``folder``, hidden ones too."""
    return {
        str(p.relative_to(folder)): (hashlib.sha256(p.read_bytes()).hexdigest(), p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*")) if p.is_file()
    }


def entries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def assert_valid_png(path: Path) -> tuple[int, int]:
    """Walk the PNG's chunks (CRCs checked), inflate the image data and check its size."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name}: not a PNG"
    pos, kinds, idat, ihdr = 8, [], b"", b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"{path.name}: bad CRC in {kind!r}"
        kinds.append(kind)
        if kind == b"IHDR":
            ihdr = body
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    assert pos == len(data), f"{path.name}: truncated"
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND", kinds
    width, height, depth, colour = struct.unpack(">IIBB", ihdr[:10])
    assert depth == 8 and colour in (0, 2, 4, 6), (depth, colour)
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    assert len(zlib.decompress(idat)) == height * (1 + width * channels)
    assert width >= 200 and height >= 200, (width, height)
    return width, height


def assert_turbine_glb(path: Path, turbine: TurbineParams, geometry: TurbineGeometry) -> None:
    """Read ``turbine.glb`` back with trimesh (an independent glTF reader) and check it is
    ``turbine``: six closed parts with valid faces; in the world frame (glTF's y up turned
    back to z up) the tower stands on the base up to the tower top, the spinner sits on the
    hub and each blade runs from the hub to its tip, at the fitted blade rotation."""
    import trimesh

    scene = trimesh.load(path, file_type="glb")
    assert scene.metadata["turbinefit"]["turbine"] == pytest.approx(turbine.to_dict())
    names = {"tower", "nacelle", "spinner", "blade_1", "blade_2", "blade_3"}
    assert set(scene.graph.nodes_geometry) == names
    world: dict[str, np.ndarray] = {}
    for name in names:
        node_T_mesh, geom = scene.graph[name]
        mesh = scene.geometry[geom]
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        assert len(v) > 0 and np.isfinite(v).all(), name
        assert f.min() >= 0 and f.max() < len(v), name
        assert mesh.area_faces.min() > 1e-8, name  # no degenerate triangle
        closed = mesh.copy()
        closed.merge_vertices(merge_tex=True, merge_norm=True)  # normals split sharp edges
        assert closed.is_watertight and closed.is_winding_consistent and closed.volume > 0, name
        gltf = v @ node_T_mesh[:3, :3].T + node_T_mesh[:3, 3]
        world[name] = np.stack([gltf[:, 0], -gltf[:, 2], gltf[:, 1]], axis=1)  # y up -> z up
    p, _ = model_points(turbine.to_vector(), geometry)
    base, top, hub, tips = p[0], p[1], p[2], p[3:]
    h, b = turbine.tower_height, abs(turbine.blade_length)
    tower = world["tower"]
    assert tower[:, 2].min() == pytest.approx(base[2], abs=1e-3)
    assert top[2] - 1e-3 <= tower[:, 2].max() <= max(top[2], hub[2]) + 1e-3
    np.testing.assert_allclose(0.5 * (tower.min(0) + tower.max(0))[:2], base[:2], atol=1e-3)
    assert 0.5 * np.ptp(tower[:, 0]) == pytest.approx(h / 30, rel=0.01)  # base radius
    spinner = world["spinner"]
    assert np.linalg.norm(spinner.mean(0) - hub) < 0.05 * b
    for i in range(3):
        d = world[f"blade_{i + 1}"] - hub
        reach = np.linalg.norm(d, axis=1)
        assert b * 0.999 <= reach.max() <= b * 1.001 + 1e-3
        far = d[np.argmax(reach)] / reach.max()
        assert far @ (tips[i] - hub) / np.linalg.norm(tips[i] - hub) > math.cos(math.radians(0.5))


# ------------------------------------------------------------------ the command line

#: `turbinefit simulate` options of the small flight of ``sim_flight_dir`` (conftest.py).
SIM_ARGS = ["--keyframes", "12", "--seed", "3", "--width", "160", "--height", "120"]
N_KEYFRAMES = 12
FIT_OUTPUTS = {"keyframes.txt", "turbine.yaml", "turbine.glb", "config.yaml", "summary.json"}


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """Run the CLI in-process; returns (exit status, stdout, stderr)."""
    from turbinefit.cli import main

    capsys.readouterr()  # drop anything printed before
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def assert_one_line_error(rc: int, out: str, err: str, *patterns: str) -> str:
    """Exit status 2, nothing on stdout, exactly one stderr line ``turbinefit: error: ...``
    matching every regex in ``patterns``, no traceback. Returns the line."""
    assert rc == 2, f"exit status {rc}, stderr: {err!r}"
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one stderr line, got {lines!r}"
    assert err.endswith("\n")
    line = lines[0]
    assert line.startswith("turbinefit: error: "), line
    assert "\r" not in line  # no progress-bar residue in front of the message
    for pat in patterns:
        assert re.search(pat, line), f"{pat!r} not in {line!r}"
    assert out == ""
    return line


def one_line_error(capsys: pytest.CaptureFixture[str], *words: str) -> str:
    """The captured stderr is one ``turbinefit: error: ...`` line holding every word."""
    err = capsys.readouterr().err
    assert err.startswith("turbinefit: error: "), err
    assert len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def poses_array(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(timestamps, wxyz_xyz) of a TUM file."""
    from turbinefit.io import read_tum

    t, poses = read_tum(path)
    return t, np.asarray(poses.wxyz_xyz)


def heatmap(flight: Path, k: int) -> Path:
    """The heat-map file of keyframe ``k`` (timestamp k) of a simulated flight folder."""
    return flight / "heatmaps" / f"{float(k):.6f}.npy"


# ------------------------------------------------------------------ sweeps

#: A sweep small enough for a test.
TINY = dict(flights=3, keyframes=12, width=160, height=120)


def tiny_sweep(study: str = "unary", **kw: object):
    """The configuration of ``study``, made :data:`TINY` (and changed by ``kw``)."""
    import dataclasses

    from turbinefit.experiments import study_config

    return dataclasses.replace(study_config(study), **{**TINY, **kw})  # type: ignore[arg-type]


# ------------------------------------------------------------------ DJI photos

#: The WGS84 origin the DJI tests place simulated flights at (the take-off point).
DJI_ORIGIN = (51.4545, -2.5879, 30.0)


def dji_test_poses(n: int = 5) -> SE3:
    """``n`` cameras 20-80 m up around a turbine, looking at it from several sides and
    pitches, with a few degrees of roll (ENU about :data:`DJI_ORIGIN`)."""
    from turbinefit.geometry.se3 import world_T_cam_from_angles

    k = np.arange(n, dtype=np.float64)
    az = 0.9 * k - 2.0
    pos = np.stack([60 * np.cos(az), 60 * np.sin(az), 20 + 15 * k], axis=-1)
    return world_T_cam_from_angles(pos, az + np.pi + 0.1 * np.sin(k), -0.15 - 1.3 * k / max(n - 1, 1),
                                   0.05 * np.cos(3 * k))


def write_dji_photos(folder: Path, world_T_cam: SE3, timestamps: np.ndarray,
                     images: list[np.ndarray] | None = None, size: tuple[int, int] = (64, 48),
                     names: str = "DJI_{:04d}.JPG", **metadata: object) -> list[Path]:
    """DJI-style JPEGs (real XMP packets and EXIF, :mod:`turbinefit.sim.dji_photos`) of
    cameras ``world_T_cam`` (ENU about :data:`DJI_ORIGIN`) at ``timestamps``; pixels from
    ``images`` or flat grey of ``size``; ``metadata``: options of ``dji_metadata``."""
    from turbinefit.io.georef import Georef
    from turbinefit.sim.dji_photos import dji_poses, write_dji_photo

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k, pose in enumerate(dji_poses(Georef(*DJI_ORIGIN), world_T_cam, timestamps)):
        pixels = (images[k] if images is not None
                  else np.full((size[1], size[0], 3), 90 + 10 * k, np.uint8))
        out.append(write_dji_photo(folder / names.format(k), pixels, pose, **metadata))  # type: ignore[arg-type]
    return out
