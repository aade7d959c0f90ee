"""A ring pinched across a diameter (scenes/pinched_ring.toml; docs/verification.md, "The
pinched ring"): the shortening of the loaded diameter against its closed form by
Castigliano's theorem (bending, stretch and shear of the Cosserat ring), with its observed
order in h; marked mpi: the same numbers on 2 ranks, and the 2-rank run equals the serial
one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import read_pvd, run_scene
from quick_scenes import ROOT, assert_serial_run_equal, quick_scene

comm = MPI.COMM_WORLD
RING = ROOT / "scenes/pinched_ring.toml"
QUIET = dict(outputs__animation=False, outputs__plots=False)
# the scene's ring (its header): radius, bending, axial and shear stiffness, the force
R, EI, EA = 1.0, 1.0, 1e4
GA = 0.886 / 2.6 * EA
FORCE = 1e-3


def flexibility() -> float:
    """delta / P for two opposite forces P on a ring of radius R: cut at the unloaded
    diameter, each cut carries P/2 and a moment M0; at the angle theta from the cut,
    N = P/2 cos theta, V = P/2 sin theta, M = M0 - P R/2 (1 - cos theta).  The energy
    4 int_0^(pi/2) (M^2/EI + N^2/EA + V^2/GA)/2 R dtheta is least in M0 (the unknown
    redundant): M0 = P R/2 (1 - 2/pi), M = P R/2 (cos theta - 2/pi), and Castigliano's
    dU/dP gives delta = P [R^3/EI (pi/4 - 2/pi) + pi R/(4 EA) + pi R/(4 GA)]; the first
    term alone is the thin ring's 0.1488 P R^3/EI (Timoshenko; Roark's ring with its
    hoop and shear factors set to 0)."""
    return R**3 / EI * (math.pi / 4 - 2 / math.pi) + math.pi * R / 4 * (1 / EA + 1 / GA)


def pinch(folder: Path) -> float:
    """delta / P from the run's ring at +P and -P: half the difference of the loaded
    point's displacements towards the held one (no term of second order in P)."""
    frames = read_pvd(folder / "rod.pvd")
    s = frames[0]["point"]["s"]
    node = int(np.argmin(np.abs(s - math.pi * R)))
    assert abs(s[node] - math.pi * R) < 1e-12                  # a node at the load
    x = [frames[k]["points"][node][0] - frames[0]["points"][node][0] for k in (1, 2)]
    return (x[1] - x[0]) / (2 * FORCE)


def test_the_thin_ring_term():
    """The bending term is the classical 0.1488 P R^3/EI."""
    assert math.pi / 4 - 2 / math.pi == pytest.approx(0.1487784, abs=1e-7)


@pytest.mark.mpi
def test_pinched_ring_shortens_by_the_closed_form(tmp_path):
    """scenes/pinched_ring.toml at 32, 64, 128 cells: delta/P = 0.144930, 0.148041,
    0.148825 against 0.149087, relative errors -2.79e-2, -7.02e-3, -1.76e-3 (orders 1.99,
    2.00); Richardson's extrapolation 7e-6 off (the central difference leaves (P R^2/EI)^2
    ~ 1e-6 of nonlinearity).  Asserted: orders 1.9-2.1 and the extrapolation within 3e-5.
    Under mpirun the 32-cell run equals the serial one to round-off."""
    folder = Path(comm.bcast(str(tmp_path), root=0))
    measured = []
    for n in (32, 64, 128):
        run = folder / str(n) / "run"
        summary = run_scene(quick_scene(RING, 2, geometry__n_cells=n, **QUIET), run,
                            quiet=True)
        assert summary["status"] == "completed", summary["message"]
        measured.append(pinch(run))
    errors = [m / flexibility() - 1 for m in measured]
    orders = [math.log2(errors[i] / errors[i + 1]) for i in (0, 1)]
    assert all(1.9 < order < 2.1 for order in orders), (measured, errors)
    extrapolated = measured[2] + (measured[2] - measured[1]) / 3
    assert abs(extrapolated / flexibility() - 1) < 3e-5, (measured, extrapolated)
    if comm.size > 1 and comm.rank == 0:
        assert_serial_run_equal(RING, folder / "32", 2, geometry__n_cells=32, **QUIET)
