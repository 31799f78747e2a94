"""``turbinefit experiment`` and ``turbinefit report``: a study run and its report rebuilt
from the rows (saying how many of the planned rows), bad sweep files and a full disk."""

from __future__ import annotations

import errno
import json
import re
import shutil
from pathlib import Path

import pytest
import yaml
from support import assert_one_line_error, entries, run, tiny_sweep

from turbinefit.cli import main
from turbinefit.experiments import SweepConfig, read_rows


def test_unknown_sweep_key_and_cli_errors(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match="unknown sweep option"):
        SweepConfig.from_dict({"flihgts": 3})
    bad = tmp_path / "bad.yaml"
    bad.write_text("flights: 3\nkeyframez: 10\n")
    out = tmp_path / "out"
    assert main(["experiment", "unary", "--config", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.yaml" in err[0] and "keyframez" in err[0]
    assert not out.exists()  # nothing started
    assert main(["report", str(tmp_path)]) == 2
    assert "not an experiment folder" in capsys.readouterr().err


def test_cli_experiment_and_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tiny_sweep("roll", flights=2)
    sweep_file = tmp_path / "roll.yaml"
    sweep_file.write_text(yaml.safe_dump(cfg.to_dict()))
    out = tmp_path / "roll"
    assert main(["experiment", "roll", "--config", str(sweep_file), "--out", str(out),
                 "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "roll: 4 of 4 planned rows" in printed and "rows/s" in printed
    report = (out / "report.md").read_text()
    assert "Mean absolute camera roll error" in report and (out / "roll.png").is_file()
    # the report is rebuilt from the rows alone
    (out / "report.md").unlink()
    (out / "roll.png").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "report.md").read_text() == report and (out / "roll.png").is_file()
    # `report` on a parent folder rebuilds every study below it
    shutil.copytree(out, tmp_path / "all" / "roll")
    assert main(["report", str(tmp_path / "all")]) == 0
    index = (tmp_path / "all" / "report.md").read_text()
    assert "| roll | 2 x 2 |" in index and "(roll/report.md)" in index
    assert "ncomplete" not in index + report
    # a report of an interrupted run says how many of the planned rows it is drawn from
    table = out / "rows.csv"
    table.write_text("".join(table.read_text().splitlines(keepends=True)[:2]))  # 1 of 4 rows
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    assert capsys.readouterr().out == (f"wrote {out / 'report.md'} from 1 of 4 planned rows "
                                       "(incomplete)\n")
    assert "**Incomplete: drawn from 1 of 4 planned rows**" in (out / "report.md").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["rows"], summary["planned_rows"]) == (1, 4)


class FullDisk:
    """The rows table of a sweep on a disk that fills up at the ``full_at``-th write: half
    of it is written, then ENOSPC."""

    def __init__(self, path: Path, mode: str, buffering: int = -1, full_at: int = 1) -> None:
        self.f = open(path, mode, buffering=buffering)
        self.writes = 0
        self.full_at = full_at

    def __enter__(self) -> FullDisk:
        return self

    def __exit__(self, *exc: object) -> None:
        self.f.close()

    def seek(self, *args: int) -> int:
        return self.f.seek(*args)

    def truncate(self, size: int) -> int:
        return self.f.truncate(size)

    def write(self, data: memoryview) -> int:
        self.writes += 1
        if self.writes == self.full_at:
            self.f.write(data[:len(data) // 2])
            raise OSError(errno.ENOSPC, "No space left on device")
        return self.f.write(data)


@pytest.mark.parametrize("full_at", [1, 2])
def test_a_full_disk_is_one_line_and_leaves_whole_rows(
        full_at: int, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    from turbinefit.experiments import sweep

    monkeypatch.setattr(sweep, "open", lambda *a, **k: FullDisk(*a, **k, full_at=full_at),
                        raising=False)
    sweep_file = tmp_path / "roll.yaml"
    cfg = tiny_sweep("roll", flights=2, configs={"joint": {"preset": "paper-best"}})
    sweep_file.write_text(yaml.safe_dump(cfg.to_dict()))
    out = tmp_path / "roll"
    rc, printed, err = run(capsys, "experiment", "roll", "--config", str(sweep_file), "--out",
                           str(out), "--workers", "1", "--quiet")
    line = assert_one_line_error(rc, printed, err,
                                 re.escape(f"no space left on device writing {out / 'rows.csv'}"))
    if full_at == 1:  # nothing finished: no trace of the run
        assert entries(tmp_path) == ["roll.yaml"]
    else:  # the first flight's rows are kept, whole, for the next run to resume from
        assert line.endswith("; its 1 finished row kept: run the same command again to resume")
        assert len(read_rows(out / "rows.csv")) == 1
        assert (out / "rows.csv").read_text().endswith("\n")
