"""``turbinefit import rosbag``: a flight folder from a ROS 1 / ROS 2 bag
(:func:`turbinefit.jobs.import_rosbag.import_rosbag`)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from turbinefit.cli.common import DefaultsFormatter, number, positive_number

if TYPE_CHECKING:
    from turbinefit.geometry.se3 import SE3


def nonneg_number(text: str) -> float:
    v = number(text)
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"must be a non-negative number, got {text!r}")
    return v


def pose7(text: str) -> tuple[float, ...]:
    """``x,y,z,qx,qy,qz,qw`` (argparse type): seven finite numbers, a unit quaternion."""
    parts = text.split(",")
    try:
        if len(parts) != 7:
            raise ValueError
        v = tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected seven numbers x,y,z,qx,qy,qz,qw, got {text!r}") from None
    n = math.sqrt(sum(x * x for x in v[3:]))
    if not all(math.isfinite(x) for x in v) or abs(n - 1.0) > 1e-3:
        raise argparse.ArgumentTypeError(
            f"expected finite numbers and a unit quaternion (norm {n:.6g}), got {text!r}")
    return v


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p: argparse.ArgumentParser = sub.add_parser(
        "rosbag", help="a ROS 1 / ROS 2 bag (images, camera_info, odometry or poses)",
        formatter_class=DefaultsFormatter,
        description="Make a flight folder from a ROS bag (ROS 1 .bag; ROS 2 folder, .db3 or "
        ".mcap; needs turbinefit[ros]): camera.yaml from camera_info, the keyframes' images, "
        "and their camera poses world_T_cam (the pose topic interpolated to each image's "
        "header stamp, times body_T_cam) in keyframes.txt and odometry.txt, timestamps the "
        "images' header stamps in seconds. Keyframes: the first image, then each after "
        "--every-m metres travelled or --every-deg degrees turned. Camera frame: the ROS "
        "optical frame (z forward, x right, y down), as OpenCV's. Details in docs/rosbag.md.")
    p.add_argument("bag", metavar="BAG", type=Path, help="the bag (file or ROS 2 folder)")
    p.add_argument("--out", metavar="FLIGHT_DIR", type=Path, required=True,
                   help="flight folder to create")
    p.add_argument("--image-topic", required=True, metavar="TOPIC",
                   help="sensor_msgs/Image or CompressedImage topic")
    p.add_argument("--camera-info-topic", metavar="TOPIC",
                   help="sensor_msgs/CameraInfo topic (default: <ns>/camera_info next to the "
                   "image topic)")
    poses = p.add_mutually_exclusive_group(required=True)
    poses.add_argument("--odometry-topic", metavar="TOPIC", help="nav_msgs/Odometry topic")
    poses.add_argument("--pose-topic", metavar="TOPIC",
                       help="geometry_msgs/PoseStamped (or PoseWithCovarianceStamped) topic")
    p.add_argument("--every-m", type=nonneg_number, default=2.0, metavar="M",
                   help="new keyframe after M metres travelled since the last one")
    p.add_argument("--every-deg", type=nonneg_number, default=10.0, metavar="DEG",
                   help="... or DEG degrees turned (--every-m 0 --every-deg 0: every image)")
    p.add_argument("--body-T-cam", type=pose7, metavar="x,y,z,qx,qy,qz,qw",
                   help="the camera (optical frame) in the pose topic's body frame [m] "
                   "(default: from /tf_static, else the identity)")
    p.add_argument("--body-frame", metavar="FRAME",
                   help="body frame of the poses for the /tf_static lookup (default: the "
                   "Odometry's child_frame_id)")
    p.add_argument("--max-gap", type=positive_number, default=0.5, metavar="S",
                   help="an image must lie between two poses at most S seconds apart")
    p.add_argument("--skip-unposed", action="store_true",
                   help="drop images without a pose within --max-gap instead of refusing")
    p.add_argument("--turbine-yaml", type=Path, metavar="FILE",
                   help="initial turbine.yaml to copy in (fit needs one)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace FLIGHT_DIR if it exists (only if it holds nothing but a flight)")
    return p


def body_T_cam(values: tuple[float, ...] | None) -> SE3 | None:
    """The pose of ``--body-T-cam`` (xyzw on the command line, wxyz inside)."""
    if values is None:
        return None
    from turbinefit.geometry.se3 import SE3

    x, y, z, qx, qy, qz, qw = values
    return SE3.from_rotation_translation([qw, qx, qy, qz], [x, y, z])


def run(args: argparse.Namespace) -> int:
    from turbinefit.jobs.import_rosbag import RosbagOptions, import_rosbag

    options = RosbagOptions(
        image_topic=args.image_topic, odometry_topic=args.odometry_topic,
        pose_topic=args.pose_topic, camera_info_topic=args.camera_info_topic,
        every_m=args.every_m, every_deg=args.every_deg, body_T_cam=body_T_cam(args.body_T_cam),
        body_frame=args.body_frame, max_gap_s=args.max_gap, skip_unposed=args.skip_unposed,
        turbine_yaml=args.turbine_yaml)
    s = import_rosbag(args.bag, args.out, options, overwrite=args.overwrite)
    print(f"imported {s.keyframes} keyframes of {s.images} images ({s.distance_m:.1f} m, "
          f"{s.duration_s:.1f} s) from {s.bag} to {s.out_dir}")
    print(f"camera: {s.width}x{s.height} from {s.camera_info_topic}; poses: {s.pose_topic} "
          f"in frame {s.world_frame or '?'}; body_T_cam: {s.extrinsic}")
    for note in s.notes:
        print(f"note: {note}")
    return 0
