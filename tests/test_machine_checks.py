"""Tests of the machine read back to its author: describe() and likely_mistakes()."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from reliability.model.machine_checks import describe, likely_mistakes


def _with_axis(machine, position, **changes):
    axes = list(machine.axis_specs)
    axes[position] = dataclasses.replace(axes[position], **changes)
    return dataclasses.replace(machine, axis_specs=tuple(axes))


def test_paper_machine_has_no_likely_mistake(hobbing):
    assert likely_mistakes(hobbing) == []


def test_first_axis_offset_is_flagged_and_really_has_no_effect(hobbing):
    shifted = _with_axis(hobbing, 0, offset=(10.0, -20.0, 300.0))
    warnings = likely_mistakes(shifted)
    assert len(warnings) == 1 and "'C' is first in the chain" in warnings[0]
    # The claim the warning makes, checked on the model: nothing changes.
    rng = np.random.default_rng(3)
    q = np.array([[1.0, 100.0, 200.0, 0.3, 50.0, 2.0], [4.0, 300.0, 450.0, -0.6, 150.0, 5.0]])
    x = rng.normal(scale=1e-3, size=(2, hobbing.n_errors))
    np.testing.assert_allclose(shifted.comprehensive_error(q, x),
                               hobbing.comprehensive_error(q, x), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(shifted.jacobian(q), hobbing.jacobian(q), rtol=1e-9,
                               atol=1e-15)
    # ... whereas the same offset on the second axis does change the result.
    moved = _with_axis(hobbing, 1, offset=(10.0, -20.0, 300.0))
    assert not np.allclose(moved.jacobian(q), hobbing.jacobian(q))
    assert likely_mistakes(moved) == []


def test_rotary_stroke_in_degrees_is_flagged(hobbing):
    degrees = _with_axis(hobbing, 3, stroke=(-45.0, 45.0))
    (warning,) = likely_mistakes(degrees)
    assert "'A'" in warning and "degrees given for radians" in warning
    assert "90 rad" in warning


def test_rotary_stroke_of_exactly_one_turn_suggests_full_turn(hobbing):
    turn = _with_axis(hobbing, 3, stroke=(-math.pi, math.pi))
    (warning,) = likely_mistakes(turn)
    assert "full_turn = true" in warning and "'A'" in warning


def test_size_in_millimetres_is_flagged(hobbing, mill3):
    (warning,) = likely_mistakes(_with_axis(hobbing, 1, size=4000.0))
    assert "'X'" in warning and "millimetres given for metres" in warning
    (warning,) = likely_mistakes(_with_axis(hobbing, 0, size=3000.0))
    assert "rotation diameter" in warning


def test_guide_shorter_than_stroke_is_flagged(hobbing):
    (warning,) = likely_mistakes(_with_axis(hobbing, 1, size=0.2))
    assert "shorter than its stroke of 400 mm" in warning


def test_linear_stroke_in_metres_is_flagged(hobbing):
    warnings = likely_mistakes(_with_axis(hobbing, 2, stroke=(0.1, 0.5)))
    assert any("'Z'" in w and "metres given for millimetres" in w for w in warnings)


def test_parallel_linear_axes_are_flagged(hobbing):
    (warning,) = likely_mistakes(_with_axis(hobbing, 4, direction="x"))
    assert "'X' and 'Y' both move along x" in warning


def test_limits_in_wrong_units_are_flagged(hobbing):
    limits = hobbing.limits.copy()
    limits[0], limits[4] = 20.0, 10.0  # µm and arc seconds typed as mm and rad
    warnings = likely_mistakes(dataclasses.replace(hobbing, limits=limits))
    assert any("limit of dx is 20 mm" in w for w in warnings)
    assert any("limit of ey is 10 rad" in w and "degrees" in w for w in warnings)


def test_initial_tolerance_above_a_limit_is_flagged(hobbing):
    initial = hobbing.initial_allocation.copy()
    initial[hobbing.error_index("Z-A.ez")] = 1e-3  # mrad typed where rad belongs
    warnings = likely_mistakes(dataclasses.replace(hobbing, initial_allocation=initial))
    assert any("Z-A.ez" in w and "initial_allocation" in w for w in warnings)


def test_describe_lists_axes_units_errors_and_requirements(hobbing, trunnion5):
    text = describe(hobbing)
    assert "C X Z A Y M (6 axes); 66 geometric errors (36 motion, 30 assembly)" in text
    assert "0 … 400 mm" in text and "full turn [0, 2π)" in text
    assert "-0.785398 … 0.785398 rad (-45° … 45°)" in text
    assert "0.02 mm" in text and "4.8e-05 rad" in text and "size [m]" in text
    assert "a = 1.98" in text and "C-X 1.3" in text
    text = describe(trunnion5)
    assert "54 geometric errors" in text and "[0, 0, -150] mm" in text
    assert "(-120° … 30°)" in text


def test_describe_omits_coefficients_a_machine_does_not_need(mill3):
    lean = dataclasses.replace(mill3, cost_coefficients=dataclasses.replace(
        mill3.cost_coefficients, c=None, d=None))
    text = describe(lean)
    assert "a = 2, b = 1.5;" in text and "c =" not in text


@pytest.mark.parametrize("name", ["hobbing", "mill3", "trunnion5"])
def test_every_warning_is_one_sentence_naming_an_item(request, name):
    machine = request.getfixturevalue(name)
    for warning in likely_mistakes(machine):
        assert "\n" not in warning and "'" in warning


def test_checks_refuse_what_is_not_a_machine(hobbing_dict):
    from reliability.basics.errors import InputTypeError

    for call in (likely_mistakes, describe):
        with pytest.raises(InputTypeError, match="machine must be a Machine.*dict"):
            call(hobbing_dict)
