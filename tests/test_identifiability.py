"""Errors that cannot be told apart: whole groups of equal sensitivity columns."""

from __future__ import annotations

import numpy as np

from reliability.first_order.fosm import fosm
from reliability.model.identifiability import indistinguishable_groups
from reliability.model.poses import workspace_grid


def _union_find_groups(machine, poses, rtol=1e-12):
    """Independent reference: every pair of columns compared over all poses at once."""
    jac = machine.jacobian(poses).reshape(-1, machine.n_errors)
    scale = np.abs(jac).max(axis=0)
    parent = list(range(machine.n_errors))

    def root(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(machine.n_errors):
        for j in range(i + 1, machine.n_errors):
            if np.abs(jac[:, i] - jac[:, j]).max() <= rtol * max(scale[i], scale[j]):
                parent[root(j)] = root(i)
    groups = {}
    for i in range(machine.n_errors):
        groups.setdefault(root(i), []).append(machine.error_names[i])
    return sorted(tuple(g) for g in groups.values() if len(g) > 1)


def test_paper_machine_has_62_of_66_errors_in_16_groups(hobbing):
    groups = indistinguishable_groups(hobbing)
    assert len(groups) == 16 and sum(map(len, groups)) == 62
    assert ("C.ez", "X.ez", "C-X.ez") in groups


def test_groups_match_an_all_pairs_comparison(hobbing, trunnion5):
    for machine in (hobbing, trunnion5):
        poses = workspace_grid(machine, 3)
        ours = sorted(indistinguishable_groups(machine, poses, memory=200_000))
        assert ours == _union_find_groups(machine, poses)


def test_only_a_groups_summed_variance_matters(trunnion5):
    group = indistinguishable_groups(trunnion5)[0]
    index = [trunnion5.error_index(name) for name in group]
    poses = workspace_grid(trunnion5, 3)
    t = trunnion5.initial_allocation.copy()
    before = fosm(trunnion5, t, poses).sigma
    total = np.sum(np.square(t[index]))
    t[index] = 0.0 + 1e-12
    t[index[0]] = np.sqrt(total - (len(index) - 1) * 1e-24)  # the whole variance on one member
    np.testing.assert_allclose(fosm(trunnion5, t, poses).sigma, before, rtol=1e-9)


def test_check_lists_whole_groups(capsys):
    from pathlib import Path

    from studies import cli

    hobbing_file = Path(__file__).parent.parent / "reliability" / "machines" / "hobbing.toml"
    assert cli.main(["check", str(hobbing_file)]) == 0
    printed = capsys.readouterr().out
    assert "62 of 66 errors in 16 groups" in printed
    assert "  - C.ez, X.ez, C-X.ez" in printed
