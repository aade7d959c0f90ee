"""The serial run on every core: `make test-serial` runs pytest-xdist's workers (`-n auto`,
two on the project's 2-core machines), one test per worker at a time.

A test that starts an MPI job of its own (``mpirun -n 2``, ``./rodenv mpirun -n 3``) gets
the whole machine from that moment to its end: Open MPI's ranks busy-poll, and beside a
third busy process a 2-rank job runs 10-30x slower (measured on this machine), which
would turn timeouts into failures.  So each worker holds a share of the cores (a shared
flock) while a test runs, and a test about to start an MPI launcher trades it for the
whole (an exclusive flock): it waits for the other workers' current tests to end, and
theirs wait for it.  A gate (a second flock) keeps new shares out while a whole is
waited for, so the MPI job is not starved.  Without xdist (plain pytest, the MPI run)
nothing here is active.
"""

from __future__ import annotations

import fcntl
import os
import subprocess
from pathlib import Path

import pytest

LAUNCHERS = {"mpirun", "mpiexec", "orterun", "prterun"}


def starts_mpi(args) -> bool:
    """Whether a Popen argument list runs an MPI launcher, itself or through a wrapper
    (``./rodenv mpirun ...``)."""
    if isinstance(args, (str, bytes, os.PathLike)):
        words = os.fsdecode(args).split()
    else:
        words = [os.fsdecode(word) for word in args]
    return any(os.path.basename(word) in LAUNCHERS for word in words[:2])


class Cores:
    """This worker's claim on the machine's cores, in flocks shared by the workers."""

    def __init__(self, folder: Path):
        self.gate = open(folder / "cores.gate", "a")
        self.lock = open(folder / "cores.lock", "a")
        self.whole = False

    def share(self) -> None:
        """A test starts: run beside the others unless one has the whole."""
        fcntl.flock(self.gate, fcntl.LOCK_EX)
        fcntl.flock(self.lock, fcntl.LOCK_SH)
        fcntl.flock(self.gate, fcntl.LOCK_UN)

    def take_whole(self) -> None:
        """An MPI job starts: wait until no other test runs, keep new ones out."""
        if self.whole:
            return
        fcntl.flock(self.lock, fcntl.LOCK_UN)   # never wait at the gate holding a share
        fcntl.flock(self.gate, fcntl.LOCK_EX)
        fcntl.flock(self.lock, fcntl.LOCK_EX)
        fcntl.flock(self.gate, fcntl.LOCK_UN)
        self.whole = True

    def release(self) -> None:
        """The test (with its fixtures' teardown) ended."""
        fcntl.flock(self.lock, fcntl.LOCK_UN)
        self.whole = False

    def close(self) -> None:
        self.gate.close()
        self.lock.close()


CORES: Cores | None = None


class _Popen(subprocess.Popen):
    """subprocess.Popen that takes the whole machine before starting an MPI launcher."""

    def __init__(self, args, *rest, **kwargs):
        if CORES is not None and starts_mpi(args):
            CORES.take_whole()
        super().__init__(args, *rest, **kwargs)


def pytest_configure(config):
    global CORES
    if hasattr(config, "workerinput"):            # a pytest-xdist worker
        # each worker's basetemp is <the run's basetemp>/gwN: the folder they share
        CORES = Cores(Path(config.option.basetemp).parent)
        subprocess.Popen = _Popen


def pytest_unconfigure(config):
    if CORES is not None:
        CORES.close()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    if CORES is None:
        yield
        return
    CORES.share()
    try:
        yield
    finally:
        CORES.release()
