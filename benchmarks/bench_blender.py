"""Benchmark: the heat-map CNN on photos of another renderer (Blender's Cycles path tracer).

The net was trained on :mod:`turbinefit.sim.images` alone. Its real target is drone photos,
which this machine has none of, so this script asks the nearest question it can answer
with numbers: does the net see *turbines*, or artefacts of the renderer it learned from?
It renders the same views twice (``--n`` held-out views of a seed never trained on, drawn
by :func:`turbinefit.sim.dataset.sample_view` exactly as the training data draws them,
each with its :func:`~turbinefit.sim.images.sample_scene` scene): once with turbinefit's
own renderer, as a training sample is made, and once with Blender (Cycles on the CPU,
``benchmarks/blender/render_scenes.py``). Blender gets the scene's content - the turbine
built as meshes round the same skeleton (tapered tower with its painted base band, box
nacelle, ellipsoid spinner, tapered twisted blades of the same chord profile and paint),
the neighbours, gravel pads and roads, sun elevation, cloud cover, overcast and terrain
kind with its colours (the sun's azimuth is the scene's mirrored, 180 deg minus it: see
:func:`blender_scene`) - and none of turbinefit's rendering: path-traced light, shadows and
reflections, a physical sky (Blender's Nishita model) under a procedural cloud deck,
procedural ground materials of Blender's own (Voronoi field patches with noise grain, or a
calm sea), and a camera model applied to the raw radiance (:func:`develop`: auto-exposure,
a filmic tone curve, white balance, JPEG), rendered at twice the size and averaged down.
Left out: hills, haze, hedges, crop rows, coastlines, doors, red tip bands, motion blur and
defocus. Both sets are scored against the same exact targets with the held-out metrics of
``bench_detect.py`` (:class:`turbinefit.eval.detection.DetectionStats`, pixels of the
320 x 240 photos).

Requires Blender (Debian: ``apt-get install blender``; 3.4 was used); it is not a
dependency of turbinefit, and ``make bench`` does not run this script. Renders are cached
in ``benchmarks/data/blender-n{N}-s{SEED}-spp{SAMPLES}/`` (an interrupted run resumes;
delete the folder after changing what a scene holds). 200 views take ~27 min here.

With ``--flights SEED ...``, also whole benchmark flights of ``bench_detect.py`` (200
keyframes, the flight's own scene): their photos rendered by Blender, the detection
figures of the flight's photos of either renderer against its ideal heat-maps, and the
fit from them (``turbinefit fit --from-images --preset paper-best --points interp --robust
cauchy``) beside the fit from the ideal heat-maps, the fit from them with no options
(the defaults for photos) and with those and ``--robust-scale 1``, and the tracker replayed
on the detected maps with the defaults and with the interp options (25-40 min a flight
here, most of it rendering).

Usage::

    python benchmarks/bench_blender.py [--n 200] [--flights SEED ...] [--samples 24]
                                       [--blender PATH] [--model M.onnx] [--out FILE]

Prints the figures and writes ``benchmarks/results/bench_blender.json`` and
``benchmarks/results/blender_examples.png`` (Blender renders, with the detected heat-maps
overlaid, above the same views by turbinefit's renderer).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from bench_defaults import track
from bench_detect import (
    DATA,
    DETECTED_OPTIONS,
    RESULTS,
    fit,
    flight_detection,
    print_heldout,
    simulate,
)
from common import write_json
from PIL import Image

from turbinefit.detect import DetectorPool, overlay
from turbinefit.eval.detection import DetectionStats
from turbinefit.io.flight_folder import IMAGE_DIR, read_flight, read_flight_folder, write_flight
from turbinefit.io.images import resize_image, write_png
from turbinefit.jobs.sources import PhotoHeatmaps, fit_config_for
from turbinefit.sim.dataset import (
    IMAGE_SCALE,
    DatasetSpec,
    Sample,
    View,
    render_sample,
    sample_view,
)
from turbinefit.sim.images import Scene, TurbineSolid, blade_profile, flight_scene, sample_scene
from turbinefit.sim.scenario import SimConfig
from turbinefit.solver.config import PRESETS, FitConfig
from turbinefit.turbine.model import TurbineGeometry

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
    the proportions of turbinefit's renderer (:class:`turbinefit.sim.images.TurbineSolid`)."""
    t = TurbineSolid(theta, geometry, scene)
    meshes: list[Mesh] = []
    top = np.array([t.base[0], t.base[1], t.tower_top_z])
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    k = 12
    s = np.linspace(0.0, 1.0, k)
    cent = t.base[None] + s[:, None] * (top - t.base)[None]
    r = t.r0 + s * (t.r1 - t.r0)
    v, f = _rings(cent, np.tile(ex, (k, 1)), np.tile(ey, (k, 1)), r, r, 32, (False, True))
    meshes.append({"vertices": v, "faces": f, "material": material, "smooth": True})
    band = min(scene.base_band[0], 0.9 * float(top[2] - t.base[2]))
    if band > 0:  # a differently painted tower base, just outside the tower
        s = np.array([0.0, band / float(top[2] - t.base[2])])
        cent = t.base[None] + s[:, None] * (top - t.base)[None]
        r = 1.01 * (t.r0 + s * (t.r1 - t.r0))
        v, f = _rings(cent, np.tile(ex, (2, 1)), np.tile(ey, (2, 1)), r, r, 32, (False, False))
        meshes.append({"vertices": v, "faces": f, "material": "band", "smooth": True})
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
    half_chord, half_thick = blade_profile(u.astype(np.float32), t.b)
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


def ground_meshes(scene: Scene) -> list[Mesh]:
    """The scene's gravel pads round the turbine bases (discs) and its roads and tracks
    (flat strips), a few centimetres above the ground plane."""
    meshes: list[Mesh] = []
    for x, y, radius in scene.pads:
        phi = 2 * math.pi * np.arange(32) / 32
        ring = np.stack([x + radius * np.cos(phi), y + radius * np.sin(phi), np.full(32, 0.03)], 1)
        meshes.append({"vertices": ring.tolist(), "faces": [list(range(32))], "material": "pad"})
    for x0, y0, x1, y1, w in scene.roads:
        d = np.array([x1 - x0, y1 - y0])
        n = np.array([-d[1], d[0]]) / max(float(np.linalg.norm(d)), 1e-9) * 0.5 * w
        quad = [[x0 + n[0], y0 + n[1], 0.02], [x1 + n[0], y1 + n[1], 0.02],
                [x1 - n[0], y1 - n[1], 0.02], [x0 - n[0], y0 - n[1], 0.02]]
        meshes.append({"vertices": quad, "faces": [[0, 1, 2, 3]], "material": "road"})
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
        meshes += ground_meshes(scene)
        cell = float(np.mean(scene.field_size)) if scene.terrain == "fields" else float(
            rng.uniform(40.0, 200.0))
        ground = {"kind": "land", "colours": [_linear(c) for c in scene.ground_colours[:3]],
                  "cell": cell, "third": float(rng.uniform(0.1, 0.4)),
                  "grain": float(rng.uniform(2.0, 15.0)) * scene.texture_scale,
                  "grain_strength": float(rng.uniform(0.3, 0.8)),
                  "roughness": float(rng.uniform(0.6, 0.95))}
    sky = {"sun_elevation_deg": math.degrees(scene.sun_elevation),
           # Blender's sun rotation r puts the sun at azimuth 90 deg - r (counter-clockwise
           # from world x, measured on a pole's shadow), so this gives the sun azimuth
           # 180 deg minus the scene's: the same uniform distribution, mirrored view by view
           # (a slip found after the published figures were rendered; kept so that they
           # reproduce; the scene's own azimuth would be 90 - degrees(scene.sun_azimuth))
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
                                    "roughness": float(rng.uniform(0.25, 0.6))},
                          "band": {"colour": _linear(scene.base_band[1:]), "roughness": 0.5},
                          "pad": {"colour": _linear(scene.pad_colour), "roughness": 0.95},
                          "road": {"colour": _linear(scene.road_colour), "roughness": 0.9}},
            "ground": ground, "sky": sky}


def develop(raw: np.ndarray, rng: np.random.Generator, width: int, height: int) -> np.ndarray:
    """A camera's photo (uint8 RGB, ``width`` x ``height``) of scene-linear radiance ``raw``
    (float32 (H, W, 4) rows bottom to top, as Blender writes it): auto-exposure on the
    log-average luminance (key 0.12-0.25), white balance within +-4 %, a filmic tone curve
    (Narkowicz's ACES fit), sRGB encoding, the resize the detector itself does (so a
    render at twice the size is averaged down, as a camera's larger sensor would be), and
    JPEG at quality 80-95."""
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


def make_views(n: int, width: int, height: int) -> tuple[list[dict], list[Sample]]:
    """The ``n`` views: their Blender descriptions (``width`` x ``height`` px) and the
    training samples of the same views (turbinefit's photo at the model's input size,
    exact targets, points in heat-map px; :func:`turbinefit.sim.dataset.render_sample`)."""
    spec = DatasetSpec(n, SEED, image_scale=IMAGE_SCALE)
    scenes, samples = [], []
    for i in range(n):
        samples.append(render_sample(spec, i))
        rng = np.random.default_rng(np.random.SeedSequence([SEED, i]))  # as render_sample
        view = sample_view(rng)
        scene = sample_scene(rng, view.turbine)
        brng = np.random.default_rng(np.random.SeedSequence([SEED, i, 1]))
        scenes.append(blender_scene(i, view, scene, brng, width, height))
    return scenes, samples


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


def score(pool: DetectorPool, photos: list[np.ndarray], items: list[Sample]) -> dict[str, float]:
    info = pool.detector.info
    stats = DetectionStats(threshold=info.threshold, tip_threshold=info.tip_threshold,
                           px_scale=info.output_scale)
    preds = pool.map(lambda det, im: det.detect_small(im), photos)
    for pred, it in zip(preds, items, strict=True):
        stats.add(pred, it.target, it.points, it.visible, it.in_sight)
    return stats.summary()


def develop_all(folder: Path, scenes: list[dict], seed: int, width: int,
                height: int) -> list[np.ndarray]:
    """The photos (``width`` x ``height``) of the raw renders of ``scenes`` in ``folder``;
    scene k's camera is seeded by (``seed``, k)."""
    photos = []
    for k, s in enumerate(scenes):
        raw = np.fromfile(folder / "blender" / s["file"], dtype=np.float32)
        raw = raw.reshape(height * OVERSAMPLE, width * OVERSAMPLE, 4)
        rng = np.random.default_rng(np.random.SeedSequence([seed, k, 2]))
        photos.append(develop(raw, rng, width, height))
    return photos


def views_benchmark(pool: DetectorPool, n: int, blender: str, samples: int) -> dict[str, Any]:
    """Held-out metrics of both renderers' photos of ``n`` views, and the example sheet."""
    info = pool.detector.info
    width, height = info.input_width, info.input_height
    folder = DATA / f"blender-n{n}-s{SEED}-spp{samples}"
    folder.mkdir(parents=True, exist_ok=True)
    print(f"{n} views (seed {SEED}): rendering with turbinefit's renderer ...")
    scenes, items = make_views(n, width * OVERSAMPLE, height * OVERSAMPLE)
    print(f"rendering the same views with {blender} (Cycles, {samples} samples) ...")
    render_blender(blender, scenes, folder, width * OVERSAMPLE, height * OVERSAMPLE, samples)
    photos = {"turbinefit": [it.image for it in items],
              "blender": develop_all(folder, scenes, SEED, width, height)}
    results = {}
    for name, ims in photos.items():
        results[name] = score(pool, ims, items)
        print(f"{name} renders ({n}), in pixels of the {width}x{height} photos:")
        print_heldout(results[name], f"{width}x{height} px")
    det = pool.detector
    picks = np.linspace(0, n - 1, 8).astype(int)
    rows = [np.concatenate([overlay(p[k], det.detect(p[k])) for k in picks[r * 4:(r + 1) * 4]], 1)
            for p in (photos["blender"], photos["turbinefit"]) for r in range(2)]
    write_png(RESULTS / "blender_examples.png", np.concatenate(rows, 0))
    return {"n": n, "seed": SEED, **results}


def track_photos(path: Path, configs: dict[str, FitConfig | None]) -> dict[str, Any]:
    """The tracker (window 20) replayed on the maps detected (once) in a flight's photos,
    with each of ``configs`` (None: the defaults for photos): ``bench_defaults.py``'s
    replay (final and causal position errors, the share of keyframes after the 20th whose
    causal position beats the initial one), by name."""
    folder = read_flight_folder(path)
    source = PhotoHeatmaps(folder)
    flight = folder.flight(source.stack(), source.camera)
    return {name: track(flight, fit_config_for(source, cfg)) for name, cfg in configs.items()}


#: ``DETECTED_OPTIONS`` (``--preset paper-best --points interp --robust cauchy``) as a
#: FitConfig, for the tracker's replay.
INTERP_CAUCHY = dataclasses.replace(PRESETS["paper-best"], points="interp", robust="cauchy")


def flight_benchmark(pool: DetectorPool, seed: int, blender: str, samples: int,
                     keyframes: int = 200) -> dict[str, Any]:
    """The benchmark flight ``seed`` (``bench_detect.py``'s, ``keyframes`` long) with its photos
    rendered by Blender from the same scene; detection on its photos and the fit from
    them (``--points interp --robust cauchy``), beside the same for turbinefit's photos of
    the flight and the ideal heat-maps."""
    src = simulate(seed, keyframes)
    fl = read_flight(src)
    assert fl.gt_turbine is not None and fl.gt_world_T_cam is not None
    geometry = SimConfig().geometry
    scene = flight_scene(fl.gt_turbine.to_vector(), seed)
    w, h = fl.camera.width, fl.camera.height
    scenes = [blender_scene(k, View(fl.gt_turbine, geometry, fl.camera, fl.gt_world_T_cam[k]),
                            scene, np.random.default_rng(np.random.SeedSequence([seed, k, 1])),
                            w * OVERSAMPLE, h * OVERSAMPLE)
              for k in range(len(fl.timestamps))]
    folder = DATA / f"blender-flight-n{keyframes}-s{seed}-spp{samples}"
    folder.mkdir(parents=True, exist_ok=True)
    print(f"flight {seed}: rendering its {len(scenes)} keyframes with {blender} ...")
    render_blender(blender, scenes, folder, w * OVERSAMPLE, h * OVERSAMPLE, samples)
    copy = folder / "flight"
    if not (copy / IMAGE_DIR).is_dir():
        write_flight(fl, copy, overwrite=True,
                     images=iter(develop_all(folder, scenes, seed, w, h)))
    out: dict[str, Any] = {"seed": seed}
    for name, path in (("turbinefit", src), ("blender", copy)):
        out[name] = {"detection": flight_detection(pool, path),
                     "fit": fit(path, ["--from-images", *DETECTED_OPTIONS]),
                     "fit_defaults": fit(path, ["--from-images"]),
                     "fit_defaults_scale1": fit(path, ["--from-images", "--robust-scale", "1"]),
                     **track_photos(path, {"track_defaults": None,
                                           "track_interp": INTERP_CAUCHY})}
    out["ideal_fit"] = fit(src, DETECTED_OPTIONS)
    print(f"flight {seed}, {' '.join(DETECTED_OPTIONS)}: ideal heat-maps "
          f"{out['ideal_fit']['position_m']:.3f} m; from turbinefit's photos "
          f"{out['turbinefit']['fit']['position_m']:.3f} m; from Blender's "
          f"{out['blender']['fit']['position_m']:.3f} m (initial "
          f"{out['ideal_fit']['before_position_m']:.3f} m)")
    for name in ("turbinefit", "blender"):
        for key, what in (("track_defaults", "no options"), ("track_interp", "interp")):
            t = out[name][key]
            print(f"  {name:10s} photos, track with {what}: final {t['final_position_m']:.3f} m, "
                  f"causal {t['causal_position_m']:.3f} m, better than initial after the 20th "
                  f"{t['causal_better_than_initial_after_20']:.0%}")
        print(f"  {name:10s} photos, fit with no options {out[name]['fit_defaults']['position_m']:.3f}"
              f" m / {out[name]['fit_defaults']['model_point_m']:.3f} m model points; the "
              f"same with --robust-scale 1 {out[name]['fit_defaults_scale1']['position_m']:.3f} m"
              f" / {out[name]['fit_defaults_scale1']['model_point_m']:.3f} m")
        d = out[name]["detection"]
        print(f"  {name:10s} photos: tips {d['tips_recall']:.1%} / {d['tips_precision']:.1%}, "
              f"hub / top / base median {d['hub_median_px']:.2f} / {d['tower_top_median_px']:.2f}"
              f" / {d['base_median_px']:.2f} px, IoU tower / nacelle / blade "
              f"{d['iou_tower']:.2f} / {d['iou_nacelle']:.2f} / {d['iou_blade']:.2f}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200, help="held-out views (0: none)")
    ap.add_argument("--flights", type=int, nargs="*", default=[],
                    help="seeds of benchmark flights to render with Blender and fit")
    ap.add_argument("--samples", type=int, default=24, help="Cycles samples per pixel")
    ap.add_argument("--blender", default=shutil.which("blender"))
    ap.add_argument("--model", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=RESULTS / "bench_blender.json")
    args = ap.parse_args()
    if not args.blender:
        sys.exit("bench_blender: Blender not found (Debian: apt-get install blender; or --blender PATH)")
    pool = DetectorPool(args.model)
    det, info = pool.detector, pool.detector.info
    assert (info.input_width, info.input_height) == (160 * IMAGE_SCALE, 120 * IMAGE_SCALE)
    out: dict[str, Any] = {
        "model": det.path.name, "samples": args.samples, "px": "input",
        "threshold": info.threshold, "tip_threshold": info.tip_threshold,
        "tip_shift_px": det.tip_shift, "flip": det.flip, "zoom": det.zoom,
        "views": views_benchmark(pool, args.n, args.blender, args.samples) if args.n else None,
        "flights": [flight_benchmark(pool, s, args.blender, args.samples) for s in args.flights]}
    write_json(args.out, out)
    print(f"wrote {args.out}"
          + (f" and {RESULTS / 'blender_examples.png'}" if args.n else ""))


if __name__ == "__main__":
    main()
