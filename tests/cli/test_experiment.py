"""``turbinefit experiment`` and ``turbinefit report``: a study run and its report rebuilt
from the rows, and bad sweep files."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from support import tiny_sweep

from turbinefit.cli import main
from turbinefit.experiments import SweepConfig


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
