"""Procedural RGB images of wind farms from a camera pose, rendered on the CPU.

These images train a CNN that turns drone photos into the seven heat-maps of
:mod:`turbinefit.heatmaps`; the targets come from :func:`turbinefit.sim.render.render_heatmaps`
on the same pose and turbine. The CNN must learn to see *turbines* (not artefacts of one
renderer) and must later work on real photos of wind farms, so the renderer aims at variety
and plausibility rather than physical exactness.

Frames and units: world metres, right-handed, z up, ground plane z = 0; poses are
``world_T_cam`` (camera-to-world, :class:`~turbinefit.geometry.se3.SE3`); the camera frame is
OpenCV's (x right, y down, z forward); pixel (0, 0) is the centre of the top-left pixel and
array element ``[i, j]`` is at ``u = j, v = i``; lens distortion (plumb_bob) is applied
exactly by casting each pixel's undistorted ray. Turbine parameters ``theta`` are those of
:class:`~turbinefit.turbine.model.TurbineParams` (metres, radians). Colours are RGB in
[0, 1]; images are uint8 (H, W, 3).

What is drawn, per pixel (everything is ray cast, vectorised with numpy):

* **Turbines** (the primary and its neighbours, same code), built on the skeleton of
  :func:`~turbinefit.turbine.model.model_points`: a tapered tower round the line base ->
  tower top (radius h/30 at the base, h/45 at the top; optional darker base section and
  door); a rounded box nacelle (height and width ~0.06 b) whose axis runs along the
  (tilted) shaft through the hub, from just behind the spinner to 1.9-2.7 nacelle lengths
  behind the tower axis, the tower reaching up into it; an ellipsoid spinner at the hub;
  three tapered, twisted blades round the lines hub -> tip (elliptic cross-sections, chord
  0.08 b near 20 % span tapering to 0.015 b at the tip, optional red tip bands). Tubes
  (tower, blades) are intersected through the closest approach of each ray to their axis,
  which gives depth, surface normal and an analytic, pixel-size aware edge coverage
  (anti-aliasing, and sub-pixel parts drawn faint instead of broken); the box by slabs
  with coverage from the gradient of its inside margin; the spinner exactly. Parts are
  composited with a depth buffer, far to near, so occlusion is correct (blades in front of
  the tower seen from the front, behind it from the back). Shading: Lambert + ambient
  (sky from above, ground bounce from below) + a little gloss; backlit turbines come out
  dark against the bright sky round the sun.
* **Sky**: zenith-to-horizon gradient (clear blue .. grey overcast), fractal-noise clouds on
  a cloud deck (cover 0..1, self-shadowed), sun disc and glow, hazy horizon.
* **Terrain**: the ground plane by per-pixel ray casting, textured in world xy (patchwork
  fields with hedges and crop rows, grass, moorland scrub, forest, dry land, snow), roads,
  access tracks and crane pads at the turbines, the sea (with sky reflection, Fresnel, sun
  glitter) beyond a coastline or everywhere offshore, cloud shadows and the turbines'
  shadows; up to three layers of distant hills as silhouettes over azimuth; aerial
  perspective (haze) growing with distance. Texture detail fades with the pixel footprint
  (no shimmering far away).
* **Surface detail**: blade wear (leading-edge erosion on the outer half, dirt streaks,
  bond lines along both edges, lightning receptors near the tip) and the tower's flange
  seams, seen in close-ups.
* **Clutter** that looks like lines (:mod:`~turbinefit.sim.images.clutter`): power lines
  on lattice pylons, wooden poles and their wires, fences, buildings, offshore platforms.
* **Camera effects** per frame: auto-exposure with jitter, white balance, colour/gamma
  jitter, vignetting, motion blur (random direction, 0-3 px), defocus (Gaussian), sensor
  noise and a JPEG round trip through Pillow, all with random strengths, sometimes nearly
  none.

Everything random about a scene's appearance is sampled once into a :class:`Scene`
(:func:`sample_scene`) and reused for every frame of a flight; per-frame effects come from
the ``rng`` passed to :func:`render_image`. The same inputs and rng state give a
bit-identical image.

Why hand-written: no Python library renders procedural turbines and landscapes on a CPU
without OpenGL (pyrender, vispy and Open3D need a GL context); path tracers are slow for
100k training images and no pip dependency (Blender's Cycles runs headless on the CPU
here but takes ~9 s for a 640x480 view: ``benchmarks/bench_blender.py`` uses it as an
independent renderer to test the net on; Mitsuba is heavier still). A 320x240 image takes
~18 ms (median, one core), a 160x120 one ~9 ms; :func:`sample_scene` ~20 ms.

Modules: :mod:`~turbinefit.sim.images.scene` (the :class:`Scene` and its sampling),
:mod:`~turbinefit.sim.images.textures` (per-scene noise tiles and hills),
:mod:`~turbinefit.sim.images.turbine` (the turbine's solid, with the proportions of
:mod:`turbinefit.turbine.solid`, which the ``turbine.glb`` of ``fit`` shares),
:mod:`~turbinefit.sim.images.frame` (rays, buffers, lights, compositing),
:mod:`~turbinefit.sim.images.landscape` (sky, ground, sea, hills),
:mod:`~turbinefit.sim.images.painter` (ray casting the turbine's parts),
:mod:`~turbinefit.sim.images.effects` (camera effects),
:mod:`~turbinefit.sim.images.render` (the rendering entry points),
:mod:`~turbinefit.sim.images.views` (random training views and close-ups),
:mod:`~turbinefit.sim.images.clutter` (pylons, wires, fences, buildings),
:mod:`~turbinefit.sim.images.arrays` (float32 channels-first helpers).
"""

from turbinefit.sim.images.render import points_in_sight as points_in_sight
from turbinefit.sim.images.render import render_flight_images as render_flight_images
from turbinefit.sim.images.render import render_image as render_image
from turbinefit.sim.images.render import render_image_and_depth as render_image_and_depth
from turbinefit.sim.images.scene import NO_EFFECTS as NO_EFFECTS
from turbinefit.sim.images.scene import TERRAINS as TERRAINS
from turbinefit.sim.images.scene import CameraEffects as CameraEffects
from turbinefit.sim.images.scene import Scene as Scene
from turbinefit.sim.images.scene import flight_scene as flight_scene
from turbinefit.sim.images.scene import sample_scene as sample_scene
from turbinefit.sim.images.turbine import TurbineSolid as TurbineSolid
from turbinefit.sim.images.turbine import blade_profile as blade_profile
from turbinefit.sim.images.views import sample_closeup_view as sample_closeup_view
from turbinefit.sim.images.views import sample_training_view as sample_training_view
