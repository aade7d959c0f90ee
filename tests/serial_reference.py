"""Serial reference runs for the MPI tests.

Under ``mpirun -n 2`` a test computes on MPI.COMM_WORLD and compares with the same case
run by a separate single-process Python (rank 0 launches it with the MPI launcher's
variables removed, so it initialises as a singleton).  scifem's real space, which holds
the uniform variant's global unknowns, only works on COMM_WORLD, so a COMM_SELF run
inside the MPI job is not an option.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

_KEEP = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "OMPI_MCA_btl")


def _singleton_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items()
            if k in _KEEP or not k.startswith(("OMPI_", "PMIX_", "PRTE_"))}


def serial(case: str, *args):
    """The JSON result of ``cases.<case>(*args)`` computed by one process."""
    import cases
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        return json.loads(json.dumps(getattr(cases, case)(*args)))
    result = None
    if comm.rank == 0:
        here = Path(__file__).parent
        code = (f"import sys, json; sys.path.insert(0, {str(here)!r}); import cases; "
                f"print(json.dumps(cases.{case}(*{args!r})))")
        proc = subprocess.run([sys.executable, "-c", code], env=_singleton_env(),
                              capture_output=True, text=True, timeout=600)
        result = (json.loads(proc.stdout.strip().splitlines()[-1]) if proc.returncode == 0
                  else RuntimeError(f"serial reference '{case}' failed:\n{proc.stderr[-2000:]}"))
    result = comm.bcast(result)
    if isinstance(result, Exception):
        raise result
    return result
