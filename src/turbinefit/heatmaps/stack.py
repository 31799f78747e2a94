"""Read access to a flight's heat-maps.

:class:`HeatmapStack` holds one in-memory array (N, 7, H, W), one array per keyframe
(e.g. read-only memory maps of ``heatmaps/*.npy``), or a flight's heat-map files
(:class:`KeyframeFiles`, :class:`turbinefit._native.FileMaps`: the compiled kernels read
the parts they need straight from the files, so that a 1000-keyframe flight holds only
those in memory); the costs only ever *gather* pixels from it. The values are float32, or
float16 (half the memory; the compiled kernels read either, :attr:`HeatmapStack.half`, and
:meth:`HeatmapStack.gather` returns float64 of both). Channel order:
:mod:`turbinefit.heatmaps.channels`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import TurbinefitError
from turbinefit.heatmaps.channels import NUM_CHANNELS

#: The coarse grid of :meth:`HeatmapStack.coarse_grid`: this many rows of each channel,
#: evenly spaced from the first to the last, ...
GRID_ROWS = 12
#: ... at about this many columns, evenly spaced from the first.
GRID_COLUMNS = 40


def grid_rows(height: int) -> NDArray[np.int64]:
    """The rows of the coarse grid of maps ``height`` px high (:data:`GRID_ROWS`)."""
    rows = np.linspace(0, height - 1, GRID_ROWS).round().astype(np.int64)
    return np.array(sorted(set(rows.tolist())), dtype=np.int64)


def grid_step(width: int) -> int:
    """Columns between those of the coarse grid of maps ``width`` px wide."""
    return max(1, width // GRID_COLUMNS)


class NonFiniteHeatmapError(TurbinefitError, ValueError):
    """A gathered heat-map value was NaN or infinite (names the keyframe index)."""

    def __init__(self, keyframe: int) -> None:
        super().__init__(f"heat-map of keyframe {keyframe} contains NaN or inf")
        self.keyframe = keyframe


class HeatmapValueError(TurbinefitError, ValueError):
    """A keyframe's heat-map file holds a NaN or a value outside [0, 1] (found by the
    check of :class:`KeyframeFiles`; ``keyframe``: its index among the files)."""

    def __init__(self, keyframe: int) -> None:
        super().__init__(f"heat-map of keyframe {keyframe} holds a value outside [0, 1]")
        self.keyframe = keyframe


@runtime_checkable
class KeyframeFiles(Protocol):
    """Heat-map files the compiled kernels read themselves
    (:class:`turbinefit._native.FileMaps`): ``shape`` (7, H, W) and storage (``half``:
    float16, else float32) of each keyframe's array, ``handle`` for the kernels,
    :meth:`read` of one keyframe's whole array, the value check (:meth:`check` of those
    not checked yet, :meth:`first_bad`) and ``grid``, the coarse grid
    (:meth:`HeatmapStack.coarse_grid`) of every keyframe checked."""

    shape: tuple[int, int, int]
    half: bool
    handle: int
    grid: NDArray[np.floating]

    def __len__(self) -> int: ...

    def read(self, k: int, check: bool = True) -> NDArray[np.floating]: ...

    def check(self) -> int: ...

    def first_bad(self) -> int: ...


class HeatmapStack:
    """Read access to N keyframes' heat-maps of a common shape (7, H, W).

    Args:
        maps: an array (N, 7, H, W), a sequence of N arrays (7, H, W) (e.g. memory maps), or
            :class:`KeyframeFiles`. Values are used as given (float32 or float16 in [0, 1]
            expected); nothing is copied. From files, ``stack[k]`` reads keyframe ``k``
            anew (an array of its own) and the compiled kernels read what they need.
        index: with files only: which of them, in order (default: all).
    """

    def __init__(self, maps: NDArray[np.floating] | Sequence[NDArray[np.floating]]
                 | KeyframeFiles, index: NDArray[np.int_] | None = None) -> None:
        self._files: KeyframeFiles | None = None
        self._index: NDArray[np.uint64] | None = None
        self._stacked: NDArray[np.floating] | None = None
        self._list: list[NDArray[np.floating]] = []
        # addresses for the compiled kernels (checked once: the arrays are never replaced)
        self._pointers: NDArray[np.uint64] | None = None
        self._flat: list[NDArray[np.floating]] = []  # flat views used by gather()
        #: Whether every keyframe's maps are float16 (else :meth:`pointers` are float32's).
        self.half = False
        # (arrays and lists first: a protocol's isinstance costs tens of microseconds, and
        # the tracker makes stacks of arrays at every keyframe)
        if not isinstance(maps, (np.ndarray, list, tuple)) and isinstance(maps, KeyframeFiles):
            self._files = maps
            n = len(maps)
            self._index = (np.arange(n, dtype=np.uint64) if index is None
                           else np.asarray(index, dtype=np.uint64))
            if not len(self._index):
                raise ValueError("no heat-maps")
            self.num_keyframes = len(self._index)
            self.height, self.width = int(maps.shape[1]), int(maps.shape[2])
            self.half = bool(maps.half)
            return
        if isinstance(maps, np.ndarray):
            if maps.ndim != 4 or maps.shape[1] != NUM_CHANNELS:
                raise ValueError(f"heat-maps must be (N, 7, H, W), got {maps.shape}")
            self._stacked = maps
            self.num_keyframes = maps.shape[0]
            self.height, self.width = int(maps.shape[2]), int(maps.shape[3])
        else:
            self._list = list(maps)
            if not self._list:
                raise ValueError("no heat-maps")
            shape = self._list[0].shape
            for k, m in enumerate(self._list):
                if m.shape != shape or len(shape) != 3 or shape[0] != NUM_CHANNELS:
                    raise ValueError(f"heat-map {k} has shape {m.shape}, expected (7, H, W)")
            self.num_keyframes = len(self._list)
            self.height, self.width = int(shape[1]), int(shape[2])
        self._flat = [m.reshape(-1) for m in self._list]  # no copies if C-contiguous
        arrays = list(self._stacked) if self._stacked is not None else self._list
        self.half = all(a.dtype == np.float16 for a in arrays)
        storage = np.float16 if self.half else np.float32
        if all(a.dtype == storage and a.flags.c_contiguous for a in arrays):
            self._pointers = np.array([a.ctypes.data for a in arrays], dtype=np.uint64)

    def __reduce__(self) -> tuple[type[HeatmapStack], tuple[object]]:
        """Pickled and copied stacks are built anew from their arrays: the addresses of
        :meth:`pointers` are those of this process's arrays only (a stack of files is
        sent as the arrays read from them)."""
        if self._files is not None:
            return HeatmapStack, ([self[k] for k in range(self.num_keyframes)],)
        return HeatmapStack, (self._stacked if self._stacked is not None else self._list,)

    def pointers(self) -> NDArray[np.uint64] | None:
        """Address of each keyframe's (7, H, W) data, for the compiled kernels: float32, or
        float16 if :attr:`half`; None unless every keyframe is in memory, C-contiguous and
        of that one storage. Valid while this stack lives."""
        return self._pointers

    def file_index(self) -> NDArray[np.uint64] | None:
        """Each keyframe's index among :attr:`files` (a stack of files), else None."""
        return self._index if self._files is not None else None

    @property
    def files(self) -> KeyframeFiles | None:
        """The heat-map files read (None: arrays in memory or memory-mapped)."""
        return self._files

    def check(self) -> None:
        """From files: check the values of every keyframe not checked yet (a no-op in
        memory).

        Raises:
            HeatmapValueError: naming the first file (among all of them) holding a NaN or
                a value outside [0, 1].
        """
        if self._files is not None:
            first = self._files.check()
            if first < len(self._files):
                raise HeatmapValueError(first)

    def __len__(self) -> int:
        return self.num_keyframes

    def __getitem__(self, k: int) -> NDArray[np.floating]:
        """Keyframe ``k``'s heat-maps (7, H, W) (a view, not a copy; from files, read anew:
        an array of its own).

        Raises:
            HeatmapValueError: from files, if its values are out of range.
        """
        if self._files is not None:
            assert self._index is not None
            return self._files.read(int(self._index[k]))
        if self._stacked is not None:
            return self._stacked[k]
        return self._list[k]

    def subset(self, keyframes: NDArray[np.int_]) -> HeatmapStack:
        """A stack of the given keyframes (no copy for per-keyframe storage or files)."""
        if self._files is not None:
            assert self._index is not None
            return HeatmapStack(self._files,
                                self._index[np.asarray(keyframes, dtype=np.int64)].astype(np.int64))
        if self._stacked is not None:
            return HeatmapStack(self._stacked[keyframes])
        return HeatmapStack([self._list[int(k)] for k in keyframes])

    def coarse_grid(self, keyframes: NDArray[np.int_]) -> NDArray[np.floating]:
        """The values of :func:`grid_rows` of each channel at every :func:`grid_step`-th
        column (K, 7, rows, columns) of ``keyframes``, as stored (float16 or float32): a
        few kB a keyframe, all that the verdict reads of a map (how much of it lights up).
        From files, those their value check keeps (no file is read again).

        Raises:
            HeatmapValueError: from files, if a value is out of range.
        """
        kf = np.asarray(keyframes, dtype=np.int64)
        rows, step = grid_rows(self.height), grid_step(self.width)
        if self._files is not None:
            assert self._index is not None
            self.check()
            return self._files.grid[self._index[kf].astype(np.int64)]
        if not len(kf):
            dtype = np.float16 if self.half else np.float32
            return np.zeros((0, NUM_CHANNELS, len(rows), len(range(0, self.width, step))),
                            dtype=dtype)
        return np.stack([self[int(k)][:, rows, ::step] for k in kf])

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
            flats: list[NDArray[np.floating]] | dict[int, NDArray[np.floating]] = self._flat
            if self._files is not None:  # the numpy twin on files: each keyframe read once
                flats = {k: self[k].reshape(-1) for k in set(keyframes.tolist())}
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
