"""Bundled scenes made cheap for the test suite: the same file with a shorter t_end and,
if asked, fewer cells and other overrides (the test-only override of issue 14)."""

from __future__ import annotations

import tomllib
from pathlib import Path

from dolfin_rod.scenes import Scene, load_scene

ROOT = Path(__file__).resolve().parents[1]


def quick_scene(path: Path | str, steps: int = 4, **overrides) -> Scene:
    """The scene at ``path`` run for ``steps`` time steps; ``overrides`` as
    table__key=value (e.g. geometry__n_cells=8) replace keys first."""
    dt = tomllib.loads(Path(path).read_text())["time"]["dt"]
    changes = {"time.t_end": steps * dt, "outputs.progress": False}
    changes.update({name.replace("__", "."): value for name, value in overrides.items()})
    return load_scene(path, changes)


def run_serially(path: Path | str, out: Path, steps: int = 4, **overrides) -> str:
    """run_scene(quick_scene(...)) by the single-process Python of the serial references
    (for MPI tests, on one rank); returns the run's status."""
    from serial_reference import on_one_process
    return on_one_process("quick_scenes.run_status", str(path), str(out), steps, overrides)


def run_status(path: str, out: str, steps: int, overrides: dict) -> str:
    """The status of run_scene(quick_scene(...)) written into ``out`` (run_serially's
    request)."""
    from dolfin_rod import run_scene
    return run_scene(quick_scene(path, steps, **overrides), out, quiet=True)["status"]


def assert_serial_run_equal(path: Path | str, folder: Path, steps: int, atol: float = 1e-10,
                            **overrides) -> None:
    """Under MPI, on rank 0: the quick scene run serially into folder/serial has the time
    series of the run in folder/run to round-off (1e-10 relative, ``atol`` absolute:
    another summation order; NaN where both have it, the first power residual)."""
    import numpy as np
    assert run_serially(path, folder / "serial", steps, **overrides) == "completed"
    parallel, serial = (np.genfromtxt(folder / name / "timeseries.csv", delimiter=",",
                                      names=True) for name in ("run", "serial"))
    for key in parallel.dtype.names:
        np.testing.assert_allclose(parallel[key], serial[key], rtol=1e-10, atol=atol,
                                   err_msg=key)


def resume_bound(row: dict[str, float], previous: dict[str, float] | None, key: str) -> float:
    """How far a resumed run's time-series value may lie from the uninterrupted run's:
    round-off of the state, 1e-12 relative.  The power residual is a difference quotient,
    (E_i - E_{i-1}) / (t_i - t_{i-1}) + the means of D and P (dolfin_rod/output/writer.py), so
    the same state agreement bounds it by 1e-12 times its inputs' scale,
    2 |E| / (t_i - t_{i-1}) + |D| + |P| (E = K + Psi).  Under mpirun in CI it differed by
    1.2e-12 and 1.8e-12 (3e-14 of that scale) while every state column agreed to 1e-12."""
    scale = 1.0
    if key == "power_residual" and previous is not None:
        energy = abs(row["kinetic_energy"]) + abs(row["free_energy"])
        scale = (2 * energy / (row["time"] - previous["time"])
                 + abs(row["dissipation_rate"]) + abs(row["load_power"]))
    return 1e-12 * max(scale, abs(row[key]))
