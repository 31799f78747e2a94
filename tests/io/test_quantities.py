"""The one check of every number that comes in (turbinefit.io.quantities): ranges, open
ends, whole numbers, NaN and infinities, the message naming file, line and field, and the
first refused value of an array named by its row."""

from __future__ import annotations

import math

import numpy as np
import pytest

from turbinefit.errors import InputError
from turbinefit.io.quantities import (
    ALTITUDE,
    ATTITUDE_DEG,
    LATITUDE,
    LENGTH,
    LONGITUDE,
    Quantity,
    check_latlonalt,
    named,
    pixel,
)


@pytest.mark.parametrize(("q", "good", "bad"), [
    (LATITUDE, [-90, 0, 51.5, 90], [-90.0001, 91, 1e9]),
    (LONGITUDE, [-180, -2.5, 180], [180.5, -359]),
    (ALTITUDE, [-430, 0, 8848], [1e7, -1e9]),
    (LENGTH, [1e-3, 80, 1000], [0, -1, 1000.5]),
    (ATTITUDE_DEG, [-180, -90, 30, 180], [200, 1e6, -181]),
    (Quantity("count", integer=True, lo=1), [1, 7], [0, 1.5]),
])
def test_ranges(q: Quantity, good: list[float], bad: list[float]) -> None:
    for v in good:
        assert q.check(v) == v
    for v in [*bad, math.nan, math.inf, -math.inf]:
        with pytest.raises(InputError):
            q.check(v)
    with pytest.raises(InputError, match="must be a number, got 'x'"):
        q.check("x")
    with pytest.raises(InputError, match="must be a number"):
        q.check(True)


def test_messages_name_where_the_number_came_from() -> None:
    with pytest.raises(InputError) as e:
        LATITUDE.check(91.5, path="georef.yaml", line=3, field="latitude")
    assert str(e.value) == ("georef.yaml:3 [latitude]: latitude 91.5 deg is out of range: it "
                            "must be between -90 and 90 deg")
    with pytest.raises(InputError) as e:
        LENGTH.check(0.0, field="--standoff")
    assert str(e.value) == "--standoff: length 0.0 m is out of range: it must be in (0, 1000] m"
    with pytest.raises(InputError, match=r"^--step: step must be a number, got nan$"):
        Quantity("step", "m", 0.01, 5).parse("nan", field="--step")
    with pytest.raises(InputError, match=r"whole number, got 1\.5"):
        Quantity("n", integer=True).check(1.5)
    assert Quantity("gap", "s", lo=0, lo_open=True).range_text() == "> 0 s"
    assert Quantity("x", hi=5).range_text() == "<= 5"
    assert named(LATITUDE, "GpsLatitude").problem(100) == \
        "GpsLatitude 100.0 deg is out of range: it must be between -90 and 90 deg"


def test_arrays_name_the_first_refused_row() -> None:
    with pytest.raises(InputError, match=r"^b\.jpg \[pitch\]: attitude angle 200\.0 deg"):
        ATTITUDE_DEG.check_array([[0, -90, 0], [10, 200, 0], [1e6, 0, 0]], field="pitch",
                                 names=["a.jpg", "b.jpg", "c.jpg"])
    with pytest.raises(InputError, match=r"^t\.txt:12: latitude must be a number, got nan"):
        LATITUDE.check_array([1.0, np.nan], path="t.txt", lines=[11, 12])
    out = LATITUDE.check_array([1, 2])
    assert out.dtype == np.float64 and out.tolist() == [1.0, 2.0]


def test_pixels_and_positions() -> None:
    x = pixel("x", 320)
    assert x.check(-0.5) == -0.5 and x.check(319.5) == 319.5
    with pytest.raises(InputError, match=r"x 1000000000\.0 px is out of range"):
        x.check(1e9)
    assert check_latlonalt(-35.6, 149.1, 600) == (-35.6, 149.1, 600.0)
    with pytest.raises(InputError, match=r"^origin longitude: longitude 181.0 deg"):
        check_latlonalt(0, 181, prefix="origin ")
