"""Every number that comes in, and the one check it passes: command-line options, fields
of input files and photo metadata share the :class:`Quantity` that names their unit and
their plausible range.

A :class:`Quantity` refuses a value that is not a number, not finite, or outside its range,
with one :class:`~turbinefit.errors.InputError` line naming where it came from (the file,
line and field, or the option) and the range. The command line turns the same check into
its option types (:func:`turbinefit.cli.common.option`), so ``--near nan,0``, a gimbal
pitch of 200 deg in a photo and ``latitude: 91`` in ``georef.yaml`` are refused by the same
code with the same words.

The catalogue below holds the quantities more than one input shares; a quantity that only
one input has (``coverage --step``, ``plan --standoff``) is declared beside its use, from
the same class, and listed in ``docs/method.md#input-limits``.

Written here rather than taken from a validation library (pydantic, attrs validators)
because the check is three comparisons; what matters is the one message format shared
with every other input error, and no such library reports ``file:line [field]``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from turbinefit.errors import InputError, plain_number
from turbinefit.io.limits import MAX_ANGLE_RAD, MAX_COORDINATE_M, MAX_LENGTH_M, MAX_TIMESTAMP_S


@dataclass(frozen=True)
class Quantity:
    """A kind of number that comes in: what it is, its unit and its plausible range.

    Attributes:
        what: its name in messages (``"latitude"``).
        unit: its unit in messages (``"deg"``; ``""`` for none).
        lo, hi: the range's ends (infinite: no end).
        lo_open, hi_open: whether an end is excluded (``> 0`` rather than ``>= 0``).
        integer: whether only whole numbers are accepted.
    """

    what: str
    unit: str = ""
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False

    def accepts(self, value: float) -> bool:
        """Whether ``value`` (a float) is finite and inside the range."""
        if not math.isfinite(value):
            return False
        above = value > self.lo if self.lo_open else value >= self.lo
        below = value < self.hi if self.hi_open else value <= self.hi
        if not (above and below):
            return False
        return not self.integer or value == int(value)

    def range_text(self) -> str:
        """The range in words: ``between -90 and 90 deg``, ``> 0 m``, ``at most 5 m``."""
        unit = f" {self.unit}" if self.unit else ""
        lo, hi = plain_number(_plain(self.lo)), plain_number(_plain(self.hi))
        kind = "a whole number" if self.integer else "a number"
        if math.isinf(self.lo) and math.isinf(self.hi):
            return f"{kind}{unit}"
        if math.isinf(self.hi):
            return f"{'>' if self.lo_open else '>='} {lo}{unit}"
        if math.isinf(self.lo):
            return f"{'<' if self.hi_open else '<='} {hi}{unit}"
        if self.lo_open or self.hi_open:
            left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            return f"in {left}{lo}, {hi}{right}{unit}"
        return f"between {lo} and {hi}{unit}"

    def problem(self, value: object) -> str | None:
        """Why ``value`` is refused (one phrase), or None if it is accepted."""
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            return f"{self.what} must be a number, got {value!r}"
        v = float(value)
        if math.isnan(v):
            return f"{self.what} must be a number, got nan"
        if self.accepts(v):
            return None
        unit = f" {self.unit}" if self.unit else ""
        if self.integer and math.isfinite(v) and v != int(v) and self._in_range(v):
            return f"{self.what} must be a whole number, got {plain_number(v)}"
        return f"{self.what} {plain_number(v)}{unit} is out of range: it must be " \
               f"{self.range_text()}"

    def _in_range(self, v: float) -> bool:
        return Quantity(self.what, self.unit, self.lo, self.hi, self.lo_open,
                        self.hi_open).accepts(v)

    def check(self, value: object, path: object | None = None, line: int | None = None,
              field: str | None = None) -> float:
        """``value`` as a float if this quantity accepts it.

        Raises:
            InputError: naming ``path``, ``line`` and ``field`` (any of them may be None),
                the value and the range.
        """
        why = self.problem(value)
        if why is not None:
            raise InputError(why, path=path, line=line, field=field)
        return float(value)  # type: ignore[arg-type]

    def parse(self, text: str, path: object | None = None, line: int | None = None,
              field: str | None = None) -> float:
        """The number written in ``text`` (``float`` syntax), checked (:meth:`check`)."""
        try:
            value = float(text.strip())
        except (ValueError, AttributeError):
            raise InputError(f"{self.what} must be a number, got {text!r}", path=path,
                             line=line, field=field) from None
        return self.check(value, path, line, field)

    def check_array(self, values: ArrayLike, path: object | None = None,
                    field: str | None = None, names: Sequence[str] | None = None,
                    lines: Sequence[int] | None = None) -> np.ndarray:
        """``values`` (any shape) as float64 if every one is accepted; otherwise the first
        refused one is named, by ``names[i]`` (e.g. the photo's file) or ``lines[i]``
        along the first axis."""
        a = np.asarray(values, dtype=np.float64)
        ok = np.isfinite(a)
        with np.errstate(invalid="ignore"):
            ok &= (a > self.lo) if self.lo_open else (a >= self.lo)
            ok &= (a < self.hi) if self.hi_open else (a <= self.hi)
            if self.integer:
                ok &= a == np.round(a)
        if ok.all():
            return a
        first = np.argwhere(~ok)[0]
        value = float(a[tuple(first)])
        i = int(first[0]) if a.ndim else 0
        where = path
        if names is not None and a.ndim:
            where = names[i]
        line = lines[i] if lines is not None and a.ndim else None
        raise InputError(self.problem(value) or "", path=where, line=line, field=field)


def _plain(x: float) -> float | int:
    return int(x) if math.isfinite(x) and x == int(x) and abs(x) < 1e15 else x


# ---- the quantities several inputs share ---------------------------------------------------

#: WGS84 latitude [deg].
LATITUDE = Quantity("latitude", "deg", -90.0, 90.0)
#: WGS84 longitude [deg].
LONGITUDE = Quantity("longitude", "deg", -180.0, 180.0)
#: Altitude [m] of a photo or a georeferenced origin, in the photos' datum: from below the
#: Dead Sea's shore (-430 m) and the geoid's lowest undulation (-106 m) to above any
#: drone's service ceiling (DJI's enterprise drones: 5000-7000 m).
ALTITUDE = Quantity("altitude", "m", -1000.0, 10000.0)
#: A coordinate [m] of a local (east-north-up or flight) frame.
COORDINATE = Quantity("coordinate", "m", -MAX_COORDINATE_M, MAX_COORDINATE_M)
#: A turbine length (tower, blade) [m]: positive, at most :data:`MAX_LENGTH_M`.
LENGTH = Quantity("length", "m", 0.0, MAX_LENGTH_M, lo_open=True)
#: An angle [rad] as the turbine's heading or blade rotation (not wrapped).
ANGLE_RAD = Quantity("angle", "rad", -MAX_ANGLE_RAD, MAX_ANGLE_RAD)
#: A timestamp [s].
TIMESTAMP = Quantity("timestamp", "s", -MAX_TIMESTAMP_S, MAX_TIMESTAMP_S)
#: An Euler angle of a drone's gimbal or body [deg], as DJI writes them (yaw, pitch, roll
#: each within a half turn either way).
ATTITUDE_DEG = Quantity("attitude angle", "deg", -180.0, 180.0)
#: A fraction in [0, 1].
FRACTION = Quantity("fraction", "", 0.0, 1.0)


def named(quantity: Quantity, what: str) -> Quantity:
    """``quantity`` under another name in messages (``named(LATITUDE, "GpsLatitude")``)."""
    return Quantity(what, quantity.unit, quantity.lo, quantity.hi, quantity.lo_open,
                    quantity.hi_open, quantity.integer)


def pixel(axis: str, size: float, margin: float = 0.5) -> Quantity:
    """A pixel coordinate ``axis`` (``"x"``) of an image ``size`` pixels along it: within
    the image, pixel centres at whole numbers from 0, edges ``margin`` beyond them."""
    return Quantity(f"{axis}", "px", -margin, size - 1 + margin)


def check_latlonalt(latitude: object, longitude: object, altitude: object | None = None,
                    path: object | None = None, line: int | None = None,
                    prefix: str = "") -> tuple[float, ...]:
    """``(latitude, longitude[, altitude])`` checked (fields named ``prefix + 'latitude'``
    and so on)."""
    out = [LATITUDE.check(latitude, path, line, f"{prefix}latitude"),
           LONGITUDE.check(longitude, path, line, f"{prefix}longitude")]
    if altitude is not None:
        out.append(ALTITUDE.check(altitude, path, line, f"{prefix}altitude"))
    return tuple(out)
