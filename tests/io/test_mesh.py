"""The fitted turbine as a glTF file (turbinefit.io.mesh): read back with trimesh, the
world frame turned to glTF's y up, smooth normals split at sharp edges, atomic writes."""

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from support import assert_turbine_glb, raises_input_error

from turbinefit.io.mesh import GLTF_FROM_WORLD, smooth_normals, turbine_glb, write_turbine_glb
from turbinefit.turbine.model import TurbineGeometry, TurbineParams
from turbinefit.turbine.solid import TurbineSolid, solid_mesh

#: Far from the origin (as a projected frame may be): the vertices stay precise.
THETA = TurbineParams(512_345.5, 5_401_234.25, 87.6, 2.4, 5.0, 0.9, 63.0)


@pytest.mark.parametrize("geometry", [TurbineGeometry(), TurbineGeometry(0.087, 0.044, 2.5)])
def test_glb_reads_back_as_the_fitted_turbine(tmp_path: Path, geometry: TurbineGeometry) -> None:
    path = write_turbine_glb(tmp_path / "turbine.glb", THETA, geometry)
    assert path == tmp_path / "turbine.glb" and [p.name for p in tmp_path.iterdir()] == ["turbine.glb"]
    assert_turbine_glb(path, THETA, geometry)


def test_glb_layout_and_frame() -> None:
    data = turbine_glb(THETA, TurbineGeometry())
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert (magic, version, length) == (b"glTF", 2, len(data))
    n, kind = struct.unpack("<I4s", data[12:20])
    assert kind == b"JSON"
    doc = json.loads(data[20:20 + n])
    assert [node["name"] for node in doc["nodes"]] == ["tower", "nacelle", "spinner", "blade_1",
                                                       "blade_2", "blade_3"]
    # every node: the base added, then z up -> y up: world (x, y, z) -> glTF (x, z, -y)
    m = np.array(doc["nodes"][0]["matrix"]).reshape(4, 4).T
    np.testing.assert_array_equal(m[:3, :3], GLTF_FROM_WORLD[:3, :3])
    np.testing.assert_array_equal(m[:3, 3], [THETA.base_x, 0.0, -THETA.base_y])
    assert GLTF_FROM_WORLD[:3, :3] @ np.array([0.0, 0.0, 1.0]) == pytest.approx([0, 1, 0])
    # positions are float32 relative to the base: a 60 m blade is to the millimetre
    pos = doc["accessors"][doc["meshes"][3]["primitives"][0]["attributes"]["POSITION"]]
    assert pos["componentType"] == 5126 and max(map(abs, pos["max"] + pos["min"])) < 200


def test_smooth_normals_split_only_sharp_edges() -> None:
    parts = {p.name: p for p in solid_mesh(TurbineSolid(THETA.to_vector()))}
    # the box: every corner split three ways, each face flat
    v, n, f = smooth_normals(parts["nacelle"], np.radians(40.0))
    assert len(v) == 24 and len(f) == 12
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    np.testing.assert_allclose(n[f[:, 0]], fn, atol=1e-9)
    # the tower: the side is smooth, the flat ends split off (two rings + two centres, twice)
    tower = parts["tower"]
    v, n, f = smooth_normals(tower, np.radians(40.0))
    assert len(v) == len(tower.vertices) * 2 - 2
    side = np.abs(n[:, 2]) < 0.1
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    # side normals point away from the tower axis
    r = v[side, :2] - [THETA.base_x, THETA.base_y]
    assert np.all(np.einsum("ij,ij->i", r, n[side, :2]) > 0)


def test_write_into_a_directory_is_refused(tmp_path: Path) -> None:
    (tmp_path / "turbine.glb").mkdir()
    with raises_input_error(tmp_path / "turbine.glb"):
        write_turbine_glb(tmp_path / "turbine.glb", THETA, TurbineGeometry())


def _gltf_json(data: bytes) -> dict:
    n = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + n])


def test_glb_records_its_georeference() -> None:
    """asset.extras.turbinefit_georeference: a point of the model taken to Earth-centred
    coordinates by its ecef_from_enu (after 3D Tiles' y-up to z-up turn) is where pymap3d
    puts the same east-north-up point; without a georeference, no block."""
    import pymap3d

    from turbinefit.io.georef import Georef

    georef = Georef(-33.87, 151.21, 35.0)
    turbine = TurbineParams(40.0, -25.0, 87.6, 2.4, 5.0, 0.9, 63.0)
    doc = _gltf_json(turbine_glb(turbine, TurbineGeometry(), georef))
    block = doc["asset"]["extras"]["turbinefit_georeference"]
    assert (block["latitude"], block["longitude"], block["altitude"]) == (-33.87, 151.21, 35.0)
    ecef_from_enu = np.array(block["ecef_from_enu"]).reshape(4, 4).T
    # the tower base node's origin in glTF: (x, y, z)_glTF = (east, up, -north)
    gltf = np.array(doc["nodes"][0]["matrix"]).reshape(4, 4).T[:, 3]
    enu = np.array([gltf[0], -gltf[2], gltf[1], 1.0])  # 3D Tiles: y up to z up
    want = pymap3d.enu2ecef(40.0, -25.0, 0.0, -33.87, 151.21, 35.0)
    np.testing.assert_allclose((ecef_from_enu @ enu)[:3], want, atol=1e-6)
    assert _gltf_json(turbine_glb(turbine, TurbineGeometry()))["asset"].get("extras") in (None, {})
