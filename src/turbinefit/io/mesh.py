"""The fitted turbine as a 3-D model file, ``turbine.glb`` (binary glTF 2.0), that any 3-D
viewer opens (Blender, MeshLab, online glTF viewers, Windows 3D Viewer).

The model is the solid of :mod:`turbinefit.turbine.solid` round the fitted skeleton (the
shapes the photo renderer draws): a tapered tower, a nacelle box, a spinner and three
tapered, twisted blades at the fitted blade rotation (chord in the rotor plane: pitch 0).
Each part is a closed triangle mesh (smooth normals, split where faces meet at more than
40 degrees) in a node of its own named ``tower``, ``nacelle``, ``spinner``, ``blade_1`` ..
``blade_3`` (the blade of ``tip_1`` .. ``tip_3``), with a plain off-white material.

Frame: the vertices are metres relative to the tower base, and each node's matrix turns
them into glTF's frame: the world frame of the fit (that of ``keyframes.txt`` and
``turbine.yaml``: metres, z up) moved to glTF's y-up convention, ``(x, y, z)_glTF =
(x, z, -y)_world`` (:data:`GLTF_FROM_WORLD`), so the turbine stands upright in a viewer and
its base is at the fitted place (in double precision: the node's matrix is JSON). The
scene's ``extras`` hold the fitted turbine, the shape details and that rule.

**Georeference.** On a georeferenced flight the glTF's ``asset.extras`` hold
``turbinefit_georeference`` (:func:`georeference_extras`): the world frame's WGS84 origin
(``latitude``, ``longitude``, ``altitude`` in the flight's datum), the axes (glTF x east,
y up, z south: ``(x, y, z)_glTF = (east, up, -north)``) and ``ecef_from_enu``, the 4 x 4
transform (column-major, as glTF and 3D Tiles write matrices) from east-north-up metres
about the origin to Earth-centred Earth-fixed WGS84 metres. That is the ``transform`` a
3D Tiles tileset (CesiumJS, Cesium ion, ArcGIS, QGIS 3.34's tiled scenes) gives its
root tile for this file as content, since 3D Tiles turns a glTF's y-up into z-up
(east-north-up here) before it; an extras block rather than an extension because no
glTF 2.0 extension georeferences a model (CESIUM_RTC was glTF 1.0's, and sets a centre
but no orientation).

Written by hand (:func:`glb_bytes`): a binary glTF is a 12-byte header and two chunks, the
JSON document and the buffer (glTF 2.0, section 4.4 "GLB File Format Specification"), which
``json``, ``struct`` and numpy write directly. A library made for the job would cost every
fit and track its import for a file of a hundred kB: pygltflib writes the same bytes but
imports dataclasses_json and marshmallow, 0.06 s on an idle machine and 0.1-0.3 s on a busy
one (``python -X importtime -c "import numpy; import pygltflib"``), as long as the rest of
writing a fit's outputs; trimesh pulls in scipy.spatial and networkx (0.6-1.7 s). The tests
read the files back with trimesh, an independent reader.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.io.atomic import StrPath, write_bytes_atomic
from turbinefit.io.georef import Georef
from turbinefit.turbine.model import TurbineGeometry, TurbineParams
from turbinefit.turbine.solid import SolidPart, TurbineSolid, solid_mesh

FloatArray = NDArray[np.float64]

#: glTF (y up) from the world frame (z up): ``(x, y, z) -> (x, z, -y)``, a rotation of
#: -90 degrees about x.
GLTF_FROM_WORLD = np.array([[1.0, 0.0, 0.0, 0.0],
                            [0.0, 0.0, 1.0, 0.0],
                            [0.0, -1.0, 0.0, 0.0],
                            [0.0, 0.0, 0.0, 1.0]])
#: Base colour of each part (linear RGB): off-white paint, the blades a touch lighter.
PART_COLOURS = {"tower": (0.74, 0.75, 0.76), "nacelle": (0.70, 0.71, 0.73),
                "spinner": (0.62, 0.64, 0.66), "blade": (0.84, 0.85, 0.86)}
#: Faces meeting at more than this angle [deg] get separate normals (a sharp edge).
SHARP_EDGE_DEG = 40.0

# glTF constants (the specification's numbers)
_FLOAT, _UINT32 = 5126, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_TRIANGLES = 4


def georeference_extras(georef: Georef) -> dict[str, Any]:
    """The ``turbinefit_georeference`` block of ``asset.extras`` (module docstring)."""
    import pymap3d

    lat, lon = math.radians(georef.latitude), math.radians(georef.longitude)
    east = [-math.sin(lon), math.cos(lon), 0.0]
    north = [-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)]
    up = [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
    origin = [float(v) for v in pymap3d.geodetic2ecef(georef.latitude, georef.longitude,
                                                      georef.altitude)]
    return {
        "latitude": georef.latitude, "longitude": georef.longitude,
        "altitude": georef.altitude,
        "altitude_datum": "the flight's (georef.yaml), taken as WGS84 ellipsoidal height",
        "axes": "(x, y, z)_glTF = (east, up, -north) metres from the origin",
        "ecef_from_enu": [*east, 0.0, *north, 0.0, *up, 0.0, *origin, 1.0],
        "ecef_from_enu_layout": "4x4, column-major (glTF, 3D Tiles): the tileset transform",
    }


def turbine_glb(turbine: TurbineParams, geometry: TurbineGeometry,
                georef: Georef | None = None) -> bytes:
    """The binary glTF of ``turbine`` (see the module docstring); with ``georef``, its
    georeference in ``asset.extras``."""
    theta = turbine.to_vector()
    world_T_local = np.eye(4)
    world_T_local[:2, 3] = theta[:2]
    theta[:2] = 0.0  # the solid round the base: its vertices as precise as the base is far
    solid = TurbineSolid(theta, geometry)
    matrix = (GLTF_FROM_WORLD @ world_T_local).T.ravel().tolist()  # column-major
    blob = bytearray()
    asset: dict[str, Any] = {} if georef is None else {
        "extras": {"turbinefit_georeference": georeference_extras(georef)}}
    asset.update(generator="turbinefit", version="2.0")
    accessors: list[dict[str, Any]] = []
    views: list[dict[str, Any]] = []
    materials: list[dict[str, Any]] = []
    meshes: list[dict[str, Any]] = []
    nodes: list[dict[str, Any]] = []
    for part in solid_mesh(solid):
        vertices, normals, faces = smooth_normals(part, math.radians(SHARP_EDGE_DEG))
        first = len(accessors)
        for data, kind, target in ((vertices.astype(np.float32), "VEC3", _ARRAY_BUFFER),
                                   (normals.astype(np.float32), "VEC3", _ARRAY_BUFFER),
                                   (faces.astype(np.uint32).ravel(), "SCALAR",
                                    _ELEMENT_ARRAY_BUFFER)):
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes,
                          "target": target})
            blob += data.astype(data.dtype.newbyteorder("<")).tobytes()
            blob += b"\0" * (-len(blob) % 4)
            accessor: dict[str, Any] = {
                "bufferView": len(views) - 1, "byteOffset": 0,
                "componentType": _UINT32 if data.dtype == np.uint32 else _FLOAT,
                "normalized": False, "count": len(data), "type": kind}
            if target == _ARRAY_BUFFER:
                accessor["max"] = data.max(axis=0).tolist()
                accessor["min"] = data.min(axis=0).tolist()
            accessors.append(accessor)
        materials.append({
            "pbrMetallicRoughness": {
                "baseColorFactor": [*PART_COLOURS[part.name.split("_")[0]], 1.0],
                "metallicFactor": 0.0, "roughnessFactor": 0.6},
            "emissiveFactor": [0.0, 0.0, 0.0], "alphaMode": "OPAQUE", "doubleSided": False,
            "name": part.name})
        meshes.append({"primitives": [{"attributes": {"POSITION": first, "NORMAL": first + 1},
                                       "indices": first + 2, "mode": _TRIANGLES,
                                       "material": len(materials) - 1}],
                       "name": part.name})
        nodes.append({"mesh": len(meshes) - 1, "matrix": matrix, "name": part.name})
    doc = {"accessors": accessors, "asset": asset, "bufferViews": views,
           "buffers": [{"byteLength": len(blob)}], "materials": materials, "meshes": meshes,
           "nodes": nodes, "scene": 0,
           "scenes": [{"extras": {"turbinefit": _extras(turbine, geometry)},
                       "name": "turbine", "nodes": list(range(len(nodes)))}]}
    return glb_bytes(doc, bytes(blob))


def glb_bytes(document: dict[str, Any], buffer: bytes) -> bytes:
    """A binary glTF file: the header, the JSON chunk (``document``, padded with spaces to
    4 bytes) and the BIN chunk (``buffer``, padded with zeros), glTF 2.0 section 4.4."""
    text = json.dumps(document, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    buffer += b"\0" * (-len(buffer) % 4)
    length = 12 + 8 + len(text) + 8 + len(buffer)
    return b"".join([struct.pack("<4sII", b"glTF", 2, length),
                     struct.pack("<I4s", len(text), b"JSON"), text,
                     struct.pack("<I4s", len(buffer), b"BIN\0"), buffer])


def write_turbine_glb(path: StrPath, turbine: TurbineParams, geometry: TurbineGeometry,
                      georef: Georef | None = None) -> Path:
    """Write :func:`turbine_glb` to ``path`` atomically; returns the path."""
    return write_bytes_atomic(path, turbine_glb(turbine, geometry, georef), fsync=False)


def smooth_normals(part: SolidPart, sharp: float
                   ) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Unit vertex normals of ``part`` for smooth shading: each face corner gets the
    area-weighted mean normal of the faces round its vertex that turn by less than
    ``sharp`` [rad] from its own face; a vertex on a sharp edge is split into one vertex
    per side. Returns (vertices (n', 3), normals (n', 3), faces (m, 3))."""
    v, f = part.vertices, part.faces
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])  # 2 area x unit normal
    fu = fn / np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    corner_v = f.ravel()
    corner_f = np.repeat(np.arange(len(f)), 3)
    # all pairs of corners at the same vertex
    order = np.argsort(corner_v, kind="stable")
    counts = np.bincount(corner_v, minlength=len(v))
    k = counts[corner_v[order]]
    start = np.repeat(np.cumsum(counts) - counts, counts)
    a = np.repeat(np.arange(order.size), k)
    b = start[a] + np.arange(a.size) - np.repeat(np.cumsum(k) - k, k)
    ca, cb = order[a], order[b]
    near = (fu[corner_f[ca]] * fu[corner_f[cb]]).sum(axis=1) > math.cos(sharp)
    n = np.zeros((corner_v.size, 3))
    np.add.at(n, ca[near], fn[corner_f[cb[near]]])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    # one vertex per (vertex, normal): corners of a smooth surface share theirs
    key = np.concatenate([corner_v[:, None].astype(np.float64), np.round(n, 6)], axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return v[corner_v[first]], n[first], inverse.reshape(-1, 3).astype(np.int64)


def _extras(turbine: TurbineParams, geometry: TurbineGeometry) -> dict[str, Any]:
    return {
        "turbine": turbine.to_dict(),
        "geometry": {"shaft_tilt": geometry.shaft_tilt, "blade_cone": geometry.blade_cone,
                     "hub_offset": geometry.hub_offset},
        "units": "metres, radians",
        "frame": "vertices: world (keyframes.txt, z up) minus the tower base; node matrix: "
                 "adds the base, then (x, y, z)_glTF = (x, z, -y)_world",
    }
