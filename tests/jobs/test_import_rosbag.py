"""The ``import rosbag`` job: a simulated flight written as a bag imports back to the same
flight (and the same fit), keyframe selection, extrinsics and interpolation."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp
from support import assert_poses_close, digest, poses_array
from support_rosbag import IMAGE_TOPIC, ODOM_TOPIC, POSE_TOPIC, BagSpec, write_flight_bag

from turbinefit.cli import main
from turbinefit.errors import InputError
from turbinefit.geometry.se3 import SE3
from turbinefit.io import read_tum
from turbinefit.jobs.import_rosbag import RosbagOptions, import_rosbag, select_keyframes

EVERY = RosbagOptions(IMAGE_TOPIC, odometry_topic=ODOM_TOPIC, every_m=0.0, every_deg=0.0)


@pytest.fixture(scope="module")
def flight(photo_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The photo flight with its keyframe poses as body-frame odometry (``odometry.txt``),
    which is what an imported bag gives."""
    folder = Path(shutil.copytree(photo_flight_dir, tmp_path_factory.mktemp("rb") / "flight"))
    shutil.copy(folder / "keyframes.txt", folder / "odometry.txt")
    return folder


@pytest.fixture(scope="module")
def flight_fit(flight: Path) -> Path:
    out = flight.parent / "fit"
    assert main(["fit", str(flight), "--from-images", "--out", str(out), "--no-plots"]) == 0
    return out


def _images(folder: Path) -> list[bytes]:
    return [p.read_bytes() for p in sorted((folder / "images").iterdir())]


def test_a_ros1_bag_of_raw_images_fits_as_the_flight_does(flight: Path, flight_fit: Path,
                                                          tmp_path: Path) -> None:
    bag = write_flight_bag(flight, tmp_path / "flight.bag", BagSpec("ros1", encoding="bgr8"))
    out = tmp_path / "imported"
    s = import_rosbag(bag, out, RosbagOptions(
        IMAGE_TOPIC, odometry_topic=ODOM_TOPIC, every_m=0.0, every_deg=0.0,
        turbine_yaml=flight / "turbine.yaml"))
    assert (s.images, s.keyframes, s.extrinsic, s.camera_info_topic) == (
        6, 6, "identity", "/cam/camera_info")
    assert sorted(p.name for p in out.iterdir()) == [
        "camera.yaml", "images", "keyframes.txt", "odometry.txt", "turbine.yaml"]
    t0, p0 = poses_array(flight / "keyframes.txt")
    t1, p1 = poses_array(out / "keyframes.txt")
    np.testing.assert_allclose(t1 - 1_700_000_000, t0, atol=1e-6)
    np.testing.assert_allclose(p1, p0, atol=1e-9)
    assert (out / "odometry.txt").read_text() == (out / "keyframes.txt").read_text()
    assert [p.name for p in sorted((out / "images").iterdir())] == [
        f"{t:.6f}.png" for t in t1]
    fit = tmp_path / "fit"
    assert main(["fit", str(out), "--from-images", "--out", str(fit), "--no-plots"]) == 0
    assert (fit / "turbine.yaml").read_text() == (flight_fit / "turbine.yaml").read_text()
    _, q0 = poses_array(flight_fit / "keyframes.txt")
    _, q1 = poses_array(fit / "keyframes.txt")
    np.testing.assert_allclose(q1, q0, atol=1e-9)


@pytest.mark.parametrize("kind", ["mcap", "sqlite3"])
def test_a_ros2_bag_of_compressed_images_gives_the_same_folder(flight: Path, tmp_path: Path,
                                                               kind: str) -> None:
    bag = write_flight_bag(flight, tmp_path / "bag", BagSpec(kind, compressed=True))
    out = tmp_path / "imported"
    import_rosbag(bag, out, EVERY)
    assert _images(out) == _images(flight)  # the PNG bytes as they are
    _, p0 = poses_array(flight / "keyframes.txt")
    _, p1 = poses_array(out / "keyframes.txt")
    np.testing.assert_allclose(p1, p0, atol=1e-9)
    assert (out / "camera.yaml").read_text().replace("rosbag", "turbinefit") == (
        flight / "camera.yaml").read_text()


def test_tf_static_extrinsic_and_interpolation_between_odometry_samples(
        flight: Path, tmp_path: Path) -> None:
    body_T_cam = SE3.from_rotation_translation([0.5, -0.5, 0.5, -0.5], [0.1, 0.0, -0.05])
    shift = 0.3  # the images 0.3 s after the keyframes, between odometry samples
    bag = write_flight_bag(flight, tmp_path / "b.bag", BagSpec(
        body_T_cam=body_T_cam, stamp_shift_s=shift, pose_stamped=True))
    with pytest.raises(InputError, match=r"b\.bag: '/cam/image_raw': image at "
                       r"1700000005\.300000000 has no pose on '/pose' within the "
                       r"interpolation window"):
        import_rosbag(bag, tmp_path / "x", RosbagOptions(
            IMAGE_TOPIC, pose_topic=POSE_TOPIC, every_m=0, every_deg=0))
    assert not (tmp_path / "x").exists()
    out = tmp_path / "imported"
    s = import_rosbag(bag, out, RosbagOptions(
        IMAGE_TOPIC, pose_topic=POSE_TOPIC, every_m=0, every_deg=0, body_frame="base_link",
        skip_unposed=True))
    assert s.extrinsic == "/tf_static: base_link -> cam_optical" and s.keyframes == 5
    assert "dropped 1 image(s)" in s.notes[0]
    t, world_T_cam = read_tum(flight / "keyframes.txt")
    body = world_T_cam @ body_T_cam.inverse()  # what the bag's poses give
    rot = Slerp(t, Rotation.from_quat(body.wxyz[:, [1, 2, 3, 0]]))(t[:5] + shift)
    pos = np.stack([np.interp(t[:5] + shift, t, body.translation[:, i]) for i in range(3)], -1)
    want = SE3.from_rotation_translation(rot.as_quat()[:, [3, 0, 1, 2]], pos) @ body_T_cam
    t1, got = read_tum(out / "keyframes.txt")
    np.testing.assert_allclose(t1 - 1_700_000_000, t[:5] + shift, atol=1e-6)
    assert_poses_close(got, want, 1e-7)
    # without the body frame a PoseStamped names none: the identity, and a note saying why
    s = import_rosbag(bag, out, RosbagOptions(
        IMAGE_TOPIC, pose_topic=POSE_TOPIC, skip_unposed=True), overwrite=True)
    assert s.extrinsic == "identity" and "names no body frame" in s.notes[1]


def test_keyframes_by_distance_travelled_and_rotation() -> None:
    n = 11
    pos = np.zeros((n, 3))
    pos[:, 0] = np.arange(n) * 0.7  # 0.7 m per image
    yaw = np.zeros(n)
    yaw[8:] = np.radians([4.0, 12.0, 21.0])  # then turning on the spot
    pos[8:, 0] = pos[7, 0]
    xyzw = Rotation.from_euler("z", yaw[:, None]).as_quat()
    poses = SE3.from_rotation_translation(xyzw[:, [3, 0, 1, 2]], pos)
    assert select_keyframes(poses, 2.0, 10.0).tolist() == [0, 3, 6, 9]
    assert select_keyframes(poses, 1.0, 5.0).tolist() == [0, 2, 4, 6, 9, 10]
    assert select_keyframes(poses, 0.0, 0.0).tolist() == list(range(n))


def test_default_keyframes_and_the_bag_left_untouched(flight: Path, tmp_path: Path) -> None:
    bag = write_flight_bag(flight, tmp_path / "b.bag")
    before = digest(tmp_path)
    s = import_rosbag(bag, tmp_path / "out", RosbagOptions(IMAGE_TOPIC, odometry_topic=ODOM_TOPIC,
                                                           every_m=300.0, every_deg=360.0))
    assert digest(tmp_path / "out") and {k: v for k, v in digest(tmp_path).items()
                                        if not k.startswith("out/")} == before
    t, _ = read_tum(tmp_path / "out" / "keyframes.txt")
    assert s.keyframes == len(t) < 6
    assert s.notes[-1].startswith("no turbine.yaml")


def test_images_of_another_size_than_camera_info_leave_nothing(flight: Path,
                                                                tmp_path: Path) -> None:
    from turbinefit.io.camera_yaml import read_camera_yaml, write_camera_yaml

    other = Path(shutil.copytree(flight, tmp_path / "other"))
    write_camera_yaml(other / "camera.yaml", read_camera_yaml(flight / "camera.yaml").scaled(2))
    bag = write_flight_bag(other, tmp_path / "b.bag")
    with pytest.raises(InputError, match=r"'/cam/image_raw' at 1700000000\.000000000: image is "
                       r"160x120 but '/cam/camera_info' says 320x240"):
        import_rosbag(bag, tmp_path / "out", EVERY)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bag", "other"]
