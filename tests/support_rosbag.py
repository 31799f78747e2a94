"""Plain helpers of the ROS bag tests: write a flight folder's photos, camera and poses as a
ROS 1 bag or a ROS 2 bag (sqlite3 or MCAP) with ``rosbags``' writers."""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from scipy.spatial.transform import Rotation, Slerp

from turbinefit.geometry.se3 import SE3
from turbinefit.io import read_tum
from turbinefit.io.camera_yaml import read_camera_yaml

#: The bags' clock: a flight's timestamp t is the stamp BASE_NS + t seconds.
BASE_NS = 1_700_000_000 * 1_000_000_000


@dataclass
class BagSpec:
    """What :func:`write_flight_bag` writes.

    kind: "ros1" (``.bag``), "mcap" or "sqlite3" (ROS 2 folders). compressed: the photos as
    CompressedImage (their PNG bytes), else Image in ``encoding``. rate: odometry samples
    per keyframe interval (they include the keyframes' stamps). body_T_cam: written to
    /tf_static (base_link -> camera frame), the odometry then gives world_T_body.
    pose_stamped: PoseStamped instead of Odometry. camera_info: write it. images: write
    them. stamp_shift_s: shift the images' stamps against the poses'.
    """

    kind: str = "ros1"
    compressed: bool = False
    encoding: str = "rgb8"
    rate: int = 3
    body_T_cam: SE3 | None = None
    pose_stamped: bool = False
    camera_info: bool = True
    images: bool = True
    stamp_shift_s: float = 0.0


IMAGE_TOPIC = "/cam/image_raw"
INFO_TOPIC = "/cam/camera_info"
ODOM_TOPIC = "/odom"
POSE_TOPIC = "/pose"


def _stamp(ts: Any, t_ns: int) -> Any:
    return ts.types["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)


def _header(ts: Any, t_ns: int, frame: str) -> Any:
    cls = ts.types["std_msgs/msg/Header"]
    kw = {"seq": 0} if "seq" in cls.__dataclass_fields__ else {}
    return cls(stamp=_stamp(ts, t_ns), frame_id=frame, **kw)


def _pose(ts: Any, wxyz_xyz: np.ndarray) -> Any:
    w, x, y, z, px, py, pz = (float(v) for v in wxyz_xyz)
    return ts.types["geometry_msgs/msg/Pose"](
        position=ts.types["geometry_msgs/msg/Point"](x=px, y=py, z=pz),
        orientation=ts.types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w))


def _pixels(path: Path, encoding: str) -> tuple[np.ndarray, int]:
    rgb = np.asarray(Image.open(path).convert("RGB"))
    if encoding == "rgb8":
        return rgb, 3
    if encoding == "bgr8":
        return rgb[:, :, ::-1], 3
    if encoding == "mono8":
        return rgb[:, :, 0], 1
    return np.dstack([rgb[:, :, ::-1], np.full(rgb.shape[:2], 255, np.uint8)]), 4  # bgra8


def odometry_samples(stamps: np.ndarray, poses: SE3, rate: int) -> tuple[np.ndarray, SE3]:
    """``rate`` poses per interval of ``stamps`` (the stamps' own among them): slerp and
    linear positions, as a recorder at a higher rate would see a smooth motion."""
    t = np.concatenate([np.linspace(a, b, rate, endpoint=False)
                        for a, b in itertools.pairwise(stamps)] + [stamps[-1:]])
    rot = Rotation.from_quat(poses.wxyz[:, [1, 2, 3, 0]])
    q = Slerp(stamps, rot)(t).as_quat()[:, [3, 0, 1, 2]]
    p = np.stack([np.interp(t, stamps, poses.translation[:, i]) for i in range(3)], -1)
    return t, SE3.from_rotation_translation(q, p)


def write_flight_bag(flight: Path, bag: Path, spec: BagSpec | None = None,
                     poses: SE3 | None = None) -> Path:
    """Write ``flight``'s photos, camera and keyframe poses (or ``poses``) as a bag."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    spec = spec or BagSpec()
    t, kf = read_tum(flight / "keyframes.txt")
    kf = kf if poses is None else poses
    camera = read_camera_yaml(flight / "camera.yaml")
    ros1 = spec.kind == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:  # rosbags' noetic store has no tf2_msgs
        from rosbags.typesys import get_types_from_msg

        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                       "tf2_msgs/msg/TFMessage"))
    T = ts.types
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    if ros1:
        writer: Any = Writer1(bag)
    else:
        plugin = StoragePlugin.MCAP if spec.kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(bag, version=9, storage_plugin=plugin)
    msgs: list[tuple[int, str, Any]] = []
    frame = "cam_optical"
    for k, tk in enumerate(t.tolist()):
        t_ns = BASE_NS + round((tk + spec.stamp_shift_s) * 1e9)
        if spec.images:
            path = flight / "images" / f"{tk:.6f}.png"
            if spec.compressed:
                msg = T["sensor_msgs/msg/CompressedImage"](
                    header=_header(ts, t_ns, frame), format="png",
                    data=np.frombuffer(path.read_bytes(), np.uint8))
            else:
                px, ch = _pixels(path, spec.encoding)
                msg = T["sensor_msgs/msg/Image"](
                    header=_header(ts, t_ns, frame), height=px.shape[0], width=px.shape[1],
                    encoding=spec.encoding, is_bigendian=0, step=px.shape[1] * ch,
                    data=np.ascontiguousarray(px).ravel())
            msgs.append((t_ns, IMAGE_TOPIC, msg))
        if spec.camera_info and k == 0:
            cls = T["sensor_msgs/msg/CameraInfo"]
            upper = "K" in cls.__dataclass_fields__
            mats = {"D": np.asarray(camera.distortion, float), "K": camera.K.ravel(),
                    "R": np.eye(3).ravel(),
                    "P": np.hstack([camera.K, np.zeros((3, 1))]).ravel()}
            msgs.append((t_ns, INFO_TOPIC, cls(
                header=_header(ts, t_ns, frame), height=camera.height, width=camera.width,
                distortion_model="plumb_bob", binning_x=0, binning_y=0,
                roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0,
                                                          width=0, do_rectify=False),
                **{(n if upper else n.lower()): v for n, v in mats.items()})))
    body = kf if spec.body_T_cam is None else kf @ spec.body_T_cam.inverse()
    ot, op = odometry_samples(t, body, spec.rate)
    for tk, pose in zip(ot.tolist(), op.wxyz_xyz, strict=True):
        t_ns = BASE_NS + round(tk * 1e9)
        if spec.pose_stamped:
            msgs.append((t_ns, POSE_TOPIC, T["geometry_msgs/msg/PoseStamped"](
                header=_header(ts, t_ns, "odom"), pose=_pose(ts, pose))))
            continue
        cov = np.zeros(36)
        v3 = T["geometry_msgs/msg/Vector3"]
        twist = T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=v3(x=0.0, y=0.0, z=0.0),
                                               angular=v3(x=0.0, y=0.0, z=0.0)),
            covariance=cov)
        msgs.append((t_ns, ODOM_TOPIC, T["nav_msgs/msg/Odometry"](
            header=_header(ts, t_ns, "odom"), child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(ts, pose),
                                                           covariance=cov),
            twist=twist)))
    if spec.body_T_cam is not None:
        w, x, y, z, px, py, pz = spec.body_T_cam.wxyz_xyz.tolist()
        tf = T["geometry_msgs/msg/TransformStamped"](
            header=_header(ts, BASE_NS, "base_link"), child_frame_id=frame,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=px, y=py, z=pz),
                rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)))
        msgs.append((BASE_NS, "/tf_static", T["tf2_msgs/msg/TFMessage"](transforms=[tf])))
    with writer:
        conns: dict[str, Any] = {}
        for t_ns, topic, msg in sorted(msgs, key=lambda m: m[0]):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=ts)
            writer.write(conns[topic], t_ns, ser(msg, msg.__msgtype__))
    return bag
