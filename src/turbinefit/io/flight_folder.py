"""Flight folders: a whole :class:`~turbinefit.flight.Flight` on disk.

Layout (names exact)::

    <folder>/
        camera.yaml                 intrinsics, ROS camera_info YAML        (required)
        keyframes.txt               TUM, initial world_T_cam per keyframe   (required)
        turbine.yaml                initial turbine parameters              (optional: without
                                    it, fit and track estimate one, turbinefit.jobs.init)
        heatmaps/<t>.npy            one per keyframe                (required, or images/)
        images/<t>.png|.jpg         one photo per keyframe                  (optional)
        odometry.txt                TUM, same timestamps                    (optional)
        groundtruth.txt             TUM, ground-truth world_T_cam           (optional)
        turbine_groundtruth.yaml    ground-truth turbine parameters         (optional)
        simulation.yaml             settings of ``turbinefit simulate``     (optional, not read)
        georef.yaml                 WGS84 origin of an ENU world frame      (optional, see
                                    :mod:`turbinefit.io.georef`; read by fit and track)
        keyframes_sigma.csv         position standard deviations per        (optional)
                                    keyframe (RTK): absolute position priors

* Poses: camera-to-world ``world_T_cam`` (OpenCV camera frame, world z up), metres; TUM
  files store quaternions xyzw (see :mod:`turbinefit.io.tum`).
* Timestamps: seconds. ``odometry.txt`` and ``groundtruth.txt`` must list the same
  timestamps as ``keyframes.txt`` (each within 1e-6 s).
* Turbine: metres and radians (see :mod:`turbinefit.io.turbine_yaml`).
* Heat-maps: ``heatmaps/<timestamp formatted %.6f>.npy`` (e.g. ``12.500000.npy``), a
  C-ordered little-endian float32 or float16 ``.npy`` array (7, h, w), channels in the
  order of :data:`turbinefit.heatmaps.CHANNEL_NAMES` (turbinefit writes float16: half the
  bytes, values to within 2.5e-4). Other files in ``heatmaps/`` are ignored.
  Values must be finite and in [0, 1] (to 1e-3): each file's minimum and maximum per
  channel are checked when it is opened, one pass over its data.
* Heat-map size: every file of a flight has the same (h, w), read from the first file's
  header; it may be smaller than the photos of ``camera.yaml`` (W x H), and then fixes
  the scale: the flight's camera is ``camera.yaml``'s resized to w x h
  (:meth:`~turbinefit.geometry.camera.PinholeCamera.resized`, each axis on its own,
  pixel centres aligned): map pixel ``(j, i)`` covers photo pixels around
  ``u = (j + 0.5) W / w - 0.5``, ``v = (i + 0.5) H / h - 0.5``, so fx, cx scale as
  ``fx w / W``, ``(cx + 0.5) w / W - 0.5`` (the same in y with h / H). Maps at the
  photos' size (h, w = H, W) use ``camera.yaml`` as it is. The size must be the photos'
  scaled by one factor up to rounding (h within a pixel of ``H w / W``, or w of
  ``W h / H``) and no larger than the photos.
* Position sigmas (``keyframes_sigma.csv``, written by ``import dji`` from RTK status):
  a header ``timestamp,sigma_x,sigma_y,sigma_z``, then one row per keyframe, the same
  timestamps as ``keyframes.txt`` (within 1e-6 s, in order): the standard deviations [m]
  of the keyframe's position in ``keyframes.txt`` along the world's x, y, z axes
  (east, north, up on a georeferenced flight), each in (0, 10000]. ``keyframes.txt`` stays
  TUM; with this file, ``fit`` and ``track`` add an absolute position prior per keyframe
  (:mod:`turbinefit.costs.position_prior`).
* Images: ``images/<timestamp formatted %.6f>.png`` (or ``.jpg`` / ``.jpeg``), the
  keyframe's photo at the size of ``camera.yaml`` (the photos' camera). A flight with ``images/`` but no
  ``heatmaps/`` is read with heat-maps detected from the photos: :func:`read_flight_folder`
  reads the rest, :func:`keyframe_images` finds the photos, and
  :mod:`turbinefit.jobs.sources` detects them.

Reading with ``mmap=True`` (default) maps every heat-map file read-only; only the
``.npy`` headers are read (one small read per file, identical headers parsed once), so
opening a 1000-keyframe flight takes a few tens of milliseconds and no RAM until pixels are
touched. Each map holds one open file descriptor (Python < 3.13's ``mmap`` keeps one), so
the process's soft open-file limit is raised towards the hard limit when a flight needs it.
float16 files are mapped as they are (the compiled kernels read them); a flight mixing
float16 and float32 files has its float16 ones converted to float32 in memory.
``mmap=False`` reads everything into one (N, 7, H, W) float32 array.

Every problem is an :class:`~turbinefit.errors.InputError` naming the file (and line or
field): missing folder or required file, malformed content, a keyframe without its
heat-map file, a heat-map of the wrong shape or dtype (or of another size than the first,
or not a scale of ``camera.yaml``), or a file that is not a valid ``.npy``.

:func:`write_flight` writes the whole folder atomically (see
:func:`turbinefit.io.atomic.atomic_output_dir`): into a hidden temporary sibling, renamed
into place at the end; an existing non-empty folder is refused unless ``overwrite=True``,
and even then only if it holds nothing but flight-folder entries (:data:`FLIGHT_ENTRIES`,
with ``.npy`` files only in ``heatmaps/``), so ``overwrite`` on a wrong path never deletes
anything that is not a turbinefit flight. :func:`check_flight_destination` applies the same
check up front.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from turbinefit.errors import InputError, plain_number
from turbinefit.flight import Flight
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3
from turbinefit.heatmaps import NUM_CHANNELS, HeatmapStack
from turbinefit.io.atomic import (
    OVERWRITE_HINT,
    StrPath,
    atomic_output_dir,
    check_output_dir,
    write_error,
    write_text_atomic,
)
from turbinefit.io.camera_yaml import format_camera_yaml, read_camera_yaml
from turbinefit.io.heatmap_files import (
    CAMERA_FILE,
    WRITTEN_HEATMAP_DTYPE,
    HeatmapDtype,
    ValueCheck,
    _kind,
    heatmap_filename,
    keyframe_stem,
    read_heatmaps,
    scaled_camera,
)
from turbinefit.io.images import IMAGE_SUFFIXES
from turbinefit.io.quantities import TIMESTAMP as TIMESTAMP_Q
from turbinefit.io.quantities import Quantity
from turbinefit.io.tum import TumTrajectory, format_tum, read_tum_lines
from turbinefit.io.turbine_yaml import format_turbine_yaml, read_turbine_yaml
from turbinefit.turbine.model import TurbineParams

KEYFRAMES_FILE = "keyframes.txt"
ODOMETRY_FILE = "odometry.txt"
TURBINE_FILE = "turbine.yaml"
HEATMAP_DIR = "heatmaps"
IMAGE_DIR = "images"
GT_POSES_FILE = "groundtruth.txt"
GT_TURBINE_FILE = "turbine_groundtruth.yaml"
#: Written by ``turbinefit simulate`` (the simulation settings); never read.
SIMULATION_FILE = "simulation.yaml"
#: The WGS84 origin of a georeferenced flight (:mod:`turbinefit.io.georef`).
GEOREF_FILE = "georef.yaml"
#: Position standard deviations per keyframe (module docstring).
SIGMA_FILE = "keyframes_sigma.csv"
SIGMA_HEADER = "timestamp,sigma_x,sigma_y,sigma_z"
#: A keyframe position's standard deviation [m].
POSITION_SIGMA = Quantity("position standard deviation", "m", 0.0, 1e4, lo_open=True)
#: Written by ``simulate`` with known defects: the defects (:mod:`turbinefit.io.defects`).
DEFECTS_FILE = "defects_groundtruth.csv"
#: Written by ``simulate`` with known defects and photos: each photo's defect boxes.
DEFECT_BOXES_FILE = "defect_boxes.csv"
#: Every entry a flight folder may contain (what ``write_flight(overwrite=True)`` may replace).
FLIGHT_ENTRIES = frozenset({CAMERA_FILE, KEYFRAMES_FILE, ODOMETRY_FILE, TURBINE_FILE,
                            HEATMAP_DIR, IMAGE_DIR, GT_POSES_FILE, GT_TURBINE_FILE,
                            SIMULATION_FILE, GEOREF_FILE, SIGMA_FILE, DEFECTS_FILE,
                            DEFECT_BOXES_FILE})
#: The entries :func:`write_flight` writes from the Flight itself (not as ``extra_texts``).
_DATA_ENTRIES = frozenset({CAMERA_FILE, KEYFRAMES_FILE, ODOMETRY_FILE, TURBINE_FILE,
                           HEATMAP_DIR, GT_POSES_FILE, GT_TURBINE_FILE, SIGMA_FILE})
#: Largest difference [s] between a keyframe's timestamp and its odometry / ground truth's.
TIMESTAMP_TOLERANCE = 1e-6
# --------------------------------------------------------------------------- flight

def _required(path: Path) -> Path:
    if _kind(path) is None:
        raise InputError("required file of a flight folder is missing", path=path)
    return path


def _read_matching_tum(path: Path, keyframes: TumTrajectory, keyframes_path: Path) -> SE3:
    traj = read_tum_lines(path)
    n, m = len(traj.timestamps), len(keyframes.timestamps)
    if n != m:
        raise InputError(f"{n} poses but {keyframes_path.name} has {m}; the timestamps must "
                         "be the same", path=path)
    diff = np.abs(traj.timestamps - keyframes.timestamps)
    bad = np.nonzero(diff > TIMESTAMP_TOLERANCE)[0]
    if bad.size:
        k = int(bad[0])
        raise InputError(
            f"timestamp {plain_number(traj.timestamps[k])} differs from keyframe {k} of "
            f"{keyframes_path.name} ({plain_number(keyframes.timestamps[k])}, line "
            f"{keyframes.lines[k]}) "
            f"by more than {TIMESTAMP_TOLERANCE:g} s", path=path, line=int(traj.lines[k]))
    return traj.poses


def keyframe_images(folder: StrPath, timestamps: ArrayLike) -> list[Path]:
    """The photo of every keyframe: ``folder/images/<%.6f timestamp>`` + the first of
    :data:`IMAGE_SUFFIXES` that exists.

    Raises:
        InputError: naming the first keyframe without a photo (or a missing folder).
    """
    img_dir = Path(folder) / IMAGE_DIR
    kind = _kind(img_dir)
    if kind != "dir":
        raise InputError("image folder not found" if kind is None else "not a directory",
                         path=img_dir)
    present = {p.name for p in img_dir.iterdir()}
    out = []
    for k, t in enumerate(np.asarray(timestamps, dtype=np.float64).tolist()):
        stem = keyframe_stem(t)
        name = next((stem + suf for suf in IMAGE_SUFFIXES if stem + suf in present), None)
        if name is None:
            raise InputError(f"no photo for keyframe {k}, timestamp {stem} (expected "
                             f"{stem}.png or .jpg)", path=img_dir)
        out.append(img_dir / name)
    return out


def has_heatmaps(folder: StrPath) -> bool:
    """Whether the flight folder has a ``heatmaps/`` entry."""
    return _kind(Path(folder) / HEATMAP_DIR) is not None


@dataclass(frozen=True)
class FlightFolder:
    """What a flight folder says apart from its heat-maps (see :func:`read_flight_folder`).

    Attributes:
        root: the folder.
        camera: intrinsics of ``camera.yaml`` (the photos' pixel grid).
        keyframes: ``keyframes.txt`` (timestamps, initial ``world_T_cam``, line numbers).
        turbine: the initial turbine (None without ``turbine.yaml``).
        odometry, gt_world_T_cam, gt_turbine: the optional files, or None.
        position_sigma: (N, 3) ``keyframes_sigma.csv``, or None.
    """

    root: Path
    camera: PinholeCamera
    keyframes: TumTrajectory
    turbine: TurbineParams | None
    odometry: SE3 | None = None
    gt_world_T_cam: SE3 | None = None
    gt_turbine: TurbineParams | None = None
    position_sigma: NDArray[np.float64] | None = None

    @property
    def timestamps(self) -> NDArray[np.float64]:
        return self.keyframes.timestamps

    @property
    def num_keyframes(self) -> int:
        return len(self.keyframes.timestamps)

    def heatmap_path(self, k: int) -> Path:
        """The heat-map file of keyframe ``k``."""
        return self.root / HEATMAP_DIR / heatmap_filename(float(self.timestamps[k]))

    def read_heatmaps(self, mmap: bool = True, check: ValueCheck = "now") -> HeatmapStack:
        """The heat-maps of ``heatmaps/``, at the size of the first file (see
        :func:`read_heatmaps`, and for ``check`` when the values are checked; their camera:
        :meth:`heatmap_camera`)."""
        hm_dir = self.root / HEATMAP_DIR
        kind = _kind(hm_dir)
        if kind is None:
            raise InputError("required heat-map directory of a flight folder is missing (or "
                             f"give photos in {IMAGE_DIR}/ to detect them)", path=hm_dir)
        return read_heatmaps(hm_dir, self.timestamps, mmap=mmap,
                             keyframes_file=self.root / KEYFRAMES_FILE,
                             keyframe_lines=self.keyframes.lines, check=check)

    def heatmap_camera(self, heatmaps: HeatmapStack) -> PinholeCamera:
        """The camera of the heat-maps' pixel grid: ``camera.yaml``'s scaled to their size
        (:func:`scaled_camera`).

        Raises:
            InputError: naming the first heat-map file (or the folder) if their size is not
                a scale of ``camera.yaml``'s.
        """
        try:
            return scaled_camera(self.camera, heatmaps.width, heatmaps.height)
        except ValueError as e:
            first = self.heatmap_path(0)
            raise InputError(str(e), path=first if _kind(first) else self.root) from None

    def flight(self, heatmaps: HeatmapStack, camera: PinholeCamera | None = None,
               turbine: TurbineParams | None = None) -> Flight:
        """The :class:`Flight` with these heat-maps, whose pixel grid is ``camera`` (default:
        ``camera.yaml``'s scaled to the maps' size, :meth:`heatmap_camera`), and whose
        initial turbine is ``turbine`` (default: ``turbine.yaml``'s; an InputError naming
        it if there is none)."""
        turbine = turbine or self.turbine
        if turbine is None:
            raise InputError("required file of a flight folder is missing",
                             path=self.root / TURBINE_FILE)
        try:
            return Flight(camera=camera or self.heatmap_camera(heatmaps),
                          timestamps=self.timestamps,
                          world_T_cam=self.keyframes.poses, heatmaps=heatmaps,
                          turbine=turbine, odometry=self.odometry,
                          gt_world_T_cam=self.gt_world_T_cam, gt_turbine=self.gt_turbine,
                          position_sigma=self.position_sigma)
        except ValueError as e:  # heat-maps given by the caller
            raise InputError(str(e), path=self.root) from e


def read_flight_folder(folder: StrPath) -> FlightFolder:
    """Read everything of a flight folder but its heat-maps (layout in the module
    docstring): the camera, keyframes, the initial turbine (if any) and the optional
    files.

    Raises:
        InputError: naming the file (and line or field) of the first problem found.
    """
    root = Path(folder)
    kind = _kind(root)
    if kind is None:
        raise InputError("flight folder not found", path=root)
    if kind != "dir":
        raise InputError("not a directory (expected a flight folder)", path=root)
    camera = read_camera_yaml(_required(root / CAMERA_FILE))
    kf_path = _required(root / KEYFRAMES_FILE)
    keyframes = read_tum_lines(kf_path)
    turbine = (read_turbine_yaml(root / TURBINE_FILE) if _kind(root / TURBINE_FILE) is not None
               else None)
    odometry = gt_poses = None
    gt_turbine: TurbineParams | None = None
    if _kind(root / ODOMETRY_FILE) is not None:
        odometry = _read_matching_tum(root / ODOMETRY_FILE, keyframes, kf_path)
    if _kind(root / GT_POSES_FILE) is not None:
        gt_poses = _read_matching_tum(root / GT_POSES_FILE, keyframes, kf_path)
    if _kind(root / GT_TURBINE_FILE) is not None:
        gt_turbine = read_turbine_yaml(root / GT_TURBINE_FILE)
    sigma = (read_position_sigmas(root / SIGMA_FILE, keyframes, kf_path)
             if _kind(root / SIGMA_FILE) is not None else None)
    return FlightFolder(root, camera, keyframes, turbine, odometry, gt_poses, gt_turbine,
                        sigma)


def format_position_sigmas(timestamps: ArrayLike, sigmas: ArrayLike) -> str:
    """The text of ``keyframes_sigma.csv`` (module docstring): ``sigmas`` (N, 3) [m]."""
    s = POSITION_SIGMA.check_array(sigmas, field=SIGMA_FILE)
    rows = [SIGMA_HEADER]
    for t, (x, y, z) in zip(np.asarray(timestamps, np.float64).tolist(), s.tolist(),
                            strict=True):
        rows.append(f"{t:.6f},{x:.6g},{y:.6g},{z:.6g}")
    return "\n".join(rows) + "\n"


def read_position_sigmas(path: Path, keyframes: TumTrajectory,
                         keyframes_path: Path) -> NDArray[np.float64]:
    """(N, 3) position standard deviations of ``keyframes_sigma.csv``, one row per keyframe.

    Raises:
        InputError: naming the file and line of a malformed row, a sigma out of range, or
            a timestamp that is not the keyframe's.
    """
    from turbinefit.io.atomic import read_text

    lines = [(i, ln.strip()) for i, ln in enumerate(read_text(path).splitlines(), start=1)
             if ln.strip()]
    if not lines or lines[0][1].replace(" ", "") != SIGMA_HEADER:
        raise InputError(f"expected the header {SIGMA_HEADER!r}", path=path, line=1)
    rows = lines[1:]
    n = len(keyframes.timestamps)
    if len(rows) != n:
        raise InputError(f"{len(rows)} rows but {keyframes_path.name} has {n} keyframes; "
                         "one row per keyframe", path=path)
    out = np.empty((n, 3))
    for k, (lineno, text) in enumerate(rows):
        cells = text.split(",")
        if len(cells) != 4:
            raise InputError(f"expected 4 comma-separated values, got {len(cells)}", path=path,
                             line=lineno)
        t = float(TIMESTAMP_Q.parse(cells[0], path, lineno, "timestamp"))
        if abs(t - keyframes.timestamps[k]) > TIMESTAMP_TOLERANCE:
            raise InputError(f"timestamp {cells[0].strip()} is not keyframe {k}'s "
                             f"({plain_number(keyframes.timestamps[k])}, "
                             f"{keyframes_path.name} line {keyframes.lines[k]})", path=path,
                             line=lineno)
        for j, name in enumerate(("sigma_x", "sigma_y", "sigma_z")):
            out[k, j] = POSITION_SIGMA.parse(cells[j + 1], path, lineno, name)
    return out


def read_flight(folder: StrPath, mmap: bool = True,
                heatmaps: HeatmapStack | None = None) -> Flight:
    """Read a flight folder (layout in the module docstring) with its heat-maps.

    Args:
        folder: the flight folder.
        mmap: memory-map the heat-maps (default; only headers are read) or load them into
            one (N, 7, H, W) float32 array.
        heatmaps: None = read ``heatmaps/``; else the heat-maps to use instead (one per
            keyframe, at the camera's size or a scale of it). Heat-maps detected from ``images/`` come from
            :class:`turbinefit.jobs.sources.PhotoHeatmaps` (see
            :func:`turbinefit.jobs.sources.open_heatmaps`).

    Raises:
        InputError: naming the file (and line or field) of the first problem found.
    """
    meta = read_flight_folder(folder)
    return meta.flight(meta.read_heatmaps(mmap) if heatmaps is None else heatmaps)


#: The flight folder's sub-folders: which file names they may hold, and what those are.
_DIR_CONTENTS: dict[str, tuple[Callable[[Path], bool], str]] = {
    HEATMAP_DIR: (lambda p: p.suffix == ".npy", "a heat-map file"),
    IMAGE_DIR: (lambda p: p.suffix.lower() in IMAGE_SUFFIXES, "a keyframe photo"),
}


def only_flight_entries(folder: Path) -> str | None:
    """None if ``folder`` holds only flight-folder entries (safe to replace), else why not.

    An OSError (e.g. an unreadable ``heatmaps/``) propagates; :func:`check_output_dir`
    turns it into an InputError."""
    for entry in folder.iterdir():
        if entry.name not in FLIGHT_ENTRIES:
            return f"{entry.name!r} is not part of a flight folder"
        if entry.name in _DIR_CONTENTS:
            allowed, what = _DIR_CONTENTS[entry.name]
            if not entry.is_dir() or entry.is_symlink():
                return f"{entry.name!r} is not a directory"
            for sub in entry.iterdir():
                if not allowed(sub) or not sub.is_file():
                    return f"'{entry.name}/{sub.name}' is not {what}"
    return None


def check_flight_destination(folder: StrPath, overwrite: bool = False,
                             overwrite_hint: str = OVERWRITE_HINT) -> None:
    """Raise the InputError :func:`write_flight` would raise for ``folder`` as destination
    (a file or symbolic link, a non-empty folder without ``overwrite``, a folder that is not
    a flight folder), before the flight to write exists. ``overwrite_hint`` ends the
    message for a non-empty folder."""
    check_output_dir(folder, overwrite, only_flight_entries, overwrite_hint)


@contextlib.contextmanager
def flight_output_dir(folder: StrPath, overwrite: bool = False,
                      overwrite_hint: str = OVERWRITE_HINT) -> Iterator[Path]:
    """:func:`~turbinefit.io.atomic.atomic_output_dir` with the overwrite guard of
    :func:`write_flight`, for writers that fill a flight folder file by file (the
    importers); ``overwrite_hint`` ends the message for a non-empty folder, also the one
    a concurrent run finds (a command line names its option)."""
    with atomic_output_dir(folder, overwrite=overwrite, may_replace=only_flight_entries,
                           overwrite_hint=overwrite_hint) as tmp:
        yield tmp


def write_flight(flight: Flight, folder: StrPath, overwrite: bool = False,
                 camera_name: str = "turbinefit",
                 extra_texts: Mapping[str, str] | None = None,
                 images: Iterable[NDArray[np.uint8]] | None = None,
                 camera: PinholeCamera | None = None,
                 overwrite_hint: str = OVERWRITE_HINT,
                 heatmap_dtype: HeatmapDtype = WRITTEN_HEATMAP_DTYPE,
                 after_images: Callable[[], Mapping[str, str]] | None = None) -> Path:
    """Write ``flight`` as a flight folder, atomically (layout in the module docstring).

    Everything is written into a hidden temporary sibling of ``folder`` and renamed into
    place at the end; on any error nothing changes and no temporary files remain.

    Args:
        flight: the flight; heat-maps are written as ``heatmap_dtype`` (converted), one
            ``np.save`` per keyframe. Optional files are written when present.
        folder: destination. Missing parents are created. An existing empty directory is
            replaced. An existing non-empty directory is refused with an
            :class:`InputError` unless ``overwrite=True``, and even then only if it contains
            nothing but flight-folder entries (a guard against ``overwrite`` on a wrong
            path). Rewriting the folder a flight was memory-mapped from is safe.
        overwrite: replace an existing non-empty flight folder.
        camera_name: ``camera_name`` written to ``camera.yaml``.
        extra_texts: further text files to write with the rest, ``{name: text}``; each name
            must be one of :data:`FLIGHT_ENTRIES` that the flight does not provide (i.e.
            ``simulation.yaml``), so that a folder ``write_flight`` wrote can always be
            replaced by it.
        images: the keyframes' photos, RGB uint8 (H, W, 3) at the size of ``camera``, in
            keyframe order (e.g. a generator: each is encoded and dropped), written as
            ``images/<t>.png``.
        camera: the photos' camera, written to ``camera.yaml``; None = ``flight.camera``
            (maps at the photos' size). The flight's heat-maps may be smaller: then
            ``flight.camera`` must be ``camera`` scaled to them (:func:`scaled_camera`),
            so that reading the folder back gives the same flight.
        overwrite_hint: ends the message refusing a non-empty folder.
        heatmap_dtype: ``float16`` (default: half the bytes of float32, values to within
            2.5e-4) or ``float32`` (the values exactly).
        after_images: gives further texts (as ``extra_texts``) once the photos are
            written, e.g. what they show.

    Returns:
        The folder written.

    Raises:
        InputError: naming the destination (file) for unwritable data or I/O failures.
    """
    root = Path(folder)
    if heatmap_dtype not in ("float16", "float32"):
        raise ValueError(f"heatmap_dtype must be float16 or float32, got {heatmap_dtype!r}")
    dtype = np.dtype(heatmap_dtype).newbyteorder("<")
    n = flight.num_keyframes
    photo_camera = camera or flight.camera
    if not _same_camera(scaled_camera(photo_camera, flight.camera.width, flight.camera.height),
                        flight.camera):
        raise ValueError(f"the flight's camera is not the {photo_camera.width}x"
                         f"{photo_camera.height} photo camera scaled to its heat-maps")
    shape = (NUM_CHANNELS, flight.camera.height, flight.camera.width)
    if len(flight.heatmaps) != n or (flight.heatmaps.height, flight.heatmaps.width) != shape[1:]:
        raise InputError(f"{len(flight.heatmaps)} heat-maps of {flight.heatmaps.height}x"
                         f"{flight.heatmaps.width} for {n} keyframes of a "
                         f"{shape[2]}x{shape[1]} camera", path=root / HEATMAP_DIR)
    # Format (and so validate) all text before touching the disk; errors name final paths.
    texts = {
        CAMERA_FILE: format_camera_yaml(photo_camera, camera_name),
        KEYFRAMES_FILE: format_tum(flight.timestamps, flight.world_T_cam, root / KEYFRAMES_FILE,
                                   "keyframe poses world_T_cam (camera-to-world)"),
        TURBINE_FILE: format_turbine_yaml(flight.turbine, "initial turbine parameters",
                                          root / TURBINE_FILE),
    }
    if flight.odometry is not None:
        texts[ODOMETRY_FILE] = format_tum(flight.timestamps, flight.odometry,
                                          root / ODOMETRY_FILE, "odometry world_T_cam")
    if flight.gt_world_T_cam is not None:
        texts[GT_POSES_FILE] = format_tum(flight.timestamps, flight.gt_world_T_cam,
                                          root / GT_POSES_FILE, "ground-truth world_T_cam")
    if flight.position_sigma is not None:
        texts[SIGMA_FILE] = format_position_sigmas(flight.timestamps, flight.position_sigma)
    if flight.gt_turbine is not None:
        texts[GT_TURBINE_FILE] = format_turbine_yaml(
            flight.gt_turbine, "ground-truth turbine parameters", root / GT_TURBINE_FILE)
    for name, text in (extra_texts or {}).items():
        if name not in FLIGHT_ENTRIES - _DATA_ENTRIES:
            raise ValueError(f"extra_texts: {name!r} is not an extra flight-folder file "
                             f"(allowed: {', '.join(sorted(FLIGHT_ENTRIES - _DATA_ENTRIES))})")
        texts[name] = text

    with atomic_output_dir(root, overwrite=overwrite, may_replace=only_flight_entries,
                           overwrite_hint=overwrite_hint) as tmp:
        for name, text in texts.items():
            write_text_atomic(tmp / name, text, fsync=False)
        hm_dir = tmp / HEATMAP_DIR
        hm_dir.mkdir()
        for k, t in enumerate(flight.timestamps.tolist()):
            arr = np.ascontiguousarray(flight.heatmaps[k], dtype=dtype)
            if arr.shape != shape:  # pragma: no cover - HeatmapStack guarantees it
                raise InputError(f"heat-map {k} has shape {arr.shape}, expected {shape}",
                                 path=root / HEATMAP_DIR / heatmap_filename(t))
            try:
                with open(hm_dir / heatmap_filename(t), "wb") as f:
                    np.save(f, arr, allow_pickle=False)
            except OSError as e:
                raise write_error(e, root / HEATMAP_DIR / heatmap_filename(t)) from e
        if images is not None:
            _write_images(tmp / IMAGE_DIR, root / IMAGE_DIR, flight, images, photo_camera)
        for name, text in (after_images() if after_images is not None else {}).items():
            if name not in FLIGHT_ENTRIES - _DATA_ENTRIES - set(texts):
                raise ValueError(f"after_images: {name!r} is not an extra flight-folder file")
            write_text_atomic(tmp / name, text, fsync=False)
    return root


def _same_camera(a: PinholeCamera, b: PinholeCamera) -> bool:
    """Whether two cameras agree (size, distortion; intrinsics to 1e-9 relative)."""
    ka, kb = (np.array([c.fx, c.fy, c.cx, c.cy, c.skew]) for c in (a, b))
    return ((a.width, a.height, a.distortion) == (b.width, b.height, b.distortion)
            and bool(np.allclose(ka, kb, rtol=1e-9, atol=1e-9)))


def _write_images(tmp_dir: Path, final_dir: Path, flight: Flight,
                  images: Iterable[NDArray[np.uint8]], camera: PinholeCamera) -> None:
    from turbinefit.io.images import encode_png

    tmp_dir.mkdir()
    want = (camera.height, camera.width, 3)
    count = 0
    for t, img in zip(flight.timestamps.tolist(), images, strict=False):
        name = keyframe_stem(t) + ".png"
        if img.shape != want or img.dtype != np.uint8:
            raise InputError(f"photo is {img.dtype} {img.shape}, expected uint8 {want}",
                             path=final_dir / name)
        try:
            (tmp_dir / name).write_bytes(encode_png(img))
        except OSError as e:
            raise write_error(e, final_dir / name) from e
        count += 1
    if count != flight.num_keyframes:
        raise InputError(f"{count} photos for {flight.num_keyframes} keyframes", path=final_dir)
