"""Pinhole camera with OpenCV ``plumb_bob`` distortion.

Camera frame: OpenCV (x right, y down, z forward), metres. Pixels: ``u`` to the right,
``v`` down, pixel (0, 0) is the centre of the top-left pixel, so heat-map element
``[i, j]`` sits at ``u = j, v = i``.

Projection of a camera-frame point ``cam_p = (X, Y, Z)``::

    x, y = X / Z, Y / Z
    r2 = x^2 + y^2,  radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    xd = x radial + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y radial + p1 (r2 + 2 y^2) + 2 p2 x y
    u = fx xd + s yd + cx,   v = fy yd + cy

Like SymForce's ``CameraCal`` it returns ``(uv, valid)`` instead of raising: points behind
the camera, too close to it, or outside the image are normal and simply flagged invalid
(their ``uv`` and Jacobian are finite but meaningless).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

#: Minimum depth [m] for a point to count as in front of the camera.
MIN_DEPTH = 0.1


def reduced_size(width: int, height: int, max_width: int) -> tuple[int, int]:
    """The size of a ``width`` x ``height`` image scaled to at most ``max_width`` px wide
    (aspect ratio kept, height rounded, at least 1): the image's own size if it is not
    wider."""
    if width <= max_width:
        return int(width), int(height)
    return int(max_width), max(1, round(height * max_width / width))


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics of a pinhole camera (pixels) with ``plumb_bob`` distortion.

    Attributes:
        width, height: image size [px].
        fx, fy: focal lengths [px]; must be positive.
        cx, cy: principal point [px].
        skew: ``K[0, 1]`` [px], usually 0.
        distortion: ``(k1, k2, p1, p2, k3)``; zeros for none.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    skew: float = 0.0
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    _r2_max: float = field(init=False, repr=False, compare=False, default=0.0)

    def __post_init__(self) -> None:
        if not (self.width > 0 and self.height > 0):
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if not (np.isfinite(self.fx) and np.isfinite(self.fy) and self.fx > 0 and self.fy > 0):
            raise ValueError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        vals = (self.cx, self.cy, self.skew, *self.distortion)
        if not all(np.isfinite(v) for v in vals):
            raise ValueError("camera parameters must be finite")
        if len(self.distortion) != 5:
            raise ValueError("plumb_bob distortion needs 5 coefficients (k1, k2, p1, p2, k3)")
        # Undistorted radius beyond which the polynomial model is not trusted (it can fold
        # far-away points back into the image): 1.5 x the image corners' radius.
        corners_x = (np.array([0.0, self.width - 1.0]) - self.cx) / self.fx
        corners_y = (np.array([0.0, self.height - 1.0]) - self.cy) / self.fy
        r2 = float(np.max(corners_x**2) + np.max(corners_y**2))
        object.__setattr__(self, "_r2_max", 2.25 * r2)

    @staticmethod
    def from_matrix(
        width: int, height: int, K: ArrayLike, distortion: ArrayLike | None = None
    ) -> PinholeCamera:
        """From a 3x3 camera matrix and up to five plumb_bob coefficients."""
        K = np.asarray(K, dtype=np.float64).reshape(3, 3)
        d = np.zeros(5)
        if distortion is not None:
            dd = np.asarray(distortion, dtype=np.float64).ravel()
            d[: min(5, dd.size)] = dd[:5]
        return PinholeCamera(
            int(width), int(height), float(K[0, 0]), float(K[1, 1]), float(K[0, 2]),
            float(K[1, 2]), float(K[0, 1]), tuple(float(x) for x in d),  # type: ignore[arg-type]
        )

    @property
    def K(self) -> FloatArray:
        return np.array([[self.fx, self.skew, self.cx], [0.0, self.fy, self.cy], [0, 0, 1.0]])

    def kernel_params(self) -> FloatArray:
        """(fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, r2_max): the camera as the compiled
        kernels take it (``r2_max``: the trusted range of the distortion model)."""
        return np.array([self.fx, self.fy, self.cx, self.cy, self.skew, *self.distortion,
                         self._r2_max])

    @property
    def has_distortion(self) -> bool:
        return any(c != 0.0 for c in self.distortion)

    def scaled(self, factor: float) -> PinholeCamera:
        """The same camera for an image resized by ``factor`` (pixel centres preserved)."""
        return self.resized(round(self.width * factor), round(self.height * factor))

    def resized(self, width: int, height: int) -> PinholeCamera:
        """The same camera for the image resized to ``width`` x ``height`` [px] (each axis
        scaled on its own; pixel centres preserved, as image resampling does)."""
        w, h = int(width), int(height)
        sx, sy = w / self.width, h / self.height
        return PinholeCamera(
            w, h, self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5,
            (self.cy + 0.5) * sy - 0.5, self.skew * sx, self.distortion,
        )

    def scaled_to(self, width: int, height: int) -> PinholeCamera:
        """The camera of this camera's images scaled down to ``width`` x ``height`` [px]
        (e.g. heat-maps smaller than the photos): itself at its own size, else
        :meth:`resized` (pixel centres aligned: pixel ``u`` of the scaled image is
        ``(u + 0.5) W / w - 0.5`` of this camera's, the same in v).

        Raises:
            ValueError: if the size is larger than the camera's, or not its size scaled by
                one factor up to rounding (h within a pixel of ``H w / W``, or w of
                ``W h / H``).
        """
        W, H, w, h = self.width, self.height, int(width), int(height)
        if (w, h) == (W, H):
            return self
        if not (1 <= w <= W and 1 <= h <= H):
            raise ValueError(f"{w}x{h} is not inside the camera's {W}x{H}")
        if abs(h - H * w / W) > 1 and abs(w - W * h / H) > 1:
            raise ValueError(f"{w}x{h} is not the camera's {W}x{H} scaled (aspect ratio "
                             f"{w / h:.4g}, camera {W / H:.4g})")
        return self.resized(w, h)

    def at_most(self, max_width: int) -> PinholeCamera:
        """The camera of its images scaled to at most ``max_width`` px wide
        (:func:`reduced_size`; itself if it is not wider)."""
        return self.scaled_to(*reduced_size(self.width, self.height, max_width))

    def in_image(self, uv: FloatArray, margin: float = 0.0) -> NDArray[np.bool_]:
        """Whether pixels lie inside the image (pixel centres ``0 .. W-1``, ``0 .. H-1``)."""
        return (
            (uv[..., 0] >= margin) & (uv[..., 0] <= self.width - 1 - margin)
            & (uv[..., 1] >= margin) & (uv[..., 1] <= self.height - 1 - margin)
        )

    def project(
        self, cam_p: ArrayLike, with_jacobian: bool = False
    ) -> tuple[FloatArray, NDArray[np.bool_], FloatArray | None]:
        """Project camera-frame points (..., 3) [m] to pixels.

        Returns:
            uv: (..., 2) pixels (finite everywhere).
            valid: (...,) in front of the camera (depth > MIN_DEPTH), inside the trusted
                distortion range and inside the image.
            J: (..., 2, 3) d uv / d cam_p, or None if not requested (zero behind the camera).
        """
        uv, front, J = self.project_unbounded(cam_p, with_jacobian)
        return uv, front & self.in_image(uv), J

    def project_unbounded(
        self, cam_p: ArrayLike, with_jacobian: bool = False
    ) -> tuple[FloatArray, NDArray[np.bool_], FloatArray | None]:
        """Like :meth:`project`, but ``front`` ignores the image bounds: in front of the
        camera and inside the trusted distortion range."""
        p = np.asarray(cam_p, dtype=np.float64)
        X, Y, Z = p[..., 0], p[..., 1], p[..., 2]
        front = Z > MIN_DEPTH
        Zs = np.where(front, Z, 1.0)
        inv_z = 1.0 / Zs
        x = X * inv_z
        y = Y * inv_z
        r2 = x * x + y * y
        in_range = r2 < self._r2_max
        k1, k2, p1, p2, k3 = self.distortion
        if self.has_distortion:
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        else:
            xd, yd = x, y
        uv = np.empty((*p.shape[:-1], 2))
        uv[..., 0] = self.fx * xd + self.skew * yd + self.cx
        uv[..., 1] = self.fy * yd + self.cy
        front = front & in_range
        if not with_jacobian:
            return uv, front, None
        # d(xd, yd)/d(x, y)
        if self.has_distortion:
            dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
            dxd_dx = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x
            dxd_dy = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
            dyd_dx = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
            dyd_dy = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x
        else:
            dxd_dx = dyd_dy = np.ones_like(x)
            dxd_dy = dyd_dx = np.zeros_like(x)
        du_dx = self.fx * dxd_dx + self.skew * dyd_dx
        du_dy = self.fx * dxd_dy + self.skew * dyd_dy
        dv_dx = self.fy * dyd_dx
        dv_dy = self.fy * dyd_dy
        J = np.empty((*p.shape[:-1], 2, 3))
        J[..., 0, 0] = du_dx * inv_z
        J[..., 0, 1] = du_dy * inv_z
        J[..., 0, 2] = -(du_dx * x + du_dy * y) * inv_z
        J[..., 1, 0] = dv_dx * inv_z
        J[..., 1, 1] = dv_dy * inv_z
        J[..., 1, 2] = -(dv_dx * x + dv_dy * y) * inv_z
        J = np.where(front[..., None, None], J, 0.0)
        return uv, front, J
