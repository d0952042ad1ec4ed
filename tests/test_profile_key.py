"""The machine file's ``[requirements] profile``: read, checked, written, overridden."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import pytest

from reliability import load_machine, machine_from_dict
from reliability.basics.errors import InputError, MachineDescriptionError
from reliability.model.machine import machine_to_dict
from studies.cli import options

MILL = Path(__file__).parent / "machines" / "mill3.toml"


def with_profile(tmp_path, value) -> Path:
    text = MILL.read_text().replace("[requirements]", f"[requirements]\nprofile = {value}", 1)
    path = tmp_path / "mill_profile.toml"
    path.write_text(text)
    return path


def test_default_is_constant_and_not_written():
    machine = load_machine(MILL)
    assert machine.profile == "constant"
    assert "profile" not in machine_to_dict(machine)["requirements"]


@pytest.mark.parametrize("value, name", [('"gp:300"', "gp:300"), ('"gp:300.0"', "gp:300"),
                                         ('"independent"', "independent")])
def test_read_and_round_trip(tmp_path, value, name):
    machine = load_machine(with_profile(tmp_path, value))
    assert machine.profile == name
    again = machine_from_dict(machine_to_dict(machine))
    assert again.profile == name and again == machine


@pytest.mark.parametrize("value, words", [('"gp:-3"', "length must be finite"), ('"smooth"', "unknown profile"),
                                          ("3", "profile")])
def test_bad_values_name_the_key(tmp_path, value, words):
    with pytest.raises(MachineDescriptionError, match="requirements.profile") as raised:
        load_machine(with_profile(tmp_path, value))
    assert words in str(raised.value)


def test_command_line_overrides_the_file(tmp_path):
    parser = argparse.ArgumentParser()
    options.add_machine(parser)
    options.add_yield_model(parser)
    path = str(with_profile(tmp_path, '"gp:300"'))
    assert options.machine(parser.parse_args([path])).profile == "gp:300"
    chosen = options.machine(parser.parse_args([path, "--profile", "independent"]))
    assert chosen.profile == "independent"
    assert parser.parse_args([path]).machines == options.DEFAULT_MACHINES
    with pytest.raises(InputError, match="--profile"):
        options.machine(parser.parse_args([path, "--profile", "gp:"]))


def test_python_replace_checks_the_name():
    with pytest.raises(InputError, match="unknown profile"):
        dataclasses.replace(load_machine(MILL), profile="wavy")
