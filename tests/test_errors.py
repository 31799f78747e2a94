"""Input errors (turbinefit.errors): one line naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from turbinefit.errors import InputError
from turbinefit.io import read_tum


def test_input_error_is_one_line_with_path(tmp_path: Path) -> None:
    path = tmp_path / "bad.txt"
    path.write_text("1 2 3\n")
    with pytest.raises(InputError) as info:
        read_tum(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}:1: ")
    assert info.value.path == path
