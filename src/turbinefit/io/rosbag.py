"""Reading ROS bags for ``turbinefit import rosbag``: images, camera_info, poses, /tf_static.

Bags are read with ``rosbags`` (pure Python, the optional ``ros`` extra: ``pip install
turbinefit[ros]``; imported only here, when a bag is opened): ROS 1 ``.bag`` files and
ROS 2 bags (a folder with ``metadata.yaml``, or one ``.db3`` / ``.mcap`` file). ROS 2 bags
without embedded message definitions are read with the definitions of the newest ROS 2
release ``rosbags`` knows.

What is read, and what it becomes:

* ``sensor_msgs/Image`` (encodings in :data:`RAW_ENCODINGS`, rows of ``step`` bytes) ->
  PNG bytes; ``sensor_msgs/CompressedImage`` -> its JPEG or PNG bytes as they are (the
  kind from the bytes' signature, not from ``format``). Stamps: ``header.stamp``.
* ``sensor_msgs/CameraInfo`` -> a :class:`~turbinefit.geometry.camera.PinholeCamera`
  (``K``, ``D``, ``distortion_model``, size; checked as :mod:`turbinefit.io.camera_yaml`
  checks a ``camera.yaml``).
* ``nav_msgs/Odometry`` (``pose.pose``), ``geometry_msgs/PoseStamped`` (``pose``) or
  ``PoseWithCovarianceStamped`` (``pose.pose``) -> :class:`PoseSamples`, the pose of
  the body frame (``child_frame_id``) in the ``header.frame_id`` frame, at
  ``header.stamp``; :func:`interpolate_poses` gives them at other stamps (positions
  linearly, orientations by slerp, ``scipy.spatial.transform``).
* ``tf2_msgs/TFMessage`` on ``/tf_static`` -> :func:`static_transform`, the transform
  between two frames along the static tree.

Times are integer nanoseconds (``sec * 10**9 + nanosec``) here; the flight folder gets
seconds. Every problem is an :class:`~turbinefit.errors.InputError` naming the bag (and
the topic and stamp where there is one).
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import InputError, TurbinefitError
from turbinefit.geometry.camera import PinholeCamera
from turbinefit.geometry.se3 import SE3

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_WITH_COVARIANCE = "geometry_msgs/msg/PoseWithCovarianceStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
IMAGE_TYPES = (IMAGE, COMPRESSED_IMAGE)
POSE_TYPES = (POSE_STAMPED, POSE_WITH_COVARIANCE)
TF_STATIC_TOPIC = "/tf_static"

#: ``sensor_msgs/Image`` encodings read: name -> (bytes per pixel, channel order to RGB,
#: or None for grey).
RAW_ENCODINGS: dict[str, tuple[int, tuple[int, ...] | None]] = {
    "rgb8": (3, (0, 1, 2)), "bgr8": (3, (2, 1, 0)), "rgba8": (4, (0, 1, 2)),
    "bgra8": (4, (2, 1, 0)), "mono8": (1, None), "8UC1": (1, None),
}
_SIGNATURES = {b"\xff\xd8\xff": ".jpg", b"\x89PNG\r\n\x1a\n": ".png"}

ROS_HINT = "reading ROS bags needs the rosbags package: pip install turbinefit[ros]"


def stamp_ns(stamp: Any) -> int:
    """A ROS time (``sec``, ``nanosec``) in integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def stamp_text(t_ns: int) -> str:
    """A stamp for messages: seconds with nine decimals."""
    return f"{t_ns // 1_000_000_000}.{t_ns % 1_000_000_000:09d}"


def _check_bag_files(path: Path) -> None:
    """Refuse a bag that is missing or that is (or holds) a FIFO, device or socket rather
    than regular files (:mod:`turbinefit.io.limits`), before a reader opens and blocks."""
    from turbinefit.io.limits import check_input_file

    if not path.is_dir():
        check_input_file(path, missing="bag not found")
        return
    for entry in sorted(path.iterdir()):
        if entry.name == "metadata.yaml" or entry.suffix in (".db3", ".mcap", ".zstd"):
            check_input_file(entry)


class Bag:
    """An open ROS bag (a context manager): its topics, and its messages topic by topic."""

    def __init__(self, path: Path) -> None:
        try:
            from rosbags.highlevel import AnyReader
            from rosbags.typesys import Stores, get_typestore
        except ImportError:
            raise TurbinefitError(ROS_HINT) from None
        self.path = path
        _check_bag_files(path)
        try:
            self._reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
            self._reader.open()
        except Exception as exc:  # rosbags raises many kinds on a file that is not a bag
            raise InputError(f"cannot read as a ROS bag: {_reason(exc)}", path=path) from None
        self.topics: dict[str, str] = {name: info.msgtype or "?"
                                       for name, info in self._reader.topics.items()}

    def __enter__(self) -> Bag:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._reader.close()

    def of_types(self, types: tuple[str, ...]) -> list[str]:
        """The bag's topics of one of ``types``, sorted."""
        return sorted(t for t, m in self.topics.items() if m in types)

    def require(self, topic: str, types: tuple[str, ...], option: str) -> str:
        """``topic``'s message type, one of ``types``; else an InputError naming the topic
        (given by ``option``) and listing the bag's topics of those types."""
        have = self.topics.get(topic)
        if have in types:
            return have
        candidates = ", ".join(self.of_types(types)) or "none"
        what = " or ".join(types)
        problem = "no topic" if have is None else f"topic is {have}, not {what}:"
        raise InputError(f"{problem} {topic!r} ({option}); {what} topics in the bag: "
                         f"{candidates}", path=self.path)

    def messages(self, topic: str) -> Iterator[Any]:
        """The deserialised messages of ``topic``, in the bag's order."""
        conns = [c for c in self._reader.connections if c.topic == topic]
        if not conns:
            return
        try:
            for conn, _, raw in self._reader.messages(connections=conns):
                yield self._reader.deserialize(raw, conn.msgtype)
        except Exception as exc:
            raise InputError(f"cannot read {topic!r}: {_reason(exc)}", path=self.path) from None


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) < 200 else text[:197] + "..."


def open_bag(path: str | Path) -> Bag:
    """Open a ROS 1 or ROS 2 bag (see the module docstring); use it in a ``with``."""
    return Bag(Path(path))


# --------------------------------------------------------------------------- images

def image_file(msg: Any, msgtype: str, topic: str, bag: Path) -> tuple[str, bytes, int, int]:
    """(suffix ``.png`` / ``.jpg``, file bytes, width, height) of an image message: raw
    images encoded as PNG, compressed ones as they are."""
    from PIL import Image

    t = stamp_text(stamp_ns(msg.header.stamp))
    if msgtype == COMPRESSED_IMAGE:
        suffix = check_image(msg, msgtype, topic, bag)
        data = bytes(msg.data)
        try:
            with Image.open(io.BytesIO(data)) as im:
                width, height = im.size
        except Exception as exc:
            raise InputError(f"{topic!r} at {t}: unreadable {suffix[1:]} image "
                             f"({_reason(exc)})", path=bag) from None
        return suffix, data, int(width), int(height)
    pixels = raw_pixels(msg, topic, bag)
    buf = io.BytesIO()
    Image.fromarray(pixels, "L" if pixels.ndim == 2 else "RGB").save(
        buf, format="PNG", compress_level=3)
    return ".png", buf.getvalue(), int(msg.width), int(msg.height)


def check_image(msg: Any, msgtype: str, topic: str, bag: Path) -> str:
    """The suffix an image message is written with (``.png`` / ``.jpg``); an InputError
    naming the topic and stamp for an encoding or compressed format that is not read."""
    t = stamp_text(stamp_ns(msg.header.stamp))
    if msgtype == IMAGE:
        if msg.encoding not in RAW_ENCODINGS:
            raise InputError(f"{topic!r} at {t}: unsupported image encoding {msg.encoding!r} "
                             f"(supported: {', '.join(RAW_ENCODINGS)}, and CompressedImage "
                             "JPEG/PNG)", path=bag)
        return ".png"
    head = bytes(msg.data[:8])
    suffix = next((s for sig, s in _SIGNATURES.items() if head.startswith(sig)), None)
    if suffix is None or "compresseddepth" in msg.format.lower():
        raise InputError(f"{topic!r} at {t}: compressed format {msg.format!r} is not a "
                         "JPEG or PNG photo", path=bag)
    return suffix


def raw_pixels(msg: Any, topic: str, bag: Path) -> NDArray[np.uint8]:
    """The pixels of a ``sensor_msgs/Image``: (H, W, 3) RGB, or (H, W) grey."""
    t = stamp_text(stamp_ns(msg.header.stamp))
    check_image(msg, IMAGE, topic, bag)
    channels, order = RAW_ENCODINGS[msg.encoding]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if h <= 0 or w <= 0 or step < w * channels or data.size < h * step:
        raise InputError(f"{topic!r} at {t}: {data.size} bytes do not hold a {w}x{h} "
                         f"{msg.encoding} image of step {step}", path=bag)
    rows = data[: h * step].reshape(h, step)[:, : w * channels].reshape(h, w, channels)
    if order is None:
        return np.ascontiguousarray(rows[:, :, 0])
    return np.ascontiguousarray(rows[:, :, list(order)])


def camera_from_info(msg: Any, topic: str, bag: Path) -> PinholeCamera:
    """The camera of a ``sensor_msgs/CameraInfo`` message (checked like a ``camera.yaml``;
    errors name the bag and topic)."""
    from turbinefit.io.camera_yaml import camera_from_mapping

    binning = (int(msg.binning_x), int(msg.binning_y))
    roi = msg.roi
    if max(binning) > 1 or (int(roi.width), int(roi.height)) != (0, 0):
        raise InputError(f"{topic!r}: binning {binning} or a region of interest is not "
                         "supported", path=bag)
    d = [float(x) for x in np.asarray(msg.d if hasattr(msg, "d") else msg.D).ravel()]
    k = [float(x) for x in np.asarray(msg.k if hasattr(msg, "k") else msg.K).ravel()]
    mapping = {
        "image_width": int(msg.width), "image_height": int(msg.height),
        "camera_matrix": {"rows": 3, "cols": 3, "data": k},
        "distortion_model": msg.distortion_model or ("plumb_bob" if d else ""),
        "distortion_coefficients": {"rows": 1, "cols": len(d), "data": d},
    }
    return camera_from_mapping(mapping, f"{bag}: {topic}")


def camera_info_topic_near(image_topic: str, topics: dict[str, str]) -> str | None:
    """The CameraInfo topic next to an image topic: ``<ns>/camera_info`` for the image
    topic's namespace or any above it (``/cam/image_raw/compressed`` ->
    ``/cam/image_raw/camera_info``, ``/cam/camera_info``, ``/camera_info``)."""
    parts = image_topic.strip("/").split("/")
    for n in range(len(parts), -1, -1):
        candidate = "/" + "/".join([*parts[:n], "camera_info"])
        if topics.get(candidate) == CAMERA_INFO:
            return candidate
    return None


# --------------------------------------------------------------------------- poses

@dataclass(frozen=True)
class PoseSamples:
    """Poses of a body frame over time: ``world_T_body`` at ``stamps_ns`` (increasing).

    Attributes:
        stamps_ns: (N,) int64 nanoseconds, strictly increasing.
        world_T_body: (N,) poses.
        world_frame: the messages' ``header.frame_id``.
        body_frame: the Odometry's ``child_frame_id`` ('' for a PoseStamped).
    """

    stamps_ns: NDArray[np.int64]
    world_T_body: SE3
    world_frame: str
    body_frame: str


def read_poses(bag: Bag, topic: str, msgtype: str) -> PoseSamples:
    """The poses of an Odometry, PoseStamped or PoseWithCovarianceStamped topic, sorted by
    header stamp (a repeated stamp keeps its first pose)."""
    stamps: list[int] = []
    rows: list[list[float]] = []
    world = body = ""
    for msg in bag.messages(topic):
        pose = msg.pose if msgtype == POSE_STAMPED else msg.pose.pose
        q, p = pose.orientation, pose.position
        stamps.append(stamp_ns(msg.header.stamp))
        rows.append([q.w, q.x, q.y, q.z, p.x, p.y, p.z])
        world = world or msg.header.frame_id
        body = body or getattr(msg, "child_frame_id", "")
    if not stamps:
        raise InputError(f"no messages on {topic!r}", path=bag.path)
    arr = np.array(rows, dtype=np.float64)
    norms = np.linalg.norm(arr[:, :4], axis=1)
    bad = np.nonzero(~np.isfinite(arr).all(axis=1) | (np.abs(norms - 1.0) > 1e-3))[0]
    if bad.size:
        k = int(bad[0])
        raise InputError(f"{topic!r} at {stamp_text(stamps[k])}: not a finite pose with a "
                         f"unit quaternion (norm {norms[k]:.6g})", path=bag.path)
    arr[:, :4] /= norms[:, None]
    t = np.array(stamps, dtype=np.int64)
    order = np.argsort(t, kind="stable")
    t, arr = t[order], arr[order]
    keep = np.concatenate([[True], np.diff(t) > 0])
    return PoseSamples(t[keep], SE3(arr[keep]), world, body)


def interpolate_poses(samples: PoseSamples, stamps_ns: NDArray[np.int64],
                      max_gap_ns: int) -> tuple[SE3, NDArray[np.bool_]]:
    """``world_T_body`` at ``stamps_ns``: positions linear, orientations slerped between the
    samples on either side (a stamp equal to a sample's takes it as it is).

    Returns the poses and which stamps have one: a stamp must coincide with a sample or lie
    between two samples at most ``max_gap_ns`` apart; the others get the identity.
    """
    from scipy.spatial.transform import Rotation, Slerp

    t = samples.stamps_ns
    q = np.asarray(stamps_ns, dtype=np.int64)
    right = np.searchsorted(t, q, side="left")  # first sample at or after each stamp
    inside = right < len(t)
    exact = inside & (t[np.minimum(right, len(t) - 1)] == q)
    left = right - 1
    between = inside & (left >= 0) & ~exact
    gap = t[np.minimum(right, len(t) - 1)] - t[np.maximum(left, 0)]
    ok = exact | (between & (gap <= max_gap_ns))
    out = SE3.identity((len(q),)).wxyz_xyz.copy()
    wxyz_xyz = samples.world_T_body.wxyz_xyz
    out[exact] = wxyz_xyz[right[exact]]
    idx = np.nonzero(ok & ~exact)[0]
    if idx.size and len(t) > 1:
        # seconds from the first sample: nanoseconds since the epoch overflow float64's
        # resolution (0.24 us at today's epoch seconds)
        ts = (t - t[0]).astype(np.float64) * 1e-9
        tq = (q[idx] - t[0]).astype(np.float64) * 1e-9
        rot = Rotation.from_quat(wxyz_xyz[:, [1, 2, 3, 0]])  # scipy: xyzw
        xyzw = Slerp(ts, rot)(tq).as_quat()
        a = (tq - ts[left[idx]]) / (ts[right[idx]] - ts[left[idx]])
        p0, p1 = wxyz_xyz[left[idx], 4:], wxyz_xyz[right[idx], 4:]
        out[idx, :4] = xyzw[:, [3, 0, 1, 2]]
        out[idx, 4:] = p0 + a[:, None] * (p1 - p0)
    return SE3(out), ok


# --------------------------------------------------------------------------- /tf_static

def read_static_transforms(bag: Bag) -> dict[tuple[str, str], SE3]:
    """``{(parent, child): parent_T_child}`` of every transform on ``/tf_static`` (none if
    the bag has no such topic; a later transform of a pair replaces an earlier one)."""
    out: dict[tuple[str, str], SE3] = {}
    if bag.topics.get(TF_STATIC_TOPIC) != TF_MESSAGE:
        return out
    for msg in bag.messages(TF_STATIC_TOPIC):
        for tf in msg.transforms:
            r, p = tf.transform.rotation, tf.transform.translation
            q = np.array([r.w, r.x, r.y, r.z], dtype=np.float64)
            n = float(np.linalg.norm(q))
            if not (np.isfinite(n) and abs(n - 1.0) < 1e-3):
                raise InputError(f"{TF_STATIC_TOPIC!r}: transform {tf.header.frame_id!r} -> "
                                 f"{tf.child_frame_id!r} has a quaternion of norm {n:.6g}",
                                 path=bag.path)
            pose = SE3(np.concatenate([q / n, [p.x, p.y, p.z]]))
            out[(tf.header.frame_id.lstrip("/"), tf.child_frame_id.lstrip("/"))] = pose
    return out


def static_transform(transforms: dict[tuple[str, str], SE3], a: str,
                     b: str) -> SE3 | None:
    """``a_T_b`` along the static transform tree (edges walked either way), or None when
    no chain joins the two frames."""
    a, b = a.lstrip("/"), b.lstrip("/")
    edges: dict[str, list[tuple[str, SE3]]] = {}
    for (parent, child), p_T_c in transforms.items():
        edges.setdefault(parent, []).append((child, p_T_c))
        edges.setdefault(child, []).append((parent, p_T_c.inverse()))
    found: dict[str, SE3] = {a: SE3.identity()}
    todo = [a]
    while todo:
        frame = todo.pop(0)
        if frame == b:
            return found[frame]
        for nxt, f_T_n in edges.get(frame, []):
            if nxt not in found:
                found[nxt] = found[frame] @ f_T_n
                todo.append(nxt)
    return None
