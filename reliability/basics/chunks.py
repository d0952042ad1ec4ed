"""Working over many poses in bounded memory: split a pose count into chunks.

Every per-pose computation that builds a large intermediate (the ``(poses, 6, errors)``
Jacobian, constraint rows, Monte-Carlo values) runs over chunks of poses whose
intermediates fit a memory budget, keeping only small per-pose results.
"""

from __future__ import annotations

from .errors import InputError

#: Default bytes of temporary arrays per chunk (64 MiB).
MEMORY_BUDGET = 64 * 2 ** 20


def chunk_size(bytes_per_item: int, memory: int | None = None) -> int:
    """Items per chunk so that ``items × bytes_per_item`` stays within ``memory`` bytes.

    Parameters
    ----------
    bytes_per_item : int
        Temporary bytes one item (pose, sample) needs.
    memory : int, optional
        Budget in bytes; :data:`MEMORY_BUDGET` by default. At least one item per chunk.
    """
    memory = MEMORY_BUDGET if memory is None else memory
    if isinstance(memory, bool) or not isinstance(memory, int) or memory < 1:
        raise InputError(f"memory must be a positive number of bytes; got {memory!r}")
    return max(1, int(memory) // max(1, int(bytes_per_item)))


def chunks(n_items: int, bytes_per_item: int, memory: int | None = None) -> list[slice]:
    """Consecutive slices covering ``range(n_items)``, each within the memory budget."""
    size = chunk_size(bytes_per_item, memory)
    return [slice(start, min(start + size, n_items)) for start in range(0, n_items, size)]


def jacobian_bytes(machine) -> int:
    """Temporary bytes per pose of :meth:`Machine.jacobian` and the quantities built on it
    (the Jacobian, its square and a working copy of the same size)."""
    return 3 * 6 * machine.n_errors * 8 + 16 * 8 * 4 * len(machine.axis_specs)
