"""The ``import rosbag`` job: a flight folder from a ROS bag's images, camera_info and poses.

:func:`import_rosbag` reads the bag with :mod:`turbinefit.io.rosbag` and writes, atomically:

* ``camera.yaml``: the CameraInfo topic's first message (the image size must be the
  images');
* ``keyframes.txt`` and ``odometry.txt``: the same TUM poses ``world_T_cam`` of the camera at
  each keyframe, the pose topic's ``world_T_body`` interpolated to the image's
  ``header.stamp`` (slerp) times ``body_T_cam``; timestamps are the images' header stamps in
  seconds;
* ``images/<stamp %.6f>.png|.jpg``: the keyframes' images (raw ones as PNG, compressed
  ones' bytes as they are);
* ``turbine.yaml``: a copy of a given one (none otherwise: ``fit`` then needs one).

Keyframes: the first image, then each image whose camera has travelled ``every_m`` metres
(along the path through the images) or turned ``every_deg`` degrees since the last
keyframe. ``body_T_cam``: the option, else the ``/tf_static`` chain from the pose topic's
body frame to the images' ``header.frame_id``, else the identity (the poses are then the
camera's own, optical frame: z forward, x right, y down).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from turbinefit.errors import InputError
from turbinefit.geometry.se3 import SE3, quat_conjugate, quat_log, quat_multiply
from turbinefit.io.atomic import StrPath, read_text, write_bytes_atomic, write_text_atomic
from turbinefit.io.camera_yaml import format_camera_yaml
from turbinefit.io.flight_folder import (
    CAMERA_FILE,
    IMAGE_DIR,
    KEYFRAMES_FILE,
    ODOMETRY_FILE,
    TURBINE_FILE,
    check_flight_destination,
    flight_output_dir,
)
from turbinefit.io.heatmap_files import keyframe_stem
from turbinefit.io.tum import format_tum
from turbinefit.jobs.outputs import OVERWRITE_HINT, check_not_input


@dataclass(frozen=True)
class RosbagOptions:
    """What to read from the bag and how to choose keyframes.

    Attributes:
        image_topic: a ``sensor_msgs/Image`` or ``CompressedImage`` topic.
        odometry_topic: a ``nav_msgs/Odometry`` topic (or give ``pose_topic``).
        pose_topic: a ``geometry_msgs/PoseStamped`` (or ``PoseWithCovarianceStamped``) topic.
        camera_info_topic: the ``sensor_msgs/CameraInfo`` topic; None = ``<ns>/camera_info``
            next to the image topic.
        every_m: a new keyframe after this distance travelled [m] ...
        every_deg: ... or this rotation [deg] since the last keyframe (0 and 0: every image).
        body_T_cam: the camera's pose in the pose topic's body frame; None = from
            ``/tf_static``, else the identity.
        body_frame: the body frame for the ``/tf_static`` lookup; None = the Odometry's
            ``child_frame_id``.
        max_gap_s: an image must lie between two poses at most this far apart [s] (or
            at the stamp of one).
        skip_unposed: drop images without a pose in reach instead of refusing the bag.
        turbine_yaml: a ``turbine.yaml`` to copy into the flight.
    """

    image_topic: str
    odometry_topic: str | None = None
    pose_topic: str | None = None
    camera_info_topic: str | None = None
    every_m: float = 2.0
    every_deg: float = 10.0
    body_T_cam: SE3 | None = None
    body_frame: str | None = None
    max_gap_s: float = 0.5
    skip_unposed: bool = False
    turbine_yaml: Path | None = None


@dataclass
class RosbagSummary:
    """What :func:`import_rosbag` read and wrote."""

    bag: str
    out_dir: str
    image_topic: str
    camera_info_topic: str
    pose_topic: str
    images: int
    keyframes: int
    width: int
    height: int
    world_frame: str
    camera_frame: str
    extrinsic: str
    duration_s: float
    distance_m: float
    turbine_yaml: bool
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def select_keyframes(world_T_cam: SE3, every_m: float, every_deg: float) -> NDArray[np.int_]:
    """Indices of the keyframes among poses in time order: the first, then each pose whose
    path length since the last keyframe reaches ``every_m`` [m] or whose rotation from it
    reaches ``every_deg`` [deg]."""
    pos = world_T_cam.translation
    steps = np.concatenate([[0.0], np.linalg.norm(np.diff(pos, axis=0), axis=1)])
    path = np.cumsum(steps)
    keep = [0]
    for k in range(1, len(world_T_cam)):
        last = keep[-1]
        dq = quat_multiply(quat_conjugate(world_T_cam.wxyz[last]), world_T_cam.wxyz[k])
        angle = math.degrees(float(np.linalg.norm(quat_log(dq))))
        if path[k] - path[last] >= every_m or angle >= every_deg:
            keep.append(k)
    return np.array(keep, dtype=np.int_)


def import_rosbag(bag_path: StrPath, out_dir: StrPath, options: RosbagOptions, *,
                  overwrite: bool = False) -> RosbagSummary:
    """Write the flight folder of a ROS bag (see the module docstring).

    Raises:
        InputError: naming the bag and topic (and stamp) of the first problem: a missing
            topic (the bag's topics of that type listed), no images, an unsupported
            encoding, an image without a pose in reach, ...; nothing is written then.
    """
    from turbinefit.io import rosbag as rb
    from turbinefit.io.turbine_yaml import read_turbine_yaml

    bag, out = Path(bag_path), Path(out_dir)
    inputs = [bag] + ([options.turbine_yaml] if options.turbine_yaml else [])
    check_not_input(out, inputs)
    check_flight_destination(out, overwrite, OVERWRITE_HINT)
    if (options.odometry_topic is None) == (options.pose_topic is None):
        raise InputError("give one of --odometry-topic and --pose-topic")
    turbine_text = None
    if options.turbine_yaml is not None:
        read_turbine_yaml(options.turbine_yaml)  # checked before copying
        turbine_text = read_text(options.turbine_yaml)
    notes: list[str] = []
    with rb.open_bag(bag) as b:
        image_type = b.require(options.image_topic, rb.IMAGE_TYPES, "--image-topic")
        if options.odometry_topic is not None:
            pose_topic = options.odometry_topic
            pose_type = b.require(pose_topic, (rb.ODOMETRY,), "--odometry-topic")
        else:
            pose_topic = options.pose_topic or ""
            pose_type = b.require(pose_topic, rb.POSE_TYPES, "--pose-topic")
        info_topic = options.camera_info_topic or rb.camera_info_topic_near(
            options.image_topic, b.topics)
        if info_topic is None:
            listed = ", ".join(b.of_types((rb.CAMERA_INFO,))) or "none"
            raise InputError(f"no camera_info topic next to {options.image_topic!r}: give "
                             f"--camera-info-topic ({rb.CAMERA_INFO} topics in the bag: "
                             f"{listed})", path=bag)
        b.require(info_topic, (rb.CAMERA_INFO,), "--camera-info-topic")
        info = next(iter(b.messages(info_topic)), None)
        if info is None:
            raise InputError(f"no messages on {info_topic!r}", path=bag)
        camera = rb.camera_from_info(info, info_topic, bag)

        # pass 1: the images' stamps and frame
        stamps: list[int] = []
        camera_frame = ""
        for msg in b.messages(options.image_topic):
            rb.check_image(msg, image_type, options.image_topic, bag)
            stamps.append(rb.stamp_ns(msg.header.stamp))
            camera_frame = camera_frame or msg.header.frame_id
        if not stamps:
            raise InputError(f"no images on {options.image_topic!r}", path=bag)
        t_ns = np.array(stamps, dtype=np.int64)
        order = np.argsort(t_ns, kind="stable")
        dup = np.nonzero(np.diff(t_ns[order]) == 0)[0]
        if dup.size:
            raise InputError(f"{options.image_topic!r}: two images at "
                             f"{rb.stamp_text(int(t_ns[order][dup[0]]))}", path=bag)

        samples = rb.read_poses(b, pose_topic, pose_type)
        world_T_body, ok = rb.interpolate_poses(samples, t_ns[order],
                                                round(options.max_gap_s * 1e9))
        if not ok.all():
            first = rb.stamp_text(int(t_ns[order][np.nonzero(~ok)[0][0]]))
            reach = (f"between {rb.stamp_text(int(samples.stamps_ns[0]))} and "
                     f"{rb.stamp_text(int(samples.stamps_ns[-1]))}, gaps at most "
                     f"{options.max_gap_s:g} s")
            if not options.skip_unposed:
                raise InputError(f"{options.image_topic!r}: image at {first} has no pose on "
                                 f"{pose_topic!r} within the interpolation window ({reach}; "
                                 "--skip-unposed drops such images)", path=bag)
            notes.append(f"dropped {int((~ok).sum())} image(s) without a pose ({reach}), "
                         f"the first at {first}")
            if not ok.any():
                raise InputError(f"{options.image_topic!r}: no image has a pose on "
                                 f"{pose_topic!r} ({reach})", path=bag)
            order, world_T_body = order[ok], world_T_body[ok]

        body_T_cam, extrinsic = _extrinsic(b, options, samples.body_frame, camera_frame,
                                           notes)
        world_T_cam = world_T_body @ body_T_cam
        chosen = select_keyframes(world_T_cam, options.every_m, options.every_deg)
        kf_index = order[chosen]  # message indices in the topic, in time order
        kf_ns = t_ns[kf_index]
        kf_poses = world_T_cam[chosen]
        seconds = kf_ns.astype(np.float64) * 1e-9
        tum = format_tum(seconds, kf_poses, out / KEYFRAMES_FILE,
                         f"world_T_cam from {pose_topic} at the stamps of {options.image_topic}")
        texts = {CAMERA_FILE: format_camera_yaml(camera, "rosbag"), KEYFRAMES_FILE: tum,
                 ODOMETRY_FILE: tum}
        if turbine_text is not None:
            texts[TURBINE_FILE] = turbine_text

        with flight_output_dir(out, overwrite, OVERWRITE_HINT) as tmp:
            for name, text in texts.items():
                write_text_atomic(tmp / name, text, fsync=False)
            (tmp / IMAGE_DIR).mkdir()
            wanted = {int(i): float(s) for i, s in zip(kf_index, seconds, strict=True)}
            for i, msg in enumerate(b.messages(options.image_topic)):
                if i not in wanted:
                    continue
                suffix, data, w, h = rb.image_file(msg, image_type, options.image_topic, bag)
                if (w, h) != (camera.width, camera.height):
                    raise InputError(
                        f"{options.image_topic!r} at {rb.stamp_text(int(t_ns[i]))}: image is "
                        f"{w}x{h} but {info_topic!r} says {camera.width}x{camera.height}",
                        path=bag)
                write_bytes_atomic(tmp / IMAGE_DIR / (keyframe_stem(wanted[i]) + suffix), data,
                                   fsync=False)

    if turbine_text is None:
        notes.append("no turbine.yaml: fit needs one (--turbine-yaml FILE, or write it by hand)")
    pos = world_T_cam.translation
    return RosbagSummary(
        bag=str(bag), out_dir=str(out), image_topic=options.image_topic,
        camera_info_topic=info_topic, pose_topic=pose_topic, images=len(stamps),
        keyframes=len(chosen), width=camera.width, height=camera.height,
        world_frame=samples.world_frame, camera_frame=camera_frame, extrinsic=extrinsic,
        duration_s=float(seconds[-1] - seconds[0]),
        distance_m=float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum()),
        turbine_yaml=turbine_text is not None, notes=notes)


def _extrinsic(b: Any, options: RosbagOptions, odometry_body: str, camera_frame: str,
               notes: list[str]) -> tuple[SE3, str]:
    """``body_T_cam`` and where it came from (notes say when it is the identity)."""
    from turbinefit.io.rosbag import TF_STATIC_TOPIC, read_static_transforms, static_transform

    if options.body_T_cam is not None:
        return options.body_T_cam, "--body-T-cam"
    body = options.body_frame or odometry_body
    transforms = read_static_transforms(b)
    if transforms and body and camera_frame:
        found = static_transform(transforms, body, camera_frame)
        if found is not None:
            return found, f"{TF_STATIC_TOPIC}: {body} -> {camera_frame}"
    if not transforms:
        why = f"the bag has no {TF_STATIC_TOPIC}"
    elif not body:
        why = "the pose topic names no body frame (--body-frame)"
    elif not camera_frame:
        why = "the images name no frame"
    else:
        why = f"{TF_STATIC_TOPIC} joins no chain from {body!r} to {camera_frame!r}"
    notes.append(f"body_T_cam is the identity ({why}; --body-T-cam sets it): the poses are "
                 "taken as the camera's own (optical frame: z forward, x right, y down)")
    return SE3.identity(), "identity"
