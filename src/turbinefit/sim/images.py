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
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from PIL import Image
from scipy import ndimage
from scipy.special import ndtr, ndtri
from tqdm import tqdm

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.sim.trajectory import distance_to_segments
from turbinefit.turbine.model import (
    BLADE_PERIOD,
    PAPER_GEOMETRY,
    TurbineGeometry,
    TurbineParams,
    model_points,
    skeleton_segments,
)

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
IntArray = NDArray[np.intp]
RGB = tuple[float, float, float]

#: Terrain kinds of :attr:`Scene.terrain`.
TERRAINS = ("fields", "grass", "scrub", "forest", "dry", "snow", "offshore")

_TILE = 256  # noise tiles are _TILE x _TILE float32, periodic
_HILL_SAMPLES = 2048  # azimuth samples of a hill silhouette
_NEAR = 0.3  # [m] nothing nearer than this to the camera is drawn
_FAR = 6.0e4  # [m] ground beyond this is pure haze
_CLEARANCE = 6.0  # [m] sample_training_view keeps this far from the turbine
_NACELLE_REAR = (1.9, 2.7)  # nacelle overhang behind the tower axis / nacelle_length
_NACELLE_REAR_MAX = 16.0  # [m]


# ---- scene description ---------------------------------------------------------------


@dataclass(frozen=True)
class CameraEffects:
    """Maximum strengths of the per-frame camera effects (each frame draws its own
    strengths uniformly up to these; :data:`NO_EFFECTS` switches everything off).

    Attributes:
        exposure_sigma: standard deviation of the log exposure gain (after auto-exposure).
        white_balance_sigma: standard deviation of the log per-channel gains.
        colour_jitter: maximum relative change of saturation, contrast and gamma.
        vignetting: maximum darkening in the image corners (fraction).
        noise: maximum sensor noise standard deviation (intensity 0..1).
        motion_blur_px: maximum motion blur length [px] (random direction).
        defocus_px: maximum Gaussian defocus standard deviation [px].
        jpeg_quality: (min, max) JPEG quality of the round trip, or None for none.
        clean_prob: probability that a frame gets only a tenth of the strengths.
    """

    exposure_sigma: float = 0.0
    white_balance_sigma: float = 0.0
    colour_jitter: float = 0.0
    vignetting: float = 0.0
    noise: float = 0.0
    motion_blur_px: float = 0.0
    defocus_px: float = 0.0
    jpeg_quality: tuple[int, int] | None = None
    clean_prob: float = 0.0


#: No camera effect at all (exact auto-exposed rendering, no JPEG).
NO_EFFECTS = CameraEffects()


@dataclass(frozen=True)
class Scene:
    """Everything random about one scene's appearance (world metres, radians, RGB in [0, 1]).

    Sampled once by :func:`sample_scene` and reused for every frame of a flight. All fields
    are plain numbers, strings and tuples (hashable); the noise tiles and hill silhouettes
    derived from ``seed`` and ``hills`` are cached per scene.

    Attributes:
        seed: seeds the scene's noise tiles (clouds, terrain, detail).
        overcast: 0 clear .. 1 fully overcast (scales direct sunlight, greys the sky).
        cloud_cover: fraction of the sky covered by clouds, 0..1.
        cloud_altitude: height of the cloud deck [m].
        cloud_scale: period of the cloud noise tile on the deck [m].
        sun_azimuth: direction of the sun from the world x axis, counter-clockwise [rad].
        sun_elevation: elevation of the sun above the horizon [rad].
        sky_zenith, sky_horizon: clear-sky colours overhead and at the horizon.
        sun_colour: colour of direct sunlight.
        cloud_colour: colour of a lit cloud.
        visibility: aerial-perspective distance [m]: haze is 1 - exp(-distance / visibility).
        haze_colour: colour of distant haze.
        terrain: one of :data:`TERRAINS`.
        ground_colours: palette of the terrain (5 colours, meaning depends on the kind).
        texture_scale: multiplies the world sizes of the terrain noise.
        field_size: (width, length) of field cells [m] (``fields`` terrain).
        field_angle: orientation of the field grid [rad].
        hedge_colour: colour of hedges and field borders.
        roads: road and track segments ``(x0, y0, x1, y1, width)`` [m].
        road_colour: colour of the roads.
        pads: gravel pads ``(x, y, radius)`` [m] round turbine bases.
        pad_colour: colour of the pads.
        centre: (x, y) of the primary turbine's base [m] (the scene is laid out round it).
        sea: ``"none"``, ``"coast"`` (sea beyond a coastline) or ``"all"`` (offshore).
        coast: (direction of the sea from the primary base [rad], distance of the
            coastline from it [m]).
        sea_colour: colour of deep water.
        hills: distant hill layers ``(distance, base height, amplitude, roughness, r, g, b)``
            [m], far to near.
        paint: turbine paint.
        base_band: ``(height, r, g, b)`` of a differently painted tower base (height 0: none).
        door: whether towers have a door.
        tip_bands: number of red bands near the blade tips (0, 1 or 2).
        tip_colour: colour of the tip bands.
        blade_pitch: blade pitch [rad] (~0 in operation, ~90 deg feathered).
        nacelle: ``(rear overhang / nacelle_length, height / blade_length, width / height)``.
        neighbours: other turbines of the wind farm, theta 7-vectors.
        effects: maximum strengths of the per-frame camera effects.
    """

    seed: int
    overcast: float
    cloud_cover: float
    cloud_altitude: float
    cloud_scale: float
    sun_azimuth: float
    sun_elevation: float
    sky_zenith: RGB
    sky_horizon: RGB
    sun_colour: RGB
    cloud_colour: RGB
    visibility: float
    haze_colour: RGB
    terrain: str
    ground_colours: tuple[RGB, ...]
    texture_scale: float
    field_size: tuple[float, float]
    field_angle: float
    hedge_colour: RGB
    roads: tuple[tuple[float, float, float, float, float], ...]
    road_colour: RGB
    pads: tuple[tuple[float, float, float], ...]
    pad_colour: RGB
    centre: tuple[float, float]
    sea: str
    coast: tuple[float, float]
    sea_colour: RGB
    hills: tuple[tuple[float, float, float, float, float, float, float], ...]
    paint: RGB
    base_band: tuple[float, float, float, float]
    door: bool
    tip_bands: int
    tip_colour: RGB
    blade_pitch: float
    nacelle: tuple[float, float, float]
    neighbours: tuple[tuple[float, float, float, float, float, float, float], ...]
    effects: CameraEffects

    def __post_init__(self) -> None:
        if self.terrain not in TERRAINS:
            raise ValueError(f"terrain must be one of {TERRAINS}, got {self.terrain!r}")
        if self.sea not in ("none", "coast", "all"):
            raise ValueError(f"sea must be none, coast or all, got {self.sea!r}")
        if len(self.ground_colours) != 5:
            raise ValueError("ground_colours needs 5 colours")
        if not self.visibility > 0:
            raise ValueError("visibility must be positive")


# ---- random helpers ------------------------------------------------------------------


def _jitter(rng: np.random.Generator, c: RGB, s: float) -> RGB:
    v = np.clip(np.asarray(c) * np.exp(rng.normal(0.0, s, 3)), 0.0, 1.0)
    return (float(v[0]), float(v[1]), float(v[2]))


def _mix(a: RGB, b: RGB, t: float) -> RGB:
    return (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t)


_PALETTES: dict[str, tuple[RGB, ...]] = {
    # fields: crop colours (greens, yellows, browns)
    "fields": ((0.33, 0.45, 0.20), (0.55, 0.55, 0.28), (0.47, 0.38, 0.26), (0.28, 0.40, 0.18),
               (0.66, 0.60, 0.38)),
    # grass: light, dark, patch, -, -
    "grass": ((0.36, 0.48, 0.22), (0.26, 0.38, 0.16), (0.42, 0.46, 0.26), (0.30, 0.36, 0.20),
              (0.45, 0.50, 0.30)),
    # scrub / moorland: heath, dry grass, bushes, rock, -
    "scrub": ((0.40, 0.38, 0.26), (0.50, 0.47, 0.32), (0.20, 0.27, 0.14), (0.48, 0.46, 0.42),
              (0.35, 0.30, 0.22)),
    # forest: canopy dark, canopy light, clearing, -, -
    "forest": ((0.13, 0.22, 0.11), (0.24, 0.34, 0.17), (0.38, 0.45, 0.24), (0.18, 0.24, 0.14),
               (0.30, 0.36, 0.20)),
    # dry: sand, ochre, shrubs, rock, -
    "dry": ((0.66, 0.57, 0.42), (0.58, 0.46, 0.32), (0.33, 0.34, 0.22), (0.55, 0.52, 0.47),
            (0.70, 0.64, 0.50)),
    # snow: snow, blue-grey snow, trees/rocks, -, -
    "snow": ((0.88, 0.90, 0.93), (0.72, 0.77, 0.85), (0.22, 0.25, 0.22), (0.55, 0.57, 0.60),
             (0.80, 0.82, 0.86)),
    # offshore: (unused ground)
    "offshore": ((0.30, 0.40, 0.45), (0.25, 0.35, 0.40), (0.20, 0.30, 0.35), (0.3, 0.3, 0.3),
                 (0.3, 0.3, 0.3)),
}


def _place_neighbours(rng: np.random.Generator, t: TurbineParams
                      ) -> tuple[tuple[float, float, float, float, float, float, float], ...]:
    """0-6 turbines 250-1500 m from the primary (row/grid layout or scattered)."""
    n = int(rng.choice(7, p=[0.1, 0.12, 0.16, 0.18, 0.17, 0.14, 0.13]))
    if n == 0:
        return ()
    cands: list[tuple[float, float]] = []
    if rng.uniform() < 0.45:
        # a grid (rows across the wind), spacing 250-700 m, jittered
        sx, sy = rng.uniform(250.0, 700.0), rng.uniform(250.0, 700.0)
        ang = t.heading + rng.normal(0.0, 0.3)
        ca, sa = math.cos(ang), math.sin(ang)
        for i in range(-6, 7):
            for j in range(-6, 7):
                if i == 0 and j == 0:
                    continue
                gx = i * sx + rng.normal(0.0, 20.0)
                gy = j * sy + (0.5 * sy if i % 2 else 0.0) * rng.integers(0, 2) + rng.normal(0, 20.0)
                cands.append((ca * gx - sa * gy, sa * gx + ca * gy))
        order = rng.permutation(len(cands))
        cands = [cands[k] for k in order]
    else:
        for _ in range(200):
            d = rng.uniform(250.0, 1500.0)
            a = rng.uniform(0.0, 2 * math.pi)
            cands.append((d * math.cos(a), d * math.sin(a)))
    placed: list[tuple[float, float]] = []
    for cx, cy in cands:
        d = math.hypot(cx, cy)
        if not 250.0 <= d <= 1500.0:
            continue
        if any(math.hypot(cx - px, cy - py) < 220.0 for px, py in placed):
            continue
        placed.append((cx, cy))
        if len(placed) == n:
            break
    out = []
    for cx, cy in placed:
        s = rng.uniform(0.92, 1.08, 3)
        heading = t.heading + (rng.normal(0.0, math.radians(5.0)) if rng.uniform() < 0.9
                               else rng.uniform(0.0, 2 * math.pi))
        h = t.tower_height * float(s[0])
        b = min(t.blade_length * float(s[2]), h - 15.0)
        out.append((t.base_x + cx, t.base_y + cy, h, heading % (2 * math.pi),
                    t.nacelle_length * float(s[1]), float(rng.uniform(0.0, BLADE_PERIOD)), b))
    return tuple(out)


def _roads(rng: np.random.Generator, t: TurbineParams,
           neighbours: tuple[tuple[float, ...], ...]
           ) -> tuple[tuple[tuple[float, float, float, float, float], ...],
                      tuple[tuple[float, float, float], ...]]:
    """Roads passing near the primary, tracks from the turbines to them, pads."""
    roads: list[tuple[float, float, float, float, float]] = []
    n_roads = int(rng.choice(3, p=[0.15, 0.55, 0.3]))
    lines = []
    for _ in range(n_roads):
        d = rng.uniform(40.0, 500.0)
        a = rng.uniform(0.0, 2 * math.pi)
        p = np.array([t.base_x + d * math.cos(a), t.base_y + d * math.sin(a)])
        direc = rng.uniform(0.0, math.pi)
        u = np.array([math.cos(direc), math.sin(direc)])
        w = rng.uniform(4.0, 7.5)
        a0, a1 = p - 4000.0 * u, p + 4000.0 * u
        roads.append((float(a0[0]), float(a0[1]), float(a1[0]), float(a1[1]), w))
        lines.append((p, u))
    bases = [(t.base_x, t.base_y)] + [(float(n[0]), float(n[1])) for n in neighbours]
    pads: list[tuple[float, float, float]] = []
    for k, (bx, by) in enumerate(bases):
        pads.append((bx, by, float(rng.uniform(10.0, 22.0))))
        if lines and (k == 0 or rng.uniform() < 0.8):
            # track to the nearest road, with a kink
            b = np.array([bx, by])
            feet = [p + ((b - p) @ u) * u for p, u in lines]
            f = min(feet, key=lambda q: float(np.linalg.norm(q - b)))
            if float(np.linalg.norm(f - b)) < 1500.0:
                mid = b + 0.5 * (f - b) + rng.normal(0.0, 0.1 * float(np.linalg.norm(f - b)), 2)
                w = rng.uniform(4.0, 5.5)
                roads.append((bx, by, float(mid[0]), float(mid[1]), w))
                roads.append((float(mid[0]), float(mid[1]), float(f[0]), float(f[1]), w))
    return tuple(roads), tuple(pads)


def sample_scene(rng: np.random.Generator, turbine: TurbineParams) -> Scene:
    """A random scene round ``turbine`` (the primary, world metres): sky, terrain,
    atmosphere, paint, neighbour turbines and camera-effect strengths.

    The scene's noise tiles are generated here (a few ms) and cached for rendering.
    """
    seed = int(rng.integers(0, 2**31 - 1))
    # sky
    kind = rng.choice(3, p=[0.35, 0.35, 0.3])  # clear, partly cloudy, overcast
    if kind == 0:
        overcast, cover = rng.uniform(0.0, 0.15), rng.uniform(0.0, 0.35)
    elif kind == 1:
        overcast, cover = rng.uniform(0.15, 0.55), rng.uniform(0.3, 0.8)
    else:
        overcast, cover = rng.uniform(0.65, 1.0), rng.uniform(0.85, 1.0)
    sun_el = math.radians(rng.uniform(5.0, 65.0))
    sun_az = rng.uniform(0.0, 2 * math.pi)
    zen = _jitter(rng, (0.22, 0.42, 0.78), 0.12)
    hor = _jitter(rng, (0.70, 0.80, 0.90), 0.05)
    grey = float(rng.uniform(0.55, 0.85))
    g3 = (grey, grey * float(rng.uniform(0.98, 1.02)), grey * float(rng.uniform(1.0, 1.06)))
    zen = _mix(zen, _mix(g3, (grey * 0.85, grey * 0.85, grey * 0.85), 0.3), overcast)
    hor = _mix(hor, g3, overcast)
    low = max(0.0, 1.0 - math.degrees(sun_el) / 20.0)  # low sun: warm light
    sun_col = _mix((1.0, 0.97, 0.92), (1.0, 0.78, 0.55), low)
    hor = _mix(hor, (0.85, 0.75, 0.65), 0.3 * low * (1 - overcast))
    cloud_col = _mix((0.97, 0.97, 0.97), g3, 0.5 * overcast)
    # atmosphere
    if rng.uniform() < 0.08:  # hazy day
        visibility = float(rng.uniform(1500.0, 4000.0))
    else:
        visibility = float(math.exp(rng.uniform(math.log(4000.0), math.log(40000.0))))
        visibility *= 1.0 - 0.35 * overcast
    haze = _mix(hor, (0.8, 0.82, 0.85), 0.3)
    # terrain
    terrain = str(rng.choice(TERRAINS, p=[0.26, 0.14, 0.16, 0.1, 0.1, 0.06, 0.18]))
    pal = tuple(_jitter(rng, c, 0.02 if terrain == "snow" else 0.05) for c in _PALETTES[terrain])
    bright = float(np.exp(rng.normal(0.0, 0.1)))
    pal = tuple(_mix(c, (0.0, 0.0, 0.0), 1.0 - bright) if bright < 1 else
                _mix(c, (1.0, 1.0, 1.0), 0.3 * (bright - 1.0)) for c in pal)
    desat = float(rng.uniform(0.1, 0.4))  # real landscapes seen from the air are muted
    pal = tuple(_mix(c, (sum(c) / 3, sum(c) / 3, sum(c) / 3), desat) for c in pal)
    sea = "all" if terrain == "offshore" else ("coast" if rng.uniform() < 0.2 else "none")
    coast = (float(rng.uniform(0.0, 2 * math.pi)), float(rng.uniform(200.0, 3000.0)))
    sea_col = _jitter(rng, (0.10, 0.20, 0.25), 0.2)
    sea_col = _mix(sea_col, (0.25, 0.27, 0.28), 0.5 * overcast)
    neighbours = _place_neighbours(rng, turbine)
    if sea == "all":
        roads: tuple[tuple[float, float, float, float, float], ...] = ()
        pads: tuple[tuple[float, float, float], ...] = ()
    else:
        roads, pads = _roads(rng, turbine, neighbours)
    # hills: far to near
    n_hills = 0 if sea == "all" and rng.uniform() < 0.7 else int(rng.choice(4, p=[0.15, 0.3, 0.35, 0.2]))
    hilly = rng.uniform() < 0.4
    hills = []
    dists = np.sort(rng.uniform(2500.0, 25000.0, n_hills))[::-1]
    for d in dists:
        amp = rng.uniform(0.02, 0.08 if hilly else 0.04) * d
        base = rng.uniform(-0.3, 0.3) * amp
        hc = _jitter(rng, pal[int(rng.integers(0, 3))] if sea != "all" else (0.3, 0.35, 0.3), 0.15)
        hc = _mix(hc, (0.25, 0.32, 0.2), 0.3)
        hills.append((float(d), float(base), float(amp), float(rng.uniform(0.8, 1.6)), *hc))
    # turbine paint
    pg = float(rng.uniform(0.78, 0.95))
    paint = _jitter(rng, (pg, pg, pg * rng.uniform(0.98, 1.03)), 0.015)
    band: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    if sea == "all":
        band = (float(rng.uniform(12.0, 20.0)), *_jitter(rng, (0.85, 0.7, 0.1), 0.08))
    elif rng.uniform() < 0.3:
        bc = [(0.22, 0.36, 0.25), (0.45, 0.47, 0.48), (0.45, 0.6, 0.42)][int(rng.integers(0, 3))]
        band = (float(rng.uniform(3.0, 12.0)), *_jitter(rng, bc, 0.1))
    tip_bands = int(rng.choice(3, p=[0.7, 0.15, 0.15]))
    pitch = (math.radians(rng.uniform(-2.0, 8.0)) if rng.uniform() < 0.88
             else math.radians(rng.uniform(70.0, 90.0)))
    nacelle = (float(rng.uniform(*_NACELLE_REAR)), float(rng.uniform(0.052, 0.068)),
               float(rng.uniform(0.85, 1.1)))
    lo_q = int(rng.integers(40, 85))
    effects = CameraEffects(
        exposure_sigma=float(rng.uniform(0.05, 0.3)),
        white_balance_sigma=float(rng.uniform(0.01, 0.07)),
        colour_jitter=float(rng.uniform(0.0, 0.2)),
        vignetting=float(rng.uniform(0.0, 0.45)),
        noise=float(rng.uniform(0.003, 0.035)),
        motion_blur_px=float(rng.uniform(0.0, 3.0)),
        defocus_px=float(rng.uniform(0.0, 1.5)),
        jpeg_quality=(lo_q, min(95, lo_q + int(rng.integers(5, 30)))),
        clean_prob=0.15,
    )
    scene = Scene(
        seed=seed, overcast=float(overcast), cloud_cover=float(cover),
        cloud_altitude=float(rng.uniform(800.0, 2500.0)),
        cloud_scale=float(rng.uniform(2500.0, 9000.0)),
        sun_azimuth=float(sun_az), sun_elevation=float(sun_el),
        sky_zenith=zen, sky_horizon=hor, sun_colour=sun_col, cloud_colour=cloud_col,
        visibility=float(visibility), haze_colour=haze, terrain=terrain,
        ground_colours=pal, texture_scale=float(rng.uniform(0.6, 1.6)),
        field_size=(float(rng.uniform(60.0, 200.0)), float(rng.uniform(100.0, 350.0))),
        field_angle=float(rng.uniform(0.0, math.pi)),
        hedge_colour=_jitter(rng, (0.14, 0.22, 0.10), 0.15),
        roads=roads, road_colour=_jitter(rng, [(0.42, 0.42, 0.42), (0.6, 0.57, 0.5)][
            int(rng.integers(0, 2))], 0.08),
        pads=pads, pad_colour=_jitter(rng, (0.55, 0.54, 0.50), 0.06),
        centre=(float(turbine.base_x), float(turbine.base_y)), sea=sea, coast=coast,
        sea_colour=sea_col, hills=tuple(hills),
        paint=paint, base_band=band, door=bool(rng.uniform() < 0.7), tip_bands=tip_bands,
        tip_colour=_jitter(rng, (0.75, 0.12, 0.1), 0.1), blade_pitch=float(pitch),
        nacelle=nacelle, neighbours=neighbours, effects=effects,
    )
    _assets(scene)  # generate the noise tiles now
    return scene


# ---- array helpers ------------------------------------------------------------------------
# Colours and directions are channels-first, (3, n): numpy broadcasting over a trailing axis
# of length 3 is 10-20x slower than over a long one.


def _col(c: RGB | FloatArray | F32) -> F32:
    """A colour as a (3, 1) float32 column."""
    return np.asarray(c, dtype=np.float32).reshape(3, 1)


def _lerp3(a: RGB | F32, b: RGB | F32, t: F32) -> F32:
    """(3, n) colours a + (b - a) t."""
    a_ = _col(a)
    return a_ + (_col(b) - a_) * t[None]


def _blend(col: F32, target: F32, w: F32) -> F32:
    """(3, n) ``col`` moved towards ``target`` ((3, 1) or (3, n)) by weights ``w`` (n,)."""
    return col + (target - col) * w[None]


def _mat(M: FloatArray | F32, D: F32) -> F32:
    """``M @ D`` for a small (k, 3) matrix and (3, n) columns, without BLAS (whose threads
    cost more than they save on such shapes)."""
    M32 = np.asarray(M, dtype=np.float32)
    out = M32[:, 0, None] * D[0][None]
    out += M32[:, 1, None] * D[1][None]
    out += M32[:, 2, None] * D[2][None]
    return out


def _dot(v: FloatArray | F32, D: F32) -> F32:
    """``v @ D`` for a 3-vector and (3, n) columns, without BLAS."""
    return np.float32(v[0]) * D[0] + np.float32(v[1]) * D[1] + np.float32(v[2]) * D[2]


def _take(a: F32, idx: IntArray) -> F32:
    """Columns ``idx`` of a (k, N) array."""
    return np.take(a, idx, axis=1)


def _put(a: F32, idx: IntArray, v: F32) -> None:
    """``a[:, idx] = v`` for a (k, N) array (row by row: much faster)."""
    for k in range(a.shape[0]):
        a[k][idx] = v[k]


def _smoothstep(e0: float, e1: float, x: F32) -> F32:
    t = np.clip((x - e0) * (1.0 / (e1 - e0)), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _smooth_np(e0: float, e1: float, x: FloatArray) -> FloatArray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# ---- per-scene assets (noise tiles, hill silhouettes) --------------------------------------


@dataclass(frozen=True)
class _Tile:
    """A periodic texture of ``size`` x ``size`` texels and ``channels`` channels, stored
    flat with one wrapped row and column, channels first: ``(channels, (size + 1) ** 2)``."""

    data: F32
    size: int

    @staticmethod
    def make(a: NDArray[np.floating]) -> _Tile:
        """From an (S, S) or (S, S, C) periodic array."""
        s = a.shape[0]
        a3 = a[..., None] if a.ndim == 2 else a
        p = np.concatenate([a3, a3[:1]], axis=0)
        p = np.concatenate([p, p[:, :1]], axis=1)
        flat = np.ascontiguousarray(np.moveaxis(p, -1, 0).reshape(a3.shape[-1], -1),
                                    dtype=np.float32)
        return _Tile(flat, s)


def _tex(tile: _Tile, x: F32, y: F32, channels: tuple[int, ...] | None = None) -> F32:
    """Bilinear, periodic lookup at texel coordinates (x, y) (n,): (channels, n), of all
    channels or of the given ones."""
    s = tile.size
    fx = np.floor(x)
    fy = np.floor(y)
    ax = x - fx
    ay = y - fy
    m = s - 1
    i00 = (fx.astype(np.intp) & m) + (fy.astype(np.intp) & m) * (s + 1)
    i01 = i00 + 1
    i10 = i00 + (s + 1)
    i11 = i00 + (s + 2)
    chans = range(tile.data.shape[0]) if channels is None else channels
    out = np.empty((len(chans), x.size), dtype=np.float32)
    for c, ch in enumerate(chans):
        d = tile.data[ch]
        v00 = np.take(d, i00)
        top = v00 + ax * (np.take(d, i01) - v00)
        v10 = np.take(d, i10)
        bot = v10 + ax * (np.take(d, i11) - v10)
        out[c] = top + ay * (bot - top)
    return out


def _gauss_field(rng: np.random.Generator, beta: float, size: int = _TILE) -> FloatArray:
    """Periodic Gaussian noise (power spectrum ~ f^-beta), zero mean, unit variance."""
    fy = np.fft.fftfreq(size)[:, None]
    fx = np.fft.rfftfreq(size)[None, :]
    fr = np.sqrt(fx * fx + fy * fy)
    fr[0, 0] = 1.0
    spec = np.fft.rfft2(rng.standard_normal((size, size))) * fr ** (-0.5 * beta)
    spec[0, 0] = 0.0
    t = np.fft.irfft2(spec, s=(size, size))
    return (t - t.mean()) / max(float(t.std()), 1e-12)


def _blur(a: FloatArray, sigma: float) -> FloatArray:
    """Periodic Gaussian blur of a square tile (by FFT), ``sigma`` in texels."""
    s = a.shape[0]
    fy = np.fft.fftfreq(s)[:, None]
    fx = np.fft.rfftfreq(s)[None, :]
    g = np.exp(-2.0 * (math.pi * sigma) ** 2 * (fx * fx + fy * fy))
    return np.fft.irfft2(np.fft.rfft2(a) * g, s=a.shape)


def _zoom(g: FloatArray, k: int, shift: tuple[int, int]) -> FloatArray:
    """The periodic field ``g`` repeated k times across its own period (k x finer)."""
    s = g.shape[0]
    idx = (np.arange(s) * k) % s
    return np.roll(g[np.ix_(idx, idx)], shift, axis=(0, 1))


@dataclass(frozen=True)
class _Assets:
    clouds: _Tile  # noise, darkness, (density, darkness) x 2 blur levels; period cloud_scale
    macro: _Tile  # RGB terrain colour (brightness for fields), period _macro_period(scene)
    detail: _Tile  # uniform noise in [0, 1], used at several small periods
    waves: _Tile  # sea surface noise in [0, 1], period _WAVE_PERIOD
    hills: tuple[F32, ...]  # silhouette height [m] per azimuth sample, per layer


_WAVE_PERIOD = 48.0
#: Blur [texels] of the cloud tile's levels 0, 1, 2.
_CLOUD_MIP_SIGMAS = (0.0, 1.5, 5.0)


def _macro_period(scene: Scene) -> float:
    return 1600.0 * scene.texture_scale


def _macro_colour(scene: Scene, large: FloatArray, mid: FloatArray) -> FloatArray:
    """Terrain colour (S, S, 3) from uniform noise at the macro scale and 8x finer."""
    p = [np.asarray(c) for c in scene.ground_colours]
    L, M = large[..., None], mid[..., None]
    kind = scene.terrain
    if kind == "fields":
        return np.repeat((0.85 + 0.3 * L) * (0.9 + 0.2 * M), 3, axis=-1)
    if kind == "grass":
        col = p[0] + (p[1] - p[0]) * L
        col = col + (p[2] - col) * _smooth_np(0.6, 0.8, M)
        return col * (0.8 + 0.4 * M)
    if kind == "scrub":
        col = p[0] + (p[1] - p[0]) * M
        col = col + (p[4] - col) * _smooth_np(0.3, 0.15, L)
        col = col + (p[3] - col) * _smooth_np(0.8, 0.88, 0.5 * L + 0.5 * M)
        return col * (0.85 + 0.3 * L)
    if kind == "forest":
        col = p[0] + (p[1] - p[0]) * M
        col = col + (p[2] - col) * _smooth_np(0.25, 0.18, 0.7 * L + 0.3 * M)
        return col * (0.85 + 0.3 * M)
    if kind == "dry":
        col = p[0] + (p[1] - p[0]) * L
        col = col + (p[3] - col) * _smooth_np(0.75, 0.9, M) * 0.6
        return col * (0.85 + 0.3 * M)
    if kind == "snow":
        col = p[0] + (p[1] - p[0]) * (0.6 * M + 0.4 * L)
        return col + (p[2] - col) * (0.6 * _smooth_np(0.8, 0.92, 0.6 * L + 0.4 * M))
    return np.broadcast_to(np.asarray(scene.sea_colour), (*large.shape, 3)).copy()


@lru_cache(maxsize=16)
def _assets(scene: Scene) -> _Assets:
    """Noise tiles and hill silhouettes of a scene (deterministic from its seed)."""
    rng = np.random.default_rng(scene.seed)
    g_cloud = _gauss_field(rng, 3.0)
    g_wisp = _gauss_field(rng, 2.2)
    n = ndtr((0.9 * g_cloud + 0.35 * _zoom(g_wisp, 2, (17, 91))) / math.hypot(0.9, 0.35))
    thr = 1.0 - scene.cloud_cover
    dens = _smooth_np(thr - 0.08, thr + 0.1, n)
    # shading (thick cloud is darker underneath) follows a smoothed field: no mottling
    dark = _smooth_np(thr - 0.05, thr + 0.5, _blur(n, 2.5))
    # three blur levels (a small mip pyramid): far clouds are looked up blurred, not aliased
    levels = [n, dark]  # level 0: raw noise, thresholded per pixel after interpolation
    for sigma in _CLOUD_MIP_SIGMAS[1:]:
        levels += [_blur(dens, sigma), _blur(dark, sigma)]
    clouds = _Tile.make(np.stack(levels, axis=-1))
    g_terr = _gauss_field(rng, 2.2)
    large = ndtr(g_terr)
    mid = ndtr(_zoom(g_terr, 8, (101, 37)))
    macro = _Tile.make(_macro_colour(scene, large, mid))
    g_det = _gauss_field(rng, 1.4)
    detail = _Tile.make(ndtr(g_det))
    waves = _Tile.make(ndtr(0.8 * g_det + 0.6 * _zoom(g_det, 6, (5, 77))))
    hills = []
    k = np.arange(1, 65)
    az = np.linspace(-math.pi, math.pi, _HILL_SAMPLES, endpoint=False)
    for _, base, amp, rough, *_c in scene.hills:
        a = rng.standard_normal(64) * k ** (-rough)
        ph = rng.uniform(0.0, 2 * math.pi, 64)
        prof = (a[:, None] * np.cos(k[:, None] * az[None] + ph[:, None])).sum(0)
        prof = (prof - prof.min()) / max(float(np.ptp(prof)), 1e-9)
        ridge = 1.0 - np.abs(2.0 * prof - 1.0)  # sharpen into ridges a little
        prof = 0.7 * prof + 0.3 * ridge
        hills.append(np.append(base + amp * prof, base + amp * prof[0]).astype(np.float32))
    return _Assets(clouds, macro, detail, waves, tuple(hills))


#: Per-kind fine-detail modulation: (period [m], threshold lo, hi, RGB strength); the
#: modulation is ``1 + strength * (smoothstep(lo, hi, n) - mean)``, zero-mean over the
#: uniform noise n, so far away (where it fades out) the average colour is unchanged.
_DETAIL: dict[str, tuple[float, float, float, RGB]] = {
    "fields": (30.0, 0.0, 1.0, (0.25, 0.25, 0.25)),
    "grass": (30.0, 0.0, 1.0, (0.2, 0.18, 0.2)),
    "scrub": (25.0, 0.55, 0.7, (-0.6, -0.45, -0.6)),
    "forest": (10.0, 0.2, 0.8, (0.9, 0.8, 0.9)),
    "dry": (30.0, 0.72, 0.8, (-0.6, -0.45, -0.65)),
    "snow": (30.0, 0.0, 1.0, (0.08, 0.08, 0.06)),
    "offshore": (30.0, 0.0, 1.0, (0.0, 0.0, 0.0)),
}


def _smooth_mean(lo: float, hi: float) -> float:
    """Mean of smoothstep(lo, hi, n) for n uniform in [0, 1]."""
    return (1.0 - hi) + 0.5 * (hi - lo)


def _hash(ix: NDArray[np.int32], iy: NDArray[np.int32], salt: int) -> F32:
    """Pseudo-random float32 in [0, 1) per integer cell."""
    h = (ix.astype(np.uint32) * np.uint32(374761393) + iy.astype(np.uint32) * np.uint32(668265263)
         + np.uint32(salt * 2246822519 % 2**32))
    h = (h ^ (h >> np.uint32(13))) * np.uint32(1274126177)
    h = h ^ (h >> np.uint32(16))
    return (h & np.uint32(0xFFFF)).astype(np.float32) * np.float32(1.0 / 65536.0)


# ---- camera rays -------------------------------------------------------------------------


@lru_cache(maxsize=8)
def _camera_rays(camera: PinholeCamera) -> tuple[F32, F32]:
    """Unit camera-frame rays of all pixels (3, H * W), row-major (``[i, j]`` at
    ``u = j, v = i``), plumb_bob distortion undone; and the squared normalised distance of
    each pixel from the image centre (H * W,) for vignetting."""
    v, u = np.mgrid[0:camera.height, 0:camera.width].astype(np.float64)
    yd = (v - camera.cy) / camera.fy
    xd = (u - camera.cx - camera.skew * yd) / camera.fx
    x, y = xd.copy(), yd.copy()
    if camera.has_distortion:
        k1, k2, p1, p2, k3 = camera.distortion
        r2max = float(camera.kernel_params()[-1])
        for _ in range(20):  # fixed-point undistortion
            r2 = np.minimum(x * x + y * y, r2max)
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            radial = np.where(np.abs(radial) < 0.2, 0.2, radial)
            dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
            x = (xd - dx) / radial
            y = (yd - dy) / radial
        ok = np.isfinite(x) & np.isfinite(y) & (np.abs(x) < 10) & (np.abs(y) < 10)
        x = np.where(ok, x, xd)
        y = np.where(ok, y, yd)
    d = np.stack([x.ravel(), y.ravel(), np.ones(x.size)])
    d /= np.linalg.norm(d, axis=0, keepdims=True)
    rn = ((u - 0.5 * (camera.width - 1)) ** 2 + (v - 0.5 * (camera.height - 1)) ** 2) / (
        0.25 * (camera.width**2 + camera.height**2))
    return np.ascontiguousarray(d, dtype=np.float32), rn.ravel().astype(np.float32)


# ---- the renderer -----------------------------------------------------------------------


class _Turbine:
    """Solid geometry of one turbine round its skeleton (world metres)."""

    def __init__(self, theta: ArrayLike, geometry: TurbineGeometry, scene: Scene,
                 door_az: float = 0.0) -> None:
        th = np.asarray(theta, dtype=np.float64).ravel()
        p, _ = model_points(th, geometry)
        self.door_az = door_az
        self.base, self.top, self.hub = p[0], p[1], p[2]
        self.tips = p[3:]
        h, w, r, b = float(th[2]), float(th[3]), abs(float(th[4])), abs(float(th[6]))
        self.h, self.b = max(h, 1.0), max(b, 0.5)
        self.r0 = self.h / 30.0
        self.r1 = self.h / 45.0
        tau = geometry.shaft_tilt
        self.shaft = np.array([math.cos(w) * math.cos(tau), math.sin(w) * math.cos(tau),
                               math.sin(tau)])
        self.up = np.array([-math.cos(w) * math.sin(tau), -math.sin(w) * math.sin(tau),
                            math.cos(tau)])
        self.side = np.cross(self.up, self.shaft)
        rear, hfrac, wfrac = scene.nacelle
        self.nac_h = hfrac * self.b
        self.nac_w = wfrac * self.nac_h
        rr = min(rear * max(r, 2.0), _NACELLE_REAR_MAX)
        front = -0.15 * r
        back = -(r + rr)
        # the nacelle's axis runs along the shaft through the hub; it starts rr behind the
        # tower axis and ends just behind the spinner
        self.nac_centre = self.hub + 0.5 * (front + back) * self.shaft
        self.nac_half = np.array([0.5 * (front - back), 0.5 * self.nac_w, 0.5 * self.nac_h])
        self.nac_rear = self.hub + back * self.shaft
        # the tower reaches up into the nacelle even if the hub sits high above the tower top
        bottom = self.hub[2] - 0.5 * self.nac_h
        self.tower_top_z = max(float(self.top[2]), bottom + 0.3)
        self.spin_len = 0.055 * self.b
        self.spin_r = 0.04 * self.b
        self.spin_centre = self.hub + 0.25 * self.spin_len * self.shaft
        self.centre = 0.5 * (p.min(axis=0) + p.max(axis=0))


def _blade_profile(u: F32, b: float) -> tuple[F32, F32]:
    """Half chord A and half thickness B [m] of a blade at span fraction u (hub = 0):
    round root (radius 0.022 b), widest (chord 0.08 b) at 22 %, tip chord 0.015 b."""
    rr = np.float32(0.022 * b)
    a_max = np.float32(0.04 * b)
    tip = np.float32(0.0075 * b)
    ramp = _smoothstep(0.03, 0.22, u)
    outer = tip + (a_max - tip) * np.clip((1.0 - u) * np.float32(1 / 0.78), 0.0, 1.0) ** 1.15
    inner = u < 0.22
    A = np.where(inner, rr + (a_max - rr) * ramp, outer)
    B = np.where(inner, rr + (np.float32(0.011 * b) - rr) * ramp, 0.27 * outer)
    return A.astype(np.float32), B.astype(np.float32)


def _unit(v: FloatArray) -> FloatArray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _perp(e: FloatArray) -> FloatArray:
    """A unit vector perpendicular to unit e."""
    a = np.array([0.0, 0.0, 1.0]) if abs(e[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    return _unit(np.cross(e, a))


class _Frame:
    """One image being rendered: rays, colour and depth buffers, lights.

    ``D`` (3, N) are the unit world directions of the pixels' rays from the camera centre
    ``o``; ``C`` (3, N) the colour buffer; ``Z`` (N,) the ray distance [m] of the nearest
    opaque turbine surface drawn so far.
    """

    def __init__(self, camera: PinholeCamera, world_T_cam: SE3, scene: Scene) -> None:
        self.cam = camera
        self.scene = scene
        self.A = _assets(scene)
        self.W, self.H = camera.width, camera.height
        self.R = world_T_cam.rotation_matrix()  # world_R_cam
        self.o = world_T_cam.translation.astype(np.float64)
        rays, self.rn = _camera_rays(camera)
        self.D: F32 = _mat(self.R, rays)
        self.f = math.sqrt(camera.fx * camera.fy)
        self.inv_f = 1.0 / self.f
        n = self.W * self.H
        self.C = np.empty((3, n), dtype=np.float32)
        self.Z = np.full(n, np.inf, dtype=np.float32)
        sc = scene
        ce = math.cos(sc.sun_elevation)
        self.sun = np.array([ce * math.cos(sc.sun_azimuth), ce * math.sin(sc.sun_azimuth),
                             math.sin(sc.sun_elevation)])
        self.sun_f = self.sun.astype(np.float32)
        self.sun_strength = 0.95 * (1.0 - 0.88 * sc.overcast)
        self.sun_rgb = _col(sc.sun_colour) * np.float32(self.sun_strength)
        sky_mean = 0.5 * (np.asarray(sc.sky_zenith) + np.asarray(sc.sky_horizon))
        sky_mean = sky_mean * (1 - sc.cloud_cover) + np.asarray(sc.cloud_colour) * sc.cloud_cover
        sky_mean = 0.7 * sky_mean + 0.3 * sky_mean.mean()  # skylight, a little desaturated
        self.amb_sky = _col((0.8 + 0.15 * sc.overcast) * sky_mean)
        # the ground's illumination: ambient (sky) part and direct-sun part
        self.ground_light = np.float32(0.55 + 0.45 * sc.overcast)
        self.ground_sun = np.float32(self.sun_strength * 1.1 * max(self.sun[2], 0.0))
        gmean = np.mean(np.asarray(sc.ground_colours[:3]), axis=0)
        if sc.sea == "all":
            gmean = np.asarray(sc.sea_colour) * 1.3
        gmean = 0.5 * gmean + 0.5 * gmean.mean()
        self.amb_ground = _col(0.5 * gmean * (self.ground_light + self.ground_sun))
        self.haze = _col(sc.haze_colour)
        self.cam_R_world = self.R.T
        self.cam_t = -self.cam_R_world @ self.o
        self.shadow_segments: list[tuple[float, float, float, float, float, float]] = []
        self.gpos: NDArray[np.int32] | None = None  # pixel -> index among ground pixels

    # -- helpers --------------------------------------------------------------------------

    def to_cam(self, p: FloatArray) -> FloatArray:
        return p @ self.cam_R_world.T + self.cam_t

    def bbox(self, world_pts: FloatArray, radius: float) -> tuple[int, int, int, int] | None:
        """Pixel box (i0, i1, j0, j1) containing the points ``(k, 3)`` inflated by ``radius``
        [m] (only their part at depth > _NEAR), or None if empty."""
        cp = self.to_cam(world_pts)
        lo = cp.min(axis=0) - radius
        hi = cp.max(axis=0) + radius
        if hi[2] <= _NEAR:
            return None
        lo[2] = max(lo[2], _NEAR)
        cam = self.cam
        z0, z1 = 1.0 / lo[2], 1.0 / hi[2]
        xs = (lo[0] * z0, lo[0] * z1, hi[0] * z0, hi[0] * z1)
        ys = (lo[1] * z0, lo[1] * z1, hi[1] * z0, hi[1] * z1)
        v0, v1 = cam.fy * min(ys) + cam.cy, cam.fy * max(ys) + cam.cy
        if cam.skew == 0.0:
            u0, u1 = cam.fx * min(xs) + cam.cx, cam.fx * max(xs) + cam.cx
        else:
            us = [cam.fx * x + cam.skew * y + cam.cx for x in xs for y in ys]
            u0, u1 = min(us), max(us)
        m = 2.0
        if cam.has_distortion:
            zs = np.array([lo[2], hi[2]])
            corners = np.stack(np.meshgrid([lo[0], hi[0]], [lo[1], hi[1]], zs, indexing="ij"),
                               -1).reshape(-1, 3)
            uv, _, _ = cam.project_unbounded(corners)
            u0, u1 = min(u0, float(uv[:, 0].min())), max(u1, float(uv[:, 0].max()))
            v0, v1 = min(v0, float(uv[:, 1].min())), max(v1, float(uv[:, 1].max()))
            m = 6.0 + 0.05 * max(u1 - u0, v1 - v0)
        if not (u1 > -m and u0 < self.W + m and v1 > -m and v0 < self.H + m):
            return None
        j0 = max(0, math.floor(max(u0, -1e6) - m))
        j1 = min(self.W, math.ceil(min(u1, 1e6) + m) + 1)
        i0 = max(0, math.floor(max(v0, -1e6) - m))
        i1 = min(self.H, math.ceil(min(v1, 1e6) + m) + 1)
        if j0 >= j1 or i0 >= i1:
            return None
        return i0, i1, j0, j1

    def box_indices(self, b: tuple[int, int, int, int]) -> IntArray:
        i0, i1, j0, j1 = b
        return (np.arange(i0, i1)[:, None] * self.W + np.arange(j0, j1)[None, :]).ravel()

    def segment_pixels(self, a: FloatArray, b: FloatArray, radius: float | FloatArray,
                       piece_px: float = 60.0, max_pieces: int = 8) -> IntArray | None:
        """Pixels near the world segment a-b: the union of the pixel boxes of pieces of it
        (at most ``max_pieces``, ~``piece_px`` long), each inflated by ``radius`` [m] (a
        number, or a function of the piece: an array over ``max_pieces`` equal pieces)."""
        cam = self.cam
        if cam.skew != 0.0 or cam.has_distortion:
            return self._segment_pixels_slow(a, b, radius, piece_px, max_pieces)
        ca, cb = self.to_cam(np.stack([a, b]))
        zmin = max(min(ca[2], cb[2]), 1.0)
        length_px = self.f * float(np.linalg.norm(ca - cb)) / zmin
        n = int(min(max_pieces, max(1, math.ceil(length_px / piece_px))))
        if np.ndim(radius) == 0:
            rad = np.full(n, float(radius))
        else:  # coarser pieces take the largest radius of the fine ones they contain
            r = np.asarray(radius, dtype=np.float64)
            edges = np.linspace(0, r.size, n + 1)
            rad = np.array([r[math.floor(edges[k]):max(math.ceil(edges[k + 1]),
                                                       math.floor(edges[k]) + 1)].max()
                            for k in range(n)])
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        P = ca + t * (cb - ca)
        lo = np.minimum(P[:-1], P[1:]) - rad[:, None]
        hi = np.maximum(P[:-1], P[1:]) + rad[:, None]
        ok = hi[:, 2] > _NEAR
        if not np.any(ok):
            return None
        lo, hi = lo[ok], hi[ok]
        z0 = 1.0 / np.maximum(lo[:, 2], _NEAR)
        z1 = 1.0 / hi[:, 2]
        xs = np.stack([lo[:, 0] * z0, lo[:, 0] * z1, hi[:, 0] * z0, hi[:, 0] * z1])
        ys = np.stack([lo[:, 1] * z0, lo[:, 1] * z1, hi[:, 1] * z0, hi[:, 1] * z1])
        m = 2.0
        u0 = np.floor(cam.fx * xs.min(axis=0) + cam.cx - m)
        u1 = np.ceil(cam.fx * xs.max(axis=0) + cam.cx + m) + 1
        v0 = np.floor(cam.fy * ys.min(axis=0) + cam.cy - m)
        v1 = np.ceil(cam.fy * ys.max(axis=0) + cam.cy + m) + 1
        j0 = np.clip(u0, 0, self.W).astype(int)
        j1 = np.clip(u1, 0, self.W).astype(int)
        i0 = np.clip(v0, 0, self.H).astype(int)
        i1 = np.clip(v1, 0, self.H).astype(int)
        good = np.flatnonzero((j1 > j0) & (i1 > i0))
        if good.size == 0:
            return None
        if good.size == 1:
            g = int(good[0])
            return self.box_indices((int(i0[g]), int(i1[g]), int(j0[g]), int(j1[g])))
        mask = np.zeros((self.H, self.W), dtype=bool)
        for g in good.tolist():
            mask[i0[g]:i1[g], j0[g]:j1[g]] = True
        return np.flatnonzero(mask)

    def _segment_pixels_slow(self, a: FloatArray, b: FloatArray, radius: float | FloatArray,
                             piece_px: float, max_pieces: int) -> IntArray | None:
        """:meth:`segment_pixels` for skewed or distorted cameras (box by box)."""
        ca, cb = self.to_cam(np.stack([a, b]))
        zmin = max(min(ca[2], cb[2]), 1.0)
        length_px = self.f * float(np.linalg.norm(ca - cb)) / zmin
        n = int(min(max_pieces, max(1, math.ceil(length_px / piece_px))))
        rmax = float(np.max(radius))
        boxes = []
        for k in range(n):
            bb = self.bbox(np.stack([a + (k / n) * (b - a), a + ((k + 1) / n) * (b - a)]), rmax)
            if bb is not None:
                boxes.append(bb)
        if not boxes:
            return None
        mask = np.zeros((self.H, self.W), dtype=bool)
        for i0, i1, j0, j1 in boxes:
            mask[i0:i1, j0:j1] = True
        return np.flatnonzero(mask)

    def ground_subset(self, idx: IntArray | None) -> IntArray | None:
        """Positions among the ground pixels of those pixels of ``idx`` that see the ground."""
        if idx is None or self.gpos is None:
            return None
        pos = self.gpos[idx]
        pos = pos[pos >= 0]
        return pos.astype(np.intp) if pos.size else None

    def shade(self, albedo: F32, nl: F32, nz: F32, nD: F32, Dl: F32, gloss: float) -> F32:
        """Lambert + hemispheric ambient (sky above, ground below) + a glossy highlight,
        from unit-normal dot products with the sun (nl), up (nz) and the ray (nD)."""
        diff = np.maximum(nl, 0.0)
        up = 0.5 + 0.5 * nz
        light = self.amb_ground + (self.amb_sky - self.amb_ground) * up[None] \
            + self.sun_rgb * diff[None]
        rl = np.clip(Dl - 2.0 * nD * nl, 0.0, 1.0)
        rl2 = rl * rl
        rl4 = rl2 * rl2
        spec = np.float32(gloss) * (rl4 * rl4) * (nl > 0)
        return albedo * light + self.sun_rgb * spec[None]

    def hazed(self, col: F32, dist: F32) -> F32:
        """Aerial perspective over ``dist`` [m]."""
        h = 1.0 - np.exp(dist * np.float32(-1.0 / self.scene.visibility))
        return _blend(col, self.haze, h)

    def composite(self, idx: IntArray, depth: F32, cov: F32, col: F32) -> None:
        """Blend a part's pixels (coverage ``cov``) over the buffer where it is nearest."""
        z = self.Z[idx]
        sel = np.flatnonzero((depth < z) & (cov > 0.003))
        if sel.size == 0:
            return
        idx, depth, cov, z = idx[sel], depth[sel], cov[sel], z[sel]
        old = _take(self.C, idx)
        _put(self.C, idx, _blend(old, _take(col, sel), cov))
        self.Z[idx] = np.where(cov > 0.5, depth, z)

    # -- background -----------------------------------------------------------------------

    def background(self) -> None:
        dz = self.D[2]
        oz = max(float(self.o[2]), 0.05)
        ground = dz < -1e-5
        gi = np.flatnonzero(ground)
        si = np.flatnonzero(~ground)
        if si.size:
            _put(self.C, si, self.sky(si))
        if gi.size:
            self.gpos = np.full(self.W * self.H, -1, dtype=np.int32)
            self.gpos[gi] = np.arange(gi.size, dtype=np.int32)
            _put(self.C, gi, self.ground(gi, oz))
        if self.scene.hills:
            self.hills(oz)

    def sky(self, idx: IntArray) -> F32:
        sc = self.scene
        D = _take(self.D, idx)
        dz = np.maximum(D[2], 0.0)
        col = _lerp3(sc.sky_horizon, sc.sky_zenith, np.sqrt(dz))
        cs = _dot(self.sun_f, D)
        clear = 1.0 - sc.overcast
        glow = (0.12 + 0.3 * clear) * np.exp(10.0 * (cs - 1.0)) + 0.6 * clear * np.exp(
            300.0 * (cs - 1.0))
        disc = np.clip((cs - math.cos(math.radians(0.4))) * 2e5, 0.0, 1.0) * (4.0 * clear)
        if sc.cloud_cover > 0.01 and self.o[2] < sc.cloud_altitude:
            ci = np.flatnonzero(dz > 0.003)
            if ci.size:
                dist = np.float32(sc.cloud_altitude - self.o[2]) / dz[ci]
                k = np.float32(self.A.clouds.size / sc.cloud_scale)
                x = (np.float32(self.o[0]) + D[0, ci] * dist) * k
                y = (np.float32(self.o[1]) + D[1, ci] * dist) * k
                # footprint [texels] -> blend of two blur levels
                fpt = dist * np.float32(k * self.inv_f) / np.sqrt(np.maximum(dz[ci], 0.02))
                dd = np.empty((2, ci.size), dtype=np.float32)
                thr = 1.0 - sc.cloud_cover
                g = np.flatnonzero(fpt < 3.0)
                if g.size:  # near: threshold the noise (+ a finer octave) per pixel
                    v = _tex(self.A.clouds, x[g], y[g], (0, 1, 2, 3))
                    # 4x finer octave, faded out before its texels get smaller than a pixel
                    det = _tex(self.A.detail, x[g] * 4.0 + 7.0, y[g] * 4.0 + 3.0)[0]
                    n = v[0] + (det - 0.5) * (0.1 * np.clip((1.0 - fpt[g]) * 1.5, 0.0, 1.0))
                    d0 = _smoothstep(thr - 0.08, thr + 0.1, n)
                    wgt = np.clip((fpt[g] - 1.0) * 0.5, 0.0, 1.0)
                    dd[0, g] = d0 + (v[2] - d0) * wgt
                    dd[1, g] = v[1] + (v[3] - v[1]) * wgt
                g = np.flatnonzero(fpt >= 3.0)
                if g.size:  # far: blend the blurred levels
                    v = _tex(self.A.clouds, x[g], y[g], (2, 3, 4, 5))
                    wgt = np.clip((fpt[g] - 3.0) * np.float32(1 / 7), 0.0, 1.0)
                    _put(dd, g, v[:2] + (v[2:] - v[:2]) * wgt[None])
                fade = np.exp(dist * np.float32(-1.0 / 25000.0))
                far = min(1.0, 1.2 * sc.cloud_cover)
                dens = dd[0] * fade + far * (1.0 - fade)
                dark = dd[1] * fade + 0.5 * far * (1.0 - fade)
                shade = 1.0 - (0.3 + 0.12 * sc.overcast) * dark
                ccol = _col(sc.cloud_colour) * shade[None]
                # silver lining: thin cloud lit from behind near the sun
                ccol = ccol + _col(sc.sun_colour) * (glow[ci] * 1.2 * (1.0 - dark) * clear)[None]
                _put(col, ci, _blend(_take(col, ci), ccol, dens))
                att = np.ones_like(glow)
                att[ci] = 1.0 - 0.9 * dens
                glow = glow * att
                disc = disc * att * att
        col = col + _col(sc.sun_colour) * (glow + disc)[None]
        # horizon haze (the sky meets the fully hazed far ground seamlessly)
        h = np.exp(dz * np.float32(-(4000.0 / max(sc.visibility, 1.0) + 8.0)))
        return _blend(col, self.haze, h)

    def ground(self, idx: IntArray, oz: float) -> F32:
        sc = self.scene
        D = _take(self.D, idx)
        ndz = np.maximum(-D[2], 1e-6)
        t = np.minimum(np.float32(oz) / ndz, _FAR)
        x = np.float32(self.o[0]) + t * D[0]
        y = np.float32(self.o[1]) + t * D[1]
        fp = t * (np.float32(self.inv_f) / np.sqrt(np.maximum(ndz, 0.02)))  # m per pixel
        if sc.sea == "all":
            return self.hazed(self.sea(D, x, y, fp), t)
        col = self.terrain(x, y, fp)
        self.features(col, x, y, fp)
        light = self.ground_light + self.ground_sun * self.shadows(x, y, fp)
        col *= light[None]
        if sc.sea == "coast":
            self.coast(col, D, x, y, fp, light)
        return self.hazed(col, t)

    def coast(self, col: F32, D: F32, x: F32, y: F32, fp: F32, light: F32) -> None:
        """Beach and sea beyond a wavy coastline (in place)."""
        sc = self.scene
        ca, sa = math.cos(sc.coast[0]), math.sin(sc.coast[0])
        k = np.float32(self.A.detail.size / 4000.0)
        s = ((x - np.float32(sc.centre[0])) * np.float32(ca)
             + (y - np.float32(sc.centre[1])) * np.float32(sa) - np.float32(sc.coast[1])
             - 400.0 * (_tex(self.A.detail, x * k + 91.0, y * k + 13.0)[0] - 0.5))
        pfp = np.maximum(fp, 0.5)
        near = np.flatnonzero(s > -40.0 - 2 * pfp)
        if near.size == 0:
            return
        sn, pn = s[near], pfp[near]
        sand = _col((0.72, 0.66, 0.52)) * light[near][None]
        c = _blend(_take(col, near), sand, np.clip((sn + 25.0) / pn + 0.5, 0.0, 1.0) * 0.85)
        wet = np.clip(sn / pn + 0.5, 0.0, 1.0)
        wi = np.flatnonzero(wet > 0)
        if wi.size:
            g = near[wi]
            sea = self.sea(_take(D, g), x[g], y[g], fp[g])
            _put(c, wi, _blend(_take(c, wi), sea, wet[wi]))
        _put(col, near, c)

    def detail(self, col: F32, x: F32, y: F32, fp: F32, period: float, lo: float, hi: float,
               strength: RGB, ox: float, oy: float) -> None:
        """Zero-mean fine modulation of ``col`` (in place) where the pixel footprint ``fp``
        resolves noise of ``period`` [m] (it fades out before it could alias)."""
        texel = period / self.A.detail.size
        sel = np.flatnonzero(fp < 4.0 * texel)
        if sel.size == 0:
            return
        k = np.float32(1.0 / texel)
        n = _tex(self.A.detail, x[sel] * k + ox, y[sel] * k + oy)[0]
        if lo > 0.0 or hi < 1.0:
            n = _smoothstep(lo, hi, n)
        fade = np.clip((4.0 * texel - fp[sel]) * np.float32(1.0 / (3.0 * texel)), 0.0, 1.0)
        m = (n - np.float32(_smooth_mean(lo, hi))) * fade
        _put(col, sel, _take(col, sel) * (1.0 + _col(strength) * m[None]))

    def terrain(self, x: F32, y: F32, fp: F32) -> F32:
        """Unlit ground colour (3, n) at world points (x, y) seen with footprint fp [m]."""
        sc = self.scene
        kmac = np.float32(self.A.macro.size / _macro_period(sc))
        col = _tex(self.A.macro, x * kmac, y * kmac)
        if sc.terrain == "fields":
            col *= self.fields(x, y, fp)
        period, lo, hi, strength = _DETAIL[sc.terrain]
        self.detail(col, x, y, fp, period * sc.texture_scale, lo, hi, strength, 0.0, 0.0)
        self.detail(col, x, y, fp, 3.0, 0.0, 1.0, (0.35, 0.35, 0.35), 57.0, 23.0)
        return col

    def fields(self, x: F32, y: F32, fp: F32) -> F32:
        """Patchwork of field cells with crop rows and hedges: colour (3, n)."""
        sc = self.scene
        ca, sa = np.float32(math.cos(sc.field_angle)), np.float32(math.sin(sc.field_angle))
        xr = x * ca + y * sa
        yr = y * ca - x * sa
        fw, fl = sc.field_size
        cx = np.floor(xr * np.float32(1.0 / fw))
        ix = cx.astype(np.int32)
        yr = yr + _hash(ix, ix, 7) * np.float32(fl)
        cy = np.floor(yr * np.float32(1.0 / fl))
        iy = cy.astype(np.int32)
        h1 = _hash(ix, iy, 1)
        h2 = _hash(ix, iy, 2)
        pal = np.ascontiguousarray(np.asarray(sc.ground_colours, np.float32).T)  # (3, 5)
        ci = np.minimum((h1 * 5.0).astype(np.intp), 4)
        col = np.take(pal, ci, axis=1) * (0.85 + 0.3 * h2)[None]
        forest = np.flatnonzero(h2 > 0.93)
        if forest.size:
            _put(col, forest, np.broadcast_to(_col(sc.hedge_colour) * 1.2, (3, forest.size)))
        fx = xr - cx * np.float32(fw)
        fy = yr - cy * np.float32(fl)
        # crop rows, along or across the cell, where the footprint resolves them
        rs = np.flatnonzero(fp < 1.2)
        if rs.size:
            along = (h1[rs] * 7.0) % 1.0 > 0.5
            spacing = 2.5 + 2.0 * ((h2[rs] * 13.0) % 1.0)
            coord = np.where(along, fx[rs], fy[rs])
            rows = np.sin(coord * (np.float32(2 * math.pi) / spacing))
            amp = np.clip(1.2 - fp[rs] / (0.35 * spacing), 0.0, 1.0) * (
                0.1 * ((h1[rs] * 3.0) % 1.0))
            _put(col, rs, _take(col, rs) * (1.0 + rows * amp)[None])
        # hedges and borders (some cells without)
        d = np.minimum(np.minimum(fx, np.float32(fw) - fx), np.minimum(fy, np.float32(fl) - fy))
        hw = np.float32(1.5)
        pfp = np.maximum(fp, 0.05)
        hedge = np.clip((hw - d) / pfp + 0.5, 0.0, 1.0) * np.minimum(1.0, 2.0 * hw / pfp)
        hedge = hedge * np.where((h2 * 31.0) % 1.0 < 0.75, 0.9, 0.3)
        return _blend(col, _col(sc.hedge_colour), hedge)

    def features(self, col: F32, x: F32, y: F32, fp: F32) -> None:
        """Roads, tracks and turbine pads (in place), only inside their screen boxes."""
        sc = self.scene
        o = self.o
        reach = 6000.0
        rc = _col(sc.road_colour)
        for x0, y0, x1, y1, w in sc.roads:
            a = np.array([x0, y0, 0.0])
            b = np.array([x1, y1, 0.0])
            # only the part within `reach` of the camera (further on it is sub-pixel)
            ab = b - a
            l2 = float(ab @ ab)
            if l2 < 1e-9:
                continue
            tc = float(np.clip((o - a) @ ab / l2, 0.0, 1.0))
            half = reach / math.sqrt(l2)
            t0, t1 = max(0.0, tc - half), min(1.0, tc + half)
            if t1 <= t0:
                continue
            a, b = a + t0 * ab, a + t1 * ab
            pos = self.ground_subset(self.segment_pixels(a, b, 0.5 * w + 1.0, 40.0, 16))
            if pos is None:
                continue
            ex, ey = float(b[0] - a[0]), float(b[1] - a[1])
            le2 = max(ex * ex + ey * ey, 1e-9)
            px = x[pos] - np.float32(a[0])
            py = y[pos] - np.float32(a[1])
            tt = np.clip((px * ex + py * ey) * np.float32(1.0 / le2), 0.0, 1.0)
            dx = px - tt * np.float32(ex)
            dy = py - tt * np.float32(ey)
            pfp = np.maximum(fp[pos], 0.03)
            d = np.sqrt(dx * dx + dy * dy)
            cov = np.clip((np.float32(0.5 * w) - d) / pfp + 0.5, 0.0, 1.0) * np.minimum(
                1.0, np.float32(w) / pfp)
            _put(col, pos, _blend(_take(col, pos), rc, 0.9 * cov))
        pc = _col(sc.pad_colour)
        for px0, py0, r in sc.pads:
            centre = np.array([px0, py0, 0.0])
            pos = self.ground_subset(self.segment_pixels(centre, centre, r + 1.0))
            if pos is None:
                continue
            dx = x[pos] - np.float32(px0)
            dy = y[pos] - np.float32(py0)
            pfp = np.maximum(fp[pos], 0.03)
            d = np.sqrt(dx * dx + dy * dy)
            cov = np.clip((np.float32(r) - d) / pfp + 0.5, 0.0, 1.0)
            _put(col, pos, _blend(_take(col, pos), pc, 0.75 * cov))

    def shadows(self, x: F32, y: F32, fp: F32) -> F32:
        """Fraction of direct sunlight reaching ground points: cloud and turbine shadows."""
        sc = self.scene
        lit = np.ones_like(x)
        if self.sun[2] <= 0.05 or self.sun_strength < 0.1:
            return lit
        sx, sy = self.sun[0] / self.sun[2], self.sun[1] / self.sun[2]
        if sc.cloud_cover > 0.02:
            k = np.float32(self.A.clouds.size / sc.cloud_scale)
            cx = (x + np.float32(sx * sc.cloud_altitude)) * k
            cy = (y + np.float32(sy * sc.cloud_altitude)) * k
            lit = 1.0 - 0.85 * _tex(self.A.clouds, cx, cy, (2,))[0]
        for ax, ay, bx, by, w0, w1 in self.shadow_segments:
            a = np.array([ax, ay, 0.0])
            b = np.array([bx, by, 0.0])
            pos = self.ground_subset(self.segment_pixels(a, b, max(w0, w1) + 1.0, 40.0, 12))
            if pos is None:
                continue
            ex, ey = bx - ax, by - ay
            l2 = max(ex * ex + ey * ey, 1e-9)
            px = x[pos] - np.float32(ax)
            py = y[pos] - np.float32(ay)
            tt = np.clip((px * ex + py * ey) * np.float32(1.0 / l2), 0.0, 1.0)
            dx = px - tt * np.float32(ex)
            dy = py - tt * np.float32(ey)
            d = np.sqrt(dx * dx + dy * dy)
            hw = np.float32(w0) + tt * np.float32(w1 - w0)
            pfp = np.maximum(fp[pos], 0.05)
            cov = np.clip((hw - d) / pfp + 0.5, 0.0, 1.0) * np.minimum(1.0, 2.0 * hw / pfp)
            lit[pos] *= 1.0 - 0.92 * cov
        return lit

    def sea(self, D: F32, x: F32, y: F32, fp: F32) -> F32:
        """Sea colour (3, n): deep water, reflected sky (Fresnel), sun glitter, foam."""
        sc = self.scene
        ndz = np.maximum(-D[2], 1e-4)
        k = np.float32(self.A.waves.size / _WAVE_PERIOD)
        texel = _WAVE_PERIOD / self.A.waves.size
        wave = _tex(self.A.waves, x * k, y * (k * 0.4))[0] - 0.5
        wave *= np.clip((16.0 * texel - fp) * np.float32(1.0 / (12.0 * texel)), 0.15, 1.0)
        # reflected sky: elevation of the mirrored ray, tilted by the waves
        el = np.clip(ndz + 0.3 * wave * np.minimum(1.0, 6.0 * ndz + 0.05), 0.0, 1.0)
        refl = _lerp3(sc.sky_horizon, sc.sky_zenith, np.sqrt(el))
        refl = _blend(refl, _col(sc.cloud_colour) * 0.85,
                      np.full(el.shape, min(1.0, sc.cloud_cover * 0.9), np.float32))
        refl = _blend(refl, self.haze, np.exp(-30.0 * el))
        c = 1.0 - el
        c2 = c * c
        fres = 0.03 + 0.97 * c2 * c2 * c
        deep = _col(sc.sea_colour) * (0.6 + 0.25 * self.ground_light + 0.4 * self.ground_sun)
        col = _blend(np.broadcast_to(deep, refl.shape), refl, fres)
        if self.sun_strength > 0.1:
            rs = D[0] * self.sun_f[0] + D[1] * self.sun_f[1] - D[2] * self.sun_f[2]
            g = np.exp((rs + 0.25 * wave - 1.0) * 40.0) * (0.3 + 2.5 * np.maximum(wave, 0.0))
            col = col + _col(sc.sun_colour) * (g * self.sun_strength)[None]
        foam = _smoothstep(0.42, 0.5, wave) * 0.35 * np.clip(1.5 - fp, 0.0, 1.0)
        return _blend(col, _col((0.85, 0.85, 0.85)), foam)

    def hills(self, oz: float) -> None:
        """Distant hill silhouettes, far to near, over whatever is behind them."""
        sc = self.scene
        D = self.D
        hor = np.sqrt(D[0] * D[0] + D[1] * D[1]) + 1e-9
        tan_el = D[2] / hor
        for (dist, base, amp, _r, cr, cg, cb), prof in zip(sc.hills, self.A.hills, strict=True):
            lo = -oz / dist
            hi = (base + amp - oz) / dist
            cand = np.flatnonzero((tan_el > lo - 2 * self.inv_f) & (tan_el < hi + 2 * self.inv_f))
            if cand.size == 0:
                continue
            te = tan_el[cand]
            az = np.arctan2(D[1, cand], D[0, cand])
            fk = np.clip((az + np.float32(math.pi)) * np.float32(_HILL_SAMPLES / (2 * math.pi)),
                         0.0, _HILL_SAMPLES - 1e-3)
            k0 = np.floor(fk)
            k = k0.astype(np.intp)
            h = prof[k] + (prof[k + 1] - prof[k]) * (fk - k0)
            top = (h - np.float32(oz)) / np.float32(dist)
            # anti-aliased silhouette: coverage from the angular distance to the ridge line
            cov = np.clip((top - te) * np.float32(self.f) + 0.5, 0.0, 1.0)
            cov *= np.clip((te - np.float32(lo)) * np.float32(self.f) + 0.5, 0.0, 1.0)
            sel = np.flatnonzero(cov > 0)
            if sel.size == 0:
                continue
            ci, cov = cand[sel], cov[sel]
            tx = az[sel] * np.float32(dist * self.A.detail.size / 900.0)
            ty = te[sel] * np.float32(dist * self.A.detail.size / 300.0)
            n = _tex(self.A.detail, tx, ty)[0]
            depth = np.clip((top[sel] - te[sel]) * np.float32(dist / max(amp, 1.0)), 0.0, 1.0)
            col = _col((cr, cg, cb)) * ((0.8 + 0.3 * n) * (1.0 - 0.25 * depth))[None]
            col = col * (self.ground_light + 0.8 * self.ground_sun)
            if sc.terrain == "snow":
                col = col + (np.float32(0.85) - col) * 0.7
            col = col + (self.haze - col) * np.float32(1.0 - math.exp(-dist / sc.visibility))
            _put(self.C, ci, _blend(_take(self.C, ci), col, cov))

    def prepare_shadows(self, turbines: list[_Turbine]) -> None:
        """Ground shadows of the turbines' tower, nacelle and blades (segments on z = 0)."""
        self.shadow_segments = []
        if self.sun[2] <= 0.05 or self.sun_strength < 0.1 or self.scene.sea == "all":
            return
        s = self.sun / self.sun[2]
        for tb in turbines:
            if float(np.linalg.norm(tb.base[:2] - self.o[:2])) > 3000.0:
                continue

            def g(p: FloatArray) -> tuple[float, float]:
                return float(p[0] - p[2] * s[0]), float(p[1] - p[2] * s[1])

            self.shadow_segments.append((*g(tb.base), *g(tb.top), tb.r0, tb.r1))
            h = g(tb.hub)
            self.shadow_segments.append((*g(tb.nac_rear), *h, 0.5 * tb.nac_h, 0.5 * tb.nac_h))
            for tip in tb.tips:
                self.shadow_segments.append((*h, *g(tip), 0.035 * tb.b, 0.008 * tb.b))


class _Painter:
    """Ray casts turbine parts into a frame."""

    def __init__(self, fr: _Frame, scene: Scene) -> None:
        self.fr = fr
        self.sc = scene

    def tube(self, a: FloatArray, e: FloatArray, L: float, kind: str, tb: _Turbine,
             c0: FloatArray) -> None:
        """A tapered tube round the axis a + s e, s in [0, L] (tower or blade), with an
        elliptic cross-section whose chord is along c0 (turned by the twist for blades).

        Each ray is intersected through its closest approach to the axis: the lateral
        distance x, compared with the silhouette half-width of the cross-section seen along
        the ray, gives the coverage (anti-aliased over one pixel); the entry point on the
        cross-section gives the normal and the depth.
        """
        fr = self.fr
        if L <= 1e-6:
            return
        if kind == "tower":
            radius: float | FloatArray = tb.r0
        else:  # per eighth of the span (tip pieces get much smaller boxes)
            uu = np.linspace(0.0, 1.0, 33, dtype=np.float32)
            prof = np.maximum(*_blade_profile(uu, tb.b))
            radius = 1.05 * np.array([prof[4 * k:4 * k + 5].max() for k in range(8)])
        idx = fr.segment_pixels(a, a + L * e, radius)
        if idx is None:
            return
        D = _take(fr.D, idx)
        w = fr.o - a
        n0 = np.cross(e, c0)
        M = np.stack([e, w, np.cross(w, e), c0, n0]).astype(np.float32)
        P = _mat(M, D)
        b_, dw, trip, Dc0, Dn0 = P
        ew = np.float32(w @ e)
        den = np.maximum(1.0 - b_ * b_, 1e-6)
        sq = np.sqrt(den)
        isq = 1.0 / sq
        s_raw = ew + (b_ * ew - dw) / den * b_  # axis coordinate of the closest approach
        s = np.clip(s_raw, 0.0, np.float32(L))
        t = s * b_ - dw  # ray distance of the point nearest the axis point s
        x = trip * isq  # signed lateral distance of the ray from the axis
        u = s * np.float32(1.0 / L)
        if kind == "tower":
            A = np.float32(tb.r0) + np.float32(tb.r1 - tb.r0) * u
            B = A
            cb = np.ones_like(u)
            sb = np.zeros_like(u)
        else:
            A, B = _blade_profile(u, tb.b)
            beta = np.float32(self.sc.blade_pitch) + np.float32(math.radians(14.0)) * np.clip(
                (1.0 - u) * np.float32(1 / 0.8), 0.0, 1.0) ** 1.5
            cb, sb = np.cos(beta), np.sin(beta)
        # view direction projected on the cross-section, in (chord, thickness) coordinates
        mc = (cb * Dc0 + sb * Dn0) * isq
        mn = (cb * Dn0 - sb * Dc0) * isq
        hw = np.sqrt((mc * B) ** 2 + (mn * A) ** 2)  # silhouette half-width
        pix = np.maximum(t, _NEAR) * np.float32(fr.inv_f)  # metres per pixel there
        # flat ends (tower base and top, blade root) are cut at the hit point below; the
        # blade tip is round
        ds = np.zeros_like(x) if kind == "tower" else np.maximum(s_raw - np.float32(L), 0.0) * sq
        cov = np.ones_like(x)
        dist = np.sqrt(x * x + ds * ds)
        # parts thinner than a pixel are drawn one pixel wide and faint, not broken up
        hw_eff = np.maximum(hw, 0.6 * pix)
        cov = cov * np.clip(0.5 + (hw_eff - dist) / pix, 0.0, 1.0) * (hw / hw_eff)
        cov = cov * (t > _NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx = idx[sel]
        D = _take(D, sel)
        x, t, u, A, B, mc, mn, cb, sb, sq, cov, Dc0, Dn0, hw, b_ = (
            v[sel] for v in (x, t, u, A, B, mc, mn, cb, sb, sq, cov, Dc0, Dn0, hw, b_))
        # entry point (X, Y) on the elliptic cross-section, and its normal
        xc = np.clip(x, -0.97 * hw, 0.97 * hw)
        iA2 = 1.0 / (A * A)
        iB2 = 1.0 / (B * B)
        al = mc * mc * iA2 + mn * mn * iB2
        be = xc * mc * mn * (iB2 - iA2)
        ga = xc * xc * (mn * mn * iA2 + mc * mc * iB2) - 1.0
        tau = (-be - np.sqrt(np.maximum(be * be - al * ga, 0.0))) / al
        X = tau * mc - xc * mn
        Y = tau * mn + xc * mc
        nX = X * iA2
        nY = Y * iB2
        inv = 1.0 / np.maximum(np.sqrt(nX * nX + nY * nY), 1e-12)
        nX *= inv
        nY *= inv
        k0 = nX * cb - nY * sb  # normal = k0 c0 + k1 n0
        k1 = nX * sb + nY * cb
        l = fr.sun
        nl = k0 * np.float32(c0 @ l) + k1 * np.float32(n0 @ l)
        nz = k0 * np.float32(c0[2]) + k1 * np.float32(n0[2])
        nD = k0 * Dc0 + k1 * Dn0
        depth = t + np.maximum(tau / sq, -3.0 * np.maximum(A, B))
        albedo = np.repeat(_col(self.sc.paint), idx.size, axis=1)
        # flat ends: where the ray enters the (infinite) tube beyond an end, it misses it
        s_hit = ew + depth * b_  # axis coordinate of the hit point
        pix = np.maximum(depth, _NEAR) * np.float32(fr.inv_f)
        cov = cov * np.clip(0.5 + s_hit * sq / pix, 0.0, 1.0)
        if kind == "tower":
            cov = cov * np.clip(0.5 + (np.float32(L) - s_hit) * sq / pix, 0.0, 1.0)
            z = np.float32(fr.o[2]) + depth * D[2]
            hb, *bc = self.sc.base_band
            if hb > 0:
                m = np.clip((np.float32(hb) - z) / (depth * np.float32(fr.inv_f)) + 0.5, 0, 1)
                albedo = _blend(albedo, _col(tuple(bc)), m)  # type: ignore[arg-type]
            if self.sc.door:
                low = np.flatnonzero(z < 3.0)
                if low.size:
                    ang = np.arctan2(Y[low], X[low])  # round the axis, in the (c0, n0) frame
                    da = np.abs((ang - np.float32(tb.door_az) + np.pi) % np.float32(2 * np.pi)
                                - np.pi)
                    dm = low[(da * A[low] < 0.55) & (z[low] > 0.15) & (z[low] < 2.4)]
                    albedo[:, dm] = _col((0.35, 0.36, 0.37))
        elif self.sc.tip_bands:
            if self.sc.tip_bands == 1:
                band = u > 0.9
            else:
                band = ((u > 0.8) & (u < 0.87)) | (u > 0.93)
            albedo[:, band] = _col(self.sc.tip_colour)
        col = fr.shade(albedo, nl, nz, nD, _dot(fr.sun_f, D), 0.3)
        fr.composite(idx, depth, cov, fr.hazed(col, depth))

    def box(self, tb: _Turbine) -> None:
        """The nacelle: a box (slab test) with rounded (superellipse) shading; coverage from
        its inside margin divided by the margin's screen gradient (~ signed pixel distance)."""
        fr = self.fr
        E = np.stack([tb.shaft, tb.side, tb.up])  # rows: local axes
        hx = tb.nac_half
        oc = E @ (fr.o - tb.nac_centre)
        if np.all(np.abs(oc) < hx + 0.2):
            return  # the camera is inside the nacelle: draw nothing rather than a wall
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        bb = fr.bbox(tb.nac_centre + (signs * hx) @ E, 0.0)
        if bb is None:
            return
        i0, i1, j0, j1 = bb
        i0, i1 = max(0, i0 - 1), min(fr.H, i1 + 1)
        j0, j1 = max(0, j0 - 1), min(fr.W, j1 + 1)
        hh, ww = i1 - i0, j1 - j0
        if hh < 2 or ww < 2:
            return
        idx = fr.box_indices((i0, i1, j0, j1))
        D = _take(fr.D, idx)
        dl = _mat(E, D)
        dl = np.where(np.abs(dl) < 1e-7, np.float32(1e-7), dl)
        inv = 1.0 / dl
        o32 = oc.astype(np.float32)[:, None]
        h32 = hx.astype(np.float32)[:, None]
        t1 = (-h32 - o32) * inv
        t2 = (h32 - o32) * inv
        tn = np.minimum(t1, t2).max(axis=0)
        tf = np.maximum(t1, t2).min(axis=0)
        g = (tf - tn).reshape(hh, ww)
        gy, gx = np.gradient(g)
        sd = g / np.maximum(np.sqrt(gx * gx + gy * gy), 1e-6)
        cov = np.clip(0.5 + sd.ravel(), 0.0, 1.0) * (tn > _NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx, tn, cov = idx[sel], tn[sel], cov[sel]
        D, dl = _take(D, sel), _take(dl, sel)
        P = o32 + tn[None] * dl
        q = np.clip(np.abs(P) / h32, 0.0, 1.0)
        q2 = q * q
        q4 = q2 * q2
        nloc = np.sign(P) * (q4 * q2 * q) / h32  # superellipse gradient: rounded edges
        nloc /= np.maximum(np.sqrt((nloc * nloc).sum(axis=0)), 1e-12)[None]
        n = _mat(E.T, nloc)
        albedo = _col(self.sc.paint) * np.float32(0.97)
        col = fr.shade(albedo, _dot(fr.sun_f, n), n[2], (n * D).sum(axis=0), _dot(fr.sun_f, D),
                       0.3)
        fr.composite(idx, tn, cov, fr.hazed(col, tn))

    def spinner(self, tb: _Turbine) -> None:
        """The spinner: an ellipsoid round the hub (exact intersection)."""
        fr = self.fr
        E = np.stack([tb.shaft, tb.side, tb.up])
        radii = np.array([tb.spin_len, tb.spin_r, tb.spin_r])
        bb = fr.bbox(tb.spin_centre[None], max(tb.spin_len, tb.spin_r))
        if bb is None:
            return
        idx = fr.box_indices(bb)
        D = _take(fr.D, idx)
        S = E / radii[:, None]  # world -> unit-sphere coordinates
        op = (S @ (fr.o - tb.spin_centre)).astype(np.float32)
        Cq = np.float32(op @ op - 1.0)
        if Cq <= 0:
            return
        dp = _mat(S, D)
        Aq = (dp * dp).sum(axis=0)
        Bq = _dot(op, dp)
        rho2 = (Cq + 1.0) - Bq * Bq / Aq  # squared distance of the ray from the centre
        t = (-Bq - np.sqrt(np.maximum(Bq * Bq - Aq * Cq, 0.0))) / Aq
        pix = np.maximum(t, _NEAR) * np.float32(fr.inv_f)
        cov = np.clip(0.5 + (1.0 - np.sqrt(np.maximum(rho2, 0.0))) * np.float32(tb.spin_r) / pix,
                      0.0, 1.0) * (t > _NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx, t, cov = idx[sel], t[sel], cov[sel]
        D, dp = _take(D, sel), _take(dp, sel)
        P = op[:, None] + t[None] * dp
        n = _mat(E.T, P / radii.astype(np.float32)[:, None])
        n /= np.maximum(np.sqrt((n * n).sum(axis=0)), 1e-12)[None]
        col = fr.shade(_col(self.sc.paint), _dot(fr.sun_f, n), n[2], (n * D).sum(axis=0),
                       _dot(fr.sun_f, D), 0.35)
        fr.composite(idx, t, cov, fr.hazed(col, t))

    def turbine(self, tb: _Turbine) -> None:
        """All parts, far to near (so that anti-aliased edges blend over what is behind)."""
        fr = self.fr
        top = np.array([tb.base[0], tb.base[1], tb.tower_top_z])
        parts: list[tuple[float, int, int]] = [
            (float(np.linalg.norm(0.5 * (tb.base + top) - fr.o)), 0, 0),
            (float(np.linalg.norm(tb.nac_centre - fr.o)), 1, 0),
            (float(np.linalg.norm(tb.spin_centre - fr.o)) - 0.5 * tb.spin_len, 2, 0),
        ]
        for i, tip in enumerate(tb.tips):
            parts.append((float(np.linalg.norm(0.5 * (tb.hub + tip) - fr.o)), 3, i))
        for _, kind, i in sorted(parts, key=lambda p: -p[0]):
            if kind == 0:
                self.tube(tb.base, np.array([0.0, 0.0, 1.0]), float(top[2] - tb.base[2]),
                          "tower", tb, np.array([1.0, 0.0, 0.0]))
            elif kind == 1:
                self.box(tb)
            elif kind == 2:
                self.spinner(tb)
            else:
                e = tb.tips[i] - tb.hub
                L = float(np.linalg.norm(e))
                if L < 1e-6:
                    continue
                e = e / L
                c0 = np.cross(tb.shaft, e)  # chord at zero pitch: in the rotor plane
                nc = float(np.linalg.norm(c0))
                c0 = c0 / nc if nc > 1e-9 else _perp(e)
                self.tube(tb.hub, e, L, "blade", tb, c0)


# ---- camera effects -----------------------------------------------------------------------

#: Standard normal quantiles of 65536 equal-probability bins: indexing with uniform 16-bit
#: integers draws (quantised) Gaussian sensor noise ~3x faster than ``standard_normal``.
_NORMAL_TABLE = ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)
#: Tone curve input resolution: intensities 0..2 in steps of 1/_TONE_STEPS.
_TONE_STEPS = 1024


@lru_cache(maxsize=64)
def _tone_lut(gamma: float, contrast: float) -> NDArray[np.uint8]:
    """uint8 output of intensities ``k / _TONE_STEPS``: linear up to 0.8, then a soft
    shoulder (highlights roll off instead of clipping), then gamma and contrast."""
    x = np.arange(2 * _TONE_STEPS + 1) / _TONE_STEPS
    y = np.where(x < 0.8, x, 0.8 + 0.2 * (1.0 - np.exp(-(x - 0.8) / 0.2)))
    y = y**gamma
    y = (y - 0.5) * contrast + 0.5
    return np.clip(y * 255.0 + 0.5, 0.0, 255.0).astype(np.uint8)


def _motion_blur(img: F32, length: float, angle: float) -> F32:
    """(3, H, W) averaged over shifted copies along a line of ``length`` px."""
    n = max(2, math.ceil(length) + 1)
    pad = math.ceil(length / 2) + 2
    P = np.pad(img, ((0, 0), (pad, pad), (pad, pad)), mode="edge")
    h, w = img.shape[1:]
    out = np.zeros_like(img)
    for k in range(n):
        off = (k / (n - 1) - 0.5) * length
        dx, dy = off * math.cos(angle), off * math.sin(angle)
        ix, iy = math.floor(dx), math.floor(dy)
        fx, fy = dx - ix, dy - iy
        for oy, wy in ((iy, 1 - fy), (iy + 1, fy)):
            for ox, wx in ((ix, 1 - fx), (ix + 1, fx)):
                wgt = wx * wy
                if wgt < 1e-3:
                    continue
                out += np.float32(wgt / n) * P[:, pad + oy:pad + oy + h, pad + ox:pad + ox + w]
    return out


def _apply_effects(img: F32, rn: F32, eff: CameraEffects, rng: np.random.Generator
                   ) -> NDArray[np.uint8]:
    """Per-frame camera effects on a (3, H, W) float32 image -> (H, W, 3) uint8."""
    h, w = img.shape[1:]
    u = rng.uniform(size=12)
    z = rng.normal(size=4)
    scale = 0.1 if u[0] < eff.clean_prob else 1.0
    # auto exposure towards a mid-grey mean, with jitter, and white balance
    lum = float(np.mean(img[:, ::4, ::4]))
    gain = (0.45 / max(lum, 0.05)) ** 0.6 * math.exp(scale * eff.exposure_sigma * z[0])
    wb = np.exp(scale * eff.white_balance_sigma * z[1:4])
    g = (gain * wb / wb.mean()).astype(np.float32)[:, None, None]
    vig = scale * eff.vignetting * u[1]
    if vig > 0.005:
        img = img * g * (1.0 - np.float32(vig) * rn.reshape(h, w))[None]
    else:
        img = img * g
    cj = scale * eff.colour_jitter
    sat = 1.0 + 1.5 * cj * (2 * u[2] - 1)
    if abs(sat - 1.0) > 0.02:
        grey = img.mean(axis=0, keepdims=True)
        img = grey + (img - grey) * np.float32(sat)
    blur = scale * eff.motion_blur_px * u[3]
    if blur > 0.3:
        img = _motion_blur(img, blur, float(u[4] * math.pi))
    sigma = scale * eff.defocus_px * u[5]
    if sigma > 0.2:
        img = ndimage.gaussian_filter(img, (0.0, sigma, sigma), truncate=2.5)
    noise = scale * eff.noise * u[6]
    if noise > 0.001:
        n = _NORMAL_TABLE[rng.integers(0, 65536, (3, h, w), dtype=np.uint16)]
        img = img + n * (np.float32(noise) * (0.5 + 0.5 * img))
    q = np.clip(img * np.float32(_TONE_STEPS), 0.0, 2 * _TONE_STEPS).astype(np.uint16)
    gamma = round(math.exp(cj * (2 * u[7] - 1)), 2)
    contrast = round(1.0 + cj * (2 * u[8] - 1), 2)
    out = np.ascontiguousarray(_tone_lut(gamma, contrast)[q].transpose(1, 2, 0))
    if eff.jpeg_quality is not None:
        lo, hi = eff.jpeg_quality
        quality = round(lo + (hi - lo) * u[9]) if scale == 1.0 else max(hi, 90)
        buf = io.BytesIO()
        Image.fromarray(out).save(buf, format="JPEG", quality=int(np.clip(quality, 1, 95)))
        buf.seek(0)
        with Image.open(buf) as im:
            out = np.asarray(im.convert("RGB"), dtype=np.uint8).copy()
    return out


# ---- public API ---------------------------------------------------------------------------


def render_image(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    scene: Scene,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> NDArray[np.uint8]:
    """An RGB image (H, W, 3) uint8 of ``turbine`` and its scene seen from one pose.

    Args:
        camera: intrinsics (H, W = its image size; plumb_bob distortion is applied).
        world_T_cam: camera-to-world pose (a single pose, world metres, OpenCV camera).
        turbine: theta (7,) of the primary turbine [m, rad]; its solid geometry is built
            round :func:`~turbinefit.turbine.model.model_points` ``(theta, geometry)``.
        scene: appearance (sky, terrain, paint, neighbours, effect strengths).
        rng: drives the per-frame camera effects only (exposure, white balance, blur,
            noise, JPEG quality).
        geometry: shaft tilt, blade cone and hub offset of every turbine of the scene.
    """
    return render_image_and_depth(camera, world_T_cam, turbine, scene, rng, geometry)[0]


def render_image_and_depth(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    scene: Scene,
    rng: np.random.Generator,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> tuple[NDArray[np.uint8], NDArray[np.float32]]:
    """:func:`render_image` (same arguments, same image) and its depth: (H, W) float32,
    the distance [m] along each pixel's ray to the nearest turbine surface (of any turbine
    of the scene) covering most of the pixel, inf where none does (sky, terrain)."""
    if world_T_cam.batch_shape != ():
        raise ValueError(f"expected one pose, got batch {world_T_cam.batch_shape}")
    fr = _Frame(camera, world_T_cam, scene)
    thetas = [np.asarray(turbine, dtype=np.float64).ravel(), *map(np.asarray, scene.neighbours)]
    doors = np.random.default_rng(scene.seed).uniform(-math.pi, math.pi, len(thetas))
    turbines = [_Turbine(th, geometry, scene, float(dz)) for th, dz in zip(thetas, doors, strict=True)]
    fr.prepare_shadows(turbines)
    fr.background()
    painter = _Painter(fr, scene)
    for tb in sorted(turbines, key=lambda q: -float(np.linalg.norm(q.centre - fr.o))):
        painter.turbine(tb)
    img = fr.C.reshape(3, camera.height, camera.width)
    np.nan_to_num(img, copy=False, nan=0.5, posinf=1.0, neginf=0.0)
    depth = fr.Z.reshape(camera.height, camera.width).copy()
    return _apply_effects(img, fr.rn, scene.effects, rng), depth


def points_in_sight(camera: PinholeCamera, world_T_cam: SE3, world_p: ArrayLike,
                    depth: NDArray[np.floating], margin_m: float = 3.0,
                    margin_rel: float = 0.02) -> NDArray[np.bool_]:
    """Which world points (M, 3) the camera sees: in front of it, inside the image and
    not behind a turbine surface of ``depth`` (:func:`render_image_and_depth`, same
    camera) nearer than the point by more than ``margin_m`` + ``margin_rel`` x its
    distance at the point's pixel (the margin lets a point inside its own part, e.g. a
    blade tip on the blade's axis or the hub inside the spinner, count as seen)."""
    p = np.asarray(world_p, dtype=np.float64).reshape(-1, 3)
    uv, ok, _ = camera.project_unbounded(world_T_cam.inverse().apply(p))
    seen = ok & camera.in_image(uv)
    dist = np.linalg.norm(p - world_T_cam.translation, axis=-1)
    for k in np.flatnonzero(seen):
        j = min(max(round(float(uv[k, 0])), 0), camera.width - 1)
        i = min(max(round(float(uv[k, 1])), 0), camera.height - 1)
        seen[k] = float(depth[i, j]) >= dist[k] - margin_m - margin_rel * dist[k]
    return seen


def flight_scene(turbine: ArrayLike, seed: int) -> Scene:
    """The :class:`Scene` of the flight simulated with ``seed`` round ``turbine`` (theta):
    the one :func:`render_flight_images` draws every keyframe in (other renderers use it
    to show the same scene)."""
    scene_ss, _ = np.random.SeedSequence(seed).spawn(2)
    theta = np.asarray(turbine, dtype=np.float64).ravel()
    return sample_scene(np.random.default_rng(scene_ss), TurbineParams.from_vector(theta))


def render_flight_images(
    camera: PinholeCamera,
    world_T_cam: SE3,
    turbine: ArrayLike,
    seed: int,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
    progress: bool = False,
) -> Iterator[NDArray[np.uint8]]:
    """Images (H, W, 3) uint8 of every keyframe of ``world_T_cam`` (N,), one at a time.

    One :class:`Scene` for the whole flight is sampled from ``seed``; each keyframe's
    effects get their own generator, spawned from the same seed (keyframe k's image depends
    only on the seed and k). ``progress`` shows a tqdm bar.
    """
    poses = SE3(world_T_cam.wxyz_xyz.reshape(-1, 7))
    n = poses.batch_shape[0]
    theta = np.asarray(turbine, dtype=np.float64).ravel()
    scene = flight_scene(theta, seed)
    _, frames_ss = np.random.SeedSequence(seed).spawn(2)
    rngs = [np.random.default_rng(s) for s in frames_ss.spawn(n)]
    for k in tqdm(range(n), desc="rendering images", unit="img", disable=not progress):
        yield render_image(camera, poses[k], theta, scene, rngs[k], geometry)


def _solid_segments(turbine: TurbineParams, geometry: TurbineGeometry) -> FloatArray:
    """Skeleton segments plus the nacelle's axis from its rear end (which the skeleton
    lacks: the nacelle overhangs behind the tower) to the hub."""
    segs = skeleton_segments(turbine, geometry)
    p, _ = model_points(turbine.to_vector(), geometry)
    w, tau = turbine.heading, geometry.shaft_tilt
    shaft = np.array([math.cos(w) * math.cos(tau), math.sin(w) * math.cos(tau), math.sin(tau)])
    r = abs(turbine.nacelle_length)
    rear = min(_NACELLE_REAR[1] * max(r, 2.0), _NACELLE_REAR_MAX)
    return np.concatenate([segs, np.stack([p[2] - (r + rear) * shaft, p[2]])[None]])


def _look(pos: FloatArray, yaw: float, pitch: float, roll: float) -> SE3:
    cp, sp = math.cos(pitch), math.sin(pitch)
    z = np.array([cp * math.cos(yaw), cp * math.sin(yaw), sp])
    x = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    y = np.cross(z, x)
    cr, sr = math.cos(roll), math.sin(roll)
    R = np.stack([cr * x + sr * y, -sr * x + cr * y, z], axis=-1)
    return SE3.from_rotation_translation(R, pos)


def sample_training_view(
    rng: np.random.Generator,
    turbine: TurbineParams,
    camera: PinholeCamera,
    geometry: TurbineGeometry = PAPER_GEOMETRY,
) -> SE3:
    """``world_T_cam`` of a varied training view of ``turbine``.

    A mix of far views (150-500 m from the turbine's centre, 30 %), medium views (40-150 m
    from a random point of the skeleton, 35 %) and close views (12-40 m from a point of the
    nacelle, a blade or the tower, 35 %) aimed at that point with random offsets of up to
    about half the field of view (more for close views, so parts leave the frame). The
    camera is at least 3 m above the ground and 6 m from the turbine's skeleton (and the
    nacelle's rear), mostly level (roll within +-5 deg), pitch within +-60 deg.
    """
    p, _ = model_points(turbine.to_vector(), geometry)
    segs = _solid_segments(turbine, geometry)
    lengths = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=-1)
    half_h = math.atan(0.5 * camera.width / camera.fx)
    half_v = math.atan(0.5 * camera.height / camera.fy)
    centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
    kind = int(rng.choice(3, p=[0.3, 0.35, 0.35]))
    pos = target = centre
    for _attempt in range(200):
        if kind == 0:
            target = centre + rng.normal(0.0, 0.1, 3) * np.array([1.0, 1.0, 2.0]) * turbine.blade_length
            dist = rng.uniform(150.0, 500.0)
            el = math.radians(rng.uniform(-25.0, 30.0))
            spread = 0.45
        elif kind == 1:
            k = int(rng.choice(5, p=lengths[:5] / lengths[:5].sum()))
            target = segs[k, 0] + rng.uniform() * (segs[k, 1] - segs[k, 0])
            dist = rng.uniform(40.0, 150.0)
            el = math.radians(rng.uniform(-40.0, 40.0))
            spread = 0.7
        else:
            part = rng.choice(3, p=[0.35, 0.4, 0.25])
            if part == 0:  # nacelle, hub, blade roots
                target = p[1] + rng.uniform(-0.5, 1.2) * (p[2] - p[1]) + rng.normal(0, 1.5, 3)
            elif part == 1:  # a blade
                i = int(rng.integers(0, 3))
                target = p[2] + rng.uniform(0.1, 1.0) * (p[3 + i] - p[2])
            else:  # the tower
                target = p[0] + rng.uniform(0.05, 1.0) * (p[1] - p[0])
            dist = rng.uniform(12.0, 40.0)
            el = math.radians(rng.uniform(-50.0, 50.0))
            spread = 1.0
        az = rng.uniform(0.0, 2 * math.pi)
        pos = target + dist * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                                        math.sin(el)])
        if pos[2] < 3.0:
            pos[2] = rng.uniform(3.0, 3.0 + 0.2 * dist)
        d, _ = distance_to_segments(pos[None], segs)
        if float(d[0]) >= _CLEARANCE:
            break
    else:  # give up on the close view: go back far enough (always succeeds)
        away = pos - centre
        away[2] = 0.0
        nrm = float(np.linalg.norm(away))
        away = away / nrm if nrm > 1e-9 else np.array([1.0, 0.0, 0.0])
        pos = centre + away * (turbine.blade_length + turbine.nacelle_length + 3 * _CLEARANCE)
        pos[2] = max(pos[2], 3.0)
        target = centre
    v = target - pos
    yaw = math.atan2(v[1], v[0]) + spread * half_h * rng.uniform(-1.0, 1.0)
    pitch = math.atan2(v[2], math.hypot(v[0], v[1])) + spread * half_v * rng.uniform(-1.0, 1.0)
    pitch = float(np.clip(pitch, -math.radians(60.0), math.radians(60.0)))
    roll = float(np.clip(rng.normal(0.0, math.radians(2.0)), -math.radians(5.0), math.radians(5.0)))
    return _look(pos, yaw, pitch, roll)
