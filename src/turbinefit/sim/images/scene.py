"""What a rendered scene looks like, and how it is drawn at random.

:class:`Scene` holds everything random about a scene's appearance (sky, atmosphere,
terrain, roads, paint, neighbour turbines, camera-effect strengths; world metres, radians,
RGB in [0, 1]); :func:`sample_scene` draws one round a turbine and :func:`flight_scene`
the one of a simulated flight's seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from turbinefit.sim.images.arrays import RGB
from turbinefit.sim.images.clutter import NO_CLUTTER, Clutter, sample_clutter
from turbinefit.sim.images.textures import scene_assets
from turbinefit.turbine.model import BLADE_PERIOD, TurbineParams
from turbinefit.turbine.solid import NACELLE_HEIGHT, NACELLE_REAR, NACELLE_WIDTH

#: Terrain kinds of :attr:`Scene.terrain`.
TERRAINS = ("fields", "grass", "scrub", "forest", "dry", "snow", "offshore")


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
        wear: 0..1, leading-edge erosion of the blades' outer halves (close-ups show it).
        dirt: 0..1, streaks of dirt and oil along blades and tower.
        tower_section: height of the tower's sections [m] (flange seams between them).
        clutter: line-like things on the ground and in the air (power lines, pylons,
            fences, buildings; :class:`~turbinefit.sim.images.clutter.Clutter`).
        blade_marks: the blades' bond lines and lightning receptors.
        surface_detail: the look of an inspection's close-ups: the blades' gelcoat
            mottled at centimetre scales (fading out where a pixel is coarser than the
            mottling), and the wear on the leading edge of a rotor turning clockwise seen
            from upwind (:mod:`turbinefit.inspection.surface`'s sides).
        defects: known defects painted on the primary turbine's blades
            (:func:`turbinefit.sim.defects.painted_defects`).

    Wear, dirt, tower seams, blade marks and clutter are drawn in the CNN's training
    renders (:func:`sample_scene`), not in simulated flights (:func:`flight_scene`) unless
    it is asked for their surface (``surface=True``, with ``surface_detail``).
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
    wear: float = 0.0
    dirt: float = 0.0
    tower_section: float = 0.0
    clutter: Clutter = NO_CLUTTER
    blade_marks: bool = False
    surface_detail: bool = False
    defects: tuple[tuple[float, ...], ...] = ()

    def __post_init__(self) -> None:
        if self.terrain not in TERRAINS:
            raise ValueError(f"terrain must be one of {TERRAINS}, got {self.terrain!r}")
        if self.sea not in ("none", "coast", "all"):
            raise ValueError(f"sea must be none, coast or all, got {self.sea!r}")
        if len(self.ground_colours) != 5:
            raise ValueError("ground_colours needs 5 colours")
        if not self.visibility > 0:
            raise ValueError("visibility must be positive")


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


def _surface_and_clutter(seed: int, turbine: TurbineParams,
                         roads: tuple[tuple[float, float, float, float, float], ...],
                         sea: str) -> tuple[float, float, float, Clutter]:
    """The blades' wear and dirt, the tower's sections and the clutter, from their own
    generator (seeded by the scene's seed), so that the rest of a scene is drawn as before
    they existed."""
    rng = np.random.default_rng([seed, 7])
    wear = float(rng.uniform(0.0, 1.0) ** 2) if rng.uniform() < 0.7 else 0.0
    return (wear, float(rng.uniform(0.0, 1.0)), float(rng.uniform(18.0, 30.0)),
            sample_clutter(rng, turbine, roads, sea))


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
    nacelle = (float(rng.uniform(*NACELLE_REAR)), float(rng.uniform(*NACELLE_HEIGHT)),
               float(rng.uniform(*NACELLE_WIDTH)))
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
    wear, dirt, section, clutter = _surface_and_clutter(seed, turbine, roads, sea)
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
        wear=wear, dirt=dirt, tower_section=section, clutter=clutter, blade_marks=True,
    )
    scene_assets(scene)  # generate the noise tiles now
    return scene


def flight_scene(turbine: ArrayLike, seed: int, surface: bool = False,
                 defects: tuple[tuple[float, ...], ...] = ()) -> Scene:
    """The :class:`Scene` of the flight simulated with ``seed`` round ``turbine`` (theta):
    the one :func:`render_flight_images` draws every keyframe in (other renderers use it
    to show the same scene). ``surface``: with the blades' and tower's surface (wear,
    dirt, seams, receptors, :attr:`Scene.surface_detail`) and the painted ``defects``
    (an inspection's close-ups); without, the flights' photos stay those the fits from
    photos were measured on."""
    scene_ss, _ = np.random.SeedSequence(seed).spawn(2)
    theta = np.asarray(turbine, dtype=np.float64).ravel()
    scene = sample_scene(np.random.default_rng(scene_ss), TurbineParams.from_vector(theta))
    if surface:
        return replace(scene, clutter=NO_CLUTTER, surface_detail=True, defects=defects,
                       wear=max(scene.wear, 0.3), dirt=min(scene.dirt, 0.5))
    return replace(scene, wear=0.0, dirt=0.0, tower_section=0.0,
                   clutter=NO_CLUTTER, blade_marks=False, defects=defects)
