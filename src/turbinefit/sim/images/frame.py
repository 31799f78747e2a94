"""One image being rendered: the pixels' camera rays (lens distortion undone), colour and
depth buffers, the scene's lights, pixel boxes of world objects, shading, haze and
depth-tested compositing.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.sim.images.arrays import (
    F32,
    FloatArray,
    IntArray,
    blend,
    column,
    matmul3,
    put_cols,
    take_cols,
)
from turbinefit.sim.images.scene import Scene
from turbinefit.sim.images.textures import scene_assets

#: [m] nothing nearer than this to the camera is drawn.
NEAR = 0.3


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


class Frame:
    """One image being rendered: rays, colour and depth buffers, lights.

    ``D`` (3, N) are the unit world directions of the pixels' rays from the camera centre
    ``o``; ``C`` (3, N) the colour buffer; ``Z`` (N,) the ray distance [m] of the nearest
    opaque turbine surface drawn so far.
    """

    def __init__(self, camera: PinholeCamera, world_T_cam: SE3, scene: Scene) -> None:
        self.cam = camera
        self.scene = scene
        self.A = scene_assets(scene)
        self.W, self.H = camera.width, camera.height
        self.R = world_T_cam.rotation_matrix()  # world_R_cam
        self.o = world_T_cam.translation.astype(np.float64)
        rays, self.rn = _camera_rays(camera)
        self.D: F32 = matmul3(self.R, rays)
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
        self.sun_rgb = column(sc.sun_colour) * np.float32(self.sun_strength)
        sky_mean = 0.5 * (np.asarray(sc.sky_zenith) + np.asarray(sc.sky_horizon))
        sky_mean = sky_mean * (1 - sc.cloud_cover) + np.asarray(sc.cloud_colour) * sc.cloud_cover
        sky_mean = 0.7 * sky_mean + 0.3 * sky_mean.mean()  # skylight, a little desaturated
        self.amb_sky = column((0.8 + 0.15 * sc.overcast) * sky_mean)
        # the ground's illumination: ambient (sky) part and direct-sun part
        self.ground_light = np.float32(0.55 + 0.45 * sc.overcast)
        self.ground_sun = np.float32(self.sun_strength * 1.1 * max(self.sun[2], 0.0))
        gmean = np.mean(np.asarray(sc.ground_colours[:3]), axis=0)
        if sc.sea == "all":
            gmean = np.asarray(sc.sea_colour) * 1.3
        gmean = 0.5 * gmean + 0.5 * gmean.mean()
        self.amb_ground = column(0.5 * gmean * (self.ground_light + self.ground_sun))
        self.haze = column(sc.haze_colour)
        self.cam_R_world = self.R.T
        self.cam_t = -self.cam_R_world @ self.o
        #: Per-pixel labels (:meth:`enable_labels`): part code, span [m] and side angle.
        self.labels: tuple[NDArray[np.int8], F32, F32] | None = None
        #: Per-pixel index into ``scene.defects`` of the defect shown (-1: none), with
        #: :attr:`labels`.
        self.defect_labels: NDArray[np.int16] | None = None

    def enable_labels(self) -> None:
        """Record, where :meth:`composite` writes the depth, the part's code, span and side
        angle it passes (:func:`~turbinefit.sim.images.render.render_labels`), and the
        defect it shows."""
        n = self.W * self.H
        self.labels = (np.zeros(n, dtype=np.int8), np.full(n, np.nan, dtype=np.float32),
                       np.full(n, np.nan, dtype=np.float32))
        self.defect_labels = np.full(n, -1, dtype=np.int16)

    def to_cam(self, p: FloatArray) -> FloatArray:
        """World points (k, 3) in the camera frame."""
        return p @ self.cam_R_world.T + self.cam_t

    def bbox(self, world_pts: FloatArray, radius: float) -> tuple[int, int, int, int] | None:
        """Pixel box (i0, i1, j0, j1) containing the points ``(k, 3)`` inflated by ``radius``
        [m] (only their part at depth > NEAR), or None if empty."""
        cp = self.to_cam(world_pts)
        lo = cp.min(axis=0) - radius
        hi = cp.max(axis=0) + radius
        if hi[2] <= NEAR:
            return None
        lo[2] = max(lo[2], NEAR)
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
        ok = hi[:, 2] > NEAR
        if not np.any(ok):
            return None
        lo, hi = lo[ok], hi[ok]
        z0 = 1.0 / np.maximum(lo[:, 2], NEAR)
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
        return blend(col, self.haze, h)

    def composite(self, idx: IntArray, depth: F32, cov: F32, col: F32,
                  label: tuple[int, F32 | None, F32 | None] = (0, None, None),
                  defect: NDArray[np.int16] | None = None) -> None:
        """Blend a part's pixels (coverage ``cov``) over the buffer where it is nearest;
        ``label``: its code and per-pixel span and side angle (or None), and ``defect``
        the per-pixel defect shown (or None: none), recorded with the depth when
        :meth:`enable_labels` was called."""
        z = self.Z[idx]
        sel = np.flatnonzero((depth < z) & (cov > 0.003))
        if sel.size == 0:
            return
        idx, depth, cov, z = idx[sel], depth[sel], cov[sel], z[sel]
        old = take_cols(self.C, idx)
        put_cols(self.C, idx, blend(old, take_cols(col, sel), cov))
        self.Z[idx] = np.where(cov > 0.5, depth, z)
        if self.labels is not None:
            solid = cov > 0.5
            at = idx[solid]
            self.labels[0][at] = label[0]
            for buf, val in zip(self.labels[1:], label[1:], strict=True):
                buf[at] = np.nan if val is None else val[sel][solid]
            if self.defect_labels is not None:
                self.defect_labels[at] = -1 if defect is None else defect[sel][solid]
