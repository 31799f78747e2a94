"""Reading ROS bags: pose interpolation, /tf_static chains, image encodings, camera_info and
bags that cannot be read."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support import assert_poses_close
from support_rosbag import BASE_NS, INFO_TOPIC, BagSpec, write_flight_bag

from turbinefit.errors import InputError, TurbinefitError
from turbinefit.geometry.se3 import SE3
from turbinefit.io import rosbag as rb


def _screw(t: np.ndarray) -> SE3:
    """A motion at constant velocity and constant angular rate about a fixed axis."""
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    xyzw = Rotation.from_rotvec(np.outer(0.4 * t, axis)).as_quat()
    pos = np.stack([2.0 * t, -1.0 * t + 3.0, 0.5 * t], -1)
    return SE3.from_rotation_translation(xyzw[:, [3, 0, 1, 2]], pos)


def _samples(t_s: np.ndarray) -> rb.PoseSamples:
    return rb.PoseSamples((BASE_NS + np.round(t_s * 1e9)).astype(np.int64), _screw(t_s),
                          "odom", "base_link")


def test_interpolation_is_exact_on_a_constant_rate_motion() -> None:
    samples = _samples(np.arange(0.0, 2.01, 0.2))
    t = np.array([0.0, 0.05, 0.33, 1.0, 1.99])
    poses, ok = rb.interpolate_poses(samples, BASE_NS + np.round(t * 1e9).astype(np.int64),
                                     250_000_000)
    assert ok.all()
    assert_poses_close(poses, _screw(t), 1e-9)


def test_a_stamp_needs_poses_close_on_both_sides() -> None:
    samples = _samples(np.array([0.0, 0.1, 1.0, 1.1]))
    t = np.array([-0.01, 0.0, 0.05, 0.5, 1.0, 1.05, 1.1, 1.2])
    _, ok = rb.interpolate_poses(samples, BASE_NS + np.round(t * 1e9).astype(np.int64),
                                 200_000_000)
    assert ok.tolist() == [False, True, True, False, True, True, True, False]


def test_static_transform_walks_the_tree_both_ways() -> None:
    rng = np.random.default_rng(0)
    a_T_b, b_T_c, a_T_d = (SE3.from_rotation_translation(
        Rotation.random(random_state=rng.integers(1000)).as_quat()[[3, 0, 1, 2]],
        rng.normal(size=3)) for _ in range(3))
    tf = {("a", "b"): a_T_b, ("b", "c"): b_T_c, ("a", "d"): a_T_d, ("x", "y"): a_T_b}
    assert_poses_close(rb.static_transform(tf, "a", "c"), a_T_b @ b_T_c)
    assert_poses_close(rb.static_transform(tf, "d", "/c"), a_T_d.inverse() @ a_T_b @ b_T_c)
    assert_poses_close(rb.static_transform(tf, "c", "c"), SE3.identity())
    assert rb.static_transform(tf, "a", "y") is None
    assert rb.static_transform(tf, "a", "nowhere") is None


def test_camera_info_is_found_next_to_the_image_topic() -> None:
    topics = {"/cam/camera_info": rb.CAMERA_INFO, "/other/camera_info": rb.CAMERA_INFO}
    assert rb.camera_info_topic_near("/cam/image_raw", topics) == "/cam/camera_info"
    assert rb.camera_info_topic_near("/cam/image_raw/compressed", topics) == "/cam/camera_info"
    assert rb.camera_info_topic_near("/left/image", topics) is None
    assert rb.camera_info_topic_near("/image", {"/camera_info": rb.CAMERA_INFO}) == "/camera_info"


def _image(encoding: str, pixels: np.ndarray, step: int) -> SimpleNamespace:
    h, w = pixels.shape[:2]
    rows = pixels.reshape(h, -1)
    padded = np.zeros((h, step), np.uint8)
    padded[:, : rows.shape[1]] = rows
    return SimpleNamespace(header=SimpleNamespace(stamp=SimpleNamespace(sec=5, nanosec=7)),
                           encoding=encoding, height=h, width=w, step=step,
                           data=padded.ravel())


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8", "mono8"])
def test_raw_encodings_give_rgb_or_grey_pixels_with_padded_rows(encoding: str) -> None:
    rgb = np.random.default_rng(1).integers(0, 256, (3, 5, 3), dtype=np.uint8)
    stored = {"rgb8": rgb, "bgr8": rgb[:, :, ::-1], "mono8": rgb[:, :, 0],
              "rgba8": np.dstack([rgb, rgb[:, :, :1]]),
              "bgra8": np.dstack([rgb[:, :, ::-1], rgb[:, :, :1]])}[encoding]
    ch = 1 if stored.ndim == 2 else stored.shape[2]
    px = rb.raw_pixels(_image(encoding, stored, 5 * ch + 3), "/cam", Path("b.bag"))
    np.testing.assert_array_equal(px, rgb[:, :, 0] if encoding == "mono8" else rgb)


def test_unsupported_encodings_and_short_data_are_refused() -> None:
    msg = _image("mono16", np.zeros((2, 2, 2), np.uint8), 4)
    with pytest.raises(InputError, match=r"b\.bag: '/cam' at 5\.000000007: unsupported image "
                       r"encoding 'mono16'"):
        rb.raw_pixels(msg, "/cam", Path("b.bag"))
    msg = _image("rgb8", np.zeros((2, 2, 3), np.uint8), 6)
    msg.data = msg.data[:-1]
    with pytest.raises(InputError, match="11 bytes do not hold a 2x2 rgb8 image"):
        rb.raw_pixels(msg, "/cam", Path("b.bag"))
    comp = SimpleNamespace(header=msg.header, format="bmp", data=np.frombuffer(b"BM....", np.uint8))
    with pytest.raises(InputError, match="compressed format 'bmp' is not a JPEG or PNG"):
        rb.check_image(comp, rb.COMPRESSED_IMAGE, "/cam", Path("b.bag"))


@pytest.mark.parametrize("kind", ["ros1", "sqlite3"])
def test_a_bag_reads_back_topics_poses_and_camera(photo_flight_dir: Path, tmp_path: Path,
                                                   kind: str) -> None:
    from turbinefit.io import read_tum
    from turbinefit.io.camera_yaml import read_camera_yaml

    bag = write_flight_bag(photo_flight_dir, tmp_path / ("b.bag" if kind == "ros1" else "b"),
                           BagSpec(kind=kind, rate=1))
    with rb.open_bag(bag) as b:
        assert b.topics == {"/cam/image_raw": rb.IMAGE, INFO_TOPIC: rb.CAMERA_INFO,
                            "/odom": rb.ODOMETRY}
        assert b.require("/odom", (rb.ODOMETRY,), "--odometry-topic") == rb.ODOMETRY
        samples = rb.read_poses(b, "/odom", rb.ODOMETRY)
        info = next(iter(b.messages(INFO_TOPIC)))
        camera = rb.camera_from_info(info, INFO_TOPIC, bag)
    t, poses = read_tum(photo_flight_dir / "keyframes.txt")
    assert (samples.world_frame, samples.body_frame) == ("odom", "base_link")
    np.testing.assert_array_equal(samples.stamps_ns, BASE_NS + np.round(t * 1e9))
    assert_poses_close(samples.world_T_body, poses, 1e-12)
    assert camera == read_camera_yaml(photo_flight_dir / "camera.yaml")


def test_unreadable_bags_and_a_missing_rosbags_are_one_line_errors(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name, data in (("junk.bag", b"#ROSBAG V2.0\n" + b"\0" * 50), ("junk.mcap", b"nope"),
                       ("notes.txt", b"hello")):
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError, match=f"{name}: cannot read as a ROS bag: .+"):
            rb.open_bag(tmp_path / name)
    with pytest.raises(InputError, match=r"missing\.bag: bag not found"):
        rb.open_bag(tmp_path / "missing.bag")
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(TurbinefitError, match=r"pip install turbinefit\[ros\]"):
        rb.open_bag(tmp_path / "junk.bag")
