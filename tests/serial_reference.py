"""Serial reference runs for the MPI tests.

Under ``mpirun -n 2`` a test computes on MPI.COMM_WORLD and compares with the same case
run by one process: rank 0 hands it to a single-process Python (started with the MPI
launcher's variables removed, so it initialises as a singleton).  scifem's real space,
which holds the uniform variant's global unknowns, only works on COMM_WORLD, so a
COMM_SELF run inside the MPI job is not an option.

That Python is started at rank 0's first reference and serves the later ones of the
session: a fresh interpreter for each paid DOLFINx's and dolfin_rod's imports and the
first loads of the compiled kernels every time (2.3 s and 3.3 s of a first rod system
against 0.3 s for the next one, at load 10), more than most references' own runs.  A
reference that fails ends it (the next one starts a new Python), so a failed run leaves
nothing behind for another; whatever the runs print goes to its stderr, which a failure
reports.
"""

from __future__ import annotations

import atexit
import importlib
import json
import os
import select
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path

from mpi4py import MPI

_KEEP = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "OMPI_MCA_btl")
ROOT = Path(__file__).resolve().parents[1]
TIMEOUT = 600.0     # seconds for one reference


def singleton_env() -> dict[str, str]:
    """This environment without the MPI launcher's variables: a Python started with it
    initialises MPI as a singleton (one rank of its own)."""
    return {k: v for k, v in os.environ.items()
            if k in _KEEP or not k.startswith(("OMPI_", "PMIX_", "PRTE_"))}


class _SerialPython:
    """The single-process Python that computes the references (one per pytest
    process, started on first use)."""

    def __init__(self):
        self.log = tempfile.TemporaryFile("w+")
        self.proc = subprocess.Popen([sys.executable, __file__], cwd=ROOT,
                                     env=singleton_env(), stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=self.log, text=True)

    def ask(self, function: str, args: tuple):
        self.proc.stdin.write(json.dumps({"function": function, "args": args}) + "\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], TIMEOUT)
        line = self.proc.stdout.readline() if ready else ""
        if not ready:
            answer = {"error": f"no answer within {TIMEOUT:.0f} s"}
        else:
            answer = json.loads(line) if line else {"error": "the serial Python ended"}
        if "error" in answer:
            self.log.seek(0)
            printed = self.log.read()[-3000:]
            self.close()
            raise RuntimeError(f"serial reference {function}, arguments {list(args)!r}, failed: "
                               f"{answer['error']}\n{printed}")
        return answer["result"]

    def close(self) -> None:
        """End the Python: its requests' end (EOF) stops its loop."""
        if self.proc.poll() is None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc.stdout.close()
        self.log.close()


_serial_python: _SerialPython | None = None


def on_one_process(function: str, *args):
    """``function(*args)`` (``"module.name"``, the module importable from tests/)
    computed by the single-process Python, called on one rank (its result must be
    JSON: lists come back for tuples)."""
    global _serial_python
    if _serial_python is None or _serial_python.proc.poll() is not None:
        _serial_python = _SerialPython()
        atexit.register(_serial_python.close)
    try:
        return _serial_python.ask(function, args)
    except RuntimeError:
        _serial_python = None
        raise


def serial(case: str, *args):
    """The JSON result of ``cases.<case>(*args)`` computed by one process, on every
    rank."""
    import cases
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        return json.loads(json.dumps(getattr(cases, case)(*args)))
    result = None
    if comm.rank == 0:
        try:
            result = on_one_process(f"cases.{case}", *args)
        except RuntimeError as err:
            result = err
    result = comm.bcast(result)
    if isinstance(result, Exception):
        raise result
    return result


def serve() -> None:
    """The single-process Python's loop: a request a line on stdin (``{"function",
    "args"}``), an answer a line (``{"result"}``, or ``{"error"}`` and the end) on the
    stdout it was started with; what the runs print goes to stderr."""
    answers = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    for line in sys.stdin:
        request = json.loads(line)
        module, name = request["function"].rsplit(".", 1)
        try:
            answer = {"result": getattr(importlib.import_module(module), name)(
                *request["args"])}
            text = json.dumps(answer)
        except BaseException:       # noqa: BLE001 (reported to the test, which raises it)
            answers.write(json.dumps({"error": traceback.format_exc()}) + "\n")
            answers.flush()
            return
        answers.write(text + "\n")
        answers.flush()


if __name__ == "__main__":
    sys.path.insert(1, str(ROOT))       # dolfin_rod of this checkout, as tests/ sees it
    serve()
