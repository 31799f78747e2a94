"""Read access to a flight's heat-maps.

:class:`HeatmapStack` holds either one in-memory array (N, 7, H, W) or one array per
keyframe (typically read-only memory maps of ``heatmaps/*.npy``, so that a 1000-keyframe
flight costs no RAM until pixels are touched); the costs only ever *gather* pixels from it.
The values are float32, or float16 (half the memory; the compiled kernels read either,
:attr:`HeatmapStack.half`, and :meth:`HeatmapStack.gather` returns float64 of both).
Channel order: :mod:`turbinefit.heatmaps.channels`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import TurbinefitError
from turbinefit.heatmaps.channels import NUM_CHANNELS


class NonFiniteHeatmapError(TurbinefitError, ValueError):
    """A gathered heat-map value was NaN or infinite (names the keyframe index)."""

    def __init__(self, keyframe: int) -> None:
        super().__init__(f"heat-map of keyframe {keyframe} contains NaN or inf")
        self.keyframe = keyframe


class HeatmapStack:
    """Read access to N keyframes' heat-maps of a common shape (7, H, W).

    Args:
        maps: an array (N, 7, H, W) or a sequence of N arrays (7, H, W) (e.g. memory maps).
            Values are used as given (float32 or float16 in [0, 1] expected); nothing is
            copied.
    """

    def __init__(self, maps: NDArray[np.floating] | Sequence[NDArray[np.floating]]) -> None:
        if isinstance(maps, np.ndarray):
            if maps.ndim != 4 or maps.shape[1] != NUM_CHANNELS:
                raise ValueError(f"heat-maps must be (N, 7, H, W), got {maps.shape}")
            self._stacked: NDArray[np.floating] | None = maps
            self._list: list[NDArray[np.floating]] = []
            self.num_keyframes = maps.shape[0]
            self.height, self.width = int(maps.shape[2]), int(maps.shape[3])
        else:
            self._stacked = None
            self._list = list(maps)
            if not self._list:
                raise ValueError("no heat-maps")
            shape = self._list[0].shape
            for k, m in enumerate(self._list):
                if m.shape != shape or len(shape) != 3 or shape[0] != NUM_CHANNELS:
                    raise ValueError(f"heat-map {k} has shape {m.shape}, expected (7, H, W)")
            self.num_keyframes = len(self._list)
            self.height, self.width = int(shape[1]), int(shape[2])
        # flat views (no copies for C-contiguous arrays) used by gather()
        self._flat = [m.reshape(-1) for m in self._list]
        arrays = list(self._stacked) if self._stacked is not None else self._list
        # addresses for the compiled kernels (checked once: the arrays are never replaced)
        self._pointers: NDArray[np.uint64] | None = None
        #: Whether every keyframe's maps are float16 (else :meth:`pointers` are float32's).
        self.half = all(a.dtype == np.float16 for a in arrays)
        storage = np.float16 if self.half else np.float32
        if all(a.dtype == storage and a.flags.c_contiguous for a in arrays):
            self._pointers = np.array([a.ctypes.data for a in arrays], dtype=np.uint64)

    def __reduce__(self) -> tuple[type[HeatmapStack], tuple[object]]:
        """Pickled and copied stacks are built anew from their arrays: the addresses of
        :meth:`pointers` are those of this process's arrays only."""
        return HeatmapStack, (self._stacked if self._stacked is not None else self._list,)

    def pointers(self) -> NDArray[np.uint64] | None:
        """Address of each keyframe's (7, H, W) data, for the compiled kernels: float32, or
        float16 if :attr:`half`; None unless every keyframe is C-contiguous and of that
        one storage. Valid while this stack lives."""
        return self._pointers

    def __len__(self) -> int:
        return self.num_keyframes

    def __getitem__(self, k: int) -> NDArray[np.floating]:
        """Keyframe ``k``'s heat-maps (7, H, W) (a view, not a copy)."""
        if self._stacked is not None:
            return self._stacked[k]
        return self._list[k]

    def subset(self, keyframes: NDArray[np.int_]) -> HeatmapStack:
        """A stack of the given keyframes (no copy for per-keyframe storage)."""
        if self._stacked is not None:
            return HeatmapStack(self._stacked[keyframes])
        return HeatmapStack([self._list[int(k)] for k in keyframes])

    def gather(self, keyframes: NDArray[np.int_], flat_index: NDArray[np.int_]) -> NDArray[np.float64]:
        """Values at flat indices into each keyframe's (7 * H * W) array.

        Args:
            keyframes: (K,) keyframe indices.
            flat_index: (K, ...) indices ``c * H * W + i * W + j``, in range.

        Returns:
            (K, ...) float64 values. Raises :class:`NonFiniteHeatmapError` on NaN/inf.
        """
        if self._stacked is not None:
            plane = NUM_CHANNELS * self.height * self.width
            flat = self._stacked.reshape(-1)
            shape = (-1,) + (1,) * (flat_index.ndim - 1)
            out = flat[keyframes.reshape(shape).astype(np.int64) * plane + flat_index]
        else:
            out = np.empty(flat_index.shape, dtype=np.float16 if self.half else np.float32)
            flats = self._flat
            idx = flat_index.reshape(flat_index.shape[0], -1)
            o = out.reshape(idx.shape)
            for row, k in enumerate(keyframes.tolist()):
                if flats[k].dtype == out.dtype:
                    np.take(flats[k], idx[row], out=o[row])
                else:  # a stack mixing float16 and float32 keyframes
                    o[row] = flats[k][idx[row]]
        vals = out.astype(np.float64)
        if not np.all(np.isfinite(vals)):
            bad = np.nonzero(~np.isfinite(vals).reshape(vals.shape[0], -1).all(axis=1))[0][0]
            raise NonFiniteHeatmapError(int(keyframes[bad]))
        return vals
