"""A folder of finished results, one file per task, so long computations can resume.

Each result is stored as soon as it is finished, as one JSON file named by a hash of the
task's parameters and the toolkit version, written atomically (:mod:`reliability.basics.files`).
A file carries a checksum of its own content, so a damaged file is detected when read
rather than silently used. A task whose parameters (or the toolkit version) change gets a
new key and is computed again; finished tasks are never recomputed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

from .errors import InputError, SavedResultError
from .files import atomic_write_text
from .saved_results import plain_json, toolkit_version


def canonical_json(value) -> str:
    """JSON with sorted keys and no spaces: equal values give equal text (and hashes)."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=plain_json)


def task_key(parameters, version: str | None = None) -> str:
    """Hex SHA-256 of a task's parameters and the toolkit version: its file name."""
    version = toolkit_version() if version is None else version
    text = canonical_json({"parameters": parameters, "version": version})
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def machine_fingerprint(machine) -> str:
    """Hex SHA-256 of everything that defines a machine's model (axes, offsets,
    requirements, cost coefficients, initial allocation, and the work zone when it has
    one)."""
    description = {"name": machine.name,
                   "axes": [dataclasses.asdict(axis) for axis in machine.axis_specs],
                   "tool_offset": machine.tool_offset, "limits": machine.limits,
                   "targets": machine.targets, "initial": machine.initial_allocation,
                   "cost": {field.name: _mapping(getattr(machine.cost_coefficients, field.name))
                            for field in dataclasses.fields(machine.cost_coefficients)}}
    if getattr(machine, "work_zone", None) is not None:
        description["work_zone"] = dataclasses.asdict(machine.work_zone)
    return hashlib.sha256(canonical_json(description).encode("utf-8")).hexdigest()


class ResultStore:
    """Finished results in a folder, one ``<key>.json`` file each.

    Parameters
    ----------
    folder : str or Path
        Created (with parents) when missing.
    version : str, optional
        Toolkit version mixed into every key; the installed one by default.
    """

    def __init__(self, folder, version: str | None = None):
        self.folder = Path(folder)
        if self.folder.exists() and not self.folder.is_dir():
            raise InputError(f"store {str(self.folder)!r} is a file; expected a folder")
        self.folder.mkdir(parents=True, exist_ok=True)
        self.version = toolkit_version() if version is None else version

    def key(self, parameters) -> str:
        """The file key of a task."""
        return task_key(parameters, self.version)

    def path(self, parameters) -> Path:
        """Where the task's result is (or will be) stored."""
        return self.folder / f"{self.key(parameters)}.json"

    def __contains__(self, parameters) -> bool:
        return self.path(parameters).exists()

    def load(self, parameters):
        """The stored result of a task, or None if it is not finished.

        Raises
        ------
        SavedResultError
            When the file is damaged or belongs to other parameters.
        """
        path = self.path(parameters)
        if not path.exists():
            return None
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            body = {name: record[name] for name in ("parameters", "version", "result")}
            checksum = record["checksum"]
        except (ValueError, KeyError, TypeError) as exc:
            raise SavedResultError(f"stored result {path} is damaged ({exc}); delete it to "
                                   f"compute the task again") from None
        if checksum != _checksum(body):
            raise SavedResultError(f"stored result {path} fails its checksum; delete it to "
                                   f"compute the task again")
        if canonical_json(body["parameters"]) != canonical_json(parameters):
            raise SavedResultError(f"stored result {path} belongs to other parameters")
        return body["result"]

    def save(self, parameters, result) -> Path:
        """Store a finished task's result (JSON-serialisable) atomically."""
        body = {"parameters": parameters, "version": self.version, "result": result}
        record = dict(body, checksum=_checksum(body))
        return atomic_write_text(self.path(parameters), canonical_json(record) + "\n",
                                 overwrite=True)


def _checksum(body) -> str:
    return hashlib.sha256(canonical_json(body).encode("utf-8")).hexdigest()


def _mapping(value):
    return dict(value) if hasattr(value, "items") else value

