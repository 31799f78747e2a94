"""Signal scans: SIGINT, SIGTERM or SIGHUP sent to a command at random moments, and how it
ends.

For each command (``track --from-images``, ``detect`` and ``fit --from-images`` on a small
simulated flight with photos; ``--commands`` picks), first timed once undisturbed, then run
``--runs`` times, each sent one signal (drawn from the three) at a moment drawn uniformly
from the end of Python's own start-up to 1.2 times that time, so that the command's
start-up, module imports (numpy's and onnxruntime's C modules included), detection, the
compiled kernels, writing and the last milliseconds are all hit. Python's own start-up (the
interpreter, ``site``, ``runpy``: the time ``python -c pass`` takes, about 20 ms) is left
out: no Python program runs code of its own then, so a signal there ends it as Python
does (SIGINT: a ``KeyboardInterrupt`` traceback from ``runpy``; SIGTERM: killed). A run
passes if it ends with

* 128 + the signal, the one line ``turbinefit: interrupted (SIG...)`` on stderr and no
  temporary folder or reservation left beside its output; or
* 0 if the signal came after its work was done (late), its output complete;

and never with a traceback, another status, or a line more. Counts go to
``benchmarks/results/bench_signals.json``.

Run: ``python benchmarks/bench_signals.py`` (150 runs, about 10 min on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def _default_dispositions() -> None:
    for sig in SIGNALS:  # whatever this benchmark inherited (nohup, a background job)
        signal.signal(sig, signal.SIG_DFL)


def _commands(flight: Path, work: Path) -> dict[str, list[str]]:
    photos = sorted(str(p) for p in (flight / "images").glob("*.png"))[:6]
    return {"track": ["track", str(flight), "--from-images", "--out", str(work / "out"),
                      "--quiet"],
            "detect": ["detect", *photos, "--out", str(work / "out"), "--quiet"],
            "fit": ["fit", str(flight), "--from-images", "--out", str(work / "out"),
                    "--quiet"]}


def _run(argv: list[str], work: Path, delay: float | None, sig: int) -> dict[str, object]:
    out = work / "out"
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "turbinefit.cli", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_dispositions)
    if delay is not None:
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=300)
    left = sorted(p.name for p in work.iterdir() if p.name.startswith(".out."))
    return {"status": proc.returncode, "stderr": stderr, "stdout": stdout, "left": left,
            "seconds": time.perf_counter() - t0, "output": out.exists()}


def _judge(r: dict[str, object], sig: int) -> str:
    """'interrupted', 'late' or what went wrong."""
    status, err = r["status"], str(r["stderr"])
    if "Traceback" in err:
        return "traceback"
    if r["left"]:
        return "left behind"
    if status == 128 + sig:
        if err != f"turbinefit: interrupted ({signal.Signals(sig).name})\n":
            return "wrong message"
        return "interrupted"
    if status == 0 and err == "" and r["output"]:
        return "late"
    return "wrong status"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50, help="runs per command")
    ap.add_argument("--commands", default="track,detect,fit")
    ap.add_argument("--keyframes", type=int, default=12, help="keyframes of the flight")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    results: dict[str, object] = {"runs_per_command": args.runs, "keyframes": args.keyframes}
    with tempfile.TemporaryDirectory() as tmp:
        flight, work = Path(tmp) / "flight", Path(tmp) / "work"
        work.mkdir()
        subprocess.run([sys.executable, "-m", "turbinefit.cli", "simulate", str(flight),
                        "--keyframes", str(args.keyframes), "--images", "--quiet"], check=True)
        commands = _commands(flight, work)
        starts = []
        for _ in range(5):
            t = time.perf_counter()
            subprocess.run([sys.executable, "-c", "pass"], check=True)
            starts.append(time.perf_counter() - t)
        python_start = sorted(starts)[2]
        results["python_start_s"] = round(python_start, 4)
        for name in args.commands.split(","):
            argv = commands[name]
            clean = _run(argv, work, None, signal.SIGINT)
            assert clean["status"] == 0, clean["stderr"]
            duration = float(clean["seconds"])  # type: ignore[arg-type]
            counts: dict[str, int] = {}
            bad: list[dict[str, object]] = []
            for _ in range(args.runs):
                sig = rng.choice(SIGNALS)
                delay = rng.uniform(python_start, 1.2 * duration)
                r = _run(argv, work, delay, sig)
                verdict = _judge(r, sig)
                counts[verdict] = counts.get(verdict, 0) + 1
                if verdict not in ("interrupted", "late"):
                    bad.append({"signal": signal.Signals(sig).name, "at_s": round(delay, 3),
                                "status": r["status"], "stderr": str(r["stderr"])[-600:],
                                "left": r["left"]})
            results[name] = {"seconds_undisturbed": round(duration, 2), "counts": counts,
                             "failures": bad}
            print(f"{name}: {duration:.1f} s undisturbed; {args.runs} runs: "
                  + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
            for b in bad:
                print(f"  {b}")
    out = HERE / "results" / "bench_signals.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONDONTWRITEBYTECODE", "1")
    main()
