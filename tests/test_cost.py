"""Tests of the power-exponent cost model (Eqs. 25-28)."""

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
import pytest

from allocation.cost.cost import COMPONENTS, CostModel, cost_weights


@dataclass(frozen=True)
class Axis:
    name: str
    kind: str
    direction: str
    size: float


@dataclass(frozen=True)
class Coefficients:
    a: float
    b: float
    c: float
    d: float
    assembly: dict = field(default_factory=dict)


@dataclass(frozen=True)
class FakeMachine:
    """Stand-in with exactly the attributes the cost model reads."""

    axis_specs: tuple
    joints: tuple
    cost_coefficients: Coefficients
    error_names: tuple = None

    def __post_init__(self):
        if self.error_names is None:
            owners = [axis.name for axis in self.axis_specs] + list(self.joints)
            names = tuple(f"{owner}.{comp}" for owner in owners for comp in COMPONENTS)
            object.__setattr__(self, "error_names", names)


def tiny_machine(**changes):
    """Two axes: a rotary table R about z (D = 2 m) carrying a linear axis L along y."""
    machine = FakeMachine(
        axis_specs=(Axis("R", "rotary", "z", 2.0), Axis("L", "linear", "y", 0.5)),
        joints=("R-L",),
        cost_coefficients=Coefficients(a=3.0, b=2.0, c=5.0, d=7.0, assembly={"R-L": 11.0}),
    )
    return replace(machine, **changes)


def paper_machine():
    """The paper's chain C X Z A Y M with Table 3 sizes and Table 5 coefficients."""
    axes = (
        Axis("C", "rotary", "z", 3.0),
        Axis("X", "linear", "x", 4.0),
        Axis("Z", "linear", "z", 5.0),
        Axis("A", "rotary", "x", 1.5),
        Axis("Y", "linear", "y", 2.0),
        Axis("M", "rotary", "y", 1.0),
    )
    m = {"C-X": 1.3, "X-Z": 1.7, "Z-A": 1.1, "A-Y": 1.34, "Y-M": 1.07}
    return FakeMachine(axes, tuple(m), Coefficients(1.98, 1.5, 1.83, 1.4, m))


def test_tiny_machine_hand_computed():
    model = CostModel.from_machine(tiny_machine())
    # R rotary about z: ez -> c = 5, others d*D = 7*2 = 14; L linear along y: dy -> a = 3,
    # others b*L = 2*0.5 = 1; joint R-L: m = 11 for all six.
    expected = [14, 14, 14, 14, 14, 5, 1, 3, 1, 1, 1, 1] + [11] * 6
    np.testing.assert_array_equal(model.weights, expected)
    t = np.full(18, 0.5)
    assert model.total(t) == pytest.approx(4 * sum(expected))
    t = np.arange(1.0, 19.0)
    assert model.total(t) == pytest.approx(sum(w / ti**2 for w, ti in zip(expected, t)))


def test_paper_weights():
    machine = paper_machine()
    w = pd.Series(cost_weights(machine), index=machine.error_names)
    assert len(w) == 66
    assert w["X.dx"] == 1.98
    assert w["X.dy"] == pytest.approx(1.5 * 4)
    assert w["Z.dz"] == 1.98
    assert w["Z.ex"] == pytest.approx(1.5 * 5)
    assert w["Y.dy"] == 1.98
    assert w["Y.dx"] == pytest.approx(1.5 * 2)
    assert w["C.ez"] == 1.83
    assert w["C.dx"] == pytest.approx(1.4 * 3)
    assert w["A.ex"] == 1.83
    assert w["A.ez"] == pytest.approx(1.4 * 1.5)
    assert w["M.ey"] == 1.83
    assert w["M.dz"] == pytest.approx(1.4 * 1.0)
    assert (w.filter(like="C-X.") == 1.3).all() and w.filter(like="C-X.").size == 6
    assert (w.filter(like="Y-M.") == 1.07).all()


def test_paper_initial_allocation_cost_with_unit_group_factors():
    # Table 4: 0.003 mm for every translation, 1.45e-5 rad for every rotation.
    machine = paper_machine()
    t = np.array([3e-3 if name.split(".")[1][0] == "d" else 1.45e-5
                  for name in machine.error_names])
    d2, e2 = 3e-3**2, 1.45e-5**2
    linear = sum(1.98 / d2 + 1.5 * length * (2 / d2 + 3 / e2) for length in (4, 5, 2))
    rotary = sum(1.83 / e2 + 1.4 * diameter * (3 / d2 + 2 / e2) for diameter in (3, 1.5, 1))
    assembly = sum(m * (3 / d2 + 3 / e2) for m in (1.3, 1.7, 1.1, 1.34, 1.07))
    sums = CostModel.from_machine(machine).by_group(t)
    np.testing.assert_allclose(sums, [linear, rotary, assembly, linear + rotary + assembly])
    assert sums["total"] == pytest.approx(4.277e11, rel=1e-3)  # as the docstring says


def test_group_factors_scale_each_group_only():
    machine = paper_machine()
    base = CostModel.from_machine(machine)
    groups = np.asarray(base.groups)
    for index, group in enumerate(("linear", "rotary", "assembly")):
        k = [1.0, 1.0, 1.0]
        k[index] = 3.0
        scaled = cost_weights(machine, k=k)
        np.testing.assert_allclose(scaled[groups == group], 3 * base.weights[groups == group])
        np.testing.assert_array_equal(scaled[groups != group], base.weights[groups != group])


def test_total_is_batched():
    model = CostModel.from_machine(paper_machine())
    rng = np.random.default_rng(1)
    t = rng.uniform(0.5, 1.5, size=(4, 3, 66))
    totals = model.total(t)
    assert totals.shape == (4, 3)
    assert totals[2, 1] == pytest.approx(model.total(t[2, 1]))
    assert isinstance(model.total(t[0, 0]), float)


def test_breakdown_and_by_group():
    model = CostModel.from_machine(paper_machine(), k1=2.0, k2=0.5, k3=1.0)
    t = np.linspace(1e-3, 5e-3, 66)
    frame = model.breakdown(t)
    assert list(frame.columns) == ["group", "owner", "weight", "tolerance", "cost", "share"]
    assert list(frame.index) == list(model.names)
    assert frame["share"].sum() == pytest.approx(1.0, abs=1e-12)
    assert frame.loc["A-Y.ez", "owner"] == "A-Y"
    assert frame.loc["A.dx", "group"] == "rotary"
    assert frame.loc["X.dx", "cost"] == pytest.approx(2.0 * 1.98 / t[6] ** 2)
    sums = model.by_group(t)
    assert list(sums.index) == ["linear", "rotary", "assembly", "total"]
    assert sums["total"] == pytest.approx(model.total(t))
    assert sums[["linear", "rotary", "assembly"]].sum() == pytest.approx(sums["total"])
    linear = frame.loc[frame["group"] == "linear", "cost"].sum()
    assert sums["linear"] == pytest.approx(linear)


def test_to_frame_lists_the_weights():
    frame = CostModel.from_machine(tiny_machine(), k3=2.0).to_frame()
    assert list(frame.columns) == ["group", "owner", "weight"]
    assert frame.loc["R-L.ey", "weight"] == 22.0
    assert frame.loc["L.dy", "owner"] == "L" and frame.loc["L.dy", "group"] == "linear"


def test_error_names_are_read_in_the_machines_order():
    machine = tiny_machine()
    shuffled = replace(machine, error_names=tuple(reversed(machine.error_names)))
    np.testing.assert_array_equal(
        cost_weights(shuffled), cost_weights(machine)[::-1]
    )


@pytest.mark.parametrize(
    "t, match",
    [
        (np.ones(17), r"shape \(\.\.\., 18\), got shape \(17,\)"),
        (np.float64(1.0), r"shape \(\.\.\., 18\), got shape \(\)"),
        (np.r_[np.ones(7), 0.0, np.ones(10)], r"tolerance of 'L.dy' is 0.0"),
        (np.r_[np.ones(12), -1.0, np.ones(5)], r"tolerance of 'R-L.dx' is -1.0"),
        (np.r_[np.nan, np.ones(17)], r"tolerance of 'R.dx' is nan"),
    ],
)
def test_bad_tolerances_are_refused(t, match):
    model = CostModel.from_machine(tiny_machine())
    with pytest.raises(ValueError, match=match):
        model.total(t)


def test_bad_tolerance_in_a_batch_names_the_batch_index():
    model = CostModel.from_machine(tiny_machine())
    t = np.ones((2, 3, 18))
    t[1, 2, 5] = np.inf
    with pytest.raises(ValueError, match=r"'R.ez' at batch index \(1, 2\) is inf"):
        model.total(t)


def test_breakdown_wants_one_allocation():
    model = CostModel.from_machine(tiny_machine())
    with pytest.raises(
        ValueError, match=r"one allocation of shape \(18,\), got shape \(2, 18\)"
    ):
        model.breakdown(np.ones((2, 18)))


@pytest.mark.parametrize(
    "changes, match",
    [
        (
            {"axis_specs": (Axis("R", "prismatic", "z", 2.0), Axis("L", "linear", "y", 0.5))},
            r"axis 'R' has kind 'prismatic'",
        ),
        (
            {"axis_specs": (Axis("R", "rotary", "w", 2.0), Axis("L", "linear", "y", 0.5))},
            r"axis 'R' has direction 'w'",
        ),
        (
            {"axis_specs": (Axis("R", "rotary", "z", 2.0), Axis("L", "linear", "y", -0.5))},
            r"axis 'L' has size -0.5",
        ),
        (
            {"cost_coefficients": Coefficients(3.0, np.nan, 5.0, 7.0, {"R-L": 11.0})},
            r"cost coefficient b is nan",
        ),
        (
            {"cost_coefficients": Coefficients(3.0, 2.0, 5.0, 7.0, {})},
            r"no assembly cost coefficient for joint\(s\) \['R-L'\]",
        ),
        (
            {"cost_coefficients": Coefficients(3.0, 2.0, 5.0, 7.0, {"R-L": 1.0, "L-Q": 1.0})},
            r"unknown joint\(s\) \['L-Q'\]",
        ),
        (
            {"cost_coefficients": Coefficients(3.0, 2.0, 5.0, 7.0, {"R-L": -1.0})},
            r"assembly cost coefficient of joint 'R-L' is -1.0",
        ),
    ],
)
def test_bad_machine_descriptions_are_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        CostModel.from_machine(tiny_machine(**changes))


def test_error_names_must_match_axes_and_joints():
    names = tiny_machine().error_names
    with pytest.raises(ValueError, match=r"error name 'R.dw' is not a component"):
        CostModel.from_machine(tiny_machine(error_names=names[:-1] + ("R.dw",)))
    with pytest.raises(ValueError, match=r"lacks 'R-L.ez'"):
        CostModel.from_machine(tiny_machine(error_names=names[:-1]))
    with pytest.raises(ValueError, match=r"'R.dx' appears more than once"):
        CostModel.from_machine(tiny_machine(error_names=names[:-1] + ("R.dx",)))


def test_bad_group_factors_are_refused():
    with pytest.raises(ValueError, match=r"k2 is -1.0"):
        CostModel.from_machine(tiny_machine(), k2=-1.0)
    with pytest.raises(ValueError, match=r"k must hold \(k1, k2, k3\), got 2 values"):
        cost_weights(tiny_machine(), k=(1.0, 1.0))


def test_linear_machine_without_rotary_coefficients_costs_the_same(mill3):
    import dataclasses

    lean = dataclasses.replace(mill3, cost_coefficients=dataclasses.replace(
        mill3.cost_coefficients, c=None, d=None))
    np.testing.assert_array_equal(CostModel.from_machine(lean).weights,
                                  CostModel.from_machine(mill3).weights)
    no_linear = dataclasses.replace(mill3, cost_coefficients=dataclasses.replace(
        mill3.cost_coefficients, b=None))
    with pytest.raises(ValueError, match="linear axis 'Y' needs cost coefficient b"):
        CostModel.from_machine(no_linear)
