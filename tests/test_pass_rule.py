"""The one pass rule ``|y| < I`` and that no hand-written pass decision remains in the
packages."""

import re
from pathlib import Path

import numpy as np

from reliability.basics.pass_rule import passes

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("reliability", "allocation", "studies")
#: ``abs(...)`` compared with a limit, either way round: a pass decision written by hand.
HAND_WRITTEN = re.compile(r"abs\(.*\)\s*[<>]=?\s*[\w.]*limit"
                          r"|limits?(\[[^\]]*\])?\s*[<>]=?\s*(np\.)?abs\(")


def test_a_value_exactly_on_the_limit_fails():
    assert not passes(0.02, 0.02)
    assert not passes(-0.02, 0.02)


def test_a_value_just_inside_passes():
    inside = np.nextafter(0.02, 0.0)
    assert passes(inside, 0.02)
    assert passes(-inside, 0.02)


def test_negative_values_pass_by_their_absolute_value():
    np.testing.assert_array_equal(passes([-0.01, -0.03, 0.01, 0.03], 0.02),
                                  [True, False, True, False])


def test_nan_fails():
    assert not passes(np.nan, 0.02)
    np.testing.assert_array_equal(passes([np.nan, 0.0], [1.0, 1.0]), [False, True])


def test_limits_broadcast_over_the_six_outputs():
    limits = np.array([0.02, 0.02, 0.03, 4e-5, 4e-5, 5e-5])
    values = np.array([[0.01, -0.02, 0.029, -3e-5, 4e-5, 0.0],
                       [0.021, 0.0, -0.031, 0.0, -3.9e-5, -5e-5]])
    expected = np.array([[True, False, True, True, False, True],
                         [False, True, False, True, True, False]])
    result = passes(values, limits)
    assert result.shape == (2, 6)
    np.testing.assert_array_equal(result, expected)
    np.testing.assert_array_equal(passes(values[:, None, :], limits), expected[:, None, :])


def test_the_pattern_finds_hand_written_decisions():
    for line in ("inside = np.abs(y) < machine.limits",
                 "ok = np.all(np.abs(outputs) <= machine.limits, axis=(1, 2))",
                 "outside = np.abs(values) > limit",
                 "fails = np.abs(y[:, 0]) >= machine.limits[0]",
                 "ok = limits[o] > np.abs(y)"):
        assert HAND_WRITTEN.search(line), line
    assert not HAND_WRITTEN.search("inside = passes(y, machine.limits)")


def test_no_hand_written_pass_decision_remains():
    found = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            name = path.relative_to(ROOT).as_posix()
            if name == "reliability/basics/pass_rule.py":
                continue
            for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                if HAND_WRITTEN.search(line):
                    found.append(f"{name}:{number}: {line.strip()}")
    assert not found, "pass decisions written by hand; use passes():\n" + "\n".join(found)
