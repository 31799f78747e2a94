"""Which labelled real photos are held out from training, by a rule fixed before any
training: a hash of the photo's *original* name.

The rule decides each photo alone (no list, no seed, no order): a photo is held out when
the SHA-256 of its original name, read as a number in [0, 1), is below the fraction
(:data:`HELD_OUT_FRACTION`). The same name is always on the same side, on every machine,
whatever other photos a set holds.

Public sets often hold augmented copies of their photos named after the original (the
ertis set's ``transformedDJI_0049.jpg`` is ``DJI_0049.jpg`` flipped). A copy must never
land on the other side from its original, or the held-out figures would be measured on
photos the net was trained on: :func:`original_name` strips the copy's prefix
(:data:`COPY_PREFIXES`) before hashing, so a copy always goes with its original.

``benchmarks/bench_real.py`` measures on the held-out part only; ``turbinefit train
--boxes`` trains on the rest (``--hold-out``). With :data:`HELD_OUT_FRACTION` 0.4 the ertis
set's held-out part is 110 of its 253 whole-turbine originals (43 %) and 93 of its 282
blade originals (33 %): at least 30 % of each class, as the benchmark requires.
"""

from __future__ import annotations

import hashlib
from pathlib import PurePath

#: The share of photo names (by hash) that is held out.
HELD_OUT_FRACTION = 0.4
#: Name prefixes of augmented copies, stripped to find the original's name.
COPY_PREFIXES = ("transformed",)


def original_name(name: str) -> str:
    """The file name of the photo ``name`` (a path or a file name) is a copy of, or its
    own file name: ``transformedDJI_0049.jpg`` -> ``DJI_0049.jpg``."""
    base = PurePath(name).name
    for prefix in COPY_PREFIXES:
        if base.startswith(prefix) and len(base) > len(prefix):
            return base[len(prefix):]
    return base


def name_hash(name: str) -> float:
    """The SHA-256 of ``name``'s original name (:func:`original_name`), as a number in
    [0, 1)."""
    digest = hashlib.sha256(original_name(name).encode("utf-8")).digest()
    return int.from_bytes(digest[:8], "big") / 2.0 ** 64


def is_held_out(name: str, fraction: float = HELD_OUT_FRACTION) -> bool:
    """Whether the photo ``name`` (with its augmented copies) is held out from training."""
    return name_hash(name) < fraction
