"""Heat-map files of a flight folder: ``heatmaps/<t>.npy`` opened by their headers.

:func:`read_heatmaps` opens one float32 or float16 (7, h, w) ``.npy`` per keyframe
(float16: half the bytes, read as they are by the compiled kernels), every file of the same
size (given, or that of the first file, at least :data:`~turbinefit.io.limits.MIN_IMAGE_SIDE`
px a side), only regular files (:func:`~turbinefit.io.limits.open_input`), each checked
finite and in [0, 1] (:func:`check_heatmap_values`: one minimum and maximum per channel).
The files are memory-mapped; with the compiled kernels they are mapped by
:class:`turbinefit._native.FileMaps`, which keeps only the pages the kernels read (a fit of
1000 keyframes of 320x240 maps holds about a quarter of them, where plain memory maps end up
holding all of them). :func:`scaled_camera` is the
camera of maps smaller than the photos (the rules are in
:mod:`turbinefit.io.flight_folder`'s docstring). Every problem is an
:class:`~turbinefit.errors.InputError` naming the file.
"""

from __future__ import annotations

import errno
import io
import math
import os
import stat
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.lib import format as npy_format
from numpy.typing import ArrayLike, NDArray

from turbinefit import _native
from turbinefit.errors import InputError, plain_number
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.heatmaps import CHANNEL_NAMES, NUM_CHANNELS, HeatmapStack, HeatmapValueError
from turbinefit.heatmaps.stack import grid_rows, grid_step
from turbinefit.io.atomic import StrPath
from turbinefit.io.limits import MAX_IMAGE_PIXELS, MIN_IMAGE_SIDE, open_input

#: The photos' camera file of a flight folder (named in messages).
CAMERA_FILE = "camera.yaml"

#: Heat-map values may lie this far outside [0, 1] (rounding of a resize or of float16).
VALUE_TOLERANCE = 1e-3

#: When :func:`read_heatmaps` checks the values: at once, or as they are first read.
ValueCheck = Literal["now", "first read"]
#: How heat-map files are stored: float16 or float32.
HeatmapDtype = Literal["float16", "float32"]
#: How turbinefit writes heat-map files (:func:`~turbinefit.io.flight_folder.write_flight`,
#: ``detect``): half the bytes of float32, values in [0, 1] to within 2.5e-4.
WRITTEN_HEATMAP_DTYPE: HeatmapDtype = "float16"

_NPY_MAGIC = b"\x93NUMPY"
_HEATMAP_DTYPE = np.dtype("<f4")
_HALF_DTYPE = np.dtype("<f2")


def keyframe_stem(timestamp: float) -> str:
    """The name of a keyframe's files without suffix, ``'%.6f' % timestamp``."""
    return f"{timestamp:.6f}"


def heatmap_filename(timestamp: float) -> str:
    """The file name of a keyframe's heat-maps, ``'%.6f.npy' % timestamp``."""
    return keyframe_stem(timestamp) + ".npy"


# --------------------------------------------------------------------------- heat-maps

_Header = tuple[tuple[int, ...], bool, np.dtype]


def _read_npy_header(f: io.RawIOBase, fname: str,
                     cache: dict[bytes, _Header]) -> tuple[_Header, int]:
    """Parse a ``.npy`` header from an open file; returns (shape, fortran, dtype), offset."""
    head = f.read(512) or b""
    if len(head) < 10 or not head.startswith(_NPY_MAGIC):
        raise InputError("not a .npy file (bad magic bytes)", path=Path(fname))
    major = head[6]
    if major == 1:
        offset = 10 + int.from_bytes(head[8:10], "little")
    elif major == 2:
        offset = 12 + int.from_bytes(head[8:12], "little")
    else:
        raise InputError(f"unsupported .npy format version {major}.{head[7]}", path=Path(fname))
    if len(head) < offset:
        f.seek(0)
        head = f.read(offset) or b""
        if len(head) < offset:
            raise InputError("truncated .npy header", path=Path(fname))
    key = head[:offset]
    parsed = cache.get(key)
    if parsed is None:
        stream = io.BytesIO(key[8:])
        try:
            if major == 1:
                shape, fortran, dtype = npy_format.read_array_header_1_0(stream)
            else:
                shape, fortran, dtype = npy_format.read_array_header_2_0(stream)
        except Exception as e:  # ValueError, SyntaxError, tokenize.TokenError, ...
            raise InputError(f"invalid .npy header: {e}", path=Path(fname)) from e
        parsed = (tuple(int(n) for n in shape), bool(fortran), np.dtype(dtype))
        cache[key] = parsed
    return parsed, offset


def _check_heatmap(header: _Header, offset: int, size: int, shape: tuple[int, ...],
                   fname: str, first: str | None) -> None:
    got_shape, fortran, dtype = header
    if dtype not in (_HEATMAP_DTYPE, _HALF_DTYPE):
        raise InputError(f"dtype {dtype.str}, expected float32 (<f4) or float16 (<f2)",
                         path=Path(fname))
    if got_shape != shape:
        why = ("7 channels x image_height x image_width" if first is None else
               f"every heat-map of a flight has the size of the first, {first}")
        raise InputError(f"shape {got_shape}, expected {shape} ({why})", path=Path(fname))
    if fortran:
        raise InputError("array is Fortran-ordered; save it C-ordered "
                         "(np.save(path, np.ascontiguousarray(a)))", path=Path(fname))
    need = offset + math.prod(shape) * dtype.itemsize
    if size < need:
        raise InputError(f"truncated: {size} bytes, expected {need}", path=Path(fname))


def _raise_open_file_limit(extra: int) -> None:
    """Make room for ``extra`` more open files: raise the soft RLIMIT_NOFILE (at most to
    the hard limit) if the descriptors already open plus ``extra`` exceed it."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not on Unix
        return
    try:
        in_use = len(os.listdir("/proc/self/fd"))
    except OSError:  # not Linux: assume a few hundred
        in_use = 256
    needed = in_use + extra
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft >= needed:
        return
    target = needed if hard == resource.RLIM_INFINITY else min(needed, hard)
    try:
        resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
    except (ValueError, OSError):  # pragma: no cover - e.g. macOS caps at OPEN_MAX
        pass


def _os_error(e: OSError, n: int, fname: str) -> InputError:
    if e.errno in (errno.EMFILE, errno.ENFILE):
        return InputError(f"too many open files: memory-mapping {n} heat-maps needs one file "
                          "descriptor each; raise the limit (ulimit -n) or read with mmap=False",
                          path=Path(fname))
    return InputError(f"cannot read: {e.strerror or e}", path=Path(fname))


def read_heatmaps(folder: StrPath, timestamps: ArrayLike, height: int | None = None,
                  width: int | None = None, mmap: bool = True,
                  keyframes_file: StrPath | None = None,
                  keyframe_lines: ArrayLike | None = None,
                  check: ValueCheck = "now") -> HeatmapStack:
    """Open ``folder/<%.6f timestamp>.npy`` for every timestamp (see module docstring).

    Args:
        folder: the ``heatmaps`` directory.
        timestamps: (N,) keyframe timestamps [s].
        height, width: expected map size [px]; None = that of the first file (the others
            must have it too).
        mmap: map files read-only (default: with the compiled kernels by
            :class:`turbinefit._native.FileMaps`, holding the pages they read; a flight
            mixing float16 and float32 files has its float16 ones converted to float32 in
            memory) or load all into one float32 (N, 7, H, W) array.
        keyframes_file, keyframe_lines: only used to point error messages at the keyframe.
        check: when the values are checked: ``"now"``, or with the compiled kernels
            ``"first read"``: each keyframe's when the kernels (or ``stack[k]``) first
            read it, in the same pass (a fit's first search reads every keyframe: the
            check then costs no pass of its own), the rest by ``stack.check()``; a value
            out of range is then a :class:`~turbinefit.heatmaps.HeatmapValueError`, which
            :func:`value_error` turns into this module's InputError.

    Raises:
        InputError: naming the heat-map file that is missing or invalid.
    """
    import mmap as mmap_module

    folder = Path(folder)
    t = np.asarray(timestamps, dtype=np.float64)
    lines = None if keyframe_lines is None else np.asarray(keyframe_lines).tolist()
    kind = _kind(folder)
    if kind is None:
        raise InputError("heat-map directory not found", path=folder)
    if kind != "dir":
        raise InputError("not a directory (expected the heat-map folder)", path=folder)
    given = height is not None and width is not None
    shape = (NUM_CHANNELS, int(height or 0), int(width or 0))
    names = [heatmap_filename(x) for x in t.tolist()]
    if len(set(names)) != len(names):
        raise InputError("two keyframe timestamps have the same %.6f text, so they would "
                         "share a heat-map file", path=keyframes_file or folder)
    cache: dict[bytes, _Header] = {}
    stacked = None
    maps: list[NDArray[np.floating]] = []
    mapped: list[tuple[NDArray[np.floating], str, int]] = []  # (map, file, data offset)
    use_files = mmap and _native.files_supported()
    opened: list[tuple[int, int, np.dtype]] = []  # with files: (descriptor, offset, dtype)
    if mmap:
        _raise_open_file_limit(len(names) + 64)
    base = os.fspath(folder)
    fnames = [os.path.join(base, name) for name in names]
    try:
        for k, (name, fname) in enumerate(zip(names, fnames, strict=True)):
            try:  # a regular file only (a FIFO would block), closed by the with below
                f = open_input(fname, missing=_missing(k, name, keyframes_file, lines))
            except InputError as e:
                cause = e.__cause__
                if isinstance(cause, OSError) and cause.errno in (errno.EMFILE, errno.ENFILE):
                    raise _os_error(cause, len(names), fname) from cause
                raise
            with f:
                try:
                    header, offset = _read_npy_header(f, fname, cache)
                    if k == 0 and not given:
                        shape = _first_shape(header[0], fname)
                    _check_heatmap(header, offset, os.fstat(f.fileno()).st_size, shape, fname,
                                   None if given else names[0])
                    if k == 0 and not mmap:
                        stacked = np.empty((len(names), *shape), dtype=np.float32)
                    if stacked is not None:
                        f.seek(offset)
                        _read_into(f, stacked[k], fname, header[2])
                        check_heatmap_values(stacked[k], fname)
                    elif use_files:  # mapped by FileMaps below
                        opened.append((os.dup(f.fileno()), offset, header[2]))
                    else:
                        mm = mmap_module.mmap(f.fileno(), 0, access=mmap_module.ACCESS_READ)
                        maps.append(np.ndarray(shape, dtype=header[2], buffer=mm,
                                               offset=offset))
                        mapped.append((maps[-1], fname, offset))
                except OSError as e:
                    raise _os_error(e, len(names), fname) from e
        if use_files and len({dtype for _, _, dtype in opened}) > 1:
            for (fd, offset, dtype), fname in zip(opened, fnames, strict=True):  # mixed: mapped
                try:
                    mm = mmap_module.mmap(fd, 0, access=mmap_module.ACCESS_READ)
                except OSError as e:
                    raise _os_error(e, len(names), fname) from e
                maps.append(np.ndarray(shape, dtype=dtype, buffer=mm, offset=offset))
                mapped.append((maps[-1], fname, offset))
            _close([fd for fd, _, _ in opened])
            opened, use_files = [], False
    except BaseException:
        _close([fd for fd, _, _ in opened])
        raise
    if use_files and opened:
        try:
            files = _native.FileMaps(
                [fd for fd, _, _ in opened], [o for _, o, _ in opened], shape,
                opened[0][2] == _HALF_DTYPE, -VALUE_TOLERANCE, 1.0 + VALUE_TOLERANCE,
                grid_rows(shape[1]), grid_step(shape[2]), on_first_read=check != "now")
        except OSError as e:
            raise _os_error(e, len(names), os.fspath(folder)) from e
        finally:
            _close([fd for fd, _, _ in opened])
        stack = HeatmapStack(files)
        if check == "now":
            try:
                stack.check()
            except HeatmapValueError as e:
                raise value_error(stack, e.keyframe, fnames[e.keyframe]) from None
        return stack
    if len({m.dtype for m in maps}) > 1:  # float16 and float32 files: float32 in memory
        for j, (m, fname, _) in enumerate(mapped):
            if m.dtype == _HALF_DTYPE:
                maps[j] = m.astype(np.float32)
                check_heatmap_values(maps[j], fname)
        mapped = [item for item in mapped if item[0].dtype == _HEATMAP_DTYPE]
    stack = HeatmapStack(stacked if stacked is not None else maps)
    if mapped:
        _check_mapped_values(mapped, shape, len(names))
    return stack


def _close(fds: list[int]) -> None:
    for fd in fds:
        try:
            os.close(fd)
        except OSError:
            pass


def value_error(stack: HeatmapStack, k: int, fname: StrPath) -> InputError:
    """The InputError of keyframe ``k`` of a stack read from files whose check found it out
    of range (:class:`~turbinefit.heatmaps.HeatmapValueError`): the message of
    :func:`check_heatmap_values` (channel and value), naming ``fname``."""
    files = stack.files
    assert files is not None
    try:
        check_heatmap_values(files.read(k, check=False), fname)
    except InputError as e:
        return e
    return InputError("changed while it was read", path=Path(fname))


def _check_mapped_values(mapped: list[tuple[NDArray[np.floating], str, int]],
                         shape: tuple[int, ...], total: int) -> None:
    """:func:`check_heatmap_values` of memory-mapped files ``(map, name, data offset)``,
    all float32 or all float16; the first bad file in keyframe order is the error. With
    the compiled kernels, one pass over the maps themselves on all threads
    (:func:`turbinefit._native.first_out_of_range`), the message from
    :func:`check_heatmap_values` of the file it names; else each file is read into a
    scratch buffer on a few threads (faster in numpy than two reductions over its memory
    map)."""
    half = mapped[0][0].dtype == _HALF_DTYPE
    if _native.available():
        pointers = np.array([m.ctypes.data for m, _, _ in mapped], dtype=np.uint64)
        lo, hi = -VALUE_TOLERANCE, 1.0 + VALUE_TOLERANCE
        start = 0
        while start < len(pointers):
            k = start + _native.first_out_of_range(pointers[start:], half, math.prod(shape),
                                                   lo, hi)
            if k < len(pointers):
                check_heatmap_values(mapped[k][0], mapped[k][1])  # raises, naming the value
            start = k + 1
        return
    _read_mapped_values([(name, offset) for _, name, offset in mapped], shape, total,
                        _HALF_DTYPE if half else _HEATMAP_DTYPE)


def _read_mapped_values(files: list[tuple[str, int]], shape: tuple[int, ...],
                        total: int, dtype: np.dtype) -> None:
    """The numpy value check of memory-mapped files: each read into a scratch buffer (faster
    than faulting in every page of its map for two reductions), on a few threads (reading
    and the reductions release the GIL)."""
    from concurrent.futures import ThreadPoolExecutor
    from threading import local

    scratch = local()

    def check(item: tuple[str, int]) -> None:
        fname, offset = item
        buf = getattr(scratch, "buf", None)
        if buf is None:
            buf = scratch.buf = np.empty(shape, dtype=dtype)
        try:
            with open_input(fname) as f:  # still a regular file, not waited on if not
                f.seek(offset)
                _read_into(f, buf, fname)
        except OSError as e:
            raise _os_error(e, total, fname) from e
        check_heatmap_values(buf, fname)

    workers = min(4, os.cpu_count() or 1, len(files))
    if workers == 1:
        for item in files:
            check(item)
        return
    with ThreadPoolExecutor(workers) as pool:
        for _ in pool.map(check, files):  # raises the first error in order
            pass


def _read_into(f: io.RawIOBase, out: NDArray[np.floating], fname: str,
               dtype: np.dtype | None = None) -> None:
    """Fill ``out`` from ``f``'s current position, whose values are ``dtype`` (default:
    ``out``'s; float16 is converted)."""
    if dtype is not None and dtype != out.dtype:
        buf = np.empty(out.shape, dtype=dtype)
        _read_into(f, buf, fname)
        out[...] = buf
        return
    view = memoryview(out.data).cast("B")
    done = 0
    while done < view.nbytes:
        n = f.readinto(view[done:])
        if not n:
            raise InputError("truncated", path=Path(fname))
        done += n


def _missing(k: int, name: str, keyframes_file: StrPath | None,
             lines: list[int] | None) -> str:
    where = f"keyframe {k}, timestamp {name[:-4]}"
    if keyframes_file is not None:
        line = f", line {lines[k]}" if lines is not None else ""
        where += f" ({Path(keyframes_file).name}{line})"
    return f"heat-map file missing for {where}"


def _first_shape(shape: tuple[int, ...], fname: str) -> tuple[int, int, int]:
    """The (7, h, w) shape of a flight's first heat-map file, checked (at least
    :data:`~turbinefit.io.limits.MIN_IMAGE_SIDE` px a side, at most
    :data:`~turbinefit.io.limits.MAX_IMAGE_PIXELS` pixels)."""
    if len(shape) != 3 or shape[0] != NUM_CHANNELS or min(shape) < 1:
        raise InputError(f"shape {shape}, expected ({NUM_CHANNELS}, height, width)",
                         path=Path(fname))
    h, w = int(shape[1]), int(shape[2])
    if min(h, w) < MIN_IMAGE_SIDE:
        raise InputError(f"heat-maps of {w}x{h} px; each side must be at least "
                         f"{MIN_IMAGE_SIDE} px", path=Path(fname))
    if h * w > MAX_IMAGE_PIXELS:
        raise InputError(f"heat-maps of {w}x{h} px, more than the {MAX_IMAGE_PIXELS / 1e6:g} MP "
                         "limit", path=Path(fname))
    return NUM_CHANNELS, h, w


def check_heatmap_values(maps: NDArray[np.floating], fname: StrPath) -> None:
    """Refuse one keyframe's heat-maps (7, h, w), of any float dtype, unless every value is
    finite and within [0, 1] up to :data:`VALUE_TOLERANCE`; the message names the file,
    the channel and the value. One pass over the data (a minimum and a maximum per
    channel)."""
    flat = maps.reshape(maps.shape[0], -1)
    lo, hi = flat.min(axis=1), flat.max(axis=1)
    ok = (lo >= -VALUE_TOLERANCE) & (hi <= 1.0 + VALUE_TOLERANCE)
    if bool(ok.all()):
        return
    c = int(np.flatnonzero(~ok)[0])
    name = CHANNEL_NAMES[c] if maps.shape[0] == NUM_CHANNELS else f"channel {c}"
    if np.isnan(lo[c]) or np.isnan(hi[c]):
        raise InputError(f"channel {c} ({name}) holds NaN; heat-map values must be finite, "
                         "in [0, 1]", path=Path(fname))
    bad = lo[c] if not lo[c] >= -VALUE_TOLERANCE else hi[c]
    raise InputError(f"channel {c} ({name}) holds {plain_number(bad)}, outside [0, 1] "
                     f"(values from {plain_number(lo[c])} to {plain_number(hi[c])}; tolerance "
                     f"{VALUE_TOLERANCE:g})", path=Path(fname))


def scaled_camera(camera: PinholeCamera, width: int, height: int) -> PinholeCamera:
    """The camera of heat-maps of ``width`` x ``height`` px made from photos of
    ``camera`` (:meth:`~turbinefit.geometry.camera.PinholeCamera.scaled_to`: ``camera``
    itself at its own size, else resized with pixel centres aligned).

    Raises:
        ValueError: if the size is larger than the camera's or not a scale of it (the
            message names ``camera.yaml``).
    """
    try:
        return camera.scaled_to(width, height)
    except ValueError as e:
        raise ValueError(f"heat-maps of {int(width)}x{int(height)} px do not fit the photos "
                         f"of {CAMERA_FILE}: {e}") from None


def _kind(path: Path) -> str | None:
    """``"dir"``, ``"file"`` (anything else that exists) or None (missing), following
    symbolic links; a path that cannot be inspected (a parent directory without search
    permission, a symbolic-link loop) is an InputError, not a "missing" or a traceback."""
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as e:
        raise InputError(f"cannot access: {e.strerror or e}", path=path) from e
    return "dir" if stat.S_ISDIR(st.st_mode) else "file"
