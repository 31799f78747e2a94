"""The background of a rendered image, ray cast per pixel: sky (gradient, clouds, sun),
ground (terrain textures, fields, roads and pads, cloud and turbine shadows, coast and sea)
and distant hills, with aerial perspective.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from turbinefit.sim.images.arrays import (
    F32,
    RGB,
    FloatArray,
    IntArray,
    blend,
    column,
    dot3,
    lerp3,
    put_cols,
    smoothstep,
    take_cols,
)
from turbinefit.sim.images.frame import Frame
from turbinefit.sim.images.textures import (
    DETAIL,
    HILL_SAMPLES,
    WAVE_PERIOD,
    cell_hash,
    macro_period,
    sample_tile,
    smooth_mean,
)
from turbinefit.sim.images.turbine import TurbineSolid

_FAR = 6.0e4  # [m] ground beyond this is pure haze


class Landscape:
    """Paints a frame's background: sky and clouds, the ground (terrain, roads, pads, cloud
    and turbine shadows, coast and sea) and distant hills, with aerial perspective."""

    def __init__(self, fr: Frame) -> None:
        self.fr = fr
        self.scene = fr.scene
        self.A = fr.A
        self.shadow_segments: list[tuple[float, float, float, float, float, float]] = []
        self.gpos: NDArray[np.int32] | None = None  # pixel -> index among ground pixels

    def ground_subset(self, idx: IntArray | None) -> IntArray | None:
        """Positions among the ground pixels of those pixels of ``idx`` that see the ground."""
        if idx is None or self.gpos is None:
            return None
        pos = self.gpos[idx]
        pos = pos[pos >= 0]
        return pos.astype(np.intp) if pos.size else None

    def paint(self) -> None:
        """Sky, ground (land or sea) and distant hills into the frame's colour buffer."""
        fr = self.fr
        dz = fr.D[2]
        oz = max(float(fr.o[2]), 0.05)
        ground = dz < -1e-5
        gi = np.flatnonzero(ground)
        si = np.flatnonzero(~ground)
        if si.size:
            put_cols(fr.C, si, self.sky(si))
        if gi.size:
            self.gpos = np.full(fr.W * fr.H, -1, dtype=np.int32)
            self.gpos[gi] = np.arange(gi.size, dtype=np.int32)
            put_cols(fr.C, gi, self.ground(gi, oz))
        if self.scene.hills:
            self.hills(oz)

    def sky(self, idx: IntArray) -> F32:
        """Sky colour (3, n) of the pixels ``idx``: gradient, clouds, sun, horizon haze."""
        fr = self.fr
        sc = self.scene
        D = take_cols(fr.D, idx)
        dz = np.maximum(D[2], 0.0)
        col = lerp3(sc.sky_horizon, sc.sky_zenith, np.sqrt(dz))
        cs = dot3(fr.sun_f, D)
        clear = 1.0 - sc.overcast
        glow = (0.12 + 0.3 * clear) * np.exp(10.0 * (cs - 1.0)) + 0.6 * clear * np.exp(
            300.0 * (cs - 1.0))
        disc = np.clip((cs - math.cos(math.radians(0.4))) * 2e5, 0.0, 1.0) * (4.0 * clear)
        if sc.cloud_cover > 0.01 and fr.o[2] < sc.cloud_altitude:
            ci = np.flatnonzero(dz > 0.003)
            if ci.size:
                dist = np.float32(sc.cloud_altitude - fr.o[2]) / dz[ci]
                k = np.float32(self.A.clouds.size / sc.cloud_scale)
                x = (np.float32(fr.o[0]) + D[0, ci] * dist) * k
                y = (np.float32(fr.o[1]) + D[1, ci] * dist) * k
                # footprint [texels] -> blend of two blur levels
                fpt = dist * np.float32(k * fr.inv_f) / np.sqrt(np.maximum(dz[ci], 0.02))
                dd = np.empty((2, ci.size), dtype=np.float32)
                thr = 1.0 - sc.cloud_cover
                g = np.flatnonzero(fpt < 3.0)
                if g.size:  # near: threshold the noise (+ a finer octave) per pixel
                    v = sample_tile(self.A.clouds, x[g], y[g], (0, 1, 2, 3))
                    # 4x finer octave, faded out before its texels get smaller than a pixel
                    det = sample_tile(self.A.detail, x[g] * 4.0 + 7.0, y[g] * 4.0 + 3.0)[0]
                    n = v[0] + (det - 0.5) * (0.1 * np.clip((1.0 - fpt[g]) * 1.5, 0.0, 1.0))
                    d0 = smoothstep(thr - 0.08, thr + 0.1, n)
                    wgt = np.clip((fpt[g] - 1.0) * 0.5, 0.0, 1.0)
                    dd[0, g] = d0 + (v[2] - d0) * wgt
                    dd[1, g] = v[1] + (v[3] - v[1]) * wgt
                g = np.flatnonzero(fpt >= 3.0)
                if g.size:  # far: blend the blurred levels
                    v = sample_tile(self.A.clouds, x[g], y[g], (2, 3, 4, 5))
                    wgt = np.clip((fpt[g] - 3.0) * np.float32(1 / 7), 0.0, 1.0)
                    put_cols(dd, g, v[:2] + (v[2:] - v[:2]) * wgt[None])
                fade = np.exp(dist * np.float32(-1.0 / 25000.0))
                far = min(1.0, 1.2 * sc.cloud_cover)
                dens = dd[0] * fade + far * (1.0 - fade)
                dark = dd[1] * fade + 0.5 * far * (1.0 - fade)
                shade = 1.0 - (0.3 + 0.12 * sc.overcast) * dark
                ccol = column(sc.cloud_colour) * shade[None]
                # silver lining: thin cloud lit from behind near the sun
                ccol = ccol + column(sc.sun_colour) * (glow[ci] * 1.2 * (1.0 - dark) * clear)[None]
                put_cols(col, ci, blend(take_cols(col, ci), ccol, dens))
                att = np.ones_like(glow)
                att[ci] = 1.0 - 0.9 * dens
                glow = glow * att
                disc = disc * att * att
        col = col + column(sc.sun_colour) * (glow + disc)[None]
        # horizon haze (the sky meets the fully hazed far ground seamlessly)
        h = np.exp(dz * np.float32(-(4000.0 / max(sc.visibility, 1.0) + 8.0)))
        return blend(col, fr.haze, h)

    def ground(self, idx: IntArray, oz: float) -> F32:
        """Ground colour (3, n) of the pixels ``idx`` (camera ``oz`` [m] above the ground)."""
        fr = self.fr
        sc = self.scene
        D = take_cols(fr.D, idx)
        ndz = np.maximum(-D[2], 1e-6)
        t = np.minimum(np.float32(oz) / ndz, _FAR)
        x = np.float32(fr.o[0]) + t * D[0]
        y = np.float32(fr.o[1]) + t * D[1]
        fp = t * (np.float32(fr.inv_f) / np.sqrt(np.maximum(ndz, 0.02)))  # m per pixel
        if sc.sea == "all":
            return fr.hazed(self.sea(D, x, y, fp), t)
        col = self.terrain(x, y, fp)
        self.features(col, x, y, fp)
        light = fr.ground_light + fr.ground_sun * self.shadows(x, y, fp)
        col *= light[None]
        if sc.sea == "coast":
            self.coast(col, D, x, y, fp, light)
        return fr.hazed(col, t)

    def coast(self, col: F32, D: F32, x: F32, y: F32, fp: F32, light: F32) -> None:
        """Beach and sea beyond a wavy coastline (in place)."""
        sc = self.scene
        ca, sa = math.cos(sc.coast[0]), math.sin(sc.coast[0])
        k = np.float32(self.A.detail.size / 4000.0)
        s = ((x - np.float32(sc.centre[0])) * np.float32(ca)
             + (y - np.float32(sc.centre[1])) * np.float32(sa) - np.float32(sc.coast[1])
             - 400.0 * (sample_tile(self.A.detail, x * k + 91.0, y * k + 13.0)[0] - 0.5))
        pfp = np.maximum(fp, 0.5)
        near = np.flatnonzero(s > -40.0 - 2 * pfp)
        if near.size == 0:
            return
        sn, pn = s[near], pfp[near]
        sand = column((0.72, 0.66, 0.52)) * light[near][None]
        c = blend(take_cols(col, near), sand, np.clip((sn + 25.0) / pn + 0.5, 0.0, 1.0) * 0.85)
        wet = np.clip(sn / pn + 0.5, 0.0, 1.0)
        wi = np.flatnonzero(wet > 0)
        if wi.size:
            g = near[wi]
            sea = self.sea(take_cols(D, g), x[g], y[g], fp[g])
            put_cols(c, wi, blend(take_cols(c, wi), sea, wet[wi]))
        put_cols(col, near, c)

    def detail(self, col: F32, x: F32, y: F32, fp: F32, period: float, lo: float, hi: float,
               strength: RGB, ox: float, oy: float) -> None:
        """Zero-mean fine modulation of ``col`` (in place) where the pixel footprint ``fp``
        resolves noise of ``period`` [m] (it fades out before it could alias)."""
        texel = period / self.A.detail.size
        sel = np.flatnonzero(fp < 4.0 * texel)
        if sel.size == 0:
            return
        k = np.float32(1.0 / texel)
        n = sample_tile(self.A.detail, x[sel] * k + ox, y[sel] * k + oy)[0]
        if lo > 0.0 or hi < 1.0:
            n = smoothstep(lo, hi, n)
        fade = np.clip((4.0 * texel - fp[sel]) * np.float32(1.0 / (3.0 * texel)), 0.0, 1.0)
        m = (n - np.float32(smooth_mean(lo, hi))) * fade
        put_cols(col, sel, take_cols(col, sel) * (1.0 + column(strength) * m[None]))

    def terrain(self, x: F32, y: F32, fp: F32) -> F32:
        """Unlit ground colour (3, n) at world points (x, y) seen with footprint fp [m]."""
        sc = self.scene
        kmac = np.float32(self.A.macro.size / macro_period(sc))
        col = sample_tile(self.A.macro, x * kmac, y * kmac)
        if sc.terrain == "fields":
            col *= self.fields(x, y, fp)
        period, lo, hi, strength = DETAIL[sc.terrain]
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
        yr = yr + cell_hash(ix, ix, 7) * np.float32(fl)
        cy = np.floor(yr * np.float32(1.0 / fl))
        iy = cy.astype(np.int32)
        h1 = cell_hash(ix, iy, 1)
        h2 = cell_hash(ix, iy, 2)
        pal = np.ascontiguousarray(np.asarray(sc.ground_colours, np.float32).T)  # (3, 5)
        ci = np.minimum((h1 * 5.0).astype(np.intp), 4)
        col = np.take(pal, ci, axis=1) * (0.85 + 0.3 * h2)[None]
        forest = np.flatnonzero(h2 > 0.93)
        if forest.size:
            put_cols(col, forest, np.broadcast_to(column(sc.hedge_colour) * 1.2, (3, forest.size)))
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
            put_cols(col, rs, take_cols(col, rs) * (1.0 + rows * amp)[None])
        # hedges and borders (some cells without)
        d = np.minimum(np.minimum(fx, np.float32(fw) - fx), np.minimum(fy, np.float32(fl) - fy))
        hw = np.float32(1.5)
        pfp = np.maximum(fp, 0.05)
        hedge = np.clip((hw - d) / pfp + 0.5, 0.0, 1.0) * np.minimum(1.0, 2.0 * hw / pfp)
        hedge = hedge * np.where((h2 * 31.0) % 1.0 < 0.75, 0.9, 0.3)
        return blend(col, column(sc.hedge_colour), hedge)

    def features(self, col: F32, x: F32, y: F32, fp: F32) -> None:
        """Roads, tracks and turbine pads (in place), only inside their screen boxes."""
        fr = self.fr
        sc = self.scene
        o = fr.o
        reach = 6000.0
        rc = column(sc.road_colour)
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
            pos = self.ground_subset(fr.segment_pixels(a, b, 0.5 * w + 1.0, 40.0, 16))
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
            put_cols(col, pos, blend(take_cols(col, pos), rc, 0.9 * cov))
        pc = column(sc.pad_colour)
        for px0, py0, r in sc.pads:
            centre = np.array([px0, py0, 0.0])
            pos = self.ground_subset(fr.segment_pixels(centre, centre, r + 1.0))
            if pos is None:
                continue
            dx = x[pos] - np.float32(px0)
            dy = y[pos] - np.float32(py0)
            pfp = np.maximum(fp[pos], 0.03)
            d = np.sqrt(dx * dx + dy * dy)
            cov = np.clip((np.float32(r) - d) / pfp + 0.5, 0.0, 1.0)
            put_cols(col, pos, blend(take_cols(col, pos), pc, 0.75 * cov))

    def shadows(self, x: F32, y: F32, fp: F32) -> F32:
        """Fraction of direct sunlight reaching ground points: cloud and turbine shadows."""
        fr = self.fr
        sc = self.scene
        lit = np.ones_like(x)
        if fr.sun[2] <= 0.05 or fr.sun_strength < 0.1:
            return lit
        sx, sy = fr.sun[0] / fr.sun[2], fr.sun[1] / fr.sun[2]
        if sc.cloud_cover > 0.02:
            k = np.float32(self.A.clouds.size / sc.cloud_scale)
            cx = (x + np.float32(sx * sc.cloud_altitude)) * k
            cy = (y + np.float32(sy * sc.cloud_altitude)) * k
            lit = 1.0 - 0.85 * sample_tile(self.A.clouds, cx, cy, (2,))[0]
        for ax, ay, bx, by, w0, w1 in self.shadow_segments:
            a = np.array([ax, ay, 0.0])
            b = np.array([bx, by, 0.0])
            pos = self.ground_subset(fr.segment_pixels(a, b, max(w0, w1) + 1.0, 40.0, 12))
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
        fr = self.fr
        sc = self.scene
        ndz = np.maximum(-D[2], 1e-4)
        k = np.float32(self.A.waves.size / WAVE_PERIOD)
        texel = WAVE_PERIOD / self.A.waves.size
        wave = sample_tile(self.A.waves, x * k, y * (k * 0.4))[0] - 0.5
        wave *= np.clip((16.0 * texel - fp) * np.float32(1.0 / (12.0 * texel)), 0.15, 1.0)
        # reflected sky: elevation of the mirrored ray, tilted by the waves
        el = np.clip(ndz + 0.3 * wave * np.minimum(1.0, 6.0 * ndz + 0.05), 0.0, 1.0)
        refl = lerp3(sc.sky_horizon, sc.sky_zenith, np.sqrt(el))
        refl = blend(refl, column(sc.cloud_colour) * 0.85,
                      np.full(el.shape, min(1.0, sc.cloud_cover * 0.9), np.float32))
        refl = blend(refl, fr.haze, np.exp(-30.0 * el))
        c = 1.0 - el
        c2 = c * c
        fres = 0.03 + 0.97 * c2 * c2 * c
        deep = column(sc.sea_colour) * (0.6 + 0.25 * fr.ground_light + 0.4 * fr.ground_sun)
        col = blend(np.broadcast_to(deep, refl.shape), refl, fres)
        if fr.sun_strength > 0.1:
            rs = D[0] * fr.sun_f[0] + D[1] * fr.sun_f[1] - D[2] * fr.sun_f[2]
            g = np.exp((rs + 0.25 * wave - 1.0) * 40.0) * (0.3 + 2.5 * np.maximum(wave, 0.0))
            col = col + column(sc.sun_colour) * (g * fr.sun_strength)[None]
        foam = smoothstep(0.42, 0.5, wave) * 0.35 * np.clip(1.5 - fp, 0.0, 1.0)
        return blend(col, column((0.85, 0.85, 0.85)), foam)

    def hills(self, oz: float) -> None:
        """Distant hill silhouettes, far to near, over whatever is behind them."""
        fr = self.fr
        sc = self.scene
        D = fr.D
        hor = np.sqrt(D[0] * D[0] + D[1] * D[1]) + 1e-9
        tan_el = D[2] / hor
        for (dist, base, amp, _r, cr, cg, cb), prof in zip(sc.hills, self.A.hills, strict=True):
            lo = -oz / dist
            hi = (base + amp - oz) / dist
            cand = np.flatnonzero((tan_el > lo - 2 * fr.inv_f) & (tan_el < hi + 2 * fr.inv_f))
            if cand.size == 0:
                continue
            te = tan_el[cand]
            az = np.arctan2(D[1, cand], D[0, cand])
            fk = np.clip((az + np.float32(math.pi)) * np.float32(HILL_SAMPLES / (2 * math.pi)),
                         0.0, HILL_SAMPLES - 1e-3)
            k0 = np.floor(fk)
            k = k0.astype(np.intp)
            h = prof[k] + (prof[k + 1] - prof[k]) * (fk - k0)
            top = (h - np.float32(oz)) / np.float32(dist)
            # anti-aliased silhouette: coverage from the angular distance to the ridge line
            cov = np.clip((top - te) * np.float32(fr.f) + 0.5, 0.0, 1.0)
            cov *= np.clip((te - np.float32(lo)) * np.float32(fr.f) + 0.5, 0.0, 1.0)
            sel = np.flatnonzero(cov > 0)
            if sel.size == 0:
                continue
            ci, cov = cand[sel], cov[sel]
            tx = az[sel] * np.float32(dist * self.A.detail.size / 900.0)
            ty = te[sel] * np.float32(dist * self.A.detail.size / 300.0)
            n = sample_tile(self.A.detail, tx, ty)[0]
            depth = np.clip((top[sel] - te[sel]) * np.float32(dist / max(amp, 1.0)), 0.0, 1.0)
            col = column((cr, cg, cb)) * ((0.8 + 0.3 * n) * (1.0 - 0.25 * depth))[None]
            col = col * (fr.ground_light + 0.8 * fr.ground_sun)
            if sc.terrain == "snow":
                col = col + (np.float32(0.85) - col) * 0.7
            col = col + (fr.haze - col) * np.float32(1.0 - math.exp(-dist / sc.visibility))
            put_cols(fr.C, ci, blend(take_cols(fr.C, ci), col, cov))

    def prepare_shadows(self, turbines: list[TurbineSolid]) -> None:
        """Ground shadows of the turbines' tower, nacelle and blades (segments on z = 0)."""
        fr = self.fr
        self.shadow_segments = []
        if fr.sun[2] <= 0.05 or fr.sun_strength < 0.1 or self.scene.sea == "all":
            return
        s = fr.sun / fr.sun[2]
        for tb in turbines:
            if float(np.linalg.norm(tb.base[:2] - fr.o[:2])) > 3000.0:
                continue

            def g(p: FloatArray) -> tuple[float, float]:
                return float(p[0] - p[2] * s[0]), float(p[1] - p[2] * s[1])

            self.shadow_segments.append((*g(tb.base), *g(tb.top), tb.r0, tb.r1))
            h = g(tb.hub)
            self.shadow_segments.append((*g(tb.nac_rear), *h, 0.5 * tb.nac_h, 0.5 * tb.nac_h))
            for tip in tb.tips:
                self.shadow_segments.append((*h, *g(tip), 0.035 * tb.b, 0.008 * tb.b))
