"""Input limits: only regular files of sane size are read, and the sizes and magnitudes
turbinefit accepts.

Every input file (flight folders, configuration YAML, label and model files, rows of an
experiment) is opened through :func:`open_input` (text through
:func:`turbinefit.io.atomic.read_text`), which

* refuses anything that is not a regular file after following symbolic links - a named
  pipe (FIFO), a character or block device (``/dev/zero``), a socket - from ``os.stat``,
  without opening it (opening a FIFO blocks until a writer comes); the file is then
  opened with ``O_NONBLOCK`` and checked again on the open descriptor, so that a file
  swapped for a FIFO in between cannot hang the reader either;
* refuses a file larger than the limit of its kind before reading a byte, and never
  reads more than that limit (a file that grows while it is read is cut off and refused).

Limits (every refusal is one :class:`~turbinefit.errors.InputError` line naming the file,
with the size and the limit):

=========================  ==========  =================================================
kind                        limit       why
=========================  ==========  =================================================
settings YAML               1 MiB       ``camera.yaml``, ``turbine.yaml``, fit options:
                                        a few hundred bytes each
tables                      256 MiB     TUM trajectories (a pose is about 120 bytes:
                                        two million keyframes), experiment rows, COCO
                                        label files, run lists
ONNX models                 2 GiB       protobuf's own limit
photos                      200 MP      from the header, before decoding (a 150 MP
                                        inspection camera fits; a 30000 x 30000 PNG
                                        does not)
=========================  ==========  =================================================

Sizes and magnitudes: photos, cameras (``camera.yaml``, ``simulate --width --height``)
and heat-maps at least :data:`MIN_IMAGE_SIDE` px a side and at most
:data:`MAX_IMAGE_PIXELS` pixels;
translations and turbine positions within :data:`MAX_COORDINATE_M` of the origin, turbine
lengths at most :data:`MAX_LENGTH_M`, angles within :data:`MAX_ANGLE_RAD`, timestamps
within :data:`MAX_TIMESTAMP_S`.
"""

from __future__ import annotations

import io
import os
import stat
from pathlib import Path

from turbinefit.errors import InputError

StrPath = str | os.PathLike[str]

MiB = 1 << 20
#: Largest settings YAML file (``camera.yaml``, ``turbine.yaml``, fit options) [bytes].
MAX_SETTINGS_BYTES = 1 * MiB
#: Largest table (TUM trajectory, experiment rows, COCO labels, JSON run list) [bytes].
MAX_TABLE_BYTES = 256 * MiB
#: Largest ONNX model file [bytes] (protobuf cannot hold more).
MAX_MODEL_BYTES = 2048 * MiB

#: Smallest side [px] of a photo, a camera (``camera.yaml``, ``simulate --width
#: --height``) and a heat-map (files, ``simulate --heatmap-size``, ``detect``'s maps): on
#: simulated flights (``simulate --keyframes 100 --width W --height H``, then ``fit``)
#: 32 x 24 px fits to 0.75 m, 16 x 12 px ends worse than it started (2.7 m, 15 m of
#: model-point error).
MIN_IMAGE_SIDE = 24
#: Most pixels of a photo or camera (200 MP), checked from the header before decoding.
MAX_IMAGE_PIXELS = 200_000_000

#: Largest |coordinate| [m] of a translation or turbine base: beyond any Earth-fixed
#: frame (ECEF coordinates are below 6.4e6 m, UTM northings below 1e7 m).
MAX_COORDINATE_M = 1e8
#: Largest turbine length (tower, nacelle, blade) [m]; the tallest turbines are ~300 m.
MAX_LENGTH_M = 1000.0
#: Largest |angle| [rad] of a turbine's heading or blade rotation (angles are not wrapped).
MAX_ANGLE_RAD = 1000.0
#: Largest |timestamp| [s] (year ~5100 in Unix time; nanoseconds given as seconds exceed it).
MAX_TIMESTAMP_S = 1e11

_KINDS = (
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a directory"),
)


def human_bytes(n: int) -> str:
    """A byte count for messages: ``512 bytes``, ``1.5 MiB``, ``23.8 GiB``."""
    if n < 1024:
        return f"{n} bytes"
    x = float(n)
    units = ("KiB", "MiB", "GiB", "TiB")
    i = 0
    while True:
        x /= 1024.0
        if x < 1024.0 or i == len(units) - 1:
            return f"{x:.3g} {units[i]}"
        i += 1


def _refuse_not_regular(st: os.stat_result, path: Path) -> None:
    if stat.S_ISREG(st.st_mode):
        return
    what = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
    if what == "a directory":
        raise InputError("is a directory, expected a file", path=path)
    raise InputError(f"is {what}, not a regular file; refusing to read it", path=path)


def _stat(path: Path, missing: str) -> os.stat_result:
    try:
        return os.stat(path)
    except (FileNotFoundError, NotADirectoryError) as e:
        raise InputError(missing, path=path) from e
    except OSError as e:
        raise InputError(f"cannot access: {e.strerror or e}", path=path) from e


def _check_size(size: int, limit: int | None, path: Path) -> None:
    if limit is not None and size > limit:
        raise InputError(f"file is {size} bytes ({human_bytes(size)}), larger than the "
                         f"{human_bytes(limit)} limit for this kind of file", path=path)


def check_input_file(path: StrPath, limit: int | None = None,
                     missing: str = "file not found") -> int:
    """Refuse ``path`` unless it is a regular file (symbolic links followed) of at most
    ``limit`` bytes (None = any size); returns its size. Nothing is opened. ``missing`` is
    the message for a file that does not exist.

    Raises:
        InputError: naming the file: missing, not a regular file (FIFO, device, socket,
            directory) or too large.
    """
    p = Path(path)
    st = _stat(p, missing)
    _refuse_not_regular(st, p)
    _check_size(st.st_size, limit, p)
    return int(st.st_size)


def open_input(path: StrPath, limit: int | None = None,
               missing: str = "file not found") -> io.FileIO:
    """``path`` opened for reading in binary, unbuffered, after :func:`check_input_file`;
    opened with ``O_NONBLOCK`` and checked again on the descriptor (a file replaced by a
    FIFO meanwhile is refused, not waited for).

    Raises:
        InputError: as :func:`check_input_file`, or if the file cannot be opened.
    """
    p = Path(path)
    check_input_file(p, limit, missing)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
                     | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError as e:
        raise InputError(missing, path=p) from e
    except IsADirectoryError as e:
        raise InputError("is a directory, expected a file", path=p) from e
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", path=p) from e
    try:
        st = os.fstat(fd)
        _refuse_not_regular(st, p)
        _check_size(st.st_size, limit, p)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb", buffering=0)
    except BaseException:
        os.close(fd)
        raise


def read_input_bytes(path: StrPath, limit: int) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (:func:`open_input`); reads
    at most ``limit + 1`` bytes, so a file growing meanwhile (or a ``/proc`` file whose
    size reads 0) is refused rather than read without end.

    Raises:
        InputError: naming the file.
    """
    p = Path(path)
    with open_input(p, limit) as f:
        try:
            chunks = []
            got = 0
            while got <= limit:
                chunk = f.read(min(limit + 1 - got, 1 << 24))
                if not chunk:
                    break
                chunks.append(chunk)
                got += len(chunk)
        except OSError as e:
            raise InputError(f"cannot read: {e.strerror or e}", path=p) from e
    if got > limit:
        raise InputError(f"file is larger than the {human_bytes(limit)} limit for this kind "
                         "of file", path=p)
    return b"".join(chunks)


def check_image_size(width: int, height: int, path: StrPath | None = None,
                     field: str | None = None, what: str = "image") -> None:
    """Refuse an image (photo, camera) size outside [:data:`MIN_IMAGE_SIDE`,
    :data:`MAX_IMAGE_PIXELS`] (``what`` names it in the message)."""
    if min(width, height) < MIN_IMAGE_SIDE:
        raise InputError(f"{what} is {width}x{height} px; each side must be at least "
                         f"{MIN_IMAGE_SIDE} px", path=path, field=field)
    if width * height > MAX_IMAGE_PIXELS:
        raise InputError(f"{what} is {width}x{height} px ({width * height / 1e6:.6g} MP), "
                         f"more than the {MAX_IMAGE_PIXELS / 1e6:g} MP limit", path=path,
                         field=field)
