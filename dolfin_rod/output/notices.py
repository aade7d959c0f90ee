"""The warnings of a run (a cut step, a rod that passed through itself, a kernel lock
removed): each as one line, "warning: ...", on rank 0's stderr as it happens (Python's
own format adds a source line that tells a user of the command nothing), and kept for
summary.json's "warnings", so a completed run read later still says what went wrong."""

from __future__ import annotations

import sys
import warnings
from contextlib import contextmanager

KEPT = 50      # summary.json lists the first 50 (a run that cuts steps all along: thousands)


@contextmanager
def noticed(comm):
    """The list of the warnings' texts shown inside the block (the filters in force
    decide which are shown: by default each text once per place)."""
    seen: list[str] = []

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        seen.append(str(message))
        if comm.rank == 0:
            print(f"warning: {message}", file=sys.stderr, flush=True)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield seen


def listed(seen: list[str]) -> list[str]:
    """The texts for summary.json: the first KEPT, then how many more there were."""
    more = len(seen) - KEPT
    return seen[:KEPT] + ([f"... and {more} more"] if more > 0 else [])
