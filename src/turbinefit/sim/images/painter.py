"""Ray casting of a turbine's parts into a frame: tapered, twisted tubes (tower, blades)
through each ray's closest approach to the axis, the nacelle box by slabs, the spinner
ellipsoid exactly; anti-aliased coverage, shading and depth-tested compositing, far to near.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from turbinefit.sim.images.arrays import (
    F32,
    FloatArray,
    blend,
    column,
    dot3,
    lerp3,
    matmul3,
    put_cols,
    take_cols,
)
from turbinefit.sim.images.clutter import Clutter
from turbinefit.sim.images.frame import NEAR, Frame
from turbinefit.sim.images.scene import Scene
from turbinefit.sim.images.textures import cell_hash, sample_tile
from turbinefit.sim.images.turbine import TurbineSolid
from turbinefit.turbine.solid import blade_profile, blade_twist

#: Per-pixel part codes of :func:`~turbinefit.sim.images.render.render_labels`: 0 nothing,
#: then the primary turbine's tower, nacelle, spinner and its model blades 0, 1, 2
#: (``model_points`` tips 3, 4, 5); another turbine of the scene is :data:`LABEL_OTHER`.
LABEL_CODES = ("none", "tower", "nacelle", "spinner", "blade_0", "blade_1", "blade_2", "other")
LABEL_OTHER = 7


class Painter:
    """Ray casts turbine parts into a frame."""

    def __init__(self, fr: Frame, scene: Scene) -> None:
        self.fr = fr
        self.sc = scene
        self.code = 0  # label of the part being drawn (see LABEL_CODES)
        self.blade = -1  # model index of the blade being drawn
        self.primary = True  # whether the turbine being drawn is the primary

    def tube(self, a: FloatArray, e: FloatArray, L: float, kind: str, tb: TurbineSolid,
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
            prof = np.maximum(*blade_profile(uu, tb.b))
            radius = 1.05 * np.array([prof[4 * k:4 * k + 5].max() for k in range(8)])
        idx = fr.segment_pixels(a, a + L * e, radius)
        if idx is None:
            return
        D = take_cols(fr.D, idx)
        w = fr.o - a
        n0 = np.cross(e, c0)
        M = np.stack([e, w, np.cross(w, e), c0, n0]).astype(np.float32)
        P = matmul3(M, D)
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
            A, B = blade_profile(u, tb.b)
            beta = blade_twist(u, self.sc.blade_pitch)
            cb, sb = np.cos(beta), np.sin(beta)
        # view direction projected on the cross-section, in (chord, thickness) coordinates
        mc = (cb * Dc0 + sb * Dn0) * isq
        mn = (cb * Dn0 - sb * Dc0) * isq
        hw = np.sqrt((mc * B) ** 2 + (mn * A) ** 2)  # silhouette half-width
        pix = np.maximum(t, NEAR) * np.float32(fr.inv_f)  # metres per pixel there
        # flat ends (tower base and top, blade root) are cut at the hit point below; the
        # blade tip is round
        ds = np.zeros_like(x) if kind == "tower" else np.maximum(s_raw - np.float32(L), 0.0) * sq
        cov = np.ones_like(x)
        dist = np.sqrt(x * x + ds * ds)
        # parts thinner than a pixel are drawn one pixel wide and faint, not broken up
        hw_eff = np.maximum(hw, 0.6 * pix)
        cov = cov * np.clip(0.5 + (hw_eff - dist) / pix, 0.0, 1.0) * (hw / hw_eff)
        cov = cov * (t > NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx = idx[sel]
        D = take_cols(D, sel)
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
        albedo = np.repeat(column(self.sc.paint), idx.size, axis=1)
        # flat ends: where the ray enters the (infinite) tube beyond an end, it misses it
        s_hit = ew + depth * b_  # axis coordinate of the hit point
        pix = np.maximum(depth, NEAR) * np.float32(fr.inv_f)
        cov = cov * np.clip(0.5 + s_hit * sq / pix, 0.0, 1.0)
        defect: NDArray[np.int16] | None = None
        if kind == "tower":
            cov = cov * np.clip(0.5 + (np.float32(L) - s_hit) * sq / pix, 0.0, 1.0)
            z = np.float32(fr.o[2]) + depth * D[2]
            if self.sc.dirt > 0 or self.sc.tower_section > 0:
                albedo = self.tower_surface(albedo, z, np.arctan2(Y, X) * A)
            hb, *bc = self.sc.base_band
            if hb > 0:
                m = np.clip((np.float32(hb) - z) / (depth * np.float32(fr.inv_f)) + 0.5, 0, 1)
                albedo = blend(albedo, column(tuple(bc)), m)  # type: ignore[arg-type]
            if self.sc.door:
                low = np.flatnonzero(z < 3.0)
                if low.size:
                    ang = np.arctan2(Y[low], X[low])  # round the axis, in the (c0, n0) frame
                    da = np.abs((ang - np.float32(tb.door_az) + np.pi) % np.float32(2 * np.pi)
                                - np.pi)
                    dm = low[(da * A[low] < 0.55) & (z[low] > 0.15) & (z[low] < 2.4)]
                    albedo[:, dm] = column((0.35, 0.36, 0.37))
        else:
            # the renderer's chord axis points to the trailing edge of inspection.surface
            flip = np.float32(-1.0 if self.sc.surface_detail else 1.0)
            albedo = self.blade_surface(albedo, u * np.float32(L), np.float32(L), flip * X / A,
                                        flip * X)
            if self.sc.tip_bands:
                if self.sc.tip_bands == 1:
                    band = u > 0.9
                else:
                    band = ((u > 0.8) & (u < 0.87)) | (u > 0.93)
                albedo[:, band] = column(self.sc.tip_colour)
            if self.sc.surface_detail:
                albedo = self.gelcoat(albedo, s_hit, X, Y, pix)
            if self.sc.defects and self.primary:
                albedo, defect = self.defects(albedo, np.clip(s_hit, 0.0, np.float32(L)), X, Y,
                                              pix)
        col = fr.shade(albedo, nl, nz, nD, dot3(fr.sun_f, D), 0.3)
        label: tuple[int, F32 | None, F32 | None] = (self.code, None, None)
        if fr.labels is not None:  # span, and the side angle of a blade (see LABEL_CODES)
            span = s_hit if kind == "tower" else np.clip(s_hit, 0.0, np.float32(L))
            label = (self.code, span, None if kind == "tower" else np.arctan2(-mn, mc))
        fr.composite(idx, depth, cov, fr.hazed(col, depth), label, defect)

    def gelcoat(self, albedo: F32, span: F32, X: F32, Y: F32, pix: F32) -> F32:
        """The blade shell's mottling at 0.6 m and 2.5 m periods (a few per cent), faded
        out where a pixel ([m], ``pix``) is coarser than its features, so that a close-up
        at millimetres per pixel shows a surface, not a flat colour."""
        tile = self.fr.A.detail
        out = albedo
        arc = X + np.float32(2.0) * Y  # round the section (Y matters on the edges)
        for period, amp, shift in ((0.6, 0.06, 17.0), (2.5, 0.05, 101.0)):
            k = np.float32(tile.size / period)
            n = sample_tile(tile, span * k + np.float32(shift), arc * k, (0,))[0]
            feature = np.float32(4.0 * period / tile.size)
            fade = np.clip(2.0 - 2.0 * pix / feature, 0.0, 1.0)
            out = out * (1.0 + np.float32(2.0 * amp) * (n - 0.5) * fade)[None]
        return out

    def defects(self, albedo: F32, span: F32, X: F32, Y: F32, pix: F32
                ) -> tuple[F32, NDArray[np.int16] | None]:
        """Paint the scene's defects on this blade (:mod:`turbinefit.sim.defects`) at the
        surface points ``(span, X, Y)`` (span [m] from the hub, ``(X, Y)`` the section's
        chord and thickness coordinates [m]); ``pix``: metres per pixel there. Returns the
        colours and, per pixel, the defect covering more than half of it (-1: none), or
        None if no defect is near."""
        out = albedo
        ids: NDArray[np.int16] | None = None
        for k, (blade, kind, s0, x0, y0, r, phase) in enumerate(self.sc.defects):
            if int(blade) != self.blade:
                continue
            ds = span - np.float32(s0)
            near = np.flatnonzero(np.abs(ds) < np.float32(r) + 2.0 * pix)
            if near.size == 0:
                continue
            ds = ds[near]
            dx, dy = X[near] - np.float32(x0), Y[near] - np.float32(y0)
            d = np.sqrt(ds * ds + dx * dx + dy * dy)
            p = pix[near]
            r32 = np.float32(r)
            if kind == 0:  # erosion: a ragged patch of pits
                th = np.arctan2(ds, np.sqrt(dx * dx + dy * dy) * np.sign(dx + 1e-9))
                rr = r32 * (0.85 + 0.12 * np.sin(3.0 * th + np.float32(phase))
                            + 0.08 * np.sin(7.0 * th + np.float32(2.0 * phase)))
                mask = np.clip(0.5 + (rr - d) / p, 0.0, 1.0)
                pit = cell_hash(np.floor(ds * 90.0).astype(np.int32),
                                np.floor((dx + dy) * 90.0).astype(np.int32), 7 + k)
                col = lerp3((0.55, 0.52, 0.47), (0.32, 0.30, 0.28), (pit > 0.6).astype(np.float32))
            elif kind == 1:  # crack: a thin jagged line, across a face or along an edge
                edge = y0 == 0.0  # on an edge, where the section's thickness is 0
                along = ds if edge else dx
                across = np.sqrt(dx * dx + dy * dy) if edge else ds
                w = np.float32(max(0.005, r / 25.0))  # half its width
                wiggle = 0.3 * r32 * 0.15 * (np.sin(along * np.float32(37.0 / r) + phase)
                                             + 0.5 * np.sin(along * np.float32(91.0 / r)))
                off = np.abs(across - wiggle)
                hw = np.maximum(w, 0.5 * p)
                # only near the centre (not through to the other face)
                mask = np.clip(0.5 + (hw - off) / p, 0.0, 1.0) * (w / hw) \
                    * np.clip(0.5 + (r32 - d) / p, 0.0, 1.0)
                col = np.repeat(column((0.12, 0.11, 0.10)), near.size, axis=1)
            else:  # receptor burn: a black scorch with a brown halo
                mask = np.clip(0.5 + (r32 - d) / p, 0.0, 1.0)
                col = lerp3((0.06, 0.05, 0.05), (0.42, 0.33, 0.24),
                            np.clip(d / r32, 0.0, 1.0) ** 2)
            sub = take_cols(out, near)
            if out is albedo:
                out = albedo.copy()
            put_cols(out, near, blend(sub, col, mask))
            if ids is None:
                ids = np.full(span.size, -1, dtype=np.int16)
            ids[near[mask > 0.5]] = k
        return out, ids

    def blade_surface(self, albedo: F32, span: F32, L: np.float32, chord: F32,
                      chord_m: F32) -> F32:
        """A blade's wear at ``span`` [m from the hub] and ``chord`` (-1 trailing .. 1
        leading edge; ``chord_m`` the same in metres from the chord's middle):
        leading-edge erosion on the outer half (speckled grey pits,
        :attr:`Scene.wear`), dirt streaks along the span (:attr:`Scene.dirt`), the shell's
        bond lines along both edges, and two lightning receptors (dark metal discs) near
        the tip (:attr:`Scene.blade_marks`). They matter in close-ups and average out far
        away."""
        sc, salt = self.sc, self.sc.seed % 100_003
        out = albedo
        if sc.blade_marks:  # bond lines along both edges
            seam = (np.abs(chord) > 0.93) & (np.abs(chord) < 0.965)
            out = out * np.where(seam, np.float32(0.86), np.float32(1.0))[None]
        if sc.dirt > 0:
            h = cell_hash(np.floor(span * 0.4).astype(np.int32),
                          np.floor((chord + 1.0) * 9.0).astype(np.int32), salt)
            out = out * (1.0 - np.float32(0.22 * sc.dirt) * h * h)[None]
        if sc.wear > 0:
            outer = np.clip((span / L - 0.5) * 2.0, 0.0, 1.0)
            edge = np.clip((chord - 0.55) * 3.0, 0.0, 1.0)
            pit = cell_hash(np.floor(span * 6.0).astype(np.int32),
                            np.floor(chord * 40.0).astype(np.int32), salt + 1)
            m = (pit < np.float32(sc.wear) * outer * edge * 1.4) & (chord > 0.4)
            out = blend(out, column((0.5, 0.49, 0.46)), m.astype(np.float32) * 0.5)
        for r_m in (0.4, 2.5) if sc.blade_marks else ():  # receptors, both faces
            d2 = (span - (L - np.float32(r_m))) ** 2 + chord_m * chord_m
            out = blend(out, column((0.28, 0.28, 0.3)), (d2 < 0.012).astype(np.float32))
        return out

    def tower_surface(self, albedo: F32, z: F32, around: F32) -> F32:
        """The tower's flange seams every :attr:`Scene.tower_section` metres and vertical
        dirt streaks (``around``: arc length round the tower [m])."""
        sc = self.sc
        out = albedo
        if sc.tower_section > 0:
            f = np.abs(((z / np.float32(sc.tower_section)) + 0.5) % 1.0 - 0.5) * sc.tower_section
            out = out * np.where(f < 0.06, np.float32(0.8), np.float32(1.0))[None]
        if sc.dirt > 0:
            h = cell_hash(np.floor(around * 1.5).astype(np.int32),
                          np.floor(z * 0.05).astype(np.int32), sc.seed % 100_003 + 2)
            out = out * (1.0 - np.float32(0.15 * sc.dirt) * h)[None]
        return out

    def box(self, tb: TurbineSolid) -> None:
        """The nacelle: a box with rounded edges (:meth:`solid_box`)."""
        self.solid_box(tb.nac_centre, np.stack([tb.shaft, tb.side, tb.up]), tb.nac_half,
                       column(self.sc.paint) * np.float32(0.97))

    def solid_box(self, centre: FloatArray, E: FloatArray, hx: FloatArray, albedo: F32) -> None:
        """A box round ``centre`` with axes the rows of ``E`` and half sizes ``hx`` (slab
        test) with rounded (superellipse) shading; coverage from its inside margin divided
        by the margin's screen gradient (~ signed pixel distance)."""
        fr = self.fr
        oc = E @ (fr.o - centre)
        if np.all(np.abs(oc) < hx + 0.2):
            return  # the camera is inside the box: draw nothing rather than a wall
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        bb = fr.bbox(centre + (signs * hx) @ E, 0.0)
        if bb is None:
            return
        i0, i1, j0, j1 = bb
        i0, i1 = max(0, i0 - 1), min(fr.H, i1 + 1)
        j0, j1 = max(0, j0 - 1), min(fr.W, j1 + 1)
        hh, ww = i1 - i0, j1 - j0
        if hh < 2 or ww < 2:
            return
        idx = fr.box_indices((i0, i1, j0, j1))
        D = take_cols(fr.D, idx)
        dl = matmul3(E, D)
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
        cov = np.clip(0.5 + sd.ravel(), 0.0, 1.0) * (tn > NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx, tn, cov = idx[sel], tn[sel], cov[sel]
        D, dl = take_cols(D, sel), take_cols(dl, sel)
        P = o32 + tn[None] * dl
        q = np.clip(np.abs(P) / h32, 0.0, 1.0)
        q2 = q * q
        q4 = q2 * q2
        nloc = np.sign(P) * (q4 * q2 * q) / h32  # superellipse gradient: rounded edges
        nloc /= np.maximum(np.sqrt((nloc * nloc).sum(axis=0)), 1e-12)[None]
        n = matmul3(E.T, nloc)
        col = fr.shade(albedo, dot3(fr.sun_f, n), n[2], (n * D).sum(axis=0), dot3(fr.sun_f, D),
                       0.3)
        fr.composite(idx, tn, cov, fr.hazed(col, tn), (self.code, None, None))

    def spinner(self, tb: TurbineSolid) -> None:
        """The spinner: an ellipsoid round the hub (exact intersection)."""
        fr = self.fr
        E = np.stack([tb.shaft, tb.side, tb.up])
        radii = np.array([tb.spin_len, tb.spin_r, tb.spin_r])
        bb = fr.bbox(tb.spin_centre[None], max(tb.spin_len, tb.spin_r))
        if bb is None:
            return
        idx = fr.box_indices(bb)
        D = take_cols(fr.D, idx)
        S = E / radii[:, None]  # world -> unit-sphere coordinates
        op = (S @ (fr.o - tb.spin_centre)).astype(np.float32)
        Cq = np.float32(op @ op - 1.0)
        if Cq <= 0:
            return
        dp = matmul3(S, D)
        Aq = (dp * dp).sum(axis=0)
        Bq = dot3(op, dp)
        rho2 = (Cq + 1.0) - Bq * Bq / Aq  # squared distance of the ray from the centre
        t = (-Bq - np.sqrt(np.maximum(Bq * Bq - Aq * Cq, 0.0))) / Aq
        pix = np.maximum(t, NEAR) * np.float32(fr.inv_f)
        cov = np.clip(0.5 + (1.0 - np.sqrt(np.maximum(rho2, 0.0))) * np.float32(tb.spin_r) / pix,
                      0.0, 1.0) * (t > NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx, t, cov = idx[sel], t[sel], cov[sel]
        D, dp = take_cols(D, sel), take_cols(dp, sel)
        P = op[:, None] + t[None] * dp
        n = matmul3(E.T, P / radii.astype(np.float32)[:, None])
        n /= np.maximum(np.sqrt((n * n).sum(axis=0)), 1e-12)[None]
        col = fr.shade(column(self.sc.paint), dot3(fr.sun_f, n), n[2], (n * D).sum(axis=0),
                       dot3(fr.sun_f, D), 0.35)
        fr.composite(idx, t, cov, fr.hazed(col, t), (self.code, None, None))

    def rod(self, a: FloatArray, b: FloatArray, r: float, albedo: F32) -> None:
        """A round rod of radius ``r`` [m] from a to b (pylon members, poles, wires): each
        ray's closest approach to the axis gives its coverage (sub-pixel wires one pixel
        wide and faint) and the cylinder's normal where it enters."""
        fr = self.fr
        ab = b - a
        L = float(np.linalg.norm(ab))
        if L <= 1e-6:
            return
        e = ab / L
        idx = fr.segment_pixels(a, b, r)
        if idx is None:
            return
        D = take_cols(fr.D, idx)
        w = fr.o - a
        b_, dw, trip = matmul3(np.stack([e, w, np.cross(w, e)]).astype(np.float32), D)
        ew = np.float32(w @ e)
        den = np.maximum(1.0 - b_ * b_, 1e-6)
        sq = np.sqrt(den)
        s_raw = ew + (b_ * ew - dw) / den * b_
        s = np.clip(s_raw, 0.0, np.float32(L))
        t = s * b_ - dw
        x = trip / sq
        pix = np.maximum(t, NEAR) * np.float32(fr.inv_f)
        ds = (np.maximum(s_raw - np.float32(L), 0.0) + np.maximum(-s_raw, 0.0)) * sq
        dist = np.sqrt(x * x + ds * ds)
        hw_eff = np.maximum(np.float32(r), 0.6 * pix)
        cov = np.clip(0.5 + (hw_eff - dist) / pix, 0.0, 1.0) * (np.float32(r) / hw_eff) * (t > NEAR)
        sel = np.flatnonzero(cov > 0.003)
        if sel.size == 0:
            return
        idx, D, x, t, b_, cov = idx[sel], take_cols(D, sel), x[sel], t[sel], b_[sel], cov[sel]
        q = np.clip(x / np.float32(r), -1.0, 1.0)
        perp = D - e.astype(np.float32)[:, None] * b_[None]
        perp /= np.maximum(np.sqrt((perp * perp).sum(axis=0)), 1e-6)[None]
        side = np.cross(e.astype(np.float32)[:, None], perp, axis=0)
        n = q[None] * side - np.sqrt(1.0 - q * q)[None] * perp
        col = fr.shade(np.repeat(albedo, idx.size, axis=1), dot3(fr.sun_f, n), n[2],
                       (n * D).sum(axis=0), dot3(fr.sun_f, D), 0.15)
        fr.composite(idx, t, cov, fr.hazed(col, t))

    def clutter(self, cl: Clutter) -> None:
        """The scene's rods and boxes that can show (in front of the camera, in or near
        the frame, and thicker than a twentieth of a pixel where nearest)."""
        fr = self.fr
        if cl.rods:
            R = np.asarray(cl.rods, dtype=np.float64)
            ca, cb = fr.to_cam(R[:, 0:3]), fr.to_cam(R[:, 3:6])
            zmin = np.maximum(np.minimum(ca[:, 2], cb[:, 2]), NEAR)
            zmax = np.maximum(ca[:, 2], cb[:, 2])
            near = np.linalg.norm(0.5 * (R[:, 0:3] + R[:, 3:6]) - fr.o, axis=1) \
                - 0.5 * np.linalg.norm(R[:, 3:6] - R[:, 0:3], axis=1)
            thick = R[:, 6] * fr.f / np.maximum(near, NEAR) > 0.05
            for k in np.flatnonzero((zmax > NEAR) & thick & (zmin < 4000.0)):
                self.rod(R[k, 0:3], R[k, 3:6], float(R[k, 6]), column(tuple(R[k, 7:10])))
        for bx in cl.boxes:
            cx, cy, cz, hx, hy, hz, yaw, *c = bx
            cw, sw = math.cos(yaw), math.sin(yaw)
            E = np.array([[cw, sw, 0.0], [-sw, cw, 0.0], [0.0, 0.0, 1.0]])
            self.solid_box(np.array([cx, cy, cz]), E, np.array([hx, hy, hz]),
                           column(tuple(c)))  # type: ignore[arg-type]

    def turbine(self, tb: TurbineSolid, primary: bool = True) -> None:
        """All parts, far to near (so that anti-aliased edges blend over what is behind);
        labelled (:data:`LABEL_CODES`) as parts of the primary turbine or as another one."""
        fr = self.fr
        top = np.array([tb.base[0], tb.base[1], tb.tower_top_z])
        parts: list[tuple[float, int, int]] = [
            (float(np.linalg.norm(0.5 * (tb.base + top) - fr.o)), 0, 0),
            (float(np.linalg.norm(tb.nac_centre - fr.o)), 1, 0),
            (float(np.linalg.norm(tb.spin_centre - fr.o)) - 0.5 * tb.spin_len, 2, 0),
        ]
        for i, tip in enumerate(tb.tips):
            parts.append((float(np.linalg.norm(0.5 * (tb.hub + tip) - fr.o)), 3, i))
        self.primary = primary
        for _, kind, i in sorted(parts, key=lambda p: -p[0]):
            self.code = (kind + 1 + i) if primary else LABEL_OTHER
            self.blade = i if kind == 3 else -1
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
                # the chord at zero pitch: in the rotor plane
                self.tube(tb.hub, e / L, L, "blade", tb, tb.chord_axis(i))
