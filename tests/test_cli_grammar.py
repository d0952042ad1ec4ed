"""The command-line grammar of precrel, read from the parsers themselves: one option name,
one type and one meaning in every command; ``--out`` a file or a folder as declared (and
as docs/cli.md shows); old spellings still parse and warn; two allocations into one
folder never collide."""

from __future__ import annotations

import argparse
import re
from collections import defaultdict
from pathlib import Path

import pandas as pd
import pytest

from studies import cli
from studies.cli import allocate, program
from studies.cli.options import Deprecated

ROOT = Path(__file__).resolve().parents[1]
MILL = str(ROOT / "tests" / "machines" / "mill3.toml")
DOCS = ROOT / "docs" / "cli.md"

#: What each command's ``--out`` names (None: the command writes nothing), as docs/cli.md's
#: grammar table shows it.
OUT_KINDS = {"check": None, "predict": "file", "allocate": "file", "choose": "file",
             "verify": "folder", "report": "folder", "front": "file", "sweep": "folder",
             "acceptance": "file", "sensitivity": "folder", "measure": "file",
             "identify": "folder", "plan": "file", "compensate": "folder",
             "evaluate": "folder", "life": "folder"}
#: The options that take a list in one command and one value in another, of the same kind:
#: ``front --target R ...`` (the front's targets) against ``allocate --target R``.
LIST_FORMS = {"--target"}
#: Every old spelling: (argv, the new option's dest, the value it gets, the new spelling).
DEPRECATED = [
    (["sweep", "spec.toml", "--store", "runs"], "out", "runs", "--out"),
    (["front", MILL, "--targets", "7"], "count", 7, "--count"),
    (["sensitivity", MILL, "--yield"], "with_yield", True, "--yield-gradient"),
    (["sensitivity", MILL, "--samples", "300"], "samples", 300, "--sobol-samples"),
    (["allocate", MILL, "--out", "a.csv", "--catalogue", "cat.toml"], "catalogue",
     "cat.toml", "precrel choose"),
    (["verify", MILL, "--tolerances", "t.csv", "--certify"], "certify", True,
     "--workspace continuous"),
]


def commands() -> dict[str, argparse.ArgumentParser]:
    """Each command's parser, from :func:`studies.cli.program.build_parser`."""
    parser = program.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def options_of(parser) -> dict[str, argparse.Action]:
    """Option string -> action, help left out."""
    return {name: action for action in parser._actions for name in action.option_strings
            if name not in ("-h", "--help")}


def test_every_command_is_registered_with_its_out_kind():
    assert set(commands()) == set(program.COMMANDS) == set(OUT_KINDS)


def test_each_option_has_one_type_and_one_meaning_in_every_command():
    """Same type, choices and nargs, and declared by the same options.add_* or with the
    same help text, wherever an option name appears (old spellings aside)."""
    seen = defaultdict(list)
    for command, parser in commands().items():
        for name, action in options_of(parser).items():
            if not isinstance(action, Deprecated):
                seen[name].append((command, action))
    for name, found in seen.items():
        kinds = {(a.type, tuple(a.choices or ()),
                  None if name in LIST_FORMS and a.nargs == "+" else a.nargs)
                 for _, a in found}
        assert len(kinds) == 1, (name, [c for c, _ in found])
        origins = {getattr(a, "origin", None) for _, a in found}
        helps = {a.help for _, a in found}
        assert (len(origins) == 1 and None not in origins) or len(helps) == 1, \
            (name, [c for c, _ in found])


@pytest.mark.parametrize("name", ["--profile", "--distribution", "--frame", "--points",
                                  "--seed", "--machines", "--executor", "--workers",
                                  "--scheduler", "--overwrite", "--bounds", "--workspace",
                                  "--rtol", "--side", "--tolerances", "--out",
                                  "--time-limit", "--quiet"])
def test_the_shared_options_are_declared_once_in_options(name):
    """The options every command shares come from one options.add_* each."""
    origins = {getattr(options_of(parser)[name], "origin", None)
               for parser in commands().values() if name in options_of(parser)
               and not isinstance(options_of(parser)[name], Deprecated)}
    assert len(origins) == 1 and None not in origins, origins


def test_out_is_a_file_or_a_folder_as_declared():
    for command, parser in commands().items():
        out = options_of(parser).get("--out")
        assert (None if out is None else out.out_kind) == OUT_KINDS[command], command


def test_docs_show_every_command_its_out_kind_and_every_option():
    text = DOCS.read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `(\w+)` \| (file|folder|none) \|", text, flags=re.MULTILINE))
    assert rows == {c: kind or "none" for c, kind in OUT_KINDS.items()}
    for command, parser in commands().items():
        for name in options_of(parser):
            assert re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", text), \
                (command, name)
    for argv, _, _, new in DEPRECATED:
        old = next(word for word in argv if word.startswith("--") and word in
                   options_of(commands()[argv[0]]) and
                   isinstance(options_of(commands()[argv[0]])[word], Deprecated))
        assert re.search(rf"`{argv[0]} {old}[^`]*`[^|]*\| `[^`]*{re.escape(new.split()[-1])}",
                         text), (argv[0], old)


def test_every_old_spelling_is_tested():
    old = {(command, name) for command, parser in commands().items()
           for name, action in options_of(parser).items() if isinstance(action, Deprecated)}
    tested = {(argv[0], word) for argv, *_ in DEPRECATED for word in argv
              if (argv[0], word) in old}
    assert old == tested


@pytest.mark.parametrize("argv, dest, value, new", DEPRECATED,
                         ids=[f"{argv[0]}-{dest}" for argv, dest, *_ in DEPRECATED])
def test_old_spellings_still_parse_and_warn_once(argv, dest, value, new, capsys):
    args = program.build_parser().parse_args(argv)
    assert getattr(args, dest) == value
    old = next(w for w in argv if w.startswith("--") and w not in ("--out", "--tolerances"))
    assert capsys.readouterr().err == f"precrel: warning: {old} is deprecated; use {new}\n"


def test_allocate_modes_name_existing_options():
    """The mode table of allocate names its own options, and every mode has a reason."""
    names = options_of(commands()["allocate"])
    for option, _, modes in allocate.MODE_OPTIONS:
        assert option.split()[0] in names
        assert set(modes) <= {allocate.TARGETS, *allocate.MODE_REASONS}


def _allocate(folder, name, *extra):
    return cli.main(["allocate", MILL, "--points", "3", "--workspace", "grid", "--out",
                     str(folder / name), *extra])


def test_two_allocations_into_one_folder_never_collide(tmp_path, capsys):
    """Different --out: both written, each with its own drawing file; the same --out again
    is refused without --overwrite and with it replaces only that allocation's files."""
    assert _allocate(tmp_path, "a.csv") == 0
    assert _allocate(tmp_path, "b.csv") == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == \
        ["a.csv", "a.drawing.csv", "b.csv", "b.drawing.csv"]
    capsys.readouterr()
    for path in tmp_path.iterdir():
        path.touch()  # mark every file, so a rewrite shows as a new inode or time
    marked = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in tmp_path.iterdir()}
    assert _allocate(tmp_path, "a.csv") == 2
    assert "--overwrite" in capsys.readouterr().err
    assert {p.name: (p.stat().st_ino, p.stat().st_mtime_ns)
            for p in tmp_path.iterdir()} == marked
    assert _allocate(tmp_path, "a.csv", "--overwrite") == 0
    after = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in tmp_path.iterdir()}
    assert set(after) == set(marked)
    assert after["b.csv"] == marked["b.csv"] and after["b.drawing.csv"] == \
        marked["b.drawing.csv"]
    assert after["a.csv"] != marked["a.csv"] and after["a.drawing.csv"] != \
        marked["a.drawing.csv"]


def test_an_earlier_drawing_beside_a_new_out_is_refused_naming_both(tmp_path, capsys):
    """A left-over STEM.drawing.csv without its allocation is not silently replaced."""
    (tmp_path / "a.drawing.csv").write_text("x\n")
    assert _allocate(tmp_path, "a.csv") == 2
    err = capsys.readouterr().err
    assert "a.drawing.csv" in err and "--overwrite" in err
    assert not (tmp_path / "a.csv").exists()


def test_allocate_yield_refuses_a_process_pool_naming_it(tmp_path, capsys):
    """``--executor`` has one set of choices; ``allocate --yield`` cannot use processes."""
    assert _allocate(tmp_path, "a.csv", "--yield", "0.9", "--executor", "processes") == 2
    err = capsys.readouterr().err
    assert "--executor processes: not available with --yield" in err
    assert not any(tmp_path.iterdir())


PLAN = ('[[tests]]\nname = "ballbar"\nkind = "circular"\nplane = "xy"\n'
        'centre = { Y = 200.0, X = 0.0, Z = -175.0 }\nradius = 100.0\nlimit = 1.0\n'
        'u = 0.0005\n')


def test_measure_writes_its_truth_beside_out_and_identify_reads_the_files_profile(
        tmp_path, capsys):
    """``measure --out m.csv`` writes ``m.truth.csv`` beside it; ``identify`` identifies
    under the machine file's ``[requirements] profile`` when ``--profile`` is not given."""
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN)
    assert cli.main(["measure", MILL, "--plan", str(plan), "--out",
                     str(tmp_path / "m.csv")]) == 0
    assert {"m.csv", "m.truth.csv"} <= {p.name for p in tmp_path.iterdir()}
    machine = tmp_path / "gp.toml"
    machine.write_text(Path(MILL).read_text().replace(
        "[requirements]\n", '[requirements]\nprofile = "gp:300"\n', 1))
    assert cli.main(["identify", str(machine), "--measurements", str(tmp_path / "m.csv"),
                     "--out", str(tmp_path / "id")]) == 0
    assert (tmp_path / "id" / "profiles.csv").exists()  # written under a gp profile only
    capsys.readouterr()


def test_predict_out_is_one_table_with_the_worst_pose(tmp_path, capsys):
    out = tmp_path / "p.csv"
    assert cli.main(["predict", MILL, "--points", "3", "--out", str(out)]) == 0
    frame = pd.read_csv(out)
    assert list(frame["output"]) == ["dx", "dy", "dz", "ex", "ey", "ez"]
    assert {"Y", "X", "Z", "sigma", "beta", "worst_two_sided"} <= set(frame.columns)
    assert (frame["sigma"] > 0).all()
    assert cli.main(["predict", MILL, "--points", "3", "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err


def test_verify_out_is_a_folder_of_its_three_tables(tmp_path, capsys):
    assert _allocate(tmp_path, "a.csv") == 0
    argv = ["verify", MILL, "--tolerances", str(tmp_path / "a.csv"), "--points", "3",
            "--repeats", "2", "--samples", "500", "--machines", "100", "--workspace", "grid",
            "--out", str(tmp_path / "v")]
    assert cli.main(argv) == 0
    assert sorted(p.name for p in (tmp_path / "v").iterdir()) == \
        ["grid_experiments.csv", "random_poses.csv", "worst_poses.csv"]
    worst = pd.read_csv(tmp_path / "v" / "worst_poses.csv")
    assert list(worst["output"]) == ["dx", "dy", "dz", "ex", "ey", "ez"]
    assert ((worst["mc_lower"] <= worst["mc_estimate"])
            & (worst["mc_estimate"] <= worst["mc_upper"])).all()
    capsys.readouterr()
    assert cli.main(argv) == 2
    assert "--overwrite" in capsys.readouterr().err
