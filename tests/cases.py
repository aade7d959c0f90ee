"""Named cases that MPI tests run on COMM_WORLD and compare with a serial run."""

from __future__ import annotations

from mpi4py import MPI

from dolfin_rod import loads
from dolfin_rod.torsion.model import TorsionParameters
from torsion_runs import run

KEYS = ("end_rotation", "mean_natural_twist", "free_energy", "dissipation_rate")


def torsion_inhomogeneous(variant: str, comm=MPI.COMM_WORLD) -> dict[str, list[float]]:
    p = TorsionParameters(alpha=lambda s: 1.0 + 3.0 * s, alpha_d=lambda s: 2.0 - s,
                          mu=0.1, mu_d=0.5)
    h = run(p, 0.5, 0.05, "bdf2", comm=comm, n_cells=17, variant=variant,
            end_torsion=loads.smooth_step(1.0, 0.2))
    return {k: [d[k] for d in h] for k in KEYS}


def rod_system(comm=MPI.COMM_WORLD) -> dict[str, float]:
    """Two unjoined dynamic rods in one RodSystem (tests/test_rod_system.py): the
    system's diagnostics after 10 steps."""
    from rod_systems import two_rods, run_system
    return run_system(two_rods(placed=True, comm=comm))


def joint_frame(comm=MPI.COMM_WORLD) -> dict[str, float]:
    """The L-frame of tests/rod_systems.py under a large load (tests/test_joints.py)."""
    from rod_systems import solve_frame
    return solve_frame(6, 1.5, steps=3, comm=comm)


def hinged_door(comm=MPI.COMM_WORLD) -> dict[str, float]:
    """The hinged door of tests/rod_systems.py for 0.1 s (tests/test_hinge.py)."""
    from rod_systems import ROUND_OFF, hinged_door as door
    from dolfin_rod import TimeStepper
    model = door(4, comm=comm)
    model.set_initial_state()
    TimeStepper(model.problem, solver_options=ROUND_OFF).run(0.0, 0.1, 5e-3)
    return model.diagnostics(0.1)


def spun_pendulum(comm=MPI.COMM_WORLD) -> dict[str, float]:
    """The double pendulum started by a rigid rotation (tests/test_system_start.py) for
    0.02 s."""
    from test_system_start import spun
    from dolfin_rod import TimeStepper
    model = spun(comm=comm)
    TimeStepper(model.problem).run(0.0, 0.02, 2e-3)
    return model.diagnostics(0.02)


def ring_fields(n_cells: int, link: float, comm=MPI.COMM_WORLD) -> dict:
    """A settled ring's energy, weld reactions and fields (tests/test_ring.py)."""
    from rings import ring, ring_fields as fields
    return fields(ring(n_cells, link, comm))


def michell_counts(n_cells: int, links: list, comm=MPI.COMM_WORLD) -> list[int]:
    """The twisted rings' counts of negative eigenvalues (tests/test_ring.py)."""
    from rings import michell_count
    return [michell_count(n_cells, link, comm) for link in links]


def free_ring(n_cells: int, link: float, push: float, comm=MPI.COMM_WORLD) -> dict:
    """A free dynamic ring after 20 steps (tests/test_ring.py)."""
    from rings import free_ring as run
    return run(n_cells, link, comm, push)


def writhing_ring(n_cells: int, link: float, comm=MPI.COMM_WORLD) -> list:
    """A pushed free ring's (Tw, Wr) step by step (tests/test_ring.py)."""
    from rings import writhing_ring as run
    return run(n_cells, link, comm)


def swinging_ring(n_cells: int, direction: int, drag: float, comm=MPI.COMM_WORLD) -> list:
    """The clamped ring pulled by a force, its node at s = L/2 (tests/test_ring.py)."""
    from rings import swinging_ring as run
    return run(n_cells, direction, drag, comm=comm)
