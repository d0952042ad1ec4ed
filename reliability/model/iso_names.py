"""ISO 230-1 symbols for the geometric errors, beside the paper's names.

ISO 230-1 names a motion error of an axis ``E`` + *error direction* + *axis name*: the
direction is one of ``X Y Z`` (a translation along x, y, z) or ``A B C`` (a rotation about
x, y, z). So a linear axis X has ``EXX`` (positioning), ``EYX`` and ``EZX``
(straightness), ``EAX`` (roll), ``EBX`` and ``ECX`` (pitch and yaw, which is which depends
on the axis' orientation); a rotary axis C has ``EXC`` and ``EYC`` (radial), ``EZC``
(axial), ``EAC`` and ``EBC`` (tilt) and ``ECC`` (angular positioning).

In this toolkit an error component ``dx dy dz ex ey ez`` is a translation along, or a
rotation about, the x, y, z directions of the frame the error acts in (the axis' own
frame, Eq. 2), so the mapping is letter for letter::

    dx dy dz ex ey ez  ->  X Y Z A B C

and the motion error ``"<axis>.<comp>"`` is ``"E" + letter(comp) + axis``
(``X.dx`` = ``EXX``, ``X.ey`` = ``EBX``, ``C.ez`` = ``ECC``). The rule does not look at the
axis' name, only at its frame: for an axis named otherwise (``"M"``, ``"X2"``, ``"W"``) the
symbol is still E + direction + the axis' name (``M.ey`` = ``EBM``, ``X2.dx`` = ``EXX2``);
for a linear axis whose direction is ``d`` the positioning error is ``E<D><axis>``
(``D`` = ``d`` upper-cased).

Assembly (joint) errors. ISO 230-1 calls the position-independent errors of an axis
*location errors* and writes them with a ``0`` between direction and axis: ``EB0X`` is the
squareness of X about y, ``EX0C`` and ``EY0C`` the position of the C axis line, ``EA0C``
and ``EB0C`` its orientation. The paper's joint ``"<a>-<b>"`` holds the six errors that
place axis ``b`` on axis ``a`` (Eq. 14), in the frame of ``b`` before its motion, so this
toolkit names them as location errors of ``b``::

    "<a>-<b>.<comp>"  ->  "E" + letter(comp) + "0" + b      ("C-X.ey" = "EB0X")

ISO 230-1 keeps only the location errors that can be identified by measuring the
machine: for a linear axis its two squareness (orientation) errors, for a rotary axis two
position and two orientation errors (sometimes the zero position too). The paper keeps
all six per joint; the extra ones (a linear axis' position along itself, say) have no
ISO 230-1 meaning but keep their symbol here so every error has one.

Every function and file that takes an error name accepts either the paper's name or its
ISO symbol (:meth:`reliability.model.machine.Machine.error_index`).

Plain names (:func:`plain_names`) say the same in words for people: "X positioning",
"X straightness in y", "X pitch", "C radial motion in x", "squareness between X and Y".
A rotation of a linear axis about its own direction is its roll; about z (for an axis not
along z) its yaw; about the third direction its pitch; a vertical axis has two tilts. A
location error that turns axis ``b`` about a direction other than its own tilts ``b``
toward the third direction, so it is named the squareness between ``b`` and the linear axis
moving along that direction (or "squareness of b to y" when no axis moves along it).
"""

from __future__ import annotations

from ..basics.errors import InputError

#: ISO 230-1 direction letter of each error component.
ISO_DIRECTIONS = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}
#: The three frame directions, in the order of the components' last letter.
DIRECTIONS = ("x", "y", "z")


def iso_symbol(name: str) -> str:
    """ISO 230-1 symbol of one error name of the paper's form.

    Parameters
    ----------
    name : str
        ``"<axis>.<comp>"`` (motion error) or ``"<a>-<b>.<comp>"`` (assembly error).

    Returns
    -------
    str
        ``"E" + direction + axis`` or ``"E" + direction + "0" + b``.

    Examples
    --------
    >>> iso_symbol("X.dx"), iso_symbol("C.ez"), iso_symbol("C-X.ey")
    ('EXX', 'ECC', 'EB0X')
    """
    owner, _, comp = name.rpartition(".")
    if not owner or comp not in ISO_DIRECTIONS:
        raise InputError(f"error name {name!r} is not of the form '<axis>.<comp>' or "
                         f"'<a>-<b>.<comp>' with comp in {tuple(ISO_DIRECTIONS)}")
    letter = ISO_DIRECTIONS[comp]
    if "-" in owner:
        return f"E{letter}0{owner.split('-')[-1]}"
    return f"E{letter}{owner}"


def iso_names(error_names) -> tuple[str, ...]:
    """ISO 230-1 symbols aligned with ``error_names``.

    Raises
    ------
    InputError
        When two errors would get the same symbol, or a symbol equals another error's
        paper name (possible only for axis names that begin with ``0``, e.g. an axis
        ``"0C"`` whose ``EX0C`` is also the C axis' location error).
    """
    names = tuple(error_names)
    symbols = tuple(iso_symbol(n) for n in names)
    seen = {}
    for name, symbol in zip(names, symbols):
        if symbol in seen:
            raise InputError(f"errors {seen[symbol]!r} and {name!r} would share the ISO 230-1 "
                             f"symbol {symbol!r}; rename the axis (axis names beginning "
                             f"with '0' clash with location-error symbols)")
        seen[symbol] = name
    clash = set(symbols) & set(names)
    if clash:
        raise InputError(f"ISO 230-1 symbol {sorted(clash)[0]!r} is also an error name")
    return symbols


def name_table(machine):
    """Paper name, ISO 230-1 symbol, owner and kind of every error, as a DataFrame."""
    import pandas as pd

    names = machine.error_names
    owners = [n.rpartition(".")[0] for n in names]
    return pd.DataFrame({
        "iso": iso_names(names),
        "owner": owners,
        "kind": ["assembly" if "-" in o else "motion" for o in owners],
    }, index=pd.Index(names, name="error"))


def plain_names(machine) -> tuple[str, ...]:
    """A plain name of every error of ``machine``, aligned with ``machine.error_names``.

    Examples
    --------
    >>> import reliability
    >>> names = dict(zip(reliability.hobbing_machine().error_names,
    ...                  plain_names(reliability.hobbing_machine())))
    >>> names["X.dx"], names["X.ey"], names["C.ez"], names["C-X.ez"]
    ('X positioning', 'X pitch', 'C angular positioning', 'squareness between X and Y')
    """
    specs = {axis.name: axis for axis in machine.axis_specs}
    linear = {}
    for axis in machine.axis_specs:
        if axis.kind == "linear":
            linear.setdefault(axis.direction, axis.name)
    names = []
    for name in machine.error_names:
        owner, _, comp = name.rpartition(".")
        if "-" in owner:
            names.append(_location_name(specs[owner.split("-")[-1]], comp, linear))
        else:
            names.append(_motion_name(specs[owner], comp))
    return tuple(names)


def _motion_name(axis, comp: str) -> str:
    """Plain name of the motion error ``comp`` of ``axis``."""
    along, moved = comp[1], axis.direction
    if axis.kind == "linear":
        if comp[0] == "d":
            return f"{axis.name} positioning" if along == moved else \
                f"{axis.name} straightness in {along}"
        if along == moved:
            return f"{axis.name} roll"
        if moved == "z":
            return f"{axis.name} tilt about {along}"
        return f"{axis.name} yaw" if along == "z" else f"{axis.name} pitch"
    if comp[0] == "d":
        return f"{axis.name} axial motion" if along == moved else \
            f"{axis.name} radial motion in {along}"
    return f"{axis.name} angular positioning" if along == moved else \
        f"{axis.name} tilt about {along}"


def _location_name(axis, comp: str, linear: dict) -> str:
    """Plain name of the location error ``comp`` of ``axis`` (where its joint places it);
    ``linear`` maps a direction to the first linear axis moving along it."""
    along, own = comp[1], axis.direction
    if comp[0] == "d":
        if axis.kind == "rotary" and along != own:
            return f"position of the {axis.name} axis line in {along}"
        return f"offset of {axis.name} along {along}"
    if along == own:
        return f"zero position of {axis.name}" if axis.kind == "rotary" else \
            f"roll of {axis.name} as mounted"
    toward = next(d for d in DIRECTIONS if d not in (along, own))
    other = linear.get(toward)
    if other is None or other == axis.name:
        return f"squareness of {axis.name} to {toward}"
    return f"squareness between {axis.name} and {other}"
