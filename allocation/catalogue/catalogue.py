"""Component catalogues: accuracy classes with prices, each fixing several error items.

A designer buys a ball-screw grade, a guideway accuracy class, a bearing tolerance class or
a finishing process for a mounting face, not a tolerance of 3.7 µm. A catalogue lists such
components; each component fixes some error items of the machine, and each of its classes
gives one tolerance for every one of those items, at a price. The file (TOML, see
docs/catalogue.md)::

    currency = "EUR"                      # optional label for prices
    [[components]]
    name = "X ball screw"
    items = ["X.dx"]
    source = "JIS B 1192, travel variation per 300 mm"   # optional citation
    [[components.classes]]
    name = "C5"
    price = 420.0
    tolerances = { "X.dx" = 0.018 }

Everything is checked before any work, and a bad catalogue is refused with one line naming
the item, the component and, where one is at fault, the class. :func:`load_catalogue`
reads a file; :meth:`Catalogue.from_dict` checks a parsed table; :meth:`Catalogue.for_machine`
checks the item names against a machine (and turns ISO 230-1 symbols into the machine's
names). Given a machine, both check a component's items before its classes, so a typo in
``items`` is named as the unknown item, with the machine's close names.
:func:`unit_warnings` lists the class tolerances that look written in µm or arc seconds. The discrete optimum over a catalogue is :func:`allocation.catalogue.discrete.solve_catalogue`.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np

from reliability.basics.errors import InputError, InputTypeError
from reliability.basics.files import check_path
from reliability.model.machine import unknown_error_text
from reliability.model.machine_checks import implausible_values

CATALOGUE_KEYS = ("currency", "components")
COMPONENT_KEYS = ("name", "items", "classes", "source")
CLASS_KEYS = ("name", "price", "tolerances")


@dataclass(frozen=True)
class CatalogueClass:
    """One accuracy class of a component.

    Attributes
    ----------
    name : str
    price : float
        > 0, in the catalogue's currency.
    tolerances : mapping
        Item name -> tolerance (mm or rad, > 0), one per item of the component.
    """

    name: str
    price: float
    tolerances: MappingProxyType


@dataclass(frozen=True)
class Component:
    """A component that fixes ``items`` at the tolerances of the class chosen for it.

    Attributes
    ----------
    name : str
    items : tuple of str
        The error items the component fixes, in the catalogue's order.
    classes : tuple of CatalogueClass
        In the catalogue's order.
    source : str
        Where the accuracy values come from (may be empty).
    """

    name: str
    items: tuple[str, ...]
    classes: tuple[CatalogueClass, ...]
    source: str = ""

    @property
    def class_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.classes)

    def tolerance_matrix(self) -> np.ndarray:
        """``(n_classes, n_items)`` tolerances, rows in the classes' order."""
        return np.array([[c.tolerances[item] for item in self.items] for c in self.classes])

    def prices(self) -> np.ndarray:
        return np.array([c.price for c in self.classes])

    def loosest_first(self) -> np.ndarray:
        """Class indices from loosest to tightest.

        A class is looser than another when the geometric mean of its tolerances over the
        component's items is larger (for a one-item component: its tolerance is larger);
        equal means keep the catalogue's order. "One class tighter" is the next class in
        this order.
        """
        size = np.log(self.tolerance_matrix()).mean(axis=1)
        return np.lexsort((np.arange(len(size)), -size))


@dataclass(frozen=True)
class Catalogue:
    """Components with their classes; build with :func:`load_catalogue` or :meth:`from_dict`.

    Attributes
    ----------
    components : tuple of Component
    currency : str
        Label of the prices (may be empty).
    source : str
        Where the catalogue was read from, used in messages.
    """

    components: tuple[Component, ...]
    currency: str = ""
    source: str = "catalogue"

    @property
    def items(self) -> tuple[str, ...]:
        """Every item fixed by some component, component by component."""
        return tuple(item for component in self.components for item in component.items)

    @property
    def n_choices(self) -> int:
        """How many different choices of one class per component there are."""
        return math.prod(len(c.classes) for c in self.components)

    @classmethod
    def from_dict(cls, data, source: str = "catalogue", machine=None) -> "Catalogue":
        """A catalogue from a parsed TOML table, checked (see the module docstring).

        Parameters
        ----------
        data : dict
        source : str
        machine : Machine, optional
            When given, each component's items are checked against it before its classes.

        Raises
        ------
        InputError, InputTypeError
            One line naming the catalogue, the component, the class and the item at fault.
        """
        where = f"catalogue {source}"
        _table(data, where)
        _known_keys(data, CATALOGUE_KEYS, where)
        currency = data.get("currency", "")
        if not isinstance(currency, str):
            raise InputTypeError(f"{where}: currency must be a string; got {currency!r}")
        if "components" not in data:
            raise InputError(f"{where}: no [[components]]; give at least one component")
        entries = data["components"]
        if not isinstance(entries, list) or not entries:
            raise InputError(f"{where}: components must be a non-empty list of "
                             f"[[components]] tables; got {entries!r}")
        components = tuple(_component(entry, where, i, machine)
                           for i, entry in enumerate(entries))
        _unique([c.name for c in components], f"{where}: component", "is listed twice")
        owner = {}
        for component in components:
            for item in component.items:
                if item in owner:
                    raise InputError(f"{where}: item {item!r} is in component "
                                     f"{owner[item]!r} and in component "
                                     f"{component.name!r}; an item belongs to at most one "
                                     f"component")
                owner[item] = component.name
        return cls(components=components, currency=currency, source=source)

    def for_machine(self, machine) -> "Catalogue":
        """The catalogue with its items checked against ``machine`` and named as the
        machine names them (ISO 230-1 symbols are accepted).

        Raises
        ------
        InputError
            An item the machine does not have, or two names of one error.
        """
        names = {item: _machine_name(machine, item,
                                     f"catalogue {self.source}: component {component.name!r}")
                 for component in self.components for item in component.items}
        owner = {}
        for component in self.components:
            for item in component.items:
                if names[item] in owner:
                    raise InputError(
                        f"catalogue {self.source}: item {names[item]!r} is in component "
                        f"{owner[names[item]]!r} and in component {component.name!r} "
                        f"(under another name); an item belongs to at most one component")
                owner[names[item]] = component.name
        return replace(self, components=tuple(_renamed(c, names) for c in self.components))


def load_catalogue(path, machine=None) -> Catalogue:
    """Read and check a catalogue file (TOML, see docs/catalogue.md).

    Parameters
    ----------
    path : str or Path
    machine : Machine, optional
        When given, the items are checked against it as well (:meth:`Catalogue.for_machine`).

    Raises
    ------
    InputError, InputTypeError
        A missing or unreadable file, invalid TOML, or a bad catalogue: one line naming the
        file, the component, the class and the item at fault.
    """
    path = check_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"catalogue {str(path)!r} does not exist") from None
    except (IsADirectoryError, UnicodeDecodeError) as exc:
        raise InputError(f"catalogue {str(path)!r} cannot be read: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"catalogue {str(path)!r} is not valid TOML: {exc}") from None
    catalogue = Catalogue.from_dict(data, source=str(path), machine=machine)
    return catalogue if machine is None else catalogue.for_machine(machine)


def unit_warnings(catalogue) -> list[str]:
    """Class tolerances that look written in µm or arc seconds (over 1 mm or 0.01 rad;
    :func:`reliability.model.machine_checks.implausible_values`), one sentence each.

    Parameters
    ----------
    catalogue : Catalogue

    Returns
    -------
    list of str
    """
    entries = [(f"catalogue {catalogue.source}: component {component.name!r}, class "
                f"{grade.name!r}: the tolerance of {item}", value,
                "rad" if item.split(".")[-1].startswith("e") else "mm")
               for component in catalogue.components for grade in component.classes
               for item, value in grade.tolerances.items()]
    return implausible_values(entries)


# ----- checks ---------------------------------------------------------------------------
def _component(entry, where, position, machine=None) -> Component:
    _table(entry, f"{where}: component #{position + 1}")
    name = _name(entry, f"{where}: component #{position + 1}")
    where = f"{where}: component {name!r}"
    _known_keys(entry, COMPONENT_KEYS, where)
    items = entry.get("items")
    if not isinstance(items, list) or not items:
        raise InputError(f"{where}: items must be a non-empty list of error names; "
                         f"got {items!r}")
    for item in items:
        if not isinstance(item, str) or not item:
            raise InputTypeError(f"{where}: item {item!r} must be an error name (a string)")
    _unique(items, f"{where}: item", "is listed twice")
    if machine is not None:
        for item in items:
            _machine_name(machine, item, where)
    source = entry.get("source", "")
    if not isinstance(source, str):
        raise InputTypeError(f"{where}: source must be a string; got {source!r}")
    classes = entry.get("classes")
    if not isinstance(classes, list) or not classes:
        raise InputError(f"{where}: no classes; give at least one [[components.classes]]")
    classes = tuple(_class(c, where, i, items) for i, c in enumerate(classes))
    _unique([c.name for c in classes], f"{where}: class", "is listed twice")
    return Component(name=name, items=tuple(items), classes=classes, source=source)


def _class(entry, where, position, items) -> CatalogueClass:
    _table(entry, f"{where}: class #{position + 1}")
    name = _name(entry, f"{where}: class #{position + 1}")
    where = f"{where}, class {name!r}"
    _known_keys(entry, CLASS_KEYS, where)
    if "price" not in entry:
        raise InputError(f"{where}: no price")
    price = _positive(entry["price"], f"{where}: price")
    tolerances = entry.get("tolerances")
    if not isinstance(tolerances, dict):
        raise InputTypeError(f"{where}: tolerances must be a table {{item = tolerance}}; "
                             f"got {tolerances!r}")
    for item in tolerances:
        if item not in items:
            raise InputError(f"{where}: tolerance for item {item!r}, which is not among "
                             f"the component's items {items}")
    for item in items:
        if item not in tolerances:
            raise InputError(f"{where}: no tolerance for item {item!r}")
    values = {item: _positive(tolerances[item], f"{where}: tolerance of item {item!r}")
              for item in items}
    return CatalogueClass(name=name, price=price, tolerances=MappingProxyType(values))


def _machine_name(machine, item: str, where: str) -> str:
    """The machine's name of ``item`` (a name or an ISO 230-1 symbol), or an InputError
    naming the unknown item and the machine's close names."""
    try:
        return machine.error_names[machine.error_index(item)]
    except KeyError:
        raise InputError(f"{where}: {unknown_error_text(item, machine.axes, 'item')}"
                         ) from None


def _renamed(component: Component, names: dict) -> Component:
    classes = tuple(replace(c, tolerances=MappingProxyType(
        {names[item]: value for item, value in c.tolerances.items()}))
        for c in component.classes)
    return replace(component, items=tuple(names[i] for i in component.items),
                   classes=classes)


def _table(value, where) -> None:
    if not isinstance(value, dict):
        raise InputTypeError(f"{where} must be a table; got {value!r}")


def _known_keys(table, allowed, where) -> None:
    unknown = [key for key in table if key not in allowed]
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r}; expected some of "
                         f"{list(allowed)}")


def _name(table, where) -> str:
    name = table.get("name")
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{where}: name must be a non-empty string; got {name!r}")
    return name


def _unique(names, what, verb) -> None:
    seen = set()
    for name in names:
        if name in seen:
            raise InputError(f"{what} {name!r} {verb}")
        seen.add(name)


def _positive(value, where) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputTypeError(f"{where} must be a number; got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{where} must be a finite number > 0; got {value!r}")
    return value

