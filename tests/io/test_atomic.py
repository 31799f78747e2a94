"""Atomic writes (turbinefit.io.atomic): files and output folders replaced whole or not at
all, and refused up front where they would fail."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from support import leftovers, raises_input_error

from turbinefit.errors import InputError
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


# ------------------------------------------------------------------ killed runs, full disks

def _dead_pid() -> int:
    """The pid of a process that has ended."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    return int(proc.stdout)


def _hidden(out: Path, tag: str, pid: int, host: str | None = None) -> Path:
    from turbinefit.io.atomic import _host

    return out.with_name(f".{out.name}.{tag}-{pid}-{host or _host()}-{'a' * 12}")


@pytest.mark.skipif(os.name != "posix", reason="liveness of a pid is tested on POSIX")
def test_stale_temporaries_of_dead_processes_are_removed(tmp_path: Path) -> None:
    out = tmp_path / "out"
    dead = _dead_pid()
    stale = _hidden(out, "tmp", dead)
    stale.mkdir()
    (stale / "keyframes.txt").write_text("valid looking\n")
    stale_file = _hidden(tmp_path / "report.md", "tmp", dead)
    stale_file.write_text("half")
    live = _hidden(tmp_path / "other", "tmp", os.getppid())  # a live process: another run
    live.mkdir()
    elsewhere = _hidden(out, "tmp", dead, host="0badc0de")  # a shared folder: not ours to judge
    elsewhere.mkdir()
    other = _hidden(tmp_path / "other", "tmp", dead)  # another output's: left to its next run
    other.mkdir()
    with atomic_output_dir(out) as tmp:
        (tmp / "a.txt").write_text("a")
    assert leftovers(tmp_path) == sorted(p.name for p in (elsewhere, live, other, stale_file))
    assert not any(".lock-" in name for name in leftovers(tmp_path))  # the reservation ended
    # the sweep folder's own files: all stale ones at once
    from turbinefit.io.atomic import remove_stale_temporaries

    assert sorted(remove_stale_temporaries(tmp_path)) == sorted([other, stale_file])
    assert leftovers(tmp_path) == sorted(p.name for p in (elsewhere, live))


@pytest.mark.skipif(os.name != "posix", reason="liveness of a pid is tested on POSIX")
@pytest.mark.parametrize("tag", ["tmp", "lock"])
def test_a_second_run_into_an_output_being_written_is_refused_at_once(tmp_path: Path,
                                                                      tag: str) -> None:
    from turbinefit.io.atomic import release_output, reserve_output

    out = tmp_path / "out"
    live = _hidden(out, tag, os.getppid())  # another live run, writing or still working
    live.mkdir() if tag == "tmp" else live.write_text("")
    with pytest.raises(InputError, match=rf"out: another turbinefit run \(process "
                                         rf"{os.getppid()}\) is writing this output folder"):
        reserve_output(out)
    with pytest.raises(InputError, match="another turbinefit run"):
        with atomic_output_dir(out):
            pass
    assert leftovers(tmp_path) == [live.name] and not out.exists()
    live.rename(_hidden(out, tag, _dead_pid()))  # that run was killed: no longer in the way
    reserve_output(out)
    mine = f".lock-{os.getpid()}-"
    assert sum(mine in name for name in leftovers(tmp_path)) == 1
    release_output(out)
    assert sum(mine in name for name in leftovers(tmp_path)) == 0


@pytest.mark.skipif(os.name != "posix", reason="liveness of a pid is tested on POSIX")
def test_a_kill_between_the_renames_of_overwrite_loses_nothing(tmp_path: Path) -> None:
    from turbinefit.io.atomic import remove_stale_temporaries

    out = tmp_path / "out"
    old = _hidden(out, "old", _dead_pid())
    old.mkdir()  # the previous output, moved aside; the new one never arrived
    (old / "a.txt").write_text("previous")
    assert remove_stale_temporaries(tmp_path, "out") == [old]
    assert (out / "a.txt").read_text() == "previous" and leftovers(tmp_path) == []
    old.mkdir()  # moved aside, and the new output is in place: the old one goes
    assert remove_stale_temporaries(tmp_path, "out") == [old]
    assert leftovers(tmp_path) == [] and (out / "a.txt").read_text() == "previous"


def test_a_full_disk_names_the_final_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    from turbinefit.io import atomic

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.os, "fsync", full)
    out = tmp_path / "out"
    with pytest.raises(InputError) as exc, atomic_output_dir(out) as tmp:
        write_text_atomic(tmp / "summary.json", "{}")
    assert str(exc.value) == f"no space left on device writing {out / 'summary.json'}"
    assert leftovers(tmp_path) == [] and not out.exists()
    quota = atomic.write_error(OSError(errno.EDQUOT, "Disk quota exceeded"), tmp_path / "x")
    assert str(quota) == f"disk quota exceeded writing {tmp_path / 'x'}"


def test_public_path_names_what_a_temporary_is_written_for(tmp_path: Path) -> None:
    from turbinefit.io.atomic import public_path

    hidden = _hidden(tmp_path / "fit", "tmp", 42) / "summary.json"
    assert public_path(hidden) == tmp_path / "fit" / "summary.json"
    assert public_path(tmp_path / ".hidden" / "a.txt") == tmp_path / ".hidden" / "a.txt"


def test_an_output_folder_that_cannot_be_created_says_so(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    import errno

    from turbinefit.io import atomic

    real_mkdir = os.mkdir

    def no_such_dir(path: str, mode: int = 0o777) -> None:  # /proc refuses any new entry
        if Path(path).name.startswith(".x.tmp-"):
            raise OSError(errno.ENOENT, "No such file or directory")
        real_mkdir(path, mode)

    monkeypatch.setattr(atomic.os, "mkdir", no_such_dir)
    out = tmp_path / "x"
    with pytest.raises(InputError) as exc, atomic_output_dir(out):
        pass
    assert str(exc.value) == f"{out}: cannot create the output folder: No such file or directory"


def test_an_output_made_by_another_process_meanwhile_is_named_as_such(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with pytest.raises(InputError, match=r"another process wrote this output directory while "
                       r"this run was working \(use --overwrite\)"):
        with atomic_output_dir(out, overwrite_hint="use --overwrite") as tmp:
            (tmp / "mine.txt").write_text("mine")
            out.mkdir()
            (out / "theirs.txt").write_text("theirs")
    assert os.listdir(out) == ["theirs.txt"] and leftovers(tmp_path) == []


def _without_override() -> None:
    """In a child, before it runs Python: without root's right to write anything, as a user
    runs (CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH dropped from the bounding set, which
    root's capabilities come from at exec)."""
    if os.geteuid() != 0:
        return
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    for cap in (1, 2):  # CAP_DAC_OVERRIDE, CAP_DAC_READ_SEARCH (linux/capability.h)
        if libc.prctl(24, cap, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            os._exit(77)


def test_overwriting_an_output_this_user_cannot_empty_is_refused_before_any_work(
        tmp_path: Path) -> None:
    # the old outputs could be moved aside but never deleted: refused up front, nothing
    # changed, no hidden folder left (was: exit 0, a RuntimeWarning and a hidden .old)
    import subprocess
    import sys

    root = tmp_path / "shared"
    out = root / "out"
    out.mkdir(parents=True)
    (out / "summary.json").write_text("{}")
    os.chmod(tmp_path, 0o755)
    os.chmod(root, 0o777)
    os.chmod(out, 0o555)  # its entries cannot be deleted (but by root)
    code = ("import sys\nfrom turbinefit.io import atomic_output_dir\n"
            "from turbinefit.errors import InputError\n"
            "try:\n    with atomic_output_dir(sys.argv[1], overwrite=True) as tmp:\n"
            "        (tmp / 'summary.json').write_text('new')\n"
            "except InputError as e:\n    print(e, file=sys.stderr)\n    sys.exit(2)\n")
    try:
        proc = subprocess.run([sys.executable, "-c", code, str(out)], capture_output=True,
                              text=True, timeout=60, preexec_fn=_without_override)
    finally:
        os.chmod(out, 0o755)
    if proc.returncode == 77:
        pytest.skip("root without the capability to drop its own capabilities")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == (f"{out}: cannot replace it: {out} is not writable, so its old "
                           "contents could not be deleted\n")
    assert sorted(p.name for p in root.iterdir()) == ["out"]
    assert (out / "summary.json").read_text() == "{}"


def test_replaced_outputs_that_cannot_be_deleted_after_all_are_named(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    import turbinefit.io.atomic as atomic

    out = tmp_path / "out"
    out.mkdir()
    (out / "a.txt").write_text("old")
    monkeypatch.setattr(atomic.shutil, "rmtree", lambda p, ignore_errors=False: None)
    with pytest.raises(InputError, match=r"the new outputs are in place, but the replaced ones "
                       r"could not all be deleted: delete .*\.out\.old-") as e:
        with atomic_output_dir(out, overwrite=True) as tmp:
            (tmp / "a.txt").write_text("new")
    assert (out / "a.txt").read_text() == "new"
    old = Path(str(e.value).rsplit("delete ", 1)[1].removesuffix(" by hand"))
    assert (old / "a.txt").read_text() == "old"
    monkeypatch.undo()
    shutil.rmtree(old)
