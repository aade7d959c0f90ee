"""Rod systems shared by tests/test_rod_system.py and the MPI case of cases.py."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from dolfin_rod import EndLoad, Rod, RodModel, RodParameters, RodSystem, TimeStepper
from dolfin_rod.theory.rotations import np_quaternion_from_rotation_vector, np_rotation_matrix

# Newton to round-off, so that the coupled solve stops where each rod's alone does
ROUND_OFF = {"snes_rtol": 1e-13, "snes_atol": 1e-13}
T_END, DT = 0.2, 0.02
A = RodParameters(length=1.0, rho_A=1.0, I11=0.01, I22=0.01, M_d=(5, 5, 5), N_d=(5, 5, 5))
B = RodParameters(length=0.7, A=(2, 1.5, 1), B=(3, 3, 4), rho_A=2.0, I11=0.02, I22=0.01,
                  M_d=(2, 2, 2), N_d=(2, 2, 2), reference_curvature=(0.3, 0, 0))
FORCE_A, COUPLE_B = (1.0, 0.0, 0.0), np.array((0.0, 0.5, 0.2))
POSITION_B, ORIENTATION_B = np.array([1.0, 2.0, 3.0]), np.array([0.3, np.pi / 2, 0.2])


def turn_b() -> np.ndarray:
    """The rotation matrix of rod b's orientation."""
    return np_rotation_matrix(np_quaternion_from_rotation_vector(ORIENTATION_B))


def two_rods(placed: bool, comm=MPI.COMM_WORLD) -> RodSystem:
    """Rod a (clamped, tip force) and rod b (pinned, its own material, reference
    curvature and cells, a tip couple); b moved to POSITION_B and, if ``placed``,
    turned by ORIENTATION_B (its dead couple turned with it)."""
    turn = turn_b() if placed else np.eye(3)
    return RodSystem([
        Rod(A, 6, end_loads=[EndLoad("force", FORCE_A)], name="a"),
        Rod(B, 5, ("pinned", "free"), end_loads=[EndLoad("couple", tuple(turn @ COUPLE_B))],
            name="b", position=POSITION_B,
            orientation=ORIENTATION_B if placed else (0.0, 0.0, 0.0))], comm=comm)


def alone(which: str) -> RodModel:
    if which == "a":
        return RodModel(A, 6, end_loads=[EndLoad("force", FORCE_A)])
    return RodModel(B, 5, ends=("pinned", "free"), end_loads=[EndLoad("couple", COUPLE_B)])


def run_system(model, t_end: float = T_END, dt: float = DT) -> dict[str, float]:
    model.set_initial_state()
    TimeStepper(model.problem, solver_options=ROUND_OFF).run(0.0, t_end, dt)
    return model.diagnostics(t_end)
