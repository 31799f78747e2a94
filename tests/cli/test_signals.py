"""Signals (turbinefit.cli.signals, turbinefit.experiments.workers): SIGTERM, SIGHUP and
SIGINT end every command alike (its temporary folder removed, one line, exit 128 + the
signal), at start-up too; an experiment's workers end with it whatever the signal; a
temporary folder left by a SIGKILL is removed by the next run into the same place.

The commands run as subprocesses on the small simulated flight; each signal is sent once
the run is seen at the stage to test (its temporary folder exists, its first rows are
written), never after a fixed sleep."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from support import entries

TIMEOUT_S = 60


def default_dispositions() -> None:
    """In the child, before it runs Python: SIGINT, SIGTERM and SIGHUP at their default
    disposition, whatever the test run inherited (a background job of a non-interactive
    shell ignores SIGINT, ``nohup`` ignores SIGHUP; an ignored signal stays ignored in the
    command, which is tested on its own below)."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)


def start(*argv: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "turbinefit.cli", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_dispositions)


def run_code(code: str) -> subprocess.CompletedProcess[str]:
    """Python ``code`` in a child with the default dispositions."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=TIMEOUT_S, preexec_fn=default_dispositions)


def wait_for(proc: subprocess.Popen[str], ready: Callable[[], bool], what: str) -> None:
    """Poll until ``ready()``; fail if the process ends first or it takes too long."""
    deadline = time.monotonic() + TIMEOUT_S
    while not ready():
        if proc.poll() is not None:
            err = proc.communicate()[1]
            pytest.fail(f"ended (status {proc.returncode}) before {what}: {err[-2000:]}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"no {what} within {TIMEOUT_S} s")
        time.sleep(0.01)


def temporaries(out: Path) -> list[Path]:
    return sorted(out.parent.glob(f".{out.name}.*"))


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (Linux /proc)."""
    found = []
    for children in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            kids = [int(c) for c in children.read_text().split()]
        except OSError:  # the thread ended meanwhile
            continue
        for kid in kids:
            found += [kid, *descendants(kid)]
    return found


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie waiting for init to reap it has ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def assert_interrupted(proc: subprocess.Popen[str], sig: int) -> None:
    out, err = proc.communicate(timeout=TIMEOUT_S)
    assert proc.returncode == 128 + sig, err
    assert err == f"turbinefit: interrupted ({signal.Signals(sig).name})\n"
    assert out == ""


needs_proc = pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc")


@pytest.mark.parametrize(("command", "sig"), [
    ("fit", signal.SIGTERM), ("fit", signal.SIGHUP), ("track", signal.SIGINT)])
def test_a_signal_while_writing_removes_the_temporary_folder(
        command: str, sig: int, sim_flight_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = start(command, str(sim_flight_dir), "--out", str(out), "--quiet")
    wait_for(proc, lambda: any(".tmp-" in p.name for p in temporaries(out)),
             "temporary output folder")  # the plots
    proc.send_signal(sig)
    assert_interrupted(proc, sig)
    assert entries(tmp_path) == []  # neither the output nor its temporary folder


def test_a_signal_while_fitting_ends_the_reservation_of_the_output(
        sim_flight_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = start("fit", str(sim_flight_dir), "--out", str(out), "--quiet")
    wait_for(proc, lambda: any(".lock-" in p.name for p in temporaries(out)),
             "reservation of the output")  # checked and reserved, before any writing
    proc.send_signal(signal.SIGTERM)
    assert_interrupted(proc, signal.SIGTERM)
    assert entries(tmp_path) == []


def test_ctrl_c_at_start_up_prints_one_line(tmp_path: Path) -> None:
    # the command's handlers are set when its package is imported, before argparse and the
    # rest: a signal right after that import is one line, not a traceback
    code = ("import os, signal, sys, time\nsys.argv = ['turbinefit']\nimport turbinefit.cli\n"
            "os.kill(os.getpid(), signal.SIGINT)\ntime.sleep(30)\n")
    proc = run_code(code)
    assert (proc.returncode, proc.stderr) == (130, "turbinefit: interrupted (SIGINT)\n")


def test_a_program_calling_main_keeps_its_own_handlers(
        capsys: pytest.CaptureFixture[str]) -> None:
    from turbinefit.cli import main, signals

    before = [signal.getsignal(s) for s in signals.SIGNALS]
    assert signals._exit_now not in before  # importing the package set nothing
    assert main(["simulate", "--list-presets"]) == 0
    assert [signal.getsignal(s) for s in signals.SIGNALS] == before


def test_an_ignored_signal_stays_ignored() -> None:
    # nohup ignores SIGHUP: the command must not start handling it
    code = ("import os, signal, sys\nsignal.signal(signal.SIGHUP, signal.SIG_IGN)\n"
            "sys.argv = ['turbinefit']\nimport turbinefit.cli\nimport turbinefit.cli.report\n"
            "def run(args):\n    os.kill(os.getpid(), signal.SIGHUP)\n"
            "    os.kill(os.getpid(), signal.SIGTERM)\n    return 0\n"
            "turbinefit.cli.report.run = run\nsys.exit(turbinefit.cli.main(['report', '.']))\n")
    proc = run_code(code)
    assert (proc.returncode, proc.stderr) == (143, "turbinefit: interrupted (SIGTERM)\n")


def _sweep(out: Path) -> subprocess.Popen[str]:
    # enough flights that the sweep is still running when its first rows are written
    return start("experiment", "unary", "--flights", "40", "--keyframes", "20", "--workers",
                 "2", "--out", str(out), "--quiet")


def _rows(out: Path) -> int:
    try:
        return len((out / "rows.csv").read_text().splitlines()) - 1
    except OSError:
        return 0


@needs_proc
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_the_workers_end_with_the_experiment(sig: int, tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    proc = _sweep(out)
    wait_for(proc, lambda: _rows(out) >= 1, "first rows")
    workers = descendants(proc.pid)
    assert len(workers) >= 2
    proc.send_signal(sig)
    if sig == signal.SIGKILL:
        proc.communicate(timeout=10)  # returns: no worker holds the pipes
    else:
        assert_interrupted(proc, sig)
    deadline = time.monotonic() + 5
    while any(alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [w for w in workers if alive(w)]
    if sig != signal.SIGKILL:
        text = (out / "rows.csv").read_text()
        assert text.endswith("\n") and _rows(out) % 4 == 0  # whole flights, to resume from
        assert not [p for p in out.iterdir() if p.name.startswith(".") or ".tmp" in p.name]


def test_the_next_run_removes_the_temporary_folder_of_a_killed_one(
        sim_flight_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = start("fit", str(sim_flight_dir), "--out", str(out), "--quiet")
    wait_for(proc, lambda: any((t / "keyframes.txt").exists() for t in temporaries(out)),
             "keyframes written")
    proc.kill()  # SIGKILL: nothing can clean up
    proc.communicate(timeout=TIMEOUT_S)
    left = temporaries(out)  # its temporary folder and its reservation of the output
    assert sorted(p.name.split("-")[0] for p in left) == [".out.lock", ".out.tmp"]
    assert all(str(proc.pid) in p.name for p in left)
    # a live run's temporary folder, by contrast, is never touched: a run into the same
    # output is refused at once while it lives
    host = left[0].name.split('-')[2]
    live = out.parent / f".{out.name}.tmp-{os.getpid()}-{host}-{'0' * 12}"
    live.mkdir()
    argv = [sys.executable, "-m", "turbinefit.cli", "fit", str(sim_flight_dir), "--out",
            str(out), "--quiet", "--no-plots", "--max-iterations", "1"]
    rerun = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT_S,
                           preexec_fn=default_dispositions)
    assert rerun.returncode == 2
    assert rerun.stderr == (f"turbinefit: error: {out}: another turbinefit run (process "
                            f"{os.getpid()}) is writing this output folder now; wait for it "
                            "to end or choose another output\n")
    assert sorted(temporaries(out)) == sorted([*left, live])
    live.rmdir()  # that run ended
    rerun = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT_S,
                           preexec_fn=default_dispositions)
    assert rerun.returncode == 0, rerun.stderr
    assert temporaries(out) == []
    assert sorted(entries(out)) == ["config.yaml", "keyframes.txt", "summary.json",
                                    "turbine.glb", "turbine.yaml"]


def test_a_signal_swallowed_in_a_finaliser_is_raised_after_it() -> None:
    # Python drops an exception raised in __del__ or a weakref callback (the import system
    # runs such callbacks): the signal must still stop the command, once that code returns
    from turbinefit.cli.signals import Interrupted, RaisingOnSignals

    inherited = signal.signal(signal.SIGTERM, signal.SIG_DFL)  # whatever the run inherited
    try:
        _swallowed_in_a_finaliser(Interrupted, RaisingOnSignals)
    finally:
        signal.signal(signal.SIGTERM, inherited)


def _swallowed_in_a_finaliser(Interrupted: type, RaisingOnSignals: type) -> None:

    class Finalised:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGTERM)
            sum(range(1000))  # the handler runs here, inside __del__

    reached_end = False
    hook = sys.unraisablehook
    with pytest.raises(Interrupted) as caught, RaisingOnSignals():
        obj = Finalised()
        del obj
        end = time.monotonic() + 5.0
        while time.monotonic() < end:
            pass
        reached_end = True
    assert caught.value.signum == signal.SIGTERM and not reached_end
    assert sys.unraisablehook is hook  # the block's hook is gone with it


def test_a_signal_after_the_work_is_done_changes_nothing() -> None:
    # main has its status (every output complete): a signal then neither kills the
    # interpreter silently as it finalises (status -15) nor prints "interrupted"; in the
    # command run as 'python -m turbinefit.cli', whose argv[0] changes after start-up
    code = ("import os, signal, sys\nsys.argv = ['-m']\nimport turbinefit.cli\n"
            "sys.argv = ['/x/turbinefit/cli/__main__.py']\n"
            "status = turbinefit.cli.main(['simulate', '--list-presets'])\n"
            "os.kill(os.getpid(), signal.SIGTERM)\nos.kill(os.getpid(), signal.SIGINT)\n"
            "sys.exit(status)\n")
    proc = run_code(code)
    assert (proc.returncode, proc.stderr) == (0, "")
    assert "default" in proc.stdout


def test_a_signal_sent_again_while_the_hook_still_runs_is_not_lost(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # the signal swallowed in a finaliser is sent again from a thread; when that comes
    # while the hook itself still runs (here: starting the thread takes 50 ms), raising it
    # there would be swallowed again: it must wait for the next sending
    import threading

    from turbinefit.cli.signals import Interrupted, RaisingOnSignals

    start = threading.Thread.start

    def slow_start(self: threading.Thread) -> None:
        start(self)
        time.sleep(0.05)

    monkeypatch.setattr(threading.Thread, "start", slow_start)
    inherited = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        _swallowed_in_a_finaliser(Interrupted, RaisingOnSignals)
    finally:
        signal.signal(signal.SIGTERM, inherited)


@pytest.mark.parametrize("made", ["ImportError", "InputError", "swallowed"])
def test_whatever_a_library_makes_of_a_signal_ends_the_command_as_the_signal(
        made: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    # numpy's C modules turn an exception raised while they initialise into an ImportError
    # that keeps nothing of it; other code may wrap it in its own error, or swallow it
    import turbinefit.cli.report
    from turbinefit.cli import main
    from turbinefit.errors import InputError

    def run(args: object) -> int:
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        except KeyboardInterrupt:
            if made == "ImportError":
                raise ImportError("numpy: PyCapsule_Import could not import module") from None
            if made == "InputError":
                raise InputError("cannot read: interrupted", path="x") from None
        return 0

    monkeypatch.setattr(turbinefit.cli.report, "run", run)
    inherited = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        status = main(["report", "anywhere"])
    finally:
        signal.signal(signal.SIGTERM, inherited)
    assert (status, capsys.readouterr().err) == (143, "turbinefit: interrupted (SIGTERM)\n")
