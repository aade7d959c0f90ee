"""Rank helpers: an error that one rank sees reaches the user and ends every rank, so no
rank waits for ever in a collective call for one that failed (issue 28, item 12).

``print_on_root`` prints once; ``largest_on_ranks`` is a float's maximum over the ranks.

Two tools for errors, for two kinds of work:

* ``agree(comm, action, errors)`` for work without collective calls inside (reading and
  validating a scene, choosing the model): every rank runs it, then the ranks compare
  outcomes, and an expected error raised on any rank is raised on every rank (the
  lowest rank's), so rank 0 prints it and every rank exits 2.
* ``alone(guard)`` after an expected error raised inside collective work (building a
  model, where the other ranks may be waiting in a collective call): it tells whether
  every rank reached the same point (all failed, the error is collective) within a few
  seconds; if not, the rank that failed prints its message and leaves (``leave``).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

# how long a rank with an error waits for the others to report theirs before it leaves
# (ranks fail in the same phase within milliseconds; a real hang is for ever; a rank
# late by more than this on a loaded machine only labels the message "seen on rank N
# only": the exit status and the message are the same)
AGREE_SECONDS = 1.0


def agree(comm, action, errors: tuple[type[BaseException], ...]):
    """``action()`` on every rank; its result there.  If it raised one of ``errors`` on
    any rank, the lowest such rank's error is raised on every rank (errors are sent
    pickled: their classes must pickle with their arguments)."""
    result, error = None, None
    try:
        result = action()
    except errors as err:
        error = err
    if comm.size > 1:
        first = next((e for e in comm.allgather(error) if e is not None), None)
        if first is not None and error is None:
            raise first
    if error is not None:
        raise error
    return result


def alone(guard, seconds: float = AGREE_SECONDS) -> bool:
    """Called by a rank that caught an expected error: False if every rank of ``guard``
    (a communicator used for nothing else) calls it within ``seconds`` (the error is
    collective: rank 0 reports it), True if this rank is alone with its error (then it
    must report it itself and abort the job: the others may wait in a collective
    call)."""
    if guard is None or guard.size == 1:
        return False
    request = guard.Ibarrier()
    deadline = time.monotonic() + seconds
    while not request.Test():
        if time.monotonic() > deadline:
            return True
        time.sleep(0.01)
    return False


def leave(status: int) -> None:
    """End this rank at once with exit ``status`` (after flushing its output), for a rank
    alone with an error while the others may wait in a collective call: mpirun then ends
    the others and exits with that status, as for any failed run (its notice "exited
    with non-zero status"), without MPI_Abort's banner around the rank's message."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def print_on_root(comm, *args, file=None) -> None:
    """print on rank 0 only (flushed: stdout and stderr interleave as written)."""
    if comm.rank == 0:
        print(*args, file=file or sys.stdout, flush=True)


def largest_on_ranks(comm, value: float) -> float:
    """The maximum of ``value`` over the ranks of ``comm`` (itself on one rank), by a
    buffer Allreduce: a pickled float's ``allreduce`` cost ~90 us per step."""
    if comm.size == 1:
        return float(value)
    from mpi4py import MPI
    buf = np.array([value], dtype=float)
    comm.Allreduce(MPI.IN_PLACE, buf, op=MPI.MAX)
    return float(buf[0])
