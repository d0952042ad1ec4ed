"""reliability.basics.streams: the one door for rng= and the three rules for extra streams."""

from __future__ import annotations

import numpy as np
import pytest

from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.streams import extra_stream, generator, spawn, verification_streams


def test_generator_accepts_every_documented_form():
    seed_sequence = np.random.SeedSequence(11)
    existing = np.random.default_rng(3)
    assert generator(existing) is existing  # shared state, not a copy
    assert generator(11).random() == np.random.default_rng(11).random()
    assert generator(seed_sequence).random() == np.random.default_rng(11).random()
    assert generator(np.int64(11)).random() == np.random.default_rng(11).random()
    assert isinstance(generator(None), np.random.Generator)


@pytest.mark.parametrize("bad, kind, words", [
    (-1, InputError, ["rng", "non-negative"]),
    (1.5, InputTypeError, ["rng", "float"]),
    ("7", InputTypeError, ["rng", "str"]),
    (True, InputTypeError, ["rng", "bool"]),
])
def test_generator_refuses_other_forms_naming_the_argument(bad, kind, words):
    with pytest.raises(kind) as caught:
        generator(bad)
    assert all(word in str(caught.value) for word in words)


def test_spawned_children_do_not_depend_on_how_many_are_asked_for():
    few, many = spawn(5, 2), spawn(5, 7)
    assert [g.random() for g in few] == [g.random() for g in many[:2]]
    assert len({g.random() for g in spawn(5, 4)}) == 4  # distinct streams


def test_extra_streams_are_their_documented_family_and_independent_of_spawn():
    reference = np.random.default_rng(np.random.SeedSequence([9, 1], spawn_key=(1,)))
    assert extra_stream(9, 1).random() == reference.random()
    draws = {extra_stream(9, 0).random(), extra_stream(9, 1).random(),
             *(g.random() for g in spawn(9, 4)), generator(9).random()}
    assert len(draws) == 7
    with pytest.raises(InputError, match="seed"):
        extra_stream(-3, 0)


def test_verification_streams_are_spawn_of_the_seed():
    grid, random_poses, worst, machines = verification_streams(7)
    expected = [g.random() for g in spawn(7, 4)]
    assert [grid.random(), random_poses.random(), worst.random(),
            machines.random()] == expected
    assert [g.random() for g in spawn(7, 3)] == expected[:3]

