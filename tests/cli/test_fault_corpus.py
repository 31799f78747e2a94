"""The fault corpus (``tests/faults.py``): every malformed input of every command gets exit
status 2, one error line naming the file or option, no traceback, no hang, nothing written
and its inputs unchanged."""

from __future__ import annotations

from pathlib import Path

import pytest
from fault_cases import CASES
from faults import make_base, run_case


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_base(tmp_path_factory.mktemp("faults"))


def test_the_corpus_is_broad() -> None:
    names = [c.name for c in CASES]
    assert len(set(names)) == len(names) >= 150
    assert {c.argv(Path("w"))[0] for c in CASES} >= {"fit", "track", "simulate", "detect",
                                                     "evaluate", "report"}


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_fault(case, base: Path, tmp_path: Path) -> None:
    work = tmp_path / "work"
    work.mkdir()
    outcome = run_case(case, base, work)
    assert outcome.problems(case) == [], outcome.stderr
