"""The house rules of the code base, checked on the source itself.

- Imports run one way: ``reliability`` <- ``allocation`` <- ``studies.workflows`` <-
  ``studies.report`` <- ``studies.cli``; ``studies.paper`` and ``studies.benchmarks`` (and the
  two entry points ``studies.reproduce_paper`` and ``studies.__main__``) may import anything
  and nothing else imports them.
- Inside ``reliability`` the rooms run one way too: ``basics`` <- ``model`` <-
  ``first_order`` <- ``sampling``; ``acceptance`` and ``measured`` stand on ``model`` and
  ``basics`` (``measured`` may read ``acceptance``'s test definitions), and ``sampling`` may use
  both; ``life`` (accuracy over time) may use every room but ``interop``. No room imports the package ``reliability`` itself (that would import every room).
- Inside ``allocation`` likewise: ``solvers`` and ``cost`` <- ``per_pose`` <- ``catalogue``
  and ``machine_yield``. No room imports the package ``allocation`` itself.
- No module of ``reliability`` or ``allocation`` is longer than 800 lines.
- No two modules import each other, directly or through a cycle (imports inside functions
  count too).
- Importing any installed module changes neither the matplotlib backend nor the BLAS
  threads.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("reliability", "allocation", "studies")
#: Rank of each floor; a module may import only modules of its own rank or lower.
FLOORS = {"reliability": 0, "allocation": 1, "studies.workflows": 2, "studies.report": 3,
          "studies.cli": 4}
#: Rooms that may import anything and that nothing outside them imports.
TOP_ROOMS = ("studies.paper", "studies.benchmarks", "studies.reproduce_paper",
             "studies.__main__")


def module_files() -> dict[str, Path]:
    """Every module of the installed packages, by dotted name."""
    modules = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            modules[name] = path
    return modules


MODULES = module_files()


def imported_modules(name: str, path: Path) -> set[str]:
    """Our modules ``name`` imports anywhere in its file (resolved to the deepest module)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([node.module] if node.module else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base
                       for alias in node.names]
        else:
            continue
        found.update(t for t in targets if t.split(".")[0] in PACKAGES)
    return found - {name}


GRAPH = {name: imported_modules(name, path) for name, path in MODULES.items()}


def room(name: str) -> str | None:
    """The floor or top room a module belongs to (None for the bare ``studies`` package)."""
    for prefix in (*TOP_ROOMS, *sorted(FLOORS, key=len, reverse=True)):
        if name == prefix or name.startswith(prefix + "."):
            return prefix
    return None


def test_every_module_lives_in_a_room():
    homeless = [name for name in MODULES if room(name) is None and name != "studies"]
    assert not homeless, f"modules outside the rooms: {homeless}"


def test_imports_run_one_way():
    upward = []
    for name, targets in GRAPH.items():
        here = room(name)
        for target in targets:
            there = room(target)
            if there in TOP_ROOMS and there != here and here not in TOP_ROOMS:
                upward.append(f"{name} -> {target} (nothing imports {there})")
            elif here in FLOORS and there in FLOORS and FLOORS[there] > FLOORS[here]:
                upward.append(f"{name} -> {target} ({here} is below {there})")
    assert not upward, "imports against the one-way rule:\n" + "\n".join(upward)


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of ``graph``."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            components.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return components


#: What each room of ``reliability`` may import besides itself.
RELIABILITY_ROOMS = {
    "reliability.basics": set(),
    "reliability.model": {"reliability.basics"},
    "reliability.first_order": {"reliability.model", "reliability.basics"},
    "reliability.acceptance": {"reliability.model", "reliability.basics"},
    "reliability.measured": {"reliability.acceptance", "reliability.model",
                             "reliability.basics"},
    "reliability.sampling": {"reliability.first_order", "reliability.measured",
                             "reliability.acceptance", "reliability.model",
                             "reliability.basics"},
    "reliability.compensation": {"reliability.measured", "reliability.model",
                                 "reliability.basics"},
    "reliability.life": {"reliability.sampling", "reliability.first_order",
                         "reliability.compensation", "reliability.measured",
                         "reliability.acceptance", "reliability.model", "reliability.basics"},
    "reliability.interop": {"reliability.sampling", "reliability.first_order",
                            "reliability.model", "reliability.basics"},
}


#: What each room of ``allocation`` may import besides itself.
ALLOCATION_ROOMS = {
    "allocation.solvers": set(),
    "allocation.cost": set(),
    "allocation.per_pose": {"allocation.solvers", "allocation.cost"},
    "allocation.catalogue": {"allocation.per_pose", "allocation.solvers", "allocation.cost"},
    "allocation.machine_yield": {"allocation.per_pose", "allocation.solvers",
                                 "allocation.cost"},
}


#: The rooms of each package of the library.
ROOMS = {"reliability": RELIABILITY_ROOMS, "allocation": ALLOCATION_ROOMS}


def room_of(package: str, name: str) -> str | None:
    """The room of ``package`` module ``name`` lives in (None for the package itself or a
    module of another package)."""
    parts = name.split(".")
    if parts[0] != package or len(parts) < 2:
        return None
    return ".".join(parts[:2])


@pytest.mark.parametrize("package", sorted(ROOMS))
def test_every_library_module_lives_in_a_room_with_a_purpose_line(package):
    rooms = ROOMS[package]
    homeless = [name for name in MODULES if name.startswith(f"{package}.")
                and room_of(package, name) not in rooms]
    assert not homeless, f"modules of {package} outside its rooms: {homeless}"
    for room in rooms:
        path = ROOT / room.replace(".", "/") / "__init__.py"
        assert path.exists(), f"{room} is not a package"
        assert ast.get_docstring(ast.parse(path.read_text())), f"{room} has no purpose line"


@pytest.mark.parametrize("package", sorted(ROOMS))
def test_rooms_of_the_library_import_one_way(package):
    rooms, upward = ROOMS[package], []
    for name, targets in GRAPH.items():
        here = room_of(package, name)
        if here is None:
            continue
        for target in targets:
            there = room_of(package, target)
            if target == package:
                upward.append(f"{name} -> {package} (the package imports every room)")
            elif there is not None and there != here and there not in rooms[here]:
                upward.append(f"{name} -> {target} ({here} may not import {there})")
    assert not upward, "imports against the rooms' one-way rule:\n" + "\n".join(upward)


def test_the_room_rule_of_reliability_sees_an_upward_import():
    assert room_of("reliability", "reliability.model.machine") == "reliability.model"
    assert "reliability.sampling" not in RELIABILITY_ROOMS["reliability.first_order"]
    assert "reliability.first_order" not in RELIABILITY_ROOMS["reliability.acceptance"]


def test_the_room_rule_of_allocation_sees_an_upward_import():
    assert room_of("allocation", "allocation.per_pose.front") == "allocation.per_pose"
    assert room_of("allocation", "allocation") is None
    assert "allocation.per_pose" not in ALLOCATION_ROOMS["allocation.solvers"]
    assert "allocation.machine_yield" not in ALLOCATION_ROOMS["allocation.catalogue"]
    assert "allocation.catalogue" not in ALLOCATION_ROOMS["allocation.machine_yield"]


def test_the_convex_core_knows_no_machine():
    """The convex core imports nothing of ours but the ground floor (``reliability.basics``:
    its saved-file fields), so it solves any problem of its form, machine or not."""
    ours = sorted(t for t in GRAPH["allocation.solvers.convex"]
                  if not t.startswith("reliability.basics."))
    assert not ours, f"allocation.solvers.convex imports {ours}"


#: Longest a module of ``reliability`` or ``allocation`` may be, in lines.
MAX_LINES = 800
def library_modules():
    """Every module of ``reliability`` and ``allocation``, by its path."""
    params = []
    for name, path in MODULES.items():
        if name.split(".")[0] not in ("reliability", "allocation"):
            continue
        relative = path.relative_to(ROOT).as_posix()
        params.append(pytest.param(relative, id=relative))
    return params


@pytest.mark.parametrize("relative", library_modules())
def test_no_library_module_is_over_800_lines(relative):
    lines = len((ROOT / relative).read_text().splitlines())
    assert lines <= MAX_LINES, f"{relative} has {lines} lines (at most {MAX_LINES})"


def test_no_import_cycles():
    cycles = [component for component in strongly_connected(GRAPH) if len(component) > 1]
    assert not cycles, f"modules importing each other: {cycles}"


def test_the_cycle_finder_finds_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert [c for c in strongly_connected(graph) if len(c) > 1] == [["a", "b", "c"]]


def test_the_room_check_sees_an_upward_import():
    assert room("reliability.first_order.fosm") == "reliability"
    assert room("studies.report.writer") == "studies.report"
    assert room("studies.paper.tables") == "studies.paper"
    assert FLOORS[room("studies.cli.verify")] > FLOORS[room("studies.workflows.sweep")]


PROBE = r"""
import json, os, sys, importlib
import numpy, pandas, matplotlib, threadpoolctl
import scipy.linalg, scipy.optimize, scipy.sparse, scipy.special, scipy.stats

BLAS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

def state():
    return {"backend": repr(dict.__getitem__(matplotlib.rcParams, "backend")),
            "env": {v: os.environ.get(v) for v in BLAS},
            "threads": sorted((i["internal_api"], i["num_threads"])
                              for i in threadpoolctl.threadpool_info())}

before = state()
for name in json.loads(sys.argv[1]):
    importlib.import_module(name)
print(json.dumps({"before": before, "after": state()}))
"""


def probe(names, extra_path=None) -> dict:
    """The backend and BLAS state before and after importing ``names`` in a fresh
    interpreter, with no backend or thread variables set by the caller."""
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("MPLBACKEND", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                "MKL_NUM_THREADS")}
    if extra_path is not None:
        environment["PYTHONPATH"] = os.pathsep.join([str(extra_path), str(ROOT)])
    done = subprocess.run([sys.executable, "-c", PROBE, json.dumps(names)], cwd=ROOT,
                          env=environment, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_importing_changes_no_backend_and_no_blas_threads():
    report = probe(sorted(n for n in MODULES if not n.endswith("__main__")))
    assert report["after"] == report["before"]


@pytest.mark.parametrize("side_effect", ['import matplotlib; matplotlib.use("pdf")',
                                         'import os; os.environ["OMP_NUM_THREADS"] = "1"'])
def test_the_probe_sees_a_module_that_changes_them(tmp_path, side_effect):
    (tmp_path / "noisy_module.py").write_text(side_effect + "\n")
    report = probe(["noisy_module"], extra_path=tmp_path)
    assert report["after"] != report["before"]


@pytest.mark.parametrize("command", [["studies", "--help"],
                                     ["studies.reproduce_paper", "--help"]])
def test_stable_entry_points_run(command):
    done = subprocess.run([sys.executable, "-m", *command], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "usage:" in done.stdout


#: What ``reliability`` and ``allocation`` exported at their top in 0.2.0, before the rooms.
EXPORTED_IN_0_2_0 = {
    "reliability": [
        "Axis", "COMPONENTS", "CostCoefficients", "FosmResult", "GridExperiment",
        "GridExperimentResult", "Machine", "MachineDescriptionError", "OUTPUTS",
        "PoseSamplingResult", "RandomPoseResult", "SystemReliability", "fosm",
        "hobbing_machine", "load_machine", "machine_from_dict", "random_poses", "rare",
        "sample_at_poses", "sample_random_poses", "system_reliability", "workspace_grid",
        "worst_system_reliability"],
    "allocation": [
        "AllocationProblem", "AllocationResult", "Catalogue", "CatalogueClass",
        "CatalogueInfeasibleError", "CatalogueResult", "Component", "ContinuousAllocation",
        "ConvexSolution", "CostModel", "FcemResult", "GwoResult", "InfeasibleAllocationError",
        "ScreenedRows", "TargetUnreachableError", "YieldAllocation", "YieldUnreachableError",
        "allocate_for_yield", "allocation_point", "cost_reliability_front", "cost_weights",
        "fcem_coefficient", "grey_wolf", "grey_wolf_reference", "load_catalogue",
        "read_allocation_csv", "requirement_table", "screen_rows", "solve_catalogue",
        "solve_continuous", "solve_convex_allocation", "solve_exact", "solve_gwo",
        "solve_over_workspace", "system_allocation"],
}


#: What ``reliability`` and ``allocation`` exported at their top in 0.3.0, before the rooms
#: of ``allocation``.
EXPORTED_IN_0_3_0 = {
    "reliability": [*EXPORTED_IN_0_2_0["reliability"], "CompensationTables", "Identification",
                    "compensation_tables", "identify", "interop", "machine_from_toml",
                    "read_compensation", "read_identification", "read_measurements",
                    "write_compensation"],
    "allocation": EXPORTED_IN_0_2_0["allocation"],
}
#: The lists written out here (not read from the packages), by release.
EXPORTED = {"0.2.0": EXPORTED_IN_0_2_0, "0.3.0": EXPORTED_IN_0_3_0}


@pytest.mark.parametrize(("release", "package"),
                         [(release, package) for release in EXPORTED for package in
                          sorted(EXPORTED[release])])
def test_every_name_exported_in_an_earlier_release_still_works(release, package):
    import importlib
    module = importlib.import_module(package)
    names = EXPORTED[release][package]
    missing = [name for name in names if not hasattr(module, name)]
    assert not missing, f"{package} no longer exports {missing} (exported in {release})"
    assert set(names) <= set(module.__all__)


def test_rare_at_the_top_is_the_rare_event_module():
    import reliability
    from reliability.sampling import rare_events
    assert reliability.rare is rare_events
    assert callable(reliability.rare.failure_probability)


@pytest.mark.parametrize("package", ["reliability", "allocation"])
def test_no_module_is_left_at_a_flat_path_of_an_earlier_release(package):
    """``reliability`` moved into rooms in 0.3.0, ``allocation`` in 0.4.0."""
    flat = sorted(p.stem for p in (ROOT / package).glob("*.py") if p.stem != "__init__")
    assert flat == [], f"modules left at the top of {package}: {flat}"


def test_no_two_library_modules_share_a_name():
    """No two modules of ``reliability`` and ``allocation`` share a name, and no module of
    ``studies.workflows`` or ``studies.report`` shares one with them (command-line modules are
    named after their commands, benchmarks after what they measure)."""
    def short_names(prefixes):
        found = {}
        for name, path in MODULES.items():
            if name.startswith(prefixes) and path.name != "__init__.py":
                found.setdefault(name.rsplit(".", 1)[1], []).append(name)
        return found

    library = short_names(("reliability.", "allocation."))
    shared = {short: full for short, full in library.items() if len(full) > 1}
    assert not shared, f"library modules of one name in two places: {shared}"
    studies = short_names(("studies.workflows.", "studies.report."))
    clash = {short: full + library[short] for short, full in studies.items() if short in library}
    assert not clash, f"studies modules named like library modules: {clash}"
