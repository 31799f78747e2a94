"""The package's exceptions: one base class, caught in one place by the CLI;
:class:`Interrupted`, a signal that stops a command, and :func:`interrupt_within`, which
finds one that a library turned into an exception of its own; and :func:`plain_number`,
how error messages print numbers.

Imported by the command line before its signal handlers are set (through
:mod:`turbinefit.cli.signals`): the standard library only, and nothing at module level.
"""

from __future__ import annotations

TYPE_CHECKING = False  # not typing's: see the docstring
if TYPE_CHECKING:
    from typing import ClassVar


class TurbinefitError(Exception):
    """Base class of every error turbinefit raises on purpose."""


class InputError(TurbinefitError):
    """Bad input: a missing or malformed file, or a value out of range.

    The message is one line naming the file (and line or field where known) and the
    problem, e.g. ``keyframes.txt:12: quaternion has zero norm``.
    """

    def __init__(self, message: str, path: object | None = None, line: int | None = None,
                 field: str | None = None) -> None:
        where = ""
        if path is not None:
            where = str(path)
            if line is not None:
                where += f":{line}"
            if field is not None:
                where += f" [{field}]"
            where += ": "
        elif field is not None:
            where = f"{field}: "
        super().__init__(where + message)
        self.path = path
        self.line = line
        self.field = field


#: The signals a command handles like Ctrl-C, by number (POSIX numbers; SIGHUP is absent
#: where the platform has none, which never raises it).
SIGNAL_NAMES = {2: "SIGINT", 15: "SIGTERM", 1: "SIGHUP"}


class Interrupted(KeyboardInterrupt):
    """A command was stopped by a signal (:mod:`turbinefit.cli.signals` raises it). A
    ``KeyboardInterrupt`` so that everything that cleans up after Ctrl-C (and lets
    ``except Exception`` pass it) does so for it too.

    The last one raised is kept in :attr:`last`, for :func:`interrupt_within`: some
    libraries keep only its name."""

    last: ClassVar[Interrupted | None] = None

    def __init__(self, signum: int) -> None:
        super().__init__(SIGNAL_NAMES.get(signum, f"signal {signum}"))
        self.signum = signum
        Interrupted.last = self

    @property
    def exit_status(self) -> int:
        """The shell's status of a process ended by the signal: 128 + its number."""
        return 128 + self.signum


def interrupt_within(exc: BaseException) -> KeyboardInterrupt | None:
    """The interrupt (Ctrl-C, or a command's signal) that a library turned into an
    exception of its own, or None. A signal's handler runs wherever Python code runs, also
    inside a library's callbacks, which may wrap what it raised:

    * a C extension's module initialisation (pybind11: onnxruntime) raises ``ImportError:
      initialization failed`` with the interrupt as its cause;
    * ctypes converting an argument (numpy's ``ndpointer`` runs Python) raises
      ``ArgumentError: argument 3: Interrupted: SIGINT``, keeping only the name: the
      interrupt is then the last one raised (:attr:`Interrupted.last`), or Ctrl-C's.
    """
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    text = str(exc)
    for name in SIGNAL_NAMES.values():
        if f"Interrupted: {name}" in text:
            last = Interrupted.last
            return last if last is not None and str(last) == name else \
                Interrupted(next(k for k, v in SIGNAL_NAMES.items() if v == name))
    if "KeyboardInterrupt" in text:
        return KeyboardInterrupt()
    return None


def plain_number(value: object) -> str:
    """A number as messages print it: ``0.0``, ``12``, ``1e+300``, ``nan``, never
    ``np.float64(0.0)``. Whole-number types print as integers, other reals with ``repr``
    precision (so a timestamp keeps its digits; a float32 or float16 with its own
    shortest digits, ``1.002`` not ``1.0019999742507935``); anything else as ``repr``."""
    import numbers

    import numpy as np

    if isinstance(value, bool):
        return repr(value)
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, (np.float32, np.float16)):
        return str(value)
    if isinstance(value, numbers.Real):
        return repr(float(value))
    return repr(value)
