"""The held-out rule of real photos (turbinefit.eval.holdout): fixed by the name alone,
copies with their originals, about the asked share."""

from __future__ import annotations

import random

import pytest

from turbinefit.eval.holdout import HELD_OUT_FRACTION, is_held_out, name_hash, original_name


def test_a_copy_is_named_after_its_original() -> None:
    assert original_name("transformedDJI_0049.jpg") == "DJI_0049.jpg"
    assert original_name("photos/blade/transformedDJI_0049.jpg") == "DJI_0049.jpg"
    assert original_name("DJI_0049.jpg") == "DJI_0049.jpg"
    assert original_name("transformed") == "transformed"  # nothing left: its own name


def test_the_rule_depends_on_the_name_alone() -> None:
    names = [f"DJI_{k:04d}.jpg" for k in range(400)]
    first = [is_held_out(n) for n in names]
    shuffled = names[:]
    random.Random(3).shuffle(shuffled)
    again = dict(zip(shuffled, (is_held_out(n) for n in shuffled), strict=True))
    assert first == [again[n] for n in names]
    # a known value: the rule may not change once figures were measured with it
    assert name_hash("DJI_0049.jpg") == pytest.approx(0.8497, abs=1e-4)
    assert not is_held_out("DJI_0049.jpg")


def test_copies_land_on_their_originals_side() -> None:
    names = [f"DJI_{k:04d}.jpg" for k in range(1000)]
    held = [n for n in names if is_held_out(n)]
    kept = [n for n in names if not is_held_out(n)]
    assert held and kept
    assert all(is_held_out("transformed" + n) for n in held)
    assert not any(is_held_out("transformed" + n) for n in kept)
    assert all(is_held_out(f"images/blade/transformed{n}") for n in held)


def test_the_share_held_out_is_about_the_fraction() -> None:
    names = [f"IMG_{k:05d}.JPG" for k in range(4000)]
    share = sum(map(is_held_out, names)) / len(names)
    assert abs(share - HELD_OUT_FRACTION) < 0.03
    assert not any(is_held_out(n, 0.0) for n in names)
    assert all(is_held_out(n, 1.0) for n in names)
    # a larger fraction holds out a superset
    assert all(is_held_out(n, 0.6) for n in names if is_held_out(n, 0.3))
