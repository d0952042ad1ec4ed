"""The toolkit's exceptions for bad input and damaged files.

Every public entry point checks its inputs before any work and raises one of these, with a
message that names the argument, the offending item and what was expected. They subclass
the built-in ``ValueError`` or ``TypeError``, so ``except ValueError`` keeps working.
"""

from __future__ import annotations


class InputError(ValueError):
    """An argument has the right type but a bad value (range, shape, size, name)."""


class InputTypeError(TypeError):
    """An argument has the wrong type (a string where a number belongs, a dict for an array)."""


class SizeBudgetError(InputError):
    """A request would need more memory than the stated budget; the message says how to
    proceed (fewer points, explicit poses, smaller chunks)."""


class SavedResultError(InputError):
    """A saved result is damaged or inconsistent; the message names the file, row and column
    (or field). An :class:`InputError`: a damaged file is bad input to the reader."""


class MachineDescriptionError(ValueError):
    """A machine description is malformed; the message names the offending item."""
