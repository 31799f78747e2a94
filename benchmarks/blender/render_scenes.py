"""Blender side of ``benchmarks/bench_blender.py``: render scenes described in a JSON file.

Run by Blender's own Python (standard library and ``bpy`` only; no turbinefit, no numpy)::

    blender -b --factory-startup -noaudio --python-exit-code 1 \
        -P benchmarks/blender/render_scenes.py -- SCENES.json OUT_DIR

Everything geometric (meshes in world metres, the camera) is computed by
``bench_blender.py`` with turbinefit's own model; this script only turns the description
into a Blender scene and renders it with Cycles on the CPU: the turbines' meshes with a
glossy paint, the ground as a large plane with a procedural material (patchwork fields from
Voronoi cells with noise grain, or a calm sea), a physically based sky (Blender's Nishita
model, sun disc included) with a procedural cloud deck and overcast. Nothing of
turbinefit's own renderer is used, so a net that learned that renderer's artefacts instead
of turbines shows it here.

Each view is written as raw scene-linear radiance, float32 RGBA, rows bottom to top (as
Blender stores images), ``width * height * 4`` values: the camera (exposure, tone curve,
white balance, JPEG) is applied by ``bench_blender.py``.

JSON: ``{"width", "height", "samples", "scenes": [...]}``; each scene has ``file`` (written
into OUT_DIR), ``seed`` (Cycles' noise seed), ``camera`` (``fx, fy, cx, cy`` in pixels,
pixel (0, 0) the centre of the top-left pixel; ``R`` (3 x 3, rows) and ``t``:
``world_T_cam`` in OpenCV's camera frame, x right, y down, z forward), ``meshes``
(``vertices`` [[x, y, z]], ``faces`` [[i, ...]], ``material`` name, ``smooth``),
``materials`` (name -> ``colour`` linear RGB, ``roughness``), ``ground`` and ``sky`` (see
:func:`ground_material` and :func:`world`). Views already rendered (their file exists)
are skipped, so an interrupted run resumes.
"""

from __future__ import annotations

import array
import json
import math
import os
import sys
import time

import bpy  # type: ignore[import-not-found]
from mathutils import Matrix  # type: ignore[import-not-found]


def clear() -> None:
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.cameras,
                 bpy.data.lights, bpy.data.worlds, bpy.data.node_groups):
        for item in list(coll):
            coll.remove(item)


def node(tree, kind: str, **inputs):
    n = tree.nodes.new(kind)
    for k, v in inputs.items():
        n.inputs[k].default_value = v
    return n


def paint(name: str, spec: dict) -> bpy.types.Material:
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*spec["colour"], 1.0)
    bsdf.inputs["Roughness"].default_value = spec["roughness"]
    bsdf.inputs["Specular"].default_value = spec.get("specular", 0.5)
    return mat


def ground_material(g: dict) -> bpy.types.Material:
    """``kind`` 'land' (``colours``: three linear RGB mixed by Voronoi cells of ``cell``
    metres and noise of ``grain`` metres, ``roughness``) or 'sea' (``colour``,
    ``roughness``, ``wave`` bump strength)."""
    mat = bpy.data.materials.new("ground")
    mat.use_nodes = True
    t = mat.node_tree
    bsdf = t.nodes["Principled BSDF"]
    coord = node(t, "ShaderNodeTexCoord")
    if g["kind"] == "sea":
        bsdf.inputs["Base Color"].default_value = (*g["colour"], 1.0)
        bsdf.inputs["Roughness"].default_value = g["roughness"]
        bsdf.inputs["Specular"].default_value = 0.6
        waves = node(t, "ShaderNodeTexNoise", Scale=0.05, Detail=8.0)
        t.links.new(coord.outputs["Object"], waves.inputs["Vector"])
        bump = node(t, "ShaderNodeBump", Strength=g["wave"])
        t.links.new(waves.outputs["Fac"], bump.inputs["Height"])
        t.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
        return mat
    a, b, c = g["colours"]
    cells = node(t, "ShaderNodeTexVoronoi", Scale=1.0 / g["cell"])
    t.links.new(coord.outputs["Object"], cells.inputs["Vector"])
    sep = node(t, "ShaderNodeSeparateColor")
    t.links.new(cells.outputs["Color"], sep.inputs["Color"])
    ramp1 = node(t, "ShaderNodeMix", Factor=0.5)
    ramp1.data_type = "RGBA"
    ramp1.inputs[6].default_value = (*a, 1.0)
    ramp1.inputs[7].default_value = (*b, 1.0)
    t.links.new(sep.outputs[0], ramp1.inputs[0])
    ramp2 = node(t, "ShaderNodeMix")
    ramp2.data_type = "RGBA"
    ramp2.inputs[7].default_value = (*c, 1.0)
    t.links.new(ramp1.outputs[2], ramp2.inputs[6])
    gate = node(t, "ShaderNodeMath", Value=0.5)
    gate.operation = "GREATER_THAN"
    gate.inputs[1].default_value = 1.0 - g["third"]
    t.links.new(sep.outputs[1], gate.inputs[0])
    t.links.new(gate.outputs[0], ramp2.inputs[0])
    grain = node(t, "ShaderNodeTexNoise", Scale=1.0 / g["grain"], Detail=6.0, Roughness=0.6)
    t.links.new(coord.outputs["Object"], grain.inputs["Vector"])
    shade = node(t, "ShaderNodeMix", Factor=g["grain_strength"])
    shade.data_type = "RGBA"
    shade.blend_type = "MULTIPLY"
    t.links.new(ramp2.outputs[2], shade.inputs[6])
    t.links.new(grain.outputs["Color"], shade.inputs[7])
    t.links.new(shade.outputs[2], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = g["roughness"]
    bsdf.inputs["Specular"].default_value = 0.2
    bump = node(t, "ShaderNodeBump", Strength=0.3)
    t.links.new(grain.outputs["Fac"], bump.inputs["Height"])
    t.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def world(s: dict) -> None:
    """Nishita sky (``sun_elevation_deg``, ``sun_azimuth_deg``, ``air``, ``dust``, ``ozone``,
    ``sun_intensity``) times ``strength``, mixed by ``overcast`` towards grey of its own
    brightness times ``overcast_gain`` (tinted ``overcast_tint``), under a procedural cloud
    deck covering ``cloud_cover`` of the sky (grey of the sky's brightness times
    ``cloud_gain``, tinted ``cloud_tint``; noise offset ``cloud_seed``)."""
    w = bpy.data.worlds.new("sky")
    bpy.context.scene.world = w
    w.use_nodes = True
    t = w.node_tree
    bg = t.nodes["Background"]
    sky = node(t, "ShaderNodeTexSky")
    sky.sky_type = "NISHITA"
    sky.sun_disc = True
    sky.sun_elevation = math.radians(s["sun_elevation_deg"])
    sky.sun_rotation = math.radians(s["sun_azimuth_deg"])
    sky.air_density = s["air"]
    sky.dust_density = s["dust"]
    sky.ozone_density = s["ozone"]
    sky.sun_intensity = s["sun_intensity"]
    # overcast and clouds: grey at the sky's own brightness times a gain
    bw = node(t, "ShaderNodeRGBToBW")
    t.links.new(sky.outputs["Color"], bw.inputs["Color"])
    grey = {}
    for name in ("overcast", "cloud"):
        g = node(t, "ShaderNodeMath")
        g.operation = "MULTIPLY"
        g.inputs[1].default_value = s[name + "_gain"]
        t.links.new(bw.outputs["Val"], g.inputs[0])
        tint = node(t, "ShaderNodeMix")
        tint.data_type = "RGBA"
        tint.blend_type = "MULTIPLY"
        tint.inputs[0].default_value = 1.0
        t.links.new(g.outputs[0], tint.inputs[6])
        tint.inputs[7].default_value = (*s[name + "_tint"], 1.0)
        grey[name] = tint
    scale = node(t, "ShaderNodeMix", Factor=s["overcast"])
    scale.data_type = "RGBA"
    t.links.new(sky.outputs["Color"], scale.inputs[6])
    t.links.new(grey["overcast"].outputs[2], scale.inputs[7])
    # the cloud deck: noise on the view ray's intersection with a plane above the camera
    coord = node(t, "ShaderNodeTexCoord")
    sep = node(t, "ShaderNodeSeparateXYZ")
    t.links.new(coord.outputs["Generated"], sep.inputs["Vector"])
    zpos = node(t, "ShaderNodeMath")
    zpos.operation = "MAXIMUM"
    zpos.inputs[1].default_value = 0.03
    t.links.new(sep.outputs["Z"], zpos.inputs[0])
    comb = node(t, "ShaderNodeCombineXYZ")
    for i, axis in enumerate(("X", "Y")):
        div = node(t, "ShaderNodeMath")
        div.operation = "DIVIDE"
        t.links.new(sep.outputs[axis], div.inputs[0])
        t.links.new(zpos.outputs[0], div.inputs[1])
        t.links.new(div.outputs[0], comb.inputs[i])
    comb.inputs[2].default_value = s["cloud_seed"]
    noise = node(t, "ShaderNodeTexNoise", Scale=1.2, Detail=8.0, Roughness=0.55)
    t.links.new(comb.outputs["Vector"], noise.inputs["Vector"])
    cover = node(t, "ShaderNodeMapRange")
    cover.inputs["From Min"].default_value = 0.62 - 0.3 * s["cloud_cover"]
    cover.inputs["From Max"].default_value = 0.72 - 0.3 * s["cloud_cover"]
    t.links.new(noise.outputs["Fac"], cover.inputs["Value"])
    horizon = node(t, "ShaderNodeMapRange")  # clouds fade into the haze at the horizon
    horizon.inputs["From Min"].default_value = 0.0
    horizon.inputs["From Max"].default_value = 0.15
    t.links.new(sep.outputs["Z"], horizon.inputs["Value"])
    mask = node(t, "ShaderNodeMath")
    mask.operation = "MULTIPLY"
    t.links.new(cover.outputs[0], mask.inputs[0])
    t.links.new(horizon.outputs[0], mask.inputs[1])
    clouds = node(t, "ShaderNodeMix")
    clouds.data_type = "RGBA"
    t.links.new(mask.outputs[0], clouds.inputs[0])
    t.links.new(scale.outputs[2], clouds.inputs[6])
    t.links.new(grey["cloud"].outputs[2], clouds.inputs[7])
    t.links.new(clouds.outputs[2], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = s["strength"]


def mesh_object(name: str, m: dict, mat: bpy.types.Material) -> None:
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in m["vertices"]], [], [tuple(f) for f in m["faces"]])
    me.update()
    if m.get("smooth"):
        for p in me.polygons:
            p.use_smooth = True
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)


def camera(c: dict, width: int, height: int) -> None:
    cam = bpy.data.cameras.new("camera")
    cam.sensor_fit = "HORIZONTAL"
    cam.sensor_width = 36.0
    cam.lens = c["fx"] * 36.0 / width
    # principal point: Blender's is the image centre, (W - 1) / 2 in pixel-centre units
    cam.shift_x = (c["cx"] - (width / 2.0 - 0.5)) / width
    cam.shift_y = -(c["cy"] - (height / 2.0 - 0.5)) / width
    cam.clip_start = 0.1
    cam.clip_end = 40000.0
    ob = bpy.data.objects.new("camera", cam)
    bpy.context.scene.collection.objects.link(ob)
    R = c["R"]
    # OpenCV camera (y down, z forward) to Blender's (y up, looking along -z)
    rows = [[R[i][0], -R[i][1], -R[i][2], c["t"][i]] for i in range(3)]
    ob.matrix_world = Matrix([*rows, [0.0, 0.0, 0.0, 1.0]])
    bpy.context.scene.camera = ob


def setup(width: int, height: int, samples: int) -> None:
    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = samples
    sc.cycles.use_adaptive_sampling = True
    sc.cycles.use_denoising = False
    sc.cycles.max_bounces = 4
    sc.cycles.diffuse_bounces = 2
    sc.cycles.glossy_bounces = 2
    sc.cycles.transmission_bounces = 0
    sc.cycles.volume_bounces = 0
    sc.render.resolution_x = width
    sc.render.resolution_y = height
    sc.render.resolution_percentage = 100
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_mode = "RGB"
    sc.render.image_settings.color_depth = "32"
    sc.render.image_settings.exr_codec = "NONE"


def render(scene: dict, out_dir: str, width: int, height: int) -> None:
    clear()
    mats = {name: paint(name, spec) for name, spec in scene["materials"].items()}
    mats["ground"] = ground_material(scene["ground"])
    size = 4.0e5  # far enough that its edge stays below the horizon
    mesh_object("ground", {"vertices": [[-size, -size, 0], [size, -size, 0], [size, size, 0],
                                        [-size, size, 0]], "faces": [[0, 1, 2, 3]]},
                mats["ground"])
    for i, m in enumerate(scene["meshes"]):
        mesh_object(f"part{i}", m, mats[m["material"]])
    world(scene["sky"])
    camera(scene["camera"], width, height)
    sc = bpy.context.scene
    sc.cycles.seed = scene["seed"]
    final = os.path.join(out_dir, scene["file"])
    exr = final + ".part.exr"
    sc.render.filepath = exr
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(exr)
    buf = array.array("f", bytes(4 * len(img.pixels)))
    img.pixels.foreach_get(buf)
    bpy.data.images.remove(img)
    os.remove(exr)
    with open(final + ".part", "wb") as f:
        buf.tofile(f)
    os.replace(final + ".part", final)  # renamed once written: nothing half-written


def main() -> None:
    argv = sys.argv[sys.argv.index("--") + 1:]
    spec_path, out_dir = argv[0], argv[1]
    with open(spec_path) as f:
        spec = json.load(f)
    os.makedirs(out_dir, exist_ok=True)
    setup(spec["width"], spec["height"], spec["samples"])
    todo = [s for s in spec["scenes"] if not os.path.exists(os.path.join(out_dir, s["file"]))]
    t0 = time.perf_counter()
    for k, scene in enumerate(todo):
        render(scene, out_dir, spec["width"], spec["height"])
        print(f"turbinefit-blender: {k + 1}/{len(todo)} {scene['file']} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
