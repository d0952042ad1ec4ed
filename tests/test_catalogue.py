"""Catalogue files: what is read, what is refused (one line naming the item, the component
and the class at fault, before any work), and the command line around them."""

from __future__ import annotations

import copy
import itertools
import json
import math
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w

import allocation
from allocation import AllocationProblem, Catalogue, load_catalogue, solve_catalogue
from reliability import hobbing_machine, load_machine, workspace_grid
from reliability.basics.errors import InputError, InputTypeError
from reliability.model.machine import OUTPUTS
from studies import cli
from studies.workflows.sweep import SweepSpec, SweepTask, run_sweep

HERE = Path(__file__).parent
MILL = str(HERE / "machines" / "mill3.toml")
MILL_CATALOGUE = str(HERE / "catalogues" / "mill3.toml")
PAPER_CATALOGUE = HERE.parent / "docs" / "examples" / "paper_catalogue.toml"


def base():
    """A good two-component catalogue of the test mill, as a parsed table."""
    return {"currency": "EUR", "components": [
        {"name": "X ball screw", "items": ["X.dx"], "classes": [
            {"name": "C5", "price": 180.0, "tolerances": {"X.dx": 0.006}},
            {"name": "C3", "price": 300.0, "tolerances": {"X.dx": 0.0027}}]},
        {"name": "Y guideway", "items": ["Y.dx", "Y.dz"], "classes": [
            {"name": "normal", "price": 120.0, "tolerances": {"Y.dx": 0.008, "Y.dz": 0.008}},
            {"name": "high", "price": 160.0, "tolerances": {"Y.dx": 0.005, "Y.dz": 0.005}}]}]}


def changed(change):
    data = copy.deepcopy(base())
    change(data)
    return data


def screw(data):
    return data["components"][0]


def guide(data):
    return data["components"][1]


def second_screw(data):
    data["components"].append({"name": "second screw", "items": ["X.dx"],
                               "classes": [{"name": "C7", "price": 1.0,
                                            "tolerances": {"X.dx": 0.05}}]})


def iso_twin(data):
    data["components"].append({"name": "X scale", "items": ["EXX"],
                               "classes": [{"name": "fine", "price": 1.0,
                                            "tolerances": {"EXX": 0.001}}]})


# (case, change of the good catalogue, words the one-line refusal must contain)
BAD = [
    ("unknown item", lambda d: screw(d).update(items=["X.dq"]) or
     screw(d)["classes"][0]["tolerances"].update({"X.dq": 0.006}),
     ["'X.dq'", "'X ball screw'"]),
    ("item in two components", second_screw, ["'X.dx'", "'X ball screw'", "'second screw'"]),
    ("one error under two names", iso_twin, ["'X.dx'", "'X ball screw'", "'X scale'"]),
    ("missing tolerance", lambda d: guide(d)["classes"][1]["tolerances"].pop("Y.dz"),
     ["'Y.dz'", "'Y guideway'", "'high'"]),
    ("extra tolerance", lambda d: guide(d)["classes"][1]["tolerances"].update({"Y.dy": 0.005}),
     ["'Y.dy'", "'Y guideway'", "'high'"]),
    ("zero price", lambda d: screw(d)["classes"][0].update(price=0.0),
     ["price", "'X ball screw'", "'C5'"]),
    ("negative price", lambda d: screw(d)["classes"][1].update(price=-3),
     ["price", "'X ball screw'", "'C3'"]),
    ("negative tolerance", lambda d: screw(d)["classes"][1]["tolerances"].update({"X.dx": -0.001}),
     ["'X.dx'", "'X ball screw'", "'C3'"]),
    ("infinite tolerance", lambda d: guide(d)["classes"][0]["tolerances"].update({"Y.dx": math.inf}),
     ["'Y.dx'", "'Y guideway'", "'normal'"]),
    ("duplicate class", lambda d: screw(d)["classes"][1].update(name="C5"),
     ["'C5'", "'X ball screw'", "twice"]),
    ("duplicate component", lambda d: guide(d).update(name="X ball screw"),
     ["'X ball screw'", "twice"]),
    ("empty classes", lambda d: guide(d).update(classes=[]), ["'Y guideway'", "no classes"]),
    ("empty items", lambda d: guide(d).update(items=[]), ["'Y guideway'", "items"]),
    ("item listed twice", lambda d: guide(d).update(items=["Y.dx", "Y.dx"]),
     ["'Y.dx'", "'Y guideway'", "twice"]),
    ("price not a number", lambda d: screw(d)["classes"][0].update(price="cheap"),
     ["price", "'X ball screw'", "'C5'", "'cheap'"]),
    ("tolerance not a number", lambda d: screw(d)["classes"][0]["tolerances"].update({"X.dx": "6 um"}),
     ["'X.dx'", "'X ball screw'", "'C5'"]),
    ("tolerances not a table", lambda d: screw(d)["classes"][0].update(tolerances=[0.006]),
     ["tolerances", "'X ball screw'", "'C5'"]),
    ("items not a list", lambda d: screw(d).update(items="X.dx"), ["items", "'X ball screw'"]),
    ("missing price", lambda d: screw(d)["classes"][0].pop("price"),
     ["price", "'X ball screw'", "'C5'"]),
    ("class without a name", lambda d: guide(d)["classes"][0].pop("name"),
     ["'Y guideway'", "class #1", "name"]),
    ("unknown class key", lambda d: screw(d)["classes"][0].update(prise=1.0),
     ["'prise'", "'X ball screw'", "'C5'"]),
    ("unknown component key", lambda d: guide(d).update(grade="H"), ["'grade'", "'Y guideway'"]),
    ("unknown top-level key", lambda d: d.update(currencies="EUR"), ["'currencies'"]),
    ("no components", lambda d: d.pop("components"), ["components"]),
    ("currency not a string", lambda d: d.update(currency=1), ["currency"]),
]


def write(tmp_path, data) -> Path:
    path = tmp_path / "catalogue.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def test_the_good_catalogue_loads(tmp_path):
    catalogue = load_catalogue(write(tmp_path, base()), load_machine(MILL))
    assert [c.name for c in catalogue.components] == ["X ball screw", "Y guideway"]
    assert catalogue.items == ("X.dx", "Y.dx", "Y.dz")
    assert catalogue.currency == "EUR" and catalogue.n_choices == 4
    np.testing.assert_array_equal(catalogue.components[1].tolerance_matrix(),
                                  [[0.008, 0.008], [0.005, 0.005]])


def test_iso_symbols_are_named_as_the_machine_names_them(tmp_path):
    data = changed(lambda d: screw(d).update(items=["EXX"]) or [
        c.update(tolerances={"EXX": c["tolerances"]["X.dx"]}) for c in screw(d)["classes"]])
    catalogue = load_catalogue(write(tmp_path, data), load_machine(MILL))
    assert catalogue.components[0].items == ("X.dx",)
    assert dict(catalogue.components[0].classes[0].tolerances) == {"X.dx": 0.006}


@pytest.mark.parametrize("case, change, words", BAD, ids=[case for case, _, _ in BAD])
def test_bad_catalogues_are_refused_in_one_line(tmp_path, case, change, words):
    path = write(tmp_path, changed(change))
    with pytest.raises((InputError, InputTypeError)) as info:
        load_catalogue(path, load_machine(MILL))
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    for word in words:
        assert word in message, message


@pytest.mark.parametrize("case, change, words", BAD, ids=[case for case, _, _ in BAD])
def test_bad_catalogues_exit_2_before_any_work(tmp_path, capsys, case, change, words):
    path = write(tmp_path, changed(change))
    out = tmp_path / "choice.csv"
    code = cli.main(["choose", MILL, "--catalogue", str(path), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("precrel: error: "), err  # no progress line
    for word in words:
        assert word in err[0]
    assert not out.exists()


def test_unreadable_files_are_refused(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        load_catalogue(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[[components]\nname = 'x'")
    with pytest.raises(InputError, match="not valid TOML"):
        load_catalogue(bad)
    with pytest.raises(InputTypeError, match="must be a table"):
        Catalogue.from_dict(["components"])


def test_classes_are_ordered_loosest_first():
    catalogue = Catalogue.from_dict(changed(lambda d: guide(d)["classes"].insert(
        0, {"name": "precision", "price": 230.0, "tolerances": {"Y.dx": 0.0012, "Y.dz": 0.004}})))
    guide_ = catalogue.components[1]
    # geometric means: precision sqrt(1.2 * 4) = 2.19 µm, normal 8 µm, high 5 µm
    assert [guide_.classes[j].name for j in guide_.loosest_first()] == \
        ["normal", "high", "precision"]


def test_paper_catalogue_loads_on_the_paper_machine():
    machine = hobbing_machine()
    catalogue = load_catalogue(PAPER_CATALOGUE, machine)
    assert len(catalogue.components) >= 10
    assert all(len(c.classes) >= 2 and c.source for c in catalogue.components)
    assert set(catalogue.items) <= set(machine.error_names)


# ----- the command line -----------------------------------------------------------------
def test_choose_from_a_catalogue(tmp_path, capsys):
    out, tolerances = tmp_path / "choice.csv", tmp_path / "choice.tolerances.csv"
    code = cli.main(["choose", MILL, "--catalogue", MILL_CATALOGUE, "--out", str(out),
                     "--points", "4", "--target", "0.95"])
    printed = capsys.readouterr().out
    assert code == 0
    machine = load_machine(MILL)
    best, price = cheapest_by_enumeration(machine, load_catalogue(MILL_CATALOGUE, machine),
                                          points=4, target=0.95)
    assert f"total price {price:.6g} EUR" in printed and "relative gap 0 (" in printed
    assert "What binds" in printed and "breaks dx" in printed
    choice = pd.read_csv(out)
    assert list(choice.columns) == ["component", "class", "price"]
    assert dict(zip(choice["component"], choice["class"])) == best
    assert choice["price"].sum() == price
    t = allocation.read_allocation_csv(tolerances, machine)
    assert t[machine.error_index("X.dx")] == 0.006
    assert t[machine.error_index("Y.dy")] == machine.initial_allocation[1]


def cheapest_by_enumeration(machine, catalogue, points, target):
    """The cheapest choice meeting every row of the grid, by trying all of them."""
    machine = replace(machine, targets=np.full(6, target))
    problem = AllocationProblem.build(machine, workspace_grid(machine, points))
    rows = problem.row_matrix().reshape(-1, machine.n_errors)
    best, price = None, np.inf
    for classes in itertools.product(*(c.classes for c in catalogue.components)):
        t = machine.initial_allocation.copy()
        for component, chosen in zip(catalogue.components, classes):
            for item, value in chosen.tolerances.items():
                t[machine.error_index(item)] = value
        total = sum(c.price for c in classes)
        if (rows @ t ** 2).max() <= 1 and total < price:
            best = {c.name: k.name for c, k in zip(catalogue.components, classes)}
            price = total
    return best, price


def test_allocate_catalogue_against_python(tmp_path, capsys):
    """The command line's choice is solve_catalogue's on the same problem; ``allocate
    --catalogue``, the old spelling of ``choose``, still works with a warning, and the
    tolerances go to ``--tolerances-out``."""
    machine = load_machine(MILL)
    start = machine.initial_allocation * np.linspace(0.8, 1.2, machine.n_errors)
    frame = pd.DataFrame({"error": machine.error_names, "allocated": start})
    frame.to_csv(tmp_path / "start.csv", index=False)
    out = tmp_path / "choice.csv"
    assert cli.main(["allocate", MILL, "--catalogue", MILL_CATALOGUE, "--out", str(out),
                     "--points", "3", "--tolerances", str(tmp_path / "start.csv"),
                     "--side", "one_sided", "--tolerances-out",
                     str(tmp_path / "t.csv")]) == 0
    assert (tmp_path / "t.csv").exists() and not (tmp_path / "choice.tolerances.csv").exists()
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3), side="one_sided",
                                      reference=start)
    result = solve_catalogue(problem, load_catalogue(MILL_CATALOGUE, machine))
    choice = pd.read_csv(out)
    assert dict(zip(choice["component"], choice["class"])) == result.choice
    captured = capsys.readouterr()
    assert f"total price {result.price:.6g}" in captured.out
    assert "precrel: warning: --catalogue is deprecated; use precrel choose" in captured.err


@pytest.mark.parametrize("extra, words", [
    (["--bounds", "0.5", "1.5"], ["--bounds", "--catalogue"]),
    (["--lock", "X.dx"], ["--lock", "--catalogue"]),
    (["--method", "gwo"], ["--method gwo", "--catalogue"]),
])
def test_allocate_catalogue_refuses_options_that_do_not_apply(tmp_path, capsys, extra, words):
    code = cli.main(["allocate", MILL, "--catalogue", MILL_CATALOGUE,
                     "--out", str(tmp_path / "c.csv"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith("precrel: error: ")
    assert all(word in err[-1] for word in words)


@pytest.mark.parametrize("extra", [["--bounds", "0.5", "1.5"], ["--lock", "X.dx"],
                                   ["--method", "gwo"]])
def test_choose_has_no_options_of_continuous_tolerances(tmp_path, capsys, extra):
    assert cli.main(["choose", MILL, "--catalogue", MILL_CATALOGUE,
                     "--out", str(tmp_path / "c.csv"), *extra]) == 2
    assert "unrecognized arguments" in capsys.readouterr().err


def test_two_choices_into_one_folder_never_collide(tmp_path, capsys):
    for name in ("a.csv", "b.csv"):
        assert cli.main(["choose", MILL, "--catalogue", MILL_CATALOGUE, "--points", "3",
                         "--out", str(tmp_path / name)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == \
        ["a.csv", "a.tolerances.csv", "b.csv", "b.tolerances.csv"]


def test_catalogue_options_need_a_catalogue(tmp_path, capsys):
    code = cli.main(["allocate", MILL, "--out", str(tmp_path / "a.csv"),
                     "--tolerances-out", str(tmp_path / "t.csv")])
    assert code == 2 and "--tolerances-out is used with --catalogue only" in \
        capsys.readouterr().err


def test_unreachable_catalogue_exits_2(tmp_path, capsys):
    data = changed(lambda d: screw(d)["classes"][1]["tolerances"].update({"X.dx": 0.05})
                   or screw(d)["classes"][0]["tolerances"].update({"X.dx": 0.06}))
    code = cli.main(["choose", MILL, "--catalogue", str(write(tmp_path, data)),
                     "--out", str(tmp_path / "c.csv"), "--points", "3"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith("precrel: error: no choice of classes meets dx")


def test_report_adds_a_component_choice_section(tmp_path, capsys):
    out = tmp_path / "report"
    code = cli.main(["report", MILL, "--out", str(out), "--catalogue", MILL_CATALOGUE,
                     "--repeats", "2", "--samples", "500", "--points", "3", "--machines", "400",
                     "--skip",
                     "front", "system", "rare", "profiles"])
    assert code == 0
    text = (out / "report.md").read_text()
    assert "## Component choice" in text and "relative gap" in text
    machine = load_machine(MILL)
    problem = AllocationProblem.build(machine, workspace_grid(machine, 3))
    result = solve_catalogue(problem, load_catalogue(MILL_CATALOGUE, machine))
    choice = pd.read_csv(out / "choice.csv")
    assert dict(zip(choice["component"], choice["class"])) == result.choice
    summary = json.loads((out / "summary.json").read_text())["catalogue"]
    assert summary["price"] == result.price and summary["certified"]
    assert set(summary["worst_pose_mc"]) == set(OUTPUTS)
    np.testing.assert_allclose(
        allocation.read_allocation_csv(out / "choice_tolerances.csv", machine),
        result.tolerances, rtol=1e-5)  # the report writes 6 significant digits
    # the report's choice and tolerances are the files the library writes, at its digits
    assert (out / "choice.csv").read_bytes() == \
        result.to_csv(tmp_path / "choice.csv", significant=6).read_bytes()
    assert (out / "choice_tolerances.csv").read_bytes() == allocation.per_pose.result_files.\
        allocation_to_csv(result, tmp_path / "tolerances.csv", significant=6).read_bytes()


def test_report_refuses_a_bad_catalogue_before_any_work(tmp_path, capsys):
    data = changed(lambda d: screw(d).update(items=["X.dq"]))
    out = tmp_path / "report"
    code = cli.main(["report", MILL, "--out", str(out), "--catalogue",
                     str(write(tmp_path, data))])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "'X.dq'" in err[0]
    assert not out.exists()


def test_sweep_with_a_catalogue(tmp_path):
    spec_path = tmp_path / "spec.toml"
    shutil.copy(MILL, tmp_path / "mill3.toml")
    shutil.copy(MILL_CATALOGUE, tmp_path / "cat.toml")
    spec_path.write_text('machines = ["mill3.toml"]\ncatalogue = "cat.toml"\n'
                         'targets = [0.95, 0.99]\nrepeats = [2]\npoints = 3\n')
    spec = SweepSpec.from_toml(spec_path)
    frame = run_sweep(spec, tmp_path / "store").frame
    machine = load_machine(MILL)
    catalogue = load_catalogue(MILL_CATALOGUE, machine)
    for row in frame.itertuples():
        targeted = replace(machine, targets=np.full(6, row.target))
        result = solve_catalogue(AllocationProblem.build(targeted, workspace_grid(machine, 3)),
                                 catalogue)
        assert row.price == result.price and row.certified
        assert row.choice == "; ".join(f"{k}={v}" for k, v in result.choice.items())
    assert frame["price"].is_monotonic_increasing  # a higher target never costs less
    # a plain sweep's tasks (and so their stored results) are unchanged
    plain = SweepTask("hobbing", "two_sided", 0.99, "independent", 0, 20, 5)
    assert "catalogue" not in plain.parameters()


def test_sweep_refuses_a_catalogue_the_machine_cannot_use(tmp_path):
    data = changed(lambda d: screw(d).update(items=["X.dq"]) or
                   screw(d)["classes"][0]["tolerances"].update({"X.dq": 0.006}))
    with pytest.raises(InputError, match="'X.dq'"):
        SweepSpec(machines=(MILL,), catalogue=str(write(tmp_path, data)))


def test_the_python_example_of_the_documentation_runs(monkeypatch, tmp_path):
    root = HERE.parent
    block = re.findall(r"```python\n(.*?)```", (root / "docs" / "catalogue.md").read_text(),
                       flags=re.S)[0]
    monkeypatch.chdir(root)
    namespace = {}
    exec(block.replace('"choice.csv"', repr(str(tmp_path / "choice.csv"))), namespace)
    result = namespace["result"]
    assert result.certified and result.price == pytest.approx(
        pd.read_csv(tmp_path / "choice.csv")["price"].sum())


def test_choose_lists_the_blocking_rows_beside_out_as_positions(tmp_path, capsys):
    """An unreachable target: the refusal names the worst row's pose, and
    ``STEM.blocking.csv`` holds every blocked row (worst first, loads above 1) with its pose
    as axis positions; a second run does not replace it without --overwrite."""
    args = ["choose", MILL, "--catalogue", MILL_CATALOGUE, "--points", "3", "--target", "0.999",
            "--out", str(tmp_path / "c.csv")]
    assert cli.main(args) == 2
    message = capsys.readouterr().err
    blocking = pd.read_csv(tmp_path / "c.blocking.csv")
    assert list(blocking.columns) == ["output", "Y_mm", "X_mm", "Z_mm", "load"]
    assert (blocking["load"] > 1).all() and blocking["load"].is_monotonic_decreasing
    first = blocking.iloc[0]
    assert (f"meets {first['output']} at Y={first['Y_mm']:g} mm, X={first['X_mm']:g} mm, "
            f"Z={first['Z_mm']:g} mm") in message
    assert f"{len(blocking)} (output, pose) row(s) blocked" in message
    assert "listed in" in message and not (tmp_path / "c.csv").exists()
    assert cli.main(args) == 2
    assert "c.blocking.csv exists; pass --overwrite" in capsys.readouterr().err
