"""``turbinefit import rosbag``: what it prints, and bad input (one line naming the bag and
topic, exit 2, nothing written, the bag untouched)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from support import assert_one_line_error, digest, run
from support_rosbag import IMAGE_TOPIC, BagSpec, write_flight_bag

ARGS = ["--image-topic", IMAGE_TOPIC, "--odometry-topic", "/odom"]


@pytest.fixture(scope="module")
def bag(photo_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_flight_bag(photo_flight_dir, tmp_path_factory.mktemp("cli") / "f.bag")


def test_import_prints_what_it_did(bag: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "flight"
    rc, stdout, err = run(capsys, "import", "rosbag", str(bag), "--out", str(out), *ARGS,
                          "--every-m", "0", "--body-T-cam", "0,0,0,0,0,0,1")
    assert rc == 0, err
    lines = stdout.splitlines()
    assert lines[0].startswith("imported 6 keyframes of 6 images (") and str(out) in lines[0]
    assert lines[1] == ("camera: 160x120 from /cam/camera_info; poses: /odom in frame odom; "
                        "body_T_cam: --body-T-cam")
    assert lines[2].startswith("note: no turbine.yaml: fit needs one")
    rc, _, err = run(capsys, "import", "rosbag", str(bag), "--out", str(out), *ARGS)
    assert_one_line_error(rc, "", err, "not empty", "--overwrite")
    rc, stdout, _ = run(capsys, "import", "rosbag", str(bag), "--out", str(out), *ARGS,
                        "--overwrite")
    assert rc == 0 and "imported" in stdout


def test_help_names_every_option(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        run(capsys, "import", "rosbag", "--help")
    text = capsys.readouterr().out
    for option in ("--image-topic", "--camera-info-topic", "--odometry-topic", "--pose-topic",
                   "--every-m", "--every-deg", "--body-T-cam", "--turbine-yaml", "--overwrite"):
        assert option in text


def _bad(capsys: pytest.CaptureFixture[str], bag: Path, tmp_path: Path, args: list[str],
         *patterns: str) -> None:
    before = digest(bag.parent) if bag.exists() else {}
    out = tmp_path / "never"
    rc, stdout, err = run(capsys, "import", "rosbag", str(bag), "--out", str(out), *args)
    assert_one_line_error(rc, stdout, err, *patterns)
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.name != bag.name
                                 and p != bag.parent] == []
    if before:
        assert digest(bag.parent) == before


@pytest.mark.parametrize(("args", "patterns"), [
    (["--image-topic", "/cam/image", "--odometry-topic", "/odom"],
     [r"f\.bag: no topic '/cam/image' \(--image-topic\); sensor_msgs/msg/Image or "
      r"sensor_msgs/msg/CompressedImage topics in the bag: /cam/image_raw$"]),
    (["--image-topic", IMAGE_TOPIC, "--odometry-topic", "/odometry"],
     [r"no topic '/odometry' \(--odometry-topic\); nav_msgs/msg/Odometry topics in the bag: "
      r"/odom$"]),
    (["--image-topic", IMAGE_TOPIC, "--pose-topic", "/odom"],
     [r"topic is nav_msgs/msg/Odometry, not geometry_msgs/msg/PoseStamped or "
      r"geometry_msgs/msg/PoseWithCovarianceStamped: '/odom' \(--pose-topic\); .* none$"]),
    ([*ARGS, "--camera-info-topic", "/odom"],
     [r"topic is nav_msgs/msg/Odometry, not sensor_msgs/msg/CameraInfo"]),
])
def test_bad_topics(bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                    args: list[str], patterns: list[str]) -> None:
    _bad(capsys, bag, tmp_path, args, *patterns)


@pytest.mark.parametrize(("args", "pattern"), [
    ([*ARGS, "--body-T-cam", "1,2,3,0,0,0,2"], r"--body-T-cam: .*a unit quaternion \(norm 2\)"),
    ([*ARGS, "--body-T-cam", "1,2,3"], r"--body-T-cam: expected seven numbers"),
    ([*ARGS, "--every-m", "-1"], r"--every-m: must be a non-negative number"),
    (["--image-topic", IMAGE_TOPIC], r"one of the arguments --odometry-topic --pose-topic"),
])
def test_usage_errors(bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                      args: list[str], pattern: str) -> None:
    with pytest.raises(SystemExit) as exc:
        run(capsys, "import", "rosbag", str(bag), "--out", str(tmp_path / "o"), *args)
    assert exc.value.code == 2
    assert re.search(pattern, capsys.readouterr().err.splitlines()[-1])
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("spec", "patterns"), [
    (BagSpec(images=False), [r"no topic '/cam/image_raw' .* topics in the bag: none$"]),
    (BagSpec(camera_info=False), [r"no camera_info topic next to '/cam/image_raw': give "
                                  r"--camera-info-topic \(.* topics in the bag: none\)"]),
    (BagSpec(encoding="bgra8"), []),
    (BagSpec(stamp_shift_s=-0.5), [r"'/cam/image_raw': image at 1699999999\.500000000 has "
                                   r"no pose on '/odom' within the interpolation window"]),
])
def test_bad_bags(photo_flight_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                  spec: BagSpec, patterns: list[str]) -> None:
    (tmp_path / "in").mkdir()
    bag = write_flight_bag(photo_flight_dir, tmp_path / "in" / "f.bag", spec)
    if not patterns:  # a readable encoding relabelled as one that is not
        data = bag.read_bytes()
        bag.write_bytes(data.replace(b"bgra8", b"yuv42"))
        patterns = [r"'/cam/image_raw' at 1700000000\.000000000: unsupported image encoding "
                    r"'yuv42'"]
    _bad(capsys, bag, tmp_path, ARGS, *patterns)


def test_unreadable_and_missing_bags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "in").mkdir()
    junk = tmp_path / "in" / "junk.bag"
    junk.write_bytes(b"not a bag at all")
    _bad(capsys, junk, tmp_path, ARGS, r"junk\.bag: cannot read as a ROS bag")
    _bad(capsys, tmp_path / "in" / "gone.bag", tmp_path, ARGS, r"gone\.bag: bag not found")


def test_a_bad_turbine_yaml_is_refused_before_reading(bag: Path, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "turbine.yaml"
    bad.write_text("base_x: 1\n")
    rc, stdout, err = run(capsys, "import", "rosbag", str(bag), "--out", str(tmp_path / "o"),
                          *ARGS, "--turbine-yaml", str(bad))
    assert_one_line_error(rc, stdout, err, r"turbine\.yaml.*missing")
    assert not (tmp_path / "o").exists()


def test_a_full_disk_while_writing_the_images_names_the_image(
        bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins
    import errno

    import turbinefit.io.atomic as atomic

    class Full:
        def __init__(self, f: object) -> None:
            self.f = f

        def __enter__(self) -> Full:
            return self

        def __exit__(self, *exc: object) -> None:
            self.f.close()  # type: ignore[attr-defined]

        def write(self, data: bytes) -> int:
            raise OSError(errno.ENOSPC, "No space left on device")  # no file name, as f.write

    def opening(path: object, mode: str = "r", *args: object, **kwargs: object) -> object:
        f = builtins.open(path, mode, *args, **kwargs)  # type: ignore[call-overload]
        return Full(f) if ".png.tmp-" in str(path) else f

    monkeypatch.setattr(atomic, "open", opening, raising=False)
    out = tmp_path / "flight"
    rc, stdout, err = run(capsys, "import", "rosbag", str(bag), "--out", str(out), *ARGS,
                          "--every-m", "0", "--body-T-cam", "0,0,0,0,0,0,1")
    assert_one_line_error(rc, stdout, err, rf"^turbinefit: error: no space left on device "
                          rf"writing {re.escape(str(out))}/images/[0-9.]+\.png$")
    assert not out.exists() and list(tmp_path.iterdir()) == []
