"""How the ``turbinefit`` command ends on SIGINT, SIGTERM and SIGHUP: the same way for
all three and every command.

* **During start-up** (the imports before :func:`turbinefit.cli.main` runs), there is
  nothing to clean up: :func:`exit_quietly_on_signals` makes each signal print one line and
  end the process at once, so that an early Ctrl-C prints no traceback.
* **While a command runs**, :class:`RaisingOnSignals` turns each signal into an
  :class:`Interrupted` exception, raised in the main thread (signal handlers run only
  there; the detector pool's threads and tqdm's monitor are waited for or are daemons), so
  that the cleanup already written for Ctrl-C runs: ``atomic_output_dir`` removes its
  temporary folder, the sweep kills its workers. A second signal during that cleanup is
  ignored (SIGKILL still ends the process). ``main`` prints ``turbinefit: interrupted
  (SIGTERM)`` and returns 128 + the signal number: 130, 143, 129.

* **Once the command's work is done** (``main`` has its exit status: every output is
  complete, renamed into place), :func:`ignore_from_now` ignores the three signals while
  the interpreter exits. A signal that arrived before that point ends the command with
  its line and 128 + the signal, even in its last milliseconds (outputs already in place
  are complete and stay); one that arrives after it is too late to stop anything and
  changes nothing: the command exits with its own status. Without this, a signal in the
  interpreter's last moments was lost (status 0) or killed it silently (status -15), as
  Python restores the default handlers when it finalises.

A signal whose disposition is "ignore" when the command starts (``nohup`` ignores SIGHUP, a
non-interactive shell's background job ignores SIGINT) stays ignored.
"""

from __future__ import annotations

import os
import sys

from turbinefit.errors import Interrupted

# Imported first of all by the command, so only what the interpreter has already loaded:
# the C module of the signals (the ``signal`` module would load ``enum`` first, 30 ms).
TYPE_CHECKING = False
if TYPE_CHECKING:
    import signal as _sig
    from collections.abc import Callable
    from types import FrameType, TracebackType
    from typing import Any
else:
    try:
        import _signal as _sig
    except ImportError:  # pragma: no cover - not CPython
        import signal as _sig

__all__ = ["Interrupted", "RaisingOnSignals", "exit_quietly_on_signals", "message",
           "signal_of"]

#: The signals every command handles like Ctrl-C, and their names.
NAMES: dict[int, str] = {int(getattr(_sig, name)): name for name in ("SIGINT", "SIGTERM", "SIGHUP")
                         if hasattr(_sig, name)}
SIGNALS = tuple(NAMES)


def signal_name(signum: int) -> str:
    return NAMES.get(signum, f"signal {signum}")


def exit_status(signum: int) -> int:
    """The shell's status of a process ended by ``signum``: 128 + its number."""
    return 128 + signum


def message(signum: int) -> str:
    """The one line a command prints when a signal stops it."""
    return f"turbinefit: interrupted ({signal_name(signum)})"


def signal_of(exc: KeyboardInterrupt) -> int:
    """The signal that raised ``exc``: its own, or SIGINT for a plain KeyboardInterrupt."""
    return exc.signum if isinstance(exc, Interrupted) else int(_sig.SIGINT)


def _exit_now(signum: int, frame: FrameType | None) -> None:
    os.write(2, (message(signum) + "\n").encode())
    os._exit(exit_status(signum))


def _handled(sig: int) -> bool:
    """Whether ``sig`` is not ignored (by the parent, ``nohup`` or ourselves)."""
    return _sig.getsignal(sig) != _sig.SIG_IGN


def started_as_command() -> bool:
    """Whether this process is the ``turbinefit`` command (its script or ``python -m
    turbinefit.cli``, whose ``argv[0]`` is ``-m`` while the package is imported), not a
    program that imports the package."""
    argv0 = (getattr(sys, "argv", None) or [""])[0]
    return argv0 == "-m" or os.path.basename(argv0) in ("turbinefit", "turbinefit.exe")


#: Whether this process is the ``turbinefit`` command, as found at start-up (while the
#: package is imported ``python -m``'s ``argv[0]`` is ``-m``; later it is a path).
_is_command = False


def exit_quietly_on_signals() -> None:
    """Start-up: each handled signal prints its line and ends the process at once."""
    global _is_command
    if not started_as_command():
        return
    _is_command = True
    for sig in SIGNALS:
        try:
            if _handled(sig):
                _sig.signal(sig, _exit_now)
        except ValueError:  # pragma: no cover - not the main thread
            return


def ignore_from_now() -> None:
    """The command's work is done: ignore its signals until the process ends (see the
    module docstring). Only in the ``turbinefit`` command, not in a program calling
    ``main``."""
    if not _is_command:
        return
    for sig in SIGNALS:
        try:
            _sig.signal(sig, _sig.SIG_IGN)
        except ValueError:  # pragma: no cover - not the main thread
            return


#: How often [s] a swallowed signal is sent again until it is raised, and for how long.
RESEND_EVERY_S, RESEND_FOR_S = 0.005, 5.0


class RaisingOnSignals:
    """While the ``with`` block runs, the first handled signal raises :class:`Interrupted`
    in the main thread and later ones are ignored; the previous handlers are restored after
    it. Outside the main thread (a caller's worker thread) this does nothing.
    :attr:`caught` is the signal received, if any: whatever exception ends the command
    after it is the signal's doing (a library may have made another of it).

    Python swallows an exception raised where nobody can catch it, in a weak reference's
    callback or a ``__del__`` (the import system runs such callbacks), and hands it to
    ``sys.unraisablehook``: the block's hook has the signal sent again, every few
    milliseconds from another thread until it is raised outside the hook (raised inside
    it, it would be swallowed again), so that it is raised once that code has returned
    instead of being lost."""

    def __init__(self) -> None:
        self.caught: int | None = None
        #: A swallowed signal being sent again, until it is raised.
        self.pending: int | None = None
        self.saved: dict[int, object] = {}
        self.saved_hook: Callable[[Any], object] | None = None

    def _raise(self, signum: int, frame: FrameType | None) -> None:
        if self.pending is None:
            if self.caught is not None:  # cleaning up after the first one: let it finish
                return
        elif _inside(frame, self._unraisable.__code__):
            return  # raised here it would be swallowed again: the next sending comes later
        self.caught = signum
        self.pending = None
        raise Interrupted(signum)

    def _unraisable(self, unraisable: Any) -> None:
        exc = unraisable.exc_value
        if isinstance(exc, Interrupted) and self.caught == exc.signum:
            # swallowed where it was raised: send it again from another thread, so that it
            # is raised after this hook and the code that swallowed it have returned
            if self.pending is None:
                import threading

                self.pending = exc.signum
                threading.Thread(target=self._resend, daemon=True,
                                 name="turbinefit-signal-resend").start()
            return
        (self.saved_hook or sys.__unraisablehook__)(unraisable)

    def _resend(self) -> None:
        import time

        end = time.monotonic() + RESEND_FOR_S
        while time.monotonic() < end:
            signum = self.pending
            if signum is None:
                return
            os.kill(os.getpid(), signum)
            time.sleep(RESEND_EVERY_S)


    def __enter__(self) -> RaisingOnSignals:
        for sig in SIGNALS:
            try:
                previous = _sig.getsignal(sig)
                if previous is None or previous == _sig.SIG_IGN:
                    continue  # ignored, or set outside Python: leave it alone
                _sig.signal(sig, self._raise)
            except ValueError:  # not the main thread of the main interpreter
                break
            self.saved[sig] = previous
        if self.saved:
            self.saved_hook = sys.unraisablehook
            sys.unraisablehook = self._unraisable
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.pending = None  # the block is over: stop sending a swallowed signal again
        for sig, previous in self.saved.items():
            _sig.signal(sig, previous)  # type: ignore[arg-type]
        if self.saved_hook is not None:
            sys.unraisablehook = self.saved_hook


def _inside(frame: FrameType | None, code: object) -> bool:
    """Whether ``frame`` or one of its callers runs ``code``."""
    while frame is not None:
        if frame.f_code is code:
            return True
        frame = frame.f_back
    return False

