"""What the report's tables and figures say, on a 5-axis machine with a long name: titles
inside their figures, poses named by axis positions, advice that keeps errors which
cannot be told apart together, and where failing machines fail first."""

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from reliability.first_order.system_reliability import system_reliability  # noqa: E402
from reliability.model.identifiability import indistinguishable_groups  # noqa: E402
from reliability.model.machine_file import machine_from_toml  # noqa: E402
from reliability.model.poses import workspace_grid  # noqa: E402
from studies.report.machine_sections import (allocation_section, answers,  # noqa: E402
                                             verification_section)
from studies.report.tradeoff_sections import system_section  # noqa: E402
from studies.report.writer import png_bytes  # noqa: E402
from studies.report.yield_section import yield_section  # noqa: E402
from studies.workflows import machine_study  # noqa: E402


MACHINE_DIR = Path(__file__).parent / "machines"
LONG_NAME = ("five-axis machining centre with a rotary C table, a B swivel head, a long "
             "cross slide and a name far longer than any figure is wide")
#: One pose entry of a table: ``C=144 deg`` or ``Y=-300 mm``.
POSITION = re.compile(r"^([A-Z]+)=(-?[0-9.e+-]+) (mm|deg)$")


@pytest.fixture(scope="module")
def swivel():
    """tests/machines/swivel5.toml under a long name."""
    text = (MACHINE_DIR / "swivel5.toml").read_text()
    return machine_from_toml(re.sub(r'^name = ".*"$', f'name = "{LONG_NAME}"', text,
                                    count=1, flags=re.M))


@pytest.fixture(scope="module")
def study(swivel):
    """A small study of the long-named swivel machine on its 3-point grid."""
    return machine_study.run(swivel, points=3, rng=0, repeats=2, samples=300,
                             machines=200, workspace="grid")


def _positions(text, machine):
    """``"C=144 deg, Y=-300 mm, ..."`` as positions in the model's units (rad, mm)."""
    parts = [POSITION.match(part) for part in text.split(", ")]
    assert all(parts), text
    assert [p.group(1) for p in parts] == list(machine.axes), text
    return np.array([np.radians(float(p.group(2))) if p.group(3) == "deg"
                     else float(p.group(2)) for p in parts])


#: Figures whose titles carry the machine's name: a suptitle, a title over one wide axes,
#: a title of several lines.
NAMED_FIGURES = ("failure_shares.png", "allocation_motion.png", "scatter_dz.png")


def test_titles_of_figures_with_a_long_machine_name_stay_inside(study):
    built = (yield_section(study), allocation_section(study), verification_section(study))
    figures = {name: figure for section in built
               for name, figure in section.figures.items() if name in NAMED_FIGURES}
    assert set(figures) == set(NAMED_FIGURES)
    for name, figure in figures.items():
        png_bytes(figure)
        renderer = FigureCanvasAgg(figure).get_renderer()
        figure.draw(renderer)
        titles = [ax.title for ax in figure.axes if ax.get_title()]
        titles += [figure._suptitle] if figure._suptitle is not None else []
        assert any(LONG_NAME[:40] in t.get_text().replace("\n", " ") for t in titles), name
        for title in titles:
            box = title.get_window_extent(renderer)
            inside = (box.x0 >= -0.5 and box.x1 <= figure.bbox.x1 + 0.5
                      and box.y0 >= -0.5 and box.y1 <= figure.bbox.y1 + 0.5)
            assert inside, (name, title.get_text(), box, figure.bbox)


def test_system_table_names_each_worst_pose_by_its_axis_positions(swivel):
    poses = workspace_grid(swivel, 3)
    section = system_section(swivel, {"initial": swivel.initial_allocation}, poses=poses,
                             rng=3)
    row = next(line for line in section.text.splitlines() if line.startswith("| initial"))
    pose = _positions(row.split(" | ")[1], swivel)
    assert np.isclose(poses, pose, atol=1e-6 * np.abs(poses).max()).all(axis=1).any()
    everywhere = system_reliability(swivel, swivel.initial_allocation, poses, n_points=256,
                                    rng=4)
    there = system_reliability(swivel, swivel.initial_allocation, pose, n_points=256, rng=5)
    # the named pose is the worst: no grid pose is lower by more than 4 standard errors
    lowest = everywhere.probability.min()
    assert there.probability[0] <= lowest + 4 * (everywhere.error.max() + there.error[0])
    assert "worst pose C=" in there.summary()


def test_advice_names_errors_that_cannot_be_told_apart_as_one_group(study):
    machine = study.machine
    lines = answers(study).splitlines()
    tighten, relax = (next(line.split(": ", 1)[1] for line in lines if line.startswith(head))
                      for head in ("- Tighten:", "- May be relaxed:"))
    groups = indistinguishable_groups(machine, study.problem.poses)
    for text in (tighten, relax):
        for member in (name for group in groups for name in group):
            assert not re.search(rf"(^|; ){re.escape(member)} \(", text), (member, text)
    dz = next(group for group in groups if all(n.endswith(".dz") for n in group))
    index = [machine.error_index(name) for name in dz]
    rss = np.sqrt(np.sum(study.optimum.tolerances[index] ** 2)
                  / np.sum(study.problem.reference[index] ** 2))
    assert f"dz group {groups.index(dz) + 1} ({len(dz)} items: " in relax
    assert f"{rss - 1:+.0%} in root-sum-square" in relax


def _claims_hold(text, poses, machine):
    """Whether every pose satisfies each ``A = v unit``, ``A = ±v unit`` or ``A = v or w
    unit`` claim of ``text``."""
    for name, values, unit in re.findall(r"([A-Z]+) = ([-±0-9.e+ or]+) (mm|deg)", text):
        column = poses[:, machine.axes.index(name)]
        column = np.degrees(column) if unit == "deg" else column
        allowed = ([-float(values[1:]), float(values[1:])] if values.startswith("±")
                   else [float(v) for v in values.split(" or ")])
        if not np.isclose(column[:, None], allowed, atol=1e-6).any(axis=1).all():
            return False
    return True


def test_failure_regions_say_which_positions_the_worst_poses_share(study):
    from reliability.sampling.machine_yield import YieldModel

    machine = study.machine
    model = YieldModel(machine, points=3)
    u = np.random.default_rng(11).standard_normal((3000, model.dimension))
    failed, rows = model.worst_rows(u, study.allocated)
    rows = rows[failed]
    deciding = model.regions.deciding_axes(model.linear.row_sigma(study.allocated))
    texts = np.array(model.regions.region_texts(rows, deciding))
    output = rows % 6
    undecided = [o for o in np.unique(output) if not deciding[o].any()]
    assert undecided, "the optimum should leave some output with no deciding axis"
    for o in undecided:
        poses = np.unique(model.experiment.poses[rows[output == o] // 6], axis=0)
        text = texts[output == o][0]
        assert (texts[output == o] == text).all()
        assert text.startswith(f"{len(poses)} poses, all with "), text
        assert _claims_hold(text, poses, machine), text
