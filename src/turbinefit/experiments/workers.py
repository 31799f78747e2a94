"""The local worker processes of a sweep, which never outlive it.

A sweep runs its flights in a :class:`concurrent.futures.ProcessPoolExecutor` of spawned
processes (:func:`process_pool`). Their lifetime belongs to the sweep's process:

* **it ends, whatever the signal** (SIGKILL included): each worker asks the kernel to kill
  it when its parent dies (Linux ``prctl(PR_SET_PDEATHSIG, SIGKILL)``; elsewhere a thread
  that checks ``os.getppid()`` every half second), and exits at once if the parent is
  already gone. A worker left running would keep the caller's pipes open, and the caller
  waiting;
* **it is interrupted** (Ctrl-C, SIGTERM, SIGHUP, an error or a full disk while it writes
  the rows): the pool's workers are killed at once instead of being waited for (a flight
  can take minutes); they hold nothing to clean up (rows live in the parent's memory until
  it writes them). Nor do they own a named semaphore, which multiprocessing's resource
  tracker would report as leaked: tqdm's lock, which the simulator's (disabled) progress
  bars create, is a thread lock in a worker;
* the workers ignore SIGINT, SIGTERM and SIGHUP, which a terminal or a service manager sends
  to the whole process group: the parent handles them (and then kills the workers), so a
  worker never dies first, printing its own traceback. A worker is started with them
  blocked (the parent blocks them in its thread while the pool spawns a process, and a
  process inherits its parent's mask), so that one arriving while the worker's interpreter
  starts waits until :func:`start_worker` has set it to be ignored, and is then dropped.

Each worker runs one solver thread (``OMP_NUM_THREADS=1``): two processes that each use
every core slow each other several times over (measured on the tracker).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

T = TypeVar("T")

#: ``prctl`` option: the signal a process gets when its parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1
#: How often a worker without ``prctl`` checks that its parent is alive [s].
PARENT_POLL_S = 0.5


def _set_death_signal() -> bool:
    """Ask Linux to SIGKILL this process when its parent dies; False if not possible."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)) == 0
    except (OSError, AttributeError):  # pragma: no cover - no C library, no prctl
        return False


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if os.getppid() != parent_pid:
            os._exit(1)


#: The signals the parent handles and its workers ignore.
PARENT_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                       if hasattr(signal, name))


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """:data:`PARENT_SIGNALS` blocked in this thread during the block (where the platform
    can): one that arrives meanwhile is delivered after it; a process started inside it
    starts with them blocked."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:  # pragma: no cover - not POSIX
        yield
        return
    old = mask(signal.SIG_BLOCK, PARENT_SIGNALS)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, old)


def start_worker(parent_pid: int) -> None:
    """The initializer of each worker (see the module docstring)."""
    for sig in PARENT_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):  # blocked since it started: now ignored
        signal.pthread_sigmask(signal.SIG_UNBLOCK, PARENT_SIGNALS)
    with contextlib.suppress(ImportError):
        from tqdm import tqdm

        tqdm.set_lock(threading.RLock())  # not a semaphore that a kill would leak
    if not _set_death_signal():
        threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True,
                         name="turbinefit-parent-watch").start()
    if os.getppid() != parent_pid:  # the parent died before the death signal was set
        os._exit(1)


def kill_workers(pool: cf.ProcessPoolExecutor) -> None:
    """Kill the pool's worker processes now (those still running a flight included)."""
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    if terminate is not None:
        terminate()
        return
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        with contextlib.suppress(Exception):  # already gone
            process.kill()


class _Pool(cf.ProcessPoolExecutor):
    """A process pool whose workers start with the parent's signals blocked: the pool
    spawns them in the thread that submits (a spawned pool adds a worker per submission
    until it has all)."""

    def submit(self, fn: Callable[..., T], /, *args: Any,
               **kwargs: Any) -> cf.Future[T]:
        with signals_held():
            return super().submit(fn, *args, **kwargs)


@contextlib.contextmanager
def process_pool(workers: int) -> Iterator[cf.ProcessPoolExecutor]:
    """A pool of ``workers`` spawned processes that end with this one; if the block raises
    (an interruption too), the workers are killed before the pool is shut down."""
    import multiprocessing as mp

    # the workers are spawned, so they read the variable when their OpenMP runtime loads
    saved = os.environ.get("OMP_NUM_THREADS")
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        with _Pool(max_workers=workers, mp_context=mp.get_context("spawn"),
                   initializer=start_worker, initargs=(os.getpid(),)) as pool:
            try:
                yield pool
            except BaseException:
                kill_workers(pool)
                pool.shutdown(wait=False, cancel_futures=True)
                # let the pool's manager thread see its killed workers and close its wake-up
                # pipe now: at interpreter exit Python 3.11 would race it, writing to that
                # pipe as it closes ("Exception ignored ... Bad file descriptor")
                manager = getattr(pool, "_executor_manager_thread", None)
                if manager is not None:
                    manager.join(timeout=5.0)
                raise
    finally:
        if saved is None:
            os.environ.pop("OMP_NUM_THREADS", None)
        else:
            os.environ["OMP_NUM_THREADS"] = saved
