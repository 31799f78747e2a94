"""The package's layers: core maths imports nothing above it, and each command loads only
what it uses."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import turbinefit

PACKAGE = Path(turbinefit.__file__).parent


#: The core: geometry, the turbine model, heat-maps, costs and solver (and what they share).
CORE = ("geometry", "turbine", "heatmaps", "costs", "solver", "flight", "errors", "_native")
#: Above the core but pure geometry: the inspection imports the core and nothing else.
INSPECTION = ("inspection",)


#: What the core must never import, even inside a function.
ABOVE_CORE = ("io", "sim", "plots", "detect", "tiepoints", "train", "cli", "jobs", "eval",
              "experiments", "mission", "view")


def _modules(names: tuple[str, ...]) -> list[Path]:
    out: list[Path] = []
    for name in names:
        p = PACKAGE / name
        out += sorted(p.rglob("*.py")) if p.is_dir() else [p.with_suffix(".py")]
    return [p for p in out if p.is_file()]


def _imported(path: Path) -> set[str]:
    """Every turbinefit module ``path`` imports, at any depth of its code."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found |= {f"{node.module}.{a.name}" for a in node.names}
    return {m for m in found if m.startswith("turbinefit.")}


def test_core_modules_exist() -> None:
    assert len(_modules(CORE)) >= 20


@pytest.mark.parametrize("path", _modules(CORE), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_core_imports_nothing_above_it(path: Path) -> None:
    bad = sorted(m for m in _imported(path)
                 if m.split(".")[1] in ABOVE_CORE)
    assert not bad, f"{path.relative_to(PACKAGE)} imports {bad}"


@pytest.mark.parametrize("path", _modules(INSPECTION), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_inspection_imports_only_the_core(path: Path) -> None:
    bad = sorted(m for m in _imported(path)
                 if m.split(".")[1] not in (*CORE, "inspection"))
    assert not bad, f"{path.relative_to(PACKAGE)} imports {bad}"


#: What the view's page builder must not import: it sits beside plots, below the jobs.
ABOVE_VIEW = ("cli", "jobs", "experiments", "train", "detect", "sim")


@pytest.mark.parametrize("path", _modules(("view",)), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_the_view_imports_nothing_above_it(path: Path) -> None:
    bad = sorted(m for m in _imported(path) if m.split(".")[1] in ABOVE_VIEW)
    assert not bad, f"{path.relative_to(PACKAGE)} imports {bad}"


#: What the mission loop must not import: it sits above the simulator, the inspection, the
#: detector and the solver, below the jobs (which write its outputs) and the command line.
ABOVE_MISSION = ("cli", "jobs", "experiments", "train", "view", "plots")


@pytest.mark.parametrize("path", _modules(("mission",)),
                         ids=lambda p: str(p.relative_to(PACKAGE)))
def test_the_mission_imports_nothing_above_it(path: Path) -> None:
    bad = sorted(m for m in _imported(path) if m.split(".")[1] in ABOVE_MISSION)
    assert not bad, f"{path.relative_to(PACKAGE)} imports {bad}"


def test_the_check_sees_a_forbidden_import(tmp_path: Path) -> None:
    p = tmp_path / "m.py"
    p.write_text("def f():\n    from turbinefit.io.tum import write_tum\n")
    assert "turbinefit.io.tum" in _imported(p)


def _loaded(argv: list[str]) -> set[str]:
    """The modules loaded by ``turbinefit ARGV`` (in a fresh interpreter)."""
    code = ("import json, sys\nfrom turbinefit.cli import main\n"
            f"try:\n    main({argv!r})\nexcept SystemExit:\n    pass\n"
            "print(json.dumps(sorted(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return set(json.loads(out.splitlines()[-1]))


HEAVY = ("onnxruntime", "torch", "matplotlib", "scipy", "PIL", "tqdm")


def test_top_level_help_loads_no_command() -> None:
    loaded = _loaded(["--help"])
    assert not {m for m in loaded if m.startswith("turbinefit.")} - {
        "turbinefit._lazy", "turbinefit.cli", "turbinefit.cli.common", "turbinefit.cli.signals",
        "turbinefit.errors"}
    assert not [m for m in loaded if m.split(".")[0] in (*HEAVY, "numpy")]


@pytest.mark.parametrize(("argv", "must_not"), [
    (["fit", "--help"], ("turbinefit.detect", "turbinefit.sim", "turbinefit.train",
                         "turbinefit.jobs", "turbinefit.cli.track", "onnxruntime", "pygltflib",
                         "matplotlib", "torch")),
    (["detect", "--help"], ("turbinefit.solver", "turbinefit.sim", "turbinefit.jobs",
                            "onnxruntime", "torch", "matplotlib")),
    (["simulate", "--help"], ("turbinefit.solver", "turbinefit.detect", "onnxruntime",
                              "torch", "matplotlib")),
    (["coverage", "--help"], ("turbinefit.solver", "turbinefit.detect", "turbinefit.sim",
                              "turbinefit.jobs", "onnxruntime", "torch", "matplotlib")),
    (["plan", "--help"], ("turbinefit.solver", "turbinefit.detect", "turbinefit.sim",
                          "turbinefit.jobs", "onnxruntime", "torch", "matplotlib")),
    (["view", "--help"], ("turbinefit.solver", "turbinefit.detect", "turbinefit.sim",
                          "turbinefit.jobs", "turbinefit.view", "onnxruntime", "torch",
                          "matplotlib")),
])
def test_a_command_loads_only_what_it_uses(argv: list[str], must_not: tuple[str, ...]) -> None:
    loaded = _loaded(argv)
    bad = sorted(m for m in loaded if any(m == x or m.startswith(x + ".") for x in must_not))
    assert not bad


@pytest.mark.parametrize("plots", [False, True])
def test_a_fit_from_heat_map_files_loads_only_what_it_uses(tmp_path: Path, plots: bool) -> None:
    """``turbinefit fit`` of a flight with heat-map files runs to the end without the
    detector (onnxruntime, scipy), turbine.glb's or a progress bar's libraries when nobody
    watches (stderr not a terminal), nor, with --no-plots, matplotlib: they cost a
    1000-keyframe fit a fifth of its time (docs/benchmarks.md)."""
    from turbinefit.io.flight_folder import write_flight
    from turbinefit.sim.scenario import SimConfig, simulate_flight

    flight = tmp_path / "flight"
    write_flight(simulate_flight(SimConfig(n_keyframes=6, seed=1)), flight)
    out = tmp_path / "fit"
    loaded = _loaded(["fit", str(flight), "--out", str(out)] + ([] if plots else ["--no-plots"]))
    assert (out / "turbine.glb").is_file() and (out / "summary.json").is_file()
    assert (out / "scene.png").is_file() is plots
    heavy = ("scipy", "onnxruntime", "torch", "pygltflib", "tqdm", "turbinefit.detect",
             "turbinefit.sim", "turbinefit.train") + (() if plots else ("matplotlib",))
    bad = sorted(m for m in loaded if any(m == x or m.startswith(x + ".") for x in heavy))
    assert not bad
    assert ("matplotlib" in loaded) is plots
