"""TUM trajectory files (turbinefit.io.tum): exact round trips, layout, bad input named by
file and line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from support import assert_poses_close, leftovers, raises_input_error, random_poses, tum_timestamps

from turbinefit.geometry.se3 import SE3
from turbinefit.io import read_tum, write_tum


def test_tum_round_trip_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    t = tum_timestamps(50)
    poses = random_poses(rng, 50)
    path = tmp_path / "traj.txt"
    write_tum(path, t, poses)
    t2, poses2 = read_tum(path)
    np.testing.assert_allclose(t2, t, rtol=0, atol=1e-9)
    assert_poses_close(poses2, poses)
    assert np.all(poses2.wxyz[:, 0] >= 0)
    assert leftovers(tmp_path) == []


def test_tum_file_order_is_xyzw(tmp_path: Path) -> None:
    # 90 degrees about z: wxyz = (c, 0, 0, s)
    c = math.sqrt(0.5)
    poses = SE3(np.array([[c, 0.0, 0.0, c, 1.0, 2.0, 3.0]]))
    path = tmp_path / "one.txt"
    write_tum(path, [10.5], poses)
    data_lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    cols = [float(x) for x in data_lines[0].split()]
    assert cols[0] == 10.5
    assert cols[1:4] == [1.0, 2.0, 3.0]
    np.testing.assert_allclose(cols[4:], [0.0, 0.0, c, c], atol=1e-12)  # qx qy qz qw

    path.write_text("0.0 1 2 3 0.5 0.5 0.5 0.5\n")
    _, p = read_tum(path)
    np.testing.assert_allclose(p.wxyz_xyz[0], [0.5, 0.5, 0.5, 0.5, 1, 2, 3])


def test_tum_comments_blank_lines_normalisation(tmp_path: Path) -> None:
    path = tmp_path / "t.txt"
    path.write_text(
        "# TUM file\n"
        "\n"
        "1.0 0 0 0 0 0 0 1.0005   # slightly off unit norm\n"
        "   \n"
        "2.0\t1 2 3 0 0 0 -1\n"
        "# end\n")
    t, p = read_tum(path)
    np.testing.assert_array_equal(t, [1.0, 2.0])
    np.testing.assert_allclose(p.wxyz, [[1, 0, 0, 0], [1, 0, 0, 0]], atol=1e-15)  # w >= 0
    np.testing.assert_allclose(p.translation[1], [1, 2, 3])


@pytest.mark.parametrize(
    ("content", "line", "message"),
    [
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", 2, "expected 8 columns"),
        ("1 0 0 0 0 0 0 1 5\n", 1, "expected 8 columns"),
        ("1 0 0 0 0 0 0 1\n\n2 0 0 x 0 0 0 1\n", 3, "not a number: 'x'"),
        ("1 0 0 0 0 0 0 1\n2 0 0 1_0 0 0 0 1\n", 2, "not a number"),
        ("1 0 0 nan 0 0 0 1\n", 1, "non-finite"),
        ("1 0 0 0 0 0 0 inf\n", 1, "non-finite"),
        ("# c\n1 0 0 0 0 0 0 0\n", 2, "zero norm"),
        ("1 0 0 0 0 0 0 1.002\n", 1, "norm 1.002"),
        ("1 0 0 0 0.5 0 0 0.5\n", 1, "expected 1"),
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n", 3, "not after"),
        ("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 2, "not after"),
    ],
)
def test_tum_bad_input_names_file_and_line(tmp_path: Path, content: str, line: int,
                                           message: str) -> None:
    path = tmp_path / "bad.txt"
    path.write_text(content)
    with raises_input_error(path, line) as info:
        read_tum(path)
    assert message in str(info.value)
    assert info.value.line == line


@pytest.mark.parametrize("content", ["", "# only a comment\n\n"])
def test_tum_empty_file(tmp_path: Path, content: str) -> None:
    path = tmp_path / "empty.txt"
    path.write_text(content)
    with raises_input_error(path) as info:
        read_tum(path)
    assert "no poses" in str(info.value)


def test_tum_missing_file_and_binary(tmp_path: Path) -> None:
    with raises_input_error(tmp_path / "nope.txt"):
        read_tum(tmp_path / "nope.txt")
    path = tmp_path / "bin.txt"
    path.write_bytes(b"\xff\xfe\x00\x81")
    with raises_input_error(path):
        read_tum(path)


def test_write_tum_rejects_bad_data(tmp_path: Path) -> None:
    path = tmp_path / "out.txt"
    poses = random_poses(np.random.default_rng(0), 2)
    with raises_input_error(path, field="timestamps"):
        write_tum(path, [1.0, 1.0000001], poses)  # same microsecond
    with raises_input_error(path, field="poses"):
        write_tum(path, [1.0, 2.0, 3.0], poses)
    bad = SE3(poses.wxyz_xyz * np.array([2.0, 2, 2, 2, 1, 1, 1]))
    with raises_input_error(path, field="poses"):
        write_tum(path, [1.0, 2.0], bad)
    assert not path.exists()
    assert leftovers(tmp_path) == []
