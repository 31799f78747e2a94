"""Atomic output: whole files and whole directories appear complete or not at all.

Nothing here knows about file formats; the writers in :mod:`turbinefit.io` use it.

* :func:`write_text_atomic` / :func:`write_bytes_atomic` write into a hidden temporary file
  ``.<name>.tmp-<pid>-<host>-<random>`` in the destination's directory, flush and ``fsync``
  it, then ``os.replace`` it over the destination. Readers see the old file or the new one,
  never a partial one; an existing file is replaced.
* :func:`atomic_output_dir` yields a hidden temporary sibling directory
  ``.<name>.tmp-<pid>-<host>-<random>`` to fill, and moves it into place when the ``with``
  block succeeds. **Existing destination:** a missing path or an empty directory is simply
  replaced; a non-empty directory is refused with an :class:`InputError` unless
  ``overwrite=True`` (and an optional ``may_replace`` check accepts it), in which case the
  old directory is renamed aside (``.<name>.old-<pid>-<host>-<random>``), the new one
  renamed into place and only then the old one deleted; if the second rename fails the old
  directory is put back. A destination that is a file or a symbolic link is always refused.
* On any exception (including ``KeyboardInterrupt`` and the command's signals) the
  temporary file or directory is removed and the destination is left untouched. Only a hard
  kill (SIGKILL, power loss) can leave a ``.<name>.tmp-*`` entry behind; it is never
  mistaken for output, and the next :func:`atomic_output_dir` into the same place removes
  it (:func:`remove_stale_temporaries`) once the process named in it is gone (a
  ``.<name>.old-*`` is removed if ``<name>`` exists, else put back: the kill came between
  the two renames). Entries of a live process, or of another host, are never touched.
* A full disk (or quota) is one line naming the final path, never the hidden temporary one
  (:func:`write_error`, :func:`public_path`).
* :func:`reserve_output` marks a destination as being produced by this process, with an
  empty ``.<name>.lock-<pid>-<host>-<random>`` beside it, from the job's first check until
  its :func:`atomic_output_dir` ends (or the process exits): a second run into the same
  place, on this host, is refused at once instead of after all its work.

Directory writes are atomic with respect to other processes and to exceptions; files inside
the temporary directory are not individually ``fsync``-ed (writing thousands of heat-maps
must stay fast), so after a power loss the renamed directory's contents are up to the OS.

Also :func:`read_text`, the one place where a text file is read (only a regular file of
at most a size limit, :mod:`turbinefit.io.limits`) and a failing read becomes an
:class:`InputError` naming the file, and :func:`check_output_dir`, the destination check of
:func:`atomic_output_dir` on its own, so that a job can refuse a bad output path before it
spends minutes computing what it would write there.

All failures are :class:`turbinefit.errors.InputError` naming the path concerned.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import os
import re
import shutil
import stat
import uuid
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path

from turbinefit.errors import InputError
from turbinefit.io.limits import MAX_TABLE_BYTES, read_input_bytes

StrPath = str | os.PathLike[str]


#: The errors of a full disk or an exhausted quota.
DISK_FULL = frozenset({errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)})
#: A hidden temporary (``tmp``), replaced (``old``) or reserving (``lock``) entry: name, tag,
#: owner's pid and host.
_HIDDEN = re.compile(r"\.(?P<name>.+)\.(?P<tag>tmp|old|lock)-(?P<pid>\d+)-(?P<host>[0-9a-f]{8})"
                     r"-[0-9a-f]{12}")


def _host() -> str:
    """This machine, as 8 hex digits (the temporary names of a shared folder say whose)."""
    node = os.uname().nodename if hasattr(os, "uname") else os.environ.get("COMPUTERNAME", "")
    return f"{zlib.crc32(node.encode()):08x}"


def _sibling(path: Path, tag: str) -> Path:
    """A hidden, random, not yet existing sibling name of ``path`` that names its owner."""
    return path.with_name(f".{path.name}.{tag}-{os.getpid()}-{_host()}-{uuid.uuid4().hex[:12]}")


def public_path(path: StrPath) -> Path:
    """``path`` with every hidden temporary component replaced by the name it is written
    for: what a message names (``out/.fit.tmp-1-2-3/summary.json`` -> ``out/fit/summary.json``)."""
    p = Path(path)
    return Path(*[m["name"] if (m := _HIDDEN.fullmatch(part)) else part for part in p.parts])


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` is a full disk or an exhausted quota."""
    return isinstance(exc, OSError) and exc.errno in DISK_FULL


def write_error(exc: OSError, path: StrPath | None) -> InputError:
    """The one-line error of a failed write of ``path`` (its final name, never a hidden
    temporary one): ``no space left on device writing PATH`` for a full disk."""
    where = None if path is None else public_path(os.fsdecode(path))
    if is_disk_full(exc):
        what = "no space left on device" if exc.errno == errno.ENOSPC else "disk quota exceeded"
        return InputError(f"{what} writing {where if where is not None else 'the output'}")
    return InputError(f"cannot write: {exc.strerror or exc}", path=where)


def _owner_gone(match: re.Match[str]) -> bool:
    """Whether the process that made a hidden entry has ended (False when unsure: another
    host, or not POSIX, where signal 0 does not test a process)."""
    if os.name != "posix" or match["host"] != _host():
        return False
    pid = int(match["pid"])
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # EPERM: alive, another user's
        return False
    return False


def _hidden_entries(folder: Path, name: str | None) -> list[tuple[str, re.Match[str]]]:
    """The hidden entries in ``folder`` (those of ``name``, or all) with their parts; none
    if the folder cannot be listed."""
    try:
        entries = [e.name for e in os.scandir(folder)]
    except OSError:
        return []
    return [(entry, m) for entry in entries if (m := _HIDDEN.fullmatch(entry)) is not None
            and (name is None or m["name"] == name)]


def remove_stale_temporaries(folder: StrPath, name: str | None = None) -> list[Path]:
    """Remove the hidden temporary entries in ``folder`` (those of ``name``, or all) left by
    a killed process (see the module docstring); returns those removed or put back. Never
    raises: what cannot be removed stays."""
    root = Path(folder)
    done: list[Path] = []
    for entry, m in _hidden_entries(root, name):
        if not _owner_gone(m):
            continue
        p, final = root / entry, root / m["name"]
        with contextlib.suppress(OSError):
            if m["tag"] == "old" and not os.path.lexists(final):
                os.rename(p, final)  # killed between the two renames: the old output is back
            elif p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                os.unlink(p)
            done.append(p)
    return done


#: This process's reservations: destination -> its lock file.
_RESERVED: dict[Path, Path] = {}


def _live_owner(folder: Path, name: str) -> int | None:
    """The pid of another live process of this host that is writing ``folder/name`` (a
    temporary or reserving entry of it), or None."""
    for _, m in _hidden_entries(folder, name):
        if (m["tag"] in ("tmp", "lock") and m["host"] == _host()
                and int(m["pid"]) != os.getpid() and not _owner_gone(m)):
            return int(m["pid"])
    return None


def reserve_output(path: StrPath) -> None:
    """Reserve ``path`` for this process (module docstring); nothing if it already holds it
    or if the parent folder does not exist yet (nobody else can be writing there).

    Raises:
        InputError: if another live process of this host is producing ``path``.
    """
    p = Path(os.path.abspath(path))
    if p in _RESERVED or not p.parent.is_dir():
        return
    lock = _sibling(p, "lock")
    _RESERVED[p] = lock  # before the file exists: a signal once it does still removes it
    try:
        os.close(os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    except OSError:
        del _RESERVED[p]
        return  # a folder we may not write to: check_output_dir says so
    pid = _live_owner(p.parent, p.name)
    if pid is not None:
        release_output(p)
        raise InputError(f"another turbinefit run (process {pid}) is writing this output "
                         "folder now; wait for it to end or choose another output", path=p)


def release_output(path: StrPath) -> None:
    """End this process's reservation of ``path`` (nothing if it holds none)."""
    lock = _RESERVED.pop(Path(os.path.abspath(path)), None)
    if lock is not None:
        with contextlib.suppress(OSError):
            os.unlink(lock)


def release_all_outputs() -> None:
    """End every reservation of this process (at exit, and when a command ends)."""
    for p in list(_RESERVED):
        release_output(p)


atexit.register(release_all_outputs)


def _make_parent(path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError as e:  # mkdir(exist_ok=True) on something that is not a directory
        raise InputError(f"not a directory, cannot create {path.name!r} in it",
                         path=path.parent) from e
    except OSError as e:
        if is_disk_full(e):
            raise write_error(e, path) from e
        raise InputError(f"cannot create directory: {e.strerror or e}", path=path.parent) from e


def read_text(path: StrPath, limit: int = MAX_TABLE_BYTES) -> str:
    """The contents of a UTF-8 text file (a BOM is ignored) of at most ``limit`` bytes;
    only regular files are read (:func:`turbinefit.io.limits.read_input_bytes`: a FIFO or
    a device is refused without being opened). Errors become InputErrors."""
    p = Path(path)
    data = read_input_bytes(p, limit)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(f"not a UTF-8 text file (byte {e.start})", path=p) from e


def write_bytes_atomic(path: StrPath, data: bytes, fsync: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (see the module docstring).

    Creates missing parent directories. The new file gets the default permissions
    (``0o666`` minus the umask). Returns the path written.
    """
    p = Path(path)
    try:
        is_dir = p.is_dir()
    except OSError as e:  # e.g. a parent directory that may not be searched
        raise InputError(f"cannot access: {e.strerror or e}", path=p) from e
    if is_dir:
        raise InputError("is a directory, cannot write a file there", path=p)
    _make_parent(p)
    tmp = _sibling(p, "tmp")
    try:  # created inside the try: a signal right after still removes it
        with open(tmp, "xb") as f:  # O_EXCL, 0o666 minus the umask
            f.write(data)
            f.flush()
            if fsync:
                os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise write_error(e, p) from e
        raise
    return p


def write_text_atomic(path: StrPath, text: str, fsync: bool = True) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) to ``path`` atomically."""
    return write_bytes_atomic(path, text.encode("utf-8"), fsync=fsync)


def _check_parent(path: Path) -> None:
    """Refuse ``path`` early if it could not be created (or renamed into place): its nearest
    existing ancestor must be a directory that we may write to."""
    parent = path.parent
    while True:
        try:
            st = os.stat(parent)
        except (FileNotFoundError, NotADirectoryError):
            if parent.parent == parent:  # pragma: no cover - the root always exists
                return
            parent = parent.parent
            continue
        except OSError as e:
            raise InputError(f"cannot access: {e.strerror or e}", path=parent) from e
        break
    if not stat.S_ISDIR(st.st_mode):
        raise InputError(f"not a directory, cannot create the output {str(path)!r} in it",
                         path=parent)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"no permission to create the output {str(path)!r} in this directory",
                         path=parent)


#: How a non-empty destination is to be replaced, for a caller of the Python API.
OVERWRITE_HINT = "pass overwrite=True to replace it"


def check_output_dir(path: StrPath, overwrite: bool = False,
                     may_replace: Callable[[Path], str | None] | None = None,
                     overwrite_hint: str = OVERWRITE_HINT, *,
                     appeared: bool = False) -> None:
    """Refuse ``path`` as the destination of :func:`atomic_output_dir` with the same rules.

    A missing path or an empty directory is fine; a symbolic link or anything that is not a
    directory is refused; a non-empty directory is refused unless ``overwrite`` is true and
    ``may_replace`` (if given) returns None for it. ``overwrite_hint`` ends the message for a
    non-empty directory (a command line says which option to use). Paths that cannot be
    inspected (permissions, symbolic-link loops) are refused too, as is a destination whose
    nearest existing ancestor is not a directory or is not writable (so the folder could
    not be created or moved into place). ``appeared``: the check after the work, so a
    non-empty directory there was made by another process meanwhile (the message says so).

    Raises:
        InputError: naming ``path``.
    """
    p = Path(path)
    try:
        st = os.lstat(p)
    except (FileNotFoundError, NotADirectoryError):
        _check_parent(p)
        return
    except OSError as e:
        raise InputError(f"cannot access output path: {e.strerror or e}", path=p) from e
    _check_parent(p)
    if stat.S_ISLNK(st.st_mode):
        raise InputError("output path is a symbolic link; refusing to replace it", path=p)
    if not stat.S_ISDIR(st.st_mode):
        raise InputError("output path exists and is not a directory", path=p)
    try:
        non_empty = any(p.iterdir())
    except OSError as e:
        raise InputError(f"cannot list output directory: {e.strerror or e}", path=p) from e
    if not non_empty:
        return
    if not overwrite:
        if appeared:
            raise InputError("another process wrote this output directory while this run was "
                             f"working ({overwrite_hint})", path=p)
        raise InputError(f"output directory exists and is not empty ({overwrite_hint})", path=p)
    if may_replace is not None:
        try:
            reason = may_replace(p)
        except OSError as e:
            raise InputError(f"cannot inspect output directory: {e.strerror or e}",
                             path=p) from e
        if reason is not None:
            raise InputError(f"refusing to overwrite: {reason}", path=p)
    locked = _undeletable(p)
    if locked is not None:
        raise InputError(f"cannot replace it: {locked} is not writable, so its old contents "
                         "could not be deleted", path=p)


def _undeletable(path: Path) -> Path | None:
    """The first directory under ``path`` (itself included) whose entries this process may
    not delete (no write or search permission; a root that may is not refused), or None."""
    for top, dirs, _files in os.walk(path, onerror=None):
        dirs[:] = [d for d in dirs if not os.path.islink(os.path.join(top, d))]
        if not os.access(top, os.W_OK | os.X_OK):
            return Path(top)
    return None


def _move_into_place(tmp: Path, path: Path) -> None:
    if not os.path.lexists(path):
        try:
            os.rename(tmp, path)
        except OSError as e:
            raise InputError(f"cannot move output into place: {e.strerror or e}", path=path) from e
        return
    old = _sibling(path, "old")
    try:
        try:
            os.rename(path, old)
        except OSError as e:
            raise InputError(f"cannot move the old directory aside: {e.strerror or e}",
                             path=path) from e
        os.rename(tmp, path)
    except BaseException as e:  # a signal too, whichever rename it came after
        if os.path.lexists(old) and not os.path.lexists(path):
            os.rename(old, path)  # put the old directory back
        if isinstance(e, OSError):
            raise InputError(f"cannot move output into place: {e.strerror or e}",
                             path=path) from e
        raise
    shutil.rmtree(old, ignore_errors=True)
    if os.path.lexists(old):  # checked before (check_output_dir): permissions changed since
        raise InputError(f"the new outputs are in place, but the replaced ones could not all "
                         f"be deleted: delete {old} by hand", path=path)


@contextlib.contextmanager
def atomic_output_dir(path: StrPath, overwrite: bool = False,
                      may_replace: Callable[[Path], str | None] | None = None,
                      overwrite_hint: str = OVERWRITE_HINT) -> Iterator[Path]:
    """Build a directory in a temporary sibling and move it to ``path`` on success.

    Usage::

        with atomic_output_dir("out/flight", overwrite=False) as tmp:
            (tmp / "a.txt").write_text("...")
        # out/flight now holds a.txt; on an exception nothing changed

    Args:
        path: the final directory. Missing parents are created.
        overwrite: replace an existing **non-empty** directory. Without it such a directory
            is refused with an :class:`InputError` before anything is written (and checked
            again before the final rename). A missing path or an empty directory is always
            fine; a file or symbolic link at ``path`` is always refused.
        may_replace: optional safety check called with an existing non-empty ``path`` when
            ``overwrite`` is true; returns ``None`` to allow replacing it or a reason
            (e.g. "contains files that are not part of a flight") to refuse.
        overwrite_hint: ends the message refusing a non-empty directory (how to replace it).

    Yields:
        The empty temporary directory ``.<name>.tmp-<pid>-<host>-<random>`` next to
        ``path``. It is renamed to ``path`` when the block exits normally and deleted when it
        raises. Stale temporaries of ``path`` left by killed processes are removed first.
    """
    p = Path(path)
    remove_stale_temporaries(p.parent, p.name)
    check_output_dir(p, overwrite, may_replace, overwrite_hint)
    _make_parent(p)
    tmp = _sibling(p, "tmp")  # unique: this process's pid and 48 random bits
    try:  # created inside the try: a signal right after still removes it
        reserve_output(p)
        try:
            os.mkdir(tmp)  # 0o777 minus umask, unlike tempfile.mkdtemp's 0o700
        except OSError as e:
            if is_disk_full(e):
                raise write_error(e, p) from e
            raise InputError(f"cannot create the output folder: {e.strerror or e}",
                             path=p) from e
        yield tmp
        check_output_dir(p, overwrite, may_replace, overwrite_hint, appeared=True)
        _move_into_place(tmp, p)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        release_output(p)
