"""The package's exceptions: one base class, caught in one place by the CLI; and
:func:`plain_number`, how error messages print numbers."""

from __future__ import annotations


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
