"""Benchmark: the heat-map CNN on photos of another renderer (Blender's Cycles path tracer).

The net was trained on :mod:`turbinefit.sim.images` alone. Its real target is drone photos,
which this machine has none of, so this script asks the nearest question it can answer
with numbers: does the net see *turbines*, or artefacts of the renderer it learned from?
It renders the same views twice (``--n`` held-out views of a seed never trained on, drawn
by :func:`turbinefit.sim.dataset.sample_view` exactly as the training data draws them,
each with its :func:`~turbinefit.sim.images.sample_scene` scene): once with turbinefit's
own renderer, as a training sample is made, and once with Blender (Cycles on the CPU,
``benchmarks/blender/render_scenes.py``): the same turbine built as meshes round the same
skeleton (tapered tower, box nacelle, ellipsoid spinner, tapered twisted blades with the
same chord profile and paint), the same neighbours, sun position, cloud cover, overcast
and terrain kind, but path-traced light and shadows, a physical sky (Blender's Nishita
model), procedural ground materials of Blender's own (Voronoi field patches, noise grain;
calm sea), Filmic tone mapping and path-tracing noise in place of the numpy renderer's
shading, textures, haze, hills, roads and camera effects. Both sets are scored against
the same exact targets with the held-out metrics of ``bench_detect.py``
(:class:`turbinefit.eval.detection.DetectionStats`, pixels of the 320 x 240 photos).

Requires Blender (Debian: ``apt-get install blender``; 3.4 was used); it is not a
dependency of turbinefit, and ``make bench`` does not run this script. Renders are cached
in ``benchmarks/data/blender-n{N}-s{SEED}/`` (an interrupted run resumes).

Usage::

    python benchmarks/bench_blender.py [--n 200] [--samples 32] [--blender PATH] [--model M.onnx]

Prints the figures and writes ``benchmarks/results/bench_blender.json`` and
``benchmarks/results/blender_examples.png`` (Blender renders, with the detected heat-maps
overlaid, above the same views by turbinefit's renderer).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from bench_detect import DATA, RESULTS, _nulls, print_heldout

from turbinefit.detect import DetectorPool, overlay
from turbinefit.eval.detection import DetectionStats
from turbinefit.io.images import resize_image, write_png
from turbinefit.sim.dataset import IMAGE_SCALE, RENDER_SCALE, TARGET_SIGMA_PX, View, sample_view
from turbinefit.sim.images import (
    Scene,
    _blade_profile,
    _Turbine,
    points_in_sight,
    render_image_and_depth,
    sample_scene,
)
from turbinefit.sim.render import RenderConfig, render_heatmaps
from turbinefit.turbine.model import TurbineGeometry, model_points

HERE = Path(__file__).resolve().parent
SCRIPT = HERE / "blender" / "render_scenes.py"
SEED = 555_555  # held-out: no training set uses it
#: Blender renders at this multiple of the photo size, averaged down by :func:`develop`
#: (a quarter of the path-tracing noise's variance).
OVERSAMPLE = 2

Mesh = dict[str, Any]


def _linear(c: tuple[float, ...]) -> list[float]:
    """Display RGB (what turbinefit's renderer paints with) to Blender's linear RGB."""
    return [float(v) ** 2.2 for v in c]


def _frame(e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``e`` to an orthonormal frame."""
    a = np.array([0.0, 0.0, 1.0]) if abs(e[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    u = np.cross(e, a)
    u /= np.linalg.norm(u)
    return u, np.cross(e, u)


def _rings(centres: np.ndarray, ax: np.ndarray, ay: np.ndarray, rx: np.ndarray,
           ry: np.ndarray, n: int, caps: tuple[bool, bool]) -> tuple[list, list]:
    """A tube of elliptic rings (centres (k, 3); per ring axes ax, ay (k, 3) and radii
    rx, ry (k,)), n vertices a ring, closed at either end by a fan."""
    phi = 2 * math.pi * np.arange(n) / n
    v = (centres[:, None] + rx[:, None, None] * np.cos(phi)[None, :, None] * ax[:, None]
         + ry[:, None, None] * np.sin(phi)[None, :, None] * ay[:, None]).reshape(-1, 3)
    verts = v.tolist()
    faces = [[r * n + j, r * n + (j + 1) % n, (r + 1) * n + (j + 1) % n, (r + 1) * n + j]
             for r in range(len(centres) - 1) for j in range(n)]
    for end, ring in ((caps[0], 0), (caps[1], len(centres) - 1)):
        if end:
            verts.append(centres[ring].tolist())
            c = len(verts) - 1
            faces += [[ring * n + j, ring * n + (j + 1) % n, c][:: 1 if ring else -1]
                      for j in range(n)]
    return verts, faces


def turbine_meshes(theta: np.ndarray, geometry: TurbineGeometry, scene: Scene,
                   material: str) -> list[Mesh]:
    """Tower, nacelle, spinner and blades of one turbine as meshes (world metres), with
    the proportions of turbinefit's renderer (:class:`turbinefit.sim.images._Turbine`)."""
    t = _Turbine(theta, geometry, scene)
    meshes: list[Mesh] = []
    top = np.array([t.base[0], t.base[1], t.tower_top_z])
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    k = 12
    s = np.linspace(0.0, 1.0, k)
    cent = t.base[None] + s[:, None] * (top - t.base)[None]
    r = t.r0 + s * (t.r1 - t.r0)
    v, f = _rings(cent, np.tile(ex, (k, 1)), np.tile(ey, (k, 1)), r, r, 32, (False, True))
    meshes.append({"vertices": v, "faces": f, "material": material, "smooth": True})
    # nacelle: a box along the shaft
    c, (hx, hy, hz) = t.nac_centre, t.nac_half
    corners = [c + sx * hx * t.shaft + sy * hy * t.side + sz * hz * t.up
               for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    box_faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                 [1, 5, 7, 3]]
    meshes.append({"vertices": [p.tolist() for p in corners], "faces": box_faces,
                   "material": material, "smooth": False})
    # spinner: an ellipsoid along the shaft
    a = np.linspace(-0.5 * math.pi, 0.5 * math.pi, 10)[1:-1]
    cent = t.spin_centre[None] + (t.spin_len * np.sin(a))[:, None] * t.shaft[None]
    rr = t.spin_r * np.cos(a)
    v, f = _rings(cent, np.tile(t.side, (len(a), 1)), np.tile(t.up, (len(a), 1)), rr, rr, 20,
                  (True, True))
    meshes.append({"vertices": v, "faces": f, "material": material, "smooth": True})
    # blades: elliptic sections of the renderer's chord profile, twisted towards the root
    u = 1.0 - (1.0 - np.linspace(0.0, 1.0, 28)) ** 1.3
    half_chord, half_thick = _blade_profile(u.astype(np.float32), t.b)
    for tip in t.tips:
        e = (tip - t.hub) / np.linalg.norm(tip - t.hub)
        chord0 = np.cross(t.shaft, e)
        chord0 /= np.linalg.norm(chord0)
        twist = scene.blade_pitch + math.radians(14.0) * (1.0 - u) ** 1.5
        ca = np.cos(twist)[:, None] * chord0 + np.sin(twist)[:, None] * np.cross(e, chord0)
        cb = np.cross(e[None], ca)
        cent = t.hub[None] + u[:, None] * (tip - t.hub)[None]
        v, f = _rings(cent, ca, cb, half_chord.astype(float), half_thick.astype(float), 14,
                      (True, True))
        meshes.append({"vertices": v, "faces": f, "material": material, "smooth": True})
    return meshes


def blender_scene(i: int, view: View, scene: Scene, rng: np.random.Generator,
                  width: int, height: int) -> dict[str, Any]:
    """The JSON description of view ``i`` for ``render_scenes.py``, at ``width`` x
    ``height`` px."""
    cam = view.camera.resized(width, height)
    pose = view.world_T_cam
    meshes = [m for theta in (view.turbine.to_vector(), *scene.neighbours)
              for m in turbine_meshes(np.asarray(theta), view.geometry, scene, "paint")]
    if scene.terrain == "offshore" or scene.sea == "all":
        ground = {"kind": "sea", "colour": _linear(scene.sea_colour),
                  "roughness": float(rng.uniform(0.05, 0.25)), "wave": float(rng.uniform(0.05, 0.3))}
    else:
        cell = float(np.mean(scene.field_size)) if scene.terrain == "fields" else float(
            rng.uniform(40.0, 200.0))
        ground = {"kind": "land", "colours": [_linear(c) for c in scene.ground_colours[:3]],
                  "cell": cell, "third": float(rng.uniform(0.1, 0.4)),
                  "grain": float(rng.uniform(2.0, 15.0)) * scene.texture_scale,
                  "grain_strength": float(rng.uniform(0.3, 0.8)),
                  "roughness": float(rng.uniform(0.6, 0.95))}
    sky = {"sun_elevation_deg": math.degrees(scene.sun_elevation),
           "sun_azimuth_deg": math.degrees(scene.sun_azimuth) - 90.0,
           "air": float(rng.uniform(0.6, 2.0)), "dust": float(rng.uniform(0.0, 4.0)),
           "ozone": float(rng.uniform(0.5, 2.0)),
           "sun_intensity": float(max(0.03, 1.0 - scene.overcast)),
           "overcast": float(scene.overcast), "overcast_gain": float(rng.uniform(0.8, 1.6)),
           "overcast_tint": [1.0, 1.0, float(rng.uniform(1.0, 1.06))],
           "cloud_cover": float(scene.cloud_cover), "cloud_gain": float(rng.uniform(1.2, 2.5)),
           "cloud_tint": [1.0, 1.0, float(rng.uniform(0.98, 1.05))],
           "cloud_seed": float(rng.uniform(0.0, 100.0)), "strength": 1.0}
    R, t = pose.rotation_matrix(), pose.translation
    return {"file": f"{i:05d}.f32", "seed": i,
            "camera": {"fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy,
                       "R": np.asarray(R).tolist(), "t": np.asarray(t).ravel().tolist()},
            "meshes": meshes,
            "materials": {"paint": {"colour": _linear(scene.paint),
                                    "roughness": float(rng.uniform(0.25, 0.6))}},
            "ground": ground, "sky": sky}


def develop(raw: np.ndarray, rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    """A camera's photo (uint8 RGB, ``width`` x ``height``) of scene-linear radiance ``raw``
    (float32 (H, W, 4) rows bottom to top, as Blender writes it): auto-exposure on the
    log-average luminance (key 0.12-0.25), white balance within +-4 %, a filmic tone curve
    (Narkowicz's ACES fit), sRGB encoding, the resize the detector itself does (so a
    render at twice the size is averaged down, as a camera's larger sensor would be), and
    JPEG at quality 80-95."""
    import io

    from PIL import Image

    lin = np.nan_to_num(raw[::-1, :, :3].astype(np.float64), nan=0.0, posinf=0.0)
    lum = lin @ np.array([0.2126, 0.7152, 0.0722])
    key = math.exp(float(np.mean(np.log(np.maximum(lum, 1e-5)))))
    x = lin * (rng.uniform(0.12, 0.25) / max(key, 1e-6)) * rng.uniform(0.96, 1.04, 3)
    y = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    srgb = np.where(y <= 0.0031308, 12.92 * y, 1.055 * y ** (1 / 2.4) - 0.055)
    photo = resize_image((srgb * 255.0 + 0.5).astype(np.uint8), width, height)
    buf = io.BytesIO()
    Image.fromarray(photo).save(buf, format="JPEG", quality=int(rng.integers(80, 96)))
    return np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))


@dataclass
class Item:
    """One view: the numpy renderer's photo, exact targets and points (heat-map px)."""

    ours: np.ndarray
    target: np.ndarray
    points: np.ndarray
    visible: np.ndarray
    in_sight: np.ndarray


def make_views(n: int, width: int, height: int) -> tuple[list[dict], list[Item]]:
    scenes, items = [], []
    for i in range(n):
        rng = np.random.default_rng(np.random.SeedSequence([SEED, i]))
        view = sample_view(rng)
        scene = sample_scene(rng, view.turbine)
        theta = view.turbine.to_vector()
        big = view.camera.resized(view.camera.width * RENDER_SCALE, view.camera.height * RENDER_SCALE)
        photo, depth = render_image_and_depth(big, view.world_T_cam, theta, scene, rng,
                                              view.geometry)
        ours = resize_image(photo, width, height)
        small = view.camera
        target = render_heatmaps(small, view.world_T_cam, theta, view.geometry,
                                 RenderConfig(sigma_px=TARGET_SIGMA_PX))
        world_p, _ = model_points(theta, view.geometry)
        uv, ok, _ = small.project_unbounded(view.world_T_cam.inverse().apply(world_p))
        visible = ok & small.in_image(uv)
        in_sight = visible & points_in_sight(big, view.world_T_cam, world_p, depth)
        items.append(Item(ours, target, np.where(np.isfinite(uv), uv, 0.0), visible, in_sight))
        brng = np.random.default_rng(np.random.SeedSequence([SEED, i, 1]))
        scenes.append(blender_scene(i, view, scene, brng, width * OVERSAMPLE,
                                    height * OVERSAMPLE))
    return scenes, items


def render_blender(blender: str, scenes: list[dict], folder: Path, width: int, height: int,
                   samples: int) -> None:
    spec = folder / "scenes.json"
    tmp = spec.with_suffix(".tmp")
    tmp.write_text(json.dumps({"width": width, "height": height, "samples": samples,
                               "scenes": scenes}))
    os.replace(tmp, spec)
    cmd = [blender, "-b", "--factory-startup", "-noaudio", "--python-exit-code", "1",
           "-P", str(SCRIPT), "--", str(spec), str(folder / "blender")]
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as p:
        assert p.stdout is not None
        log = []
        for line in p.stdout:
            log.append(line)
            if line.startswith("turbinefit-blender:"):
                print("  " + line.split(":", 1)[1].strip(), end="\r", flush=True)
    print()
    if p.returncode != 0:
        sys.exit("blender failed:\n" + "".join(log[-30:]))


def score(pool: DetectorPool, photos: list[np.ndarray], items: list[Item]) -> dict[str, float]:
    info = pool.detector.info
    stats = DetectionStats(threshold=info.threshold, tip_threshold=info.tip_threshold,
                           px_scale=info.output_scale)
    preds = pool.map(lambda det, im: det.detect_small(im), photos)
    for pred, it in zip(preds, items, strict=True):
        stats.add(pred, it.target, it.points, it.visible, it.in_sight)
    return stats.summary()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--samples", type=int, default=32, help="Cycles samples per pixel")
    ap.add_argument("--blender", default=shutil.which("blender"))
    ap.add_argument("--model", type=Path, default=None)
    args = ap.parse_args()
    if not args.blender:
        sys.exit("bench_blender: Blender not found (Debian: apt-get install blender; or --blender PATH)")
    pool = DetectorPool(args.model)
    info = pool.detector.info
    width, height = info.input_width, info.input_height
    assert (width, height) == (160 * IMAGE_SCALE, 120 * IMAGE_SCALE)
    folder = DATA / f"blender-n{args.n}-s{SEED}"
    folder.mkdir(parents=True, exist_ok=True)
    print(f"{args.n} views (seed {SEED}): rendering with turbinefit's renderer ...")
    scenes, items = make_views(args.n, width, height)
    print(f"rendering the same views with {args.blender} (Cycles, {args.samples} samples) ...")
    render_blender(args.blender, scenes, folder, width * OVERSAMPLE, height * OVERSAMPLE,
                   args.samples)
    blender = []
    for i, s in enumerate(scenes):
        raw = np.fromfile(folder / "blender" / s["file"], dtype=np.float32)
        raw = raw.reshape(height * OVERSAMPLE, width * OVERSAMPLE, 4)
        blender.append(develop(raw, np.random.default_rng(np.random.SeedSequence([SEED, i, 2])),
                               width, height))
    ours = [it.ours for it in items]
    results = {}
    for name, photos in (("turbinefit", ours), ("blender", blender)):
        m = score(pool, photos, items)
        results[name] = m
        print(f"{name} renders ({args.n}), in pixels of the {width}x{height} photos:")
        print_heldout(m, f"{width}x{height} px")
    det = pool.detector
    picks = np.linspace(0, args.n - 1, 8).astype(int)
    rows = [np.concatenate([overlay(p[k], det.detect(p[k])) for k in picks[r * 4:(r + 1) * 4]], 1)
            for p in (blender, ours) for r in range(2)]
    write_png(RESULTS / "blender_examples.png", np.concatenate(rows, 0))
    out = {"model": str(det.path), "n": args.n, "seed": SEED, "samples": args.samples,
           "px": "input", "threshold": info.threshold, "tip_threshold": info.tip_threshold,
           "tip_shift_px": det.tip_shift, "flip": det.flip, "zoom": det.zoom, **results}
    (RESULTS / "bench_blender.json").write_text(json.dumps(_nulls(out), indent=2, allow_nan=False)
                                                + "\n")
    print(f"wrote {RESULTS / 'bench_blender.json'} and {RESULTS / 'blender_examples.png'}")


if __name__ == "__main__":
    main()
