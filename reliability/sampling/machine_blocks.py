"""Per-machine evaluations over fixed blocks of built machines, here or on a Dask cluster.

Built machines are independent: the verdict on one machine never depends on another. The
engine of the machine yield (:class:`reliability.sampling.machine_yield.YieldModel`) therefore
evaluates its machines in blocks, consecutive slices of the draws ``u`` whose temporary
arrays fit the model's memory budget. The blocks depend only on the number of machines and
that budget, never on where they run, and :class:`MachineBlocks` runs the same function on
the same arrays of every block

* here, one block after the other (no client), or
* on a ``distributed.Client``, one task per block,

and returns the blocks' results in block order, so both give the same bytes.

On a client, the object that evaluates (the model) and the draws ``u`` are sent to the
workers once (``client.scatter`` of a copy) and kept there while the caller keeps the same
Python object: a search that judges many allocations on one sample of machines ships that
sample once, not once per allocation. What varies per call (the tolerances, a block's
poses) travels with the tasks.

Dask is optional (the ``dask`` extra): this module imports nothing of it; the caller hands
over a client it made.
"""

from __future__ import annotations

import copy
import weakref

from ..basics.errors import InputTypeError


class MachineBlocks:
    """Where the blocks of machines are evaluated: here, or on a Dask client.

    Parameters
    ----------
    client : distributed.Client, optional
        Run each block as a task of this client; None runs them here, in order.
    """

    def __init__(self, client=None):
        if client is not None and not _is_dask_client(client):
            raise InputTypeError(f"executor must be None or a dask.distributed.Client; got "
                                 f"{type(client).__name__}")
        self.client = client
        self._shipped = {}

    def __getstate__(self):
        """A copy sent elsewhere evaluates its blocks where it arrives."""
        return {"client": None, "_shipped": {}}

    def map(self, function, owner, u, blocks, arguments=(), per_machine=()) -> list:
        """``[function(owner, u[b], *arguments, *(a[b] for a in per_machine)) for b in
        blocks]``, here or as one task per block on the client.

        Parameters
        ----------
        function : callable
            A module-level function or a class's function (Dask pickles it by name).
        owner : object
            Its first argument, e.g. the model (an object that takes weak references);
            sent to the workers once.
        u : ndarray (machines, ...)
            The draws of the machines; sent to the workers once.
        blocks : list of slice
            Consecutive slices of the machines.
        arguments : tuple
            Further arguments, the same for every block.
        per_machine : tuple of ndarray
            Arrays with one row per machine, sliced like ``u``.

        Returns
        -------
        list
            The result of every block, in the order of ``blocks``.
        """
        if self.client is None:
            return [function(owner, u[block], *arguments, *(a[block] for a in per_machine))
                    for block in blocks]
        owner_there, u_there = self._on_workers(owner), self._on_workers(u)
        tasks = [self.client.submit(_block, function, owner_there, u_there, block, arguments,
                                    [a[block] for a in per_machine], pure=False)
                 for block in blocks]
        return self.client.gather(tasks)

    def _on_workers(self, value):
        """The future of a copy of ``value`` on every worker, sent on first use; released on
        the cluster once ``value`` is gone (at the next call) or this object is.

        The workers get a deep copy, so that workers in this process hold no reference to
        ``value`` itself (nor to this object, which a copy of the owner holds only as a
        local one: :meth:`__getstate__`)."""
        self._shipped = {key: (alive, future) for key, (alive, future)
                         in self._shipped.items() if alive() is not None}
        key = id(value)
        if key not in self._shipped:  # a live entry under this id is this object
            future = self.client.scatter(copy.deepcopy(value), broadcast=True, hash=False)
            self._shipped[key] = (weakref.ref(value), future)
        return self._shipped[key][1]


def _block(function, owner, u, block, arguments, sliced):
    """One block on a worker: ``function(owner, u[block], *arguments, *sliced)``."""
    return function(owner, u[block], *arguments, *sliced)


def _is_dask_client(value) -> bool:
    """Whether ``value`` is a ``distributed.Client`` (told without importing Dask)."""
    return type(value).__module__.split(".")[0] == "distributed" and \
        all(hasattr(value, name) for name in ("scatter", "submit", "gather"))
