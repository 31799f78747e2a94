"""Atomic writes (turbinefit.io.atomic): files and output folders replaced whole or not at
all, and refused up front where they would fail."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from support import leftovers, raises_input_error

from turbinefit.io import atomic_output_dir, write_bytes_atomic, write_text_atomic
from turbinefit.io.atomic import check_output_dir


def test_write_text_atomic_replaces_and_cleans_up(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "sub" / "a.txt"
    write_text_atomic(path, "one\n")
    write_text_atomic(path, "two\n")
    assert path.read_text() == "two\n"
    write_bytes_atomic(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"

    def broken_replace(src: str, dst: str) -> None:
        raise OSError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", broken_replace)
    with raises_input_error(path):
        write_text_atomic(path, "three\n")
    monkeypatch.undo()
    assert path.read_bytes() == b"\x00\x01"
    assert leftovers(path.parent) == []
    with raises_input_error(tmp_path / "sub"):
        write_text_atomic(tmp_path / "sub", "x")


def test_atomic_output_dir(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with atomic_output_dir(out) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".out.tmp-")
        assert not out.exists()
        (tmp / "x.txt").write_text("1")
    assert (out / "x.txt").read_text() == "1"

    with pytest.raises(RuntimeError), atomic_output_dir(out, overwrite=True) as tmp:
        (tmp / "y.txt").write_text("2")
        raise RuntimeError("boom")
    assert sorted(p.name for p in out.iterdir()) == ["x.txt"]
    assert leftovers(tmp_path) == []

    with raises_input_error(out), atomic_output_dir(out):
        pass
    with atomic_output_dir(out, overwrite=True) as tmp:
        (tmp / "z.txt").write_text("3")
    assert sorted(p.name for p in out.iterdir()) == ["z.txt"]

    link = tmp_path / "link"
    link.symlink_to(out)
    with raises_input_error(link), atomic_output_dir(link, overwrite=True):
        pass
    assert leftovers(tmp_path) == []


def test_check_output_dir_refuses_what_atomic_output_dir_would(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    check_output_dir(tmp_path / "new" / "deeper")  # missing parents are created later
    (tmp_path / "empty").mkdir()
    check_output_dir(tmp_path / "empty")
    afile = tmp_path / "afile"
    afile.write_text("x")
    with raises_input_error(afile) as info:
        check_output_dir(afile, overwrite=True)
    assert "not a directory" in str(info.value)
    for below in (afile / "out", afile / "a" / "b"):  # the parent is a file: refused up front
        with raises_input_error(afile) as info:
            check_output_dir(below)
        assert "not a directory" in str(info.value)
        with raises_input_error(afile), atomic_output_dir(below):
            pass
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    with raises_input_error(loop) as info:
        check_output_dir(loop, overwrite=True)
    assert "symbolic link" in str(info.value)

    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "a.txt").write_text("1")
    with raises_input_error(busy) as info:
        check_output_dir(busy, overwrite_hint="use --force")
    assert str(info.value).endswith("not empty (use --force)")
    check_output_dir(busy, overwrite=True)

    def unreadable(path: Path) -> str | None:
        raise PermissionError(13, "Permission denied", str(path / "sub"))

    with raises_input_error(busy) as info:
        check_output_dir(busy, overwrite=True, may_replace=unreadable)
    assert "Permission denied" in str(info.value)

    import turbinefit.io.atomic as atomic

    monkeypatch.setattr(atomic.os, "access", lambda path, mode, **kw: False)  # a read-only parent
    with raises_input_error(tmp_path) as info:
        check_output_dir(tmp_path / "new")
    assert "no permission" in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "busy", "empty", "loop"]


def test_atomic_output_dir_restores_old_dir_when_final_rename_fails(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("old")
    real_rename = os.rename

    def rename(src: str | Path, dst: str | Path) -> None:
        if Path(src).name.startswith(".out.tmp-"):
            raise OSError(18, "Invalid cross-device link")
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    with raises_input_error(out) as info, atomic_output_dir(out, overwrite=True) as tmp:
        (tmp / "new.txt").write_text("new")
    assert "cross-device" in str(info.value)
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]
    assert leftovers(tmp_path) == []
