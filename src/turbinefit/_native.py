"""Typed access to the compiled kernels of ``_kernels.c`` (loaded with ctypes).

The kernels fuse, per keyframe, what the numpy reference implementation does in many
vectorised passes: projecting the model, evaluating the heat-map or correspondence cost
with its gradient and Hessian model, and folding the result into the keyframe's 13 x 13
normal-equation block; also the correspondence searches and the block-tridiagonal solve.
They read the heat-maps in place through one pointer per keyframe, float32 or float16 as a
flight stores them; a flight's heat-map files (:class:`FileMaps`) are mapped, and the
kernels note the pages they read and drop the others that the system maps round them, so
that a fit holds the quarter or third of a flight's maps it reads, not all of them.
No library offers these model-specific loops (the solver study measured generic back-ends
with per-factor Python callbacks 5-30x slower than the vectorised numpy version, which in
turn spends 130 ms per evaluation of a 1000-keyframe flight on temporaries).

Every function here has a numpy twin that defines its result; the tests compare the two.
The kernels are used when the extension was built (``pip install`` compiles it; with no C
compiler the install still succeeds) and ``TURBINEFIT_NATIVE`` is not ``0``; otherwise
:func:`available` is False and the callers use numpy.
"""

from __future__ import annotations

import ctypes
import importlib.util
import os
import weakref
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import interrupt_within
from turbinefit.heatmaps import HeatmapStack, HeatmapValueError, NonFiniteHeatmapError

FloatArray = NDArray[np.float64]

_f64 = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
_i64 = np.ctypeslib.ndpointer(dtype=np.int64, flags="C_CONTIGUOUS")
_u64 = np.ctypeslib.ndpointer(dtype=np.uint64, flags="C_CONTIGUOUS")
_u8 = np.ctypeslib.ndpointer(dtype=np.uint8, flags="C_CONTIGUOUS")
_ptr = ctypes.c_void_p
_int = ctypes.c_int64
_dbl = ctypes.c_double


def _load() -> ctypes.CDLL | None:
    spec = importlib.util.find_spec("turbinefit._kernels")
    if spec is None or spec.origin is None:
        return None
    try:
        lib = ctypes.CDLL(spec.origin, use_errno=True)
        _declare(lib)
    except (OSError, AttributeError):  # not loadable, or built from an older _kernels.c
        return None
    return lib


def _declare(lib: ctypes.CDLL) -> None:
    """Declare the kernels' signatures (AttributeError if one is missing)."""
    lib.tf_image_terms.restype = _int
    lib.tf_image_terms.argtypes = [
        _int, _int, _f64, _f64, _int, _int, _f64, _f64, _ptr, _ptr, _ptr, _int, _i64, _u64,
        _int, _ptr, _i64, _int, _ptr, _ptr, _ptr, _f64, _int, _ptr, _ptr, _f64, _i64]
    lib.tf_point_search_scaled.restype = _int
    lib.tf_point_search_scaled.argtypes = [
        _int, _int, _int, _int, _u64, _int, _ptr, _i64, _i64, _f64, _u8, _int, _i64, _int,
        _i64, _int, _int, _dbl, _f64, _u8]
    lib.tf_line_search_scaled.restype = _int
    lib.tf_line_search_scaled.argtypes = [
        _int, _int, _int, _int, _u64, _int, _ptr, _i64, _i64, _f64, _f64, _u8, _int, _dbl,
        _dbl, _f64, _u8]
    lib.tf_block_tridiag_solve.restype = _int
    lib.tf_block_tridiag_solve.argtypes = [_int, _int, _f64, _f64, _f64, _f64]
    lib.tf_project.restype = None
    lib.tf_project.argtypes = [_int, _int, _f64, _f64, _int, _int, _f64, _int, _f64, _u8, _u8]
    lib.tf_num_threads.restype = _int
    lib.tf_num_threads.argtypes = []
    lib.tf_first_out_of_range.restype = _int
    lib.tf_first_out_of_range.argtypes = [_int, _u64, _int, _int, _dbl, _dbl]
    lib.tf_files_new.restype = _ptr
    lib.tf_files_new.argtypes = [_int, _i64, _i64, _int, _int]
    lib.tf_files_free.restype = None
    lib.tf_files_free.argtypes = [_ptr]
    lib.tf_files_used.restype = _int
    lib.tf_files_used.argtypes = [_ptr]
    lib.tf_files_read.restype = None
    lib.tf_files_read.argtypes = [_ptr, _int, _ptr]
    lib.tf_files_check_setup.restype = _int
    lib.tf_files_check_setup.argtypes = [_ptr, _dbl, _dbl, _int, _int, _i64, _int, _int, _ptr,
                                         _int]
    lib.tf_files_check.restype = _int
    lib.tf_files_check.argtypes = [_ptr]
    lib.tf_files_first_bad.restype = _int
    lib.tf_files_first_bad.argtypes = [_ptr]
    lib.tf_files_checked.restype = _int
    lib.tf_files_checked.argtypes = [_ptr, _int]


_LIB = _load()
_ROBUST = {"none": 0, "huber": 1, "cauchy": 2}


def available() -> bool:
    """Whether the compiled kernels are loaded and not disabled (``TURBINEFIT_NATIVE=0``)."""
    return _LIB is not None and os.environ.get("TURBINEFIT_NATIVE", "1") != "0"


def num_threads() -> int:
    """OpenMP threads the kernels use (1 without OpenMP or without the kernels)."""
    return int(_LIB.tf_num_threads()) if _LIB is not None else 1


def first_out_of_range(maps: NDArray[np.uint64], half: bool, count: int, lo: float,
                       hi: float) -> int:
    """Index of the first of ``len(maps)`` float32 arrays (float16 if ``half``; ``count``
    values at each address of ``maps``) holding a NaN or a value outside [``lo``, ``hi``]
    (compared in float32), or ``len(maps)`` if none; all threads, one pass
    (``tf_first_out_of_range``). Its numpy twin is
    :func:`turbinefit.io.heatmap_files.check_heatmap_values` applied in turn."""
    assert _LIB is not None
    return int(_run(_LIB.tf_first_out_of_range, len(maps), _c(maps, np.uint64), int(half),
                    int(count), float(lo), float(hi)))


class NativeMaps(NamedTuple):
    """How the kernels reach a stack's heat-maps
    (:func:`native_maps`): per keyframe, the address of
    its (7, H, W) array in memory or, with ``files`` (a :class:`FileMaps` handle), its index
    among the ``n_files`` files; float16 if ``half``, else float32."""

    maps: NDArray[np.uint64]
    half: bool
    files: int | None = None
    n_files: int = 0


def native_maps(stack: HeatmapStack) -> NativeMaps | None:
    """How the kernels reach ``stack``'s maps: each keyframe's address
    (:meth:`~turbinefit.heatmaps.HeatmapStack.pointers`) or, from files, its index among
    them with their handle; None if they cannot (the numpy implementation then reads
    them)."""
    files, index = stack.files, stack.file_index()
    if files is not None and index is not None:
        return NativeMaps(index, stack.half, files.handle, len(files))
    pointers = stack.pointers()
    return None if pointers is None else NativeMaps(pointers, stack.half)


class FileMaps:
    """A flight's heat-map files as the kernels read them (``tf_files_new``): each mapped
    read-only, the kernels noting every value they read; when a kernel is done with a
    keyframe that read a page for the first time, the pages the system mapped round it
    (64 kB at a time on Linux) that nothing read are dropped again (they stay in the page
    cache). A fit reads a quarter to a third of the pages of a flight (the bands round the
    projected model), so the process holds about that much, where plain memory maps would
    hold every page of every file.

    Every value is checked once to lie in [``lo``, ``hi``] (compared in float32; NaN is
    out): by :meth:`check`, or with ``on_first_read`` the first time a kernel or
    :meth:`read` reads the keyframe (in the same pass as that read: the check brings in
    the pages the kernel reads next), :meth:`check` doing the rest. A keyframe out of range
    makes the kernels' callers raise :class:`~turbinefit.heatmaps.HeatmapValueError`
    (:func:`_check`), and :meth:`read` too; :meth:`first_bad` names it. The check keeps
    :attr:`grid`, the values of ``rows`` of each channel at every ``step``-th column
    (N, 7, len(rows), ceil(W / step)), those of
    :meth:`turbinefit.heatmaps.HeatmapStack.coarse_grid`.

    Args:
        fds: an open descriptor of each keyframe's file (mapped here: the caller closes
            them).
        offsets: where each file's values start.
        shape: (7, H, W) of each keyframe's array; ``half``: float16, else float32.
        lo, hi: the values allowed.
        rows, step: the coarse grid's rows and column step.
        on_first_read: check each keyframe when it is first read (else by :meth:`check`).

    Raises:
        OSError: if a file cannot be mapped.
    """

    def __init__(self, fds: list[int], offsets: list[int], shape: tuple[int, int, int],
                 half: bool, lo: float, hi: float, rows: NDArray[np.int_], step: int,
                 on_first_read: bool = False) -> None:
        assert _LIB is not None
        self.shape = shape
        self.half = bool(half)
        self.dtype = np.dtype("<f2" if half else "<f4")
        self._n = len(fds)
        _, H, W = shape
        r = _c(rows, np.int64)
        self.grid: NDArray[np.floating] = np.zeros((self._n, shape[0], len(r), -(-W // step)),
                                                   dtype=self.dtype)
        ctypes.set_errno(0)
        handle = _LIB.tf_files_new(len(fds), _c(fds, np.int64), _c(offsets, np.int64),
                                   int(np.prod(shape)), int(half))
        if not handle:
            code = ctypes.get_errno() or 12  # ENOMEM
            raise OSError(code, os.strerror(code))
        self.handle: int = handle
        self._finalizer = weakref.finalize(self, _LIB.tf_files_free, handle)
        code = int(_LIB.tf_files_check_setup(handle, float(lo), float(hi), H, W, r, len(r),
                                              int(step), self.grid.ctypes.data,
                                              int(on_first_read)))
        if code:
            raise OSError(code, os.strerror(code))

    def __len__(self) -> int:
        return self._n

    def read(self, k: int, check: bool = True) -> NDArray[np.floating]:
        """Keyframe ``k``'s (7, H, W) array (a read-only copy of its own, as read-only as a
        memory map of the file).

        Raises:
            HeatmapValueError: if ``check`` and its values were found out of range.
        """
        assert _LIB is not None
        out = np.empty(self.shape, dtype=self.dtype)
        _LIB.tf_files_read(self.handle, int(k), out.ctypes.data)
        if check and int(_LIB.tf_files_checked(self.handle, int(k))) == 2:
            raise HeatmapValueError(int(k))
        out.flags.writeable = False
        return out

    def check(self) -> int:
        """Check every keyframe not checked yet, on all threads (``tf_files_check``; its
        numpy twin is :func:`turbinefit.io.heatmap_files.check_heatmap_values` of
        :meth:`read` in turn); returns :meth:`first_bad`."""
        assert _LIB is not None
        return int(_run(_LIB.tf_files_check, self.handle))

    def first_bad(self) -> int:
        """The first keyframe found holding a NaN or a value out of range so far (all of
        them after :meth:`check`), or ``len(self)`` if none."""
        assert _LIB is not None
        return int(_LIB.tf_files_first_bad(self.handle))

    def checked(self, k: int) -> bool:
        """Whether keyframe ``k``'s values were checked (in range or not)."""
        assert _LIB is not None
        return bool(_LIB.tf_files_checked(self.handle, int(k)))

    def used_bytes(self) -> int:
        """Bytes of the pages the kernels read so far (the process holds these of the
        files, and the gaps under 64 kB between them)."""
        assert _LIB is not None
        return int(_LIB.tf_files_used(self.handle))


def files_supported() -> bool:
    """Whether the kernels can map heat-map files themselves (:class:`FileMaps`): they
    are :func:`available`, on a POSIX system."""
    return available() and os.name == "posix"


def _run(kernel: Any, *args: Any) -> Any:
    """``kernel(*args)``. A signal handled while ctypes converts the arguments (numpy's
    ``ndpointer`` checks run Python code, where handlers run) raises its interrupt, not the
    ``ctypes.ArgumentError`` ctypes makes of it."""
    try:
        return kernel(*args)
    except ctypes.ArgumentError as e:
        interrupt = interrupt_within(e)
        if interrupt is None:
            raise
        raise interrupt from None


def _check(bad: int, keyframes: NDArray[np.int_], maps: NativeMaps) -> None:
    """After a kernel: raise :class:`~turbinefit.heatmaps.HeatmapValueError` if it found a
    keyframe of files out of range (:class:`FileMaps` checked on first read), else
    :class:`~turbinefit.heatmaps.NonFiniteHeatmapError` if it returned the first row
    ``bad`` (>= 0) whose heat-map had a NaN or inf."""
    if maps.files is not None:
        assert _LIB is not None
        first = int(_LIB.tf_files_first_bad(maps.files))
        if first < maps.n_files:
            raise HeatmapValueError(first)
    if bad >= 0:
        raise NonFiniteHeatmapError(int(keyframes[bad]))


def _c(a: Any, dtype: Any) -> NDArray[Any]:
    return np.ascontiguousarray(a, dtype=dtype)


def _opt(a: NDArray[Any] | None) -> int | None:
    return None if a is None else a.ctypes.data


def image_terms(
    poses: FloatArray, camera_params: FloatArray, width: int, height: int,
    A: FloatArray, B: FloatArray, JA: FloatArray | None, JB: FloatArray | None,
    frac: FloatArray | None, channels: NDArray[np.int_], maps: NativeMaps,
    keyframes: NDArray[np.int_], kind: str, target: FloatArray | None,
    found: NDArray[np.bool_] | None, normal: FloatArray | None, lam: float,
    pixel_sigma: float, margin: float, floor: float, robust: str, robust_scale: float,
    with_jacobian: bool, JtHJ: FloatArray | None, g: FloatArray | None,
) -> tuple[FloatArray, NDArray[np.int64]]:
    """One image term over N keyframes and M points (see ``tf_image_terms``).

    Points are ``(1 - f) A + f B`` with ``f = frac`` (N, M) (None: f = 0), their theta
    Jacobians ``(1 - f) JA + f JB`` (M, 3, 7). Adds ``J^T H J`` and ``J^T g`` into ``JtHJ``
    (N, 13, 13) and ``g`` (N, 13) in place. ``maps``: the stack's
    :func:`native_maps`. Returns the per-keyframe cost
    (N,) and the points in view (N,); raises NonFiniteHeatmapError on a NaN or inf
    heat-map value."""
    assert _LIB is not None
    N, M = poses.shape[0], A.shape[0]
    cost = np.zeros(N)
    count = np.zeros(N, dtype=np.int64)
    fr = None if frac is None else _c(frac, np.float64)
    JAc = None if JA is None else _c(JA, np.float64)
    JBc = None if JB is None else _c(JB, np.float64)
    tg = None if target is None else _c(target, np.float64)
    fd = None if found is None else _c(found, np.uint8)
    nm = None if normal is None else _c(normal, np.float64)
    par = np.array([lam, pixel_sigma, margin, floor, _ROBUST[robust], robust_scale])
    bad = _run(_LIB.tf_image_terms,
        N, M, _c(poses, np.float64), _c(camera_params, np.float64), width, height,
        _c(A, np.float64), _c(B, np.float64), _opt(JAc), _opt(JBc), _opt(fr), M,
        _c(channels, np.int64), maps.maps, int(maps.half), maps.files, _c(keyframes, np.int64),
        0 if kind == "interp" else 1,
        _opt(tg), _opt(fd), _opt(nm), par, int(with_jacobian),
        None if JtHJ is None else JtHJ.ctypes.data, None if g is None else g.ctypes.data,
        cost, count)
    _check(int(bad), keyframes, maps)
    return cost, count


def project(poses: FloatArray, camera_params: FloatArray, width: int, height: int,
            world_p: FloatArray) -> tuple[FloatArray, NDArray[np.bool_], NDArray[np.bool_]]:
    """Pixels (N, M, 2), front and inside (N, M) of world points (M, 3) or (N, M, 3)."""
    assert _LIB is not None
    N = poses.shape[0]
    M = world_p.shape[-2]
    uv = np.empty((N, M, 2))
    front = np.empty((N, M), dtype=np.uint8)
    inside = np.empty((N, M), dtype=np.uint8)
    _run(_LIB.tf_project, N, M, _c(poses, np.float64), _c(camera_params, np.float64), width,
         height, _c(world_p, np.float64), 0 if world_p.ndim == 2 else 3 * M, uv, front, inside)
    return uv, front.astype(bool), inside.astype(bool)


def point_search(
    maps: NativeMaps, width: int, height: int, keyframes: NDArray[np.int_],
    channels: NDArray[np.int_], uv: FloatArray, usable: NDArray[np.bool_], radius: int,
    coarse: NDArray[np.int64], fine: NDArray[np.int64], step: int, threshold: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Circular-window search (see correspondence.find_point_correspondences); ``maps`` as
    for :func:`image_terms`."""
    assert _LIB is not None
    N, M = uv.shape[:2]
    target = np.empty((N, M, 2))
    found = np.empty((N, M), dtype=np.uint8)
    bad = _run(_LIB.tf_point_search_scaled,
        N, M, width, height, maps.maps, int(maps.half), maps.files, _c(keyframes, np.int64),
        _c(channels, np.int64), _c(uv, np.float64), _c(usable, np.uint8), radius,
        _c(coarse, np.int64),
        coarse.shape[0], _c(fine, np.int64), fine.shape[0], step, threshold, target, found)
    _check(int(bad), keyframes, maps)
    return target, found.astype(bool)


def line_search(
    maps: NativeMaps, width: int, height: int, keyframes: NDArray[np.int_],
    channels: NDArray[np.int_], uv: FloatArray, normal: FloatArray,
    usable: NDArray[np.bool_], half_length: int, step: float, threshold: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Perpendicular search over ``+-half_length`` steps of ``step`` px (see
    correspondence.find_line_correspondences); ``maps`` as for :func:`image_terms`."""
    assert _LIB is not None
    N, M = uv.shape[:2]
    target = np.empty((N, M, 2))
    found = np.empty((N, M), dtype=np.uint8)
    bad = _run(_LIB.tf_line_search_scaled,
        N, M, width, height, maps.maps, int(maps.half), maps.files, _c(keyframes, np.int64),
        _c(channels, np.int64), _c(uv, np.float64), _c(normal, np.float64),
        _c(usable, np.uint8), half_length,
        step, threshold, target, found)
    _check(int(bad), keyframes, maps)
    return target, found.astype(bool)


def block_tridiag_solve(D: FloatArray, B: FloatArray, b: FloatArray) -> FloatArray:
    """``A x = b`` for symmetric block-tridiagonal A (6x6 blocks) by block Cholesky.

    Raises ``numpy.linalg.LinAlgError`` if A is not positive definite."""
    assert _LIB is not None
    n, s, m = b.shape
    assert s == 6
    x = np.array(b, dtype=np.float64, order="C", copy=True)
    work = np.empty((2 * n, 6, 6))
    Bc = _c(B, np.float64) if n > 1 else np.zeros((1, 6, 6))
    err = _run(_LIB.tf_block_tridiag_solve, n, m, _c(D, np.float64), Bc, x, work)
    if err:
        raise np.linalg.LinAlgError(f"pivot block {err - 1} is not positive definite")
    return x
