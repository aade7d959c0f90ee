"""The set-up shortcuts of issue 30 (target 1) give the numbers of the general path.

The reference strains of a straight rod along e_3 are written directly (u_ref = 0,
v_ref = e_3; rod/initial_state.py) instead of interpolating the compiled strain
expressions: here they are compared, bit for bit, with those expressions evaluated on
the same state, for each kind of rotation unknown and each model that computes its
strains differently (rotation vectors, quaternions, an unshearable rod, the uniform
variant).  Speed itself is measured by benchmarks/setup_cost.py.
"""

from __future__ import annotations

import dolfinx.fem as fem
import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod.fem import compat
from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters

CASES = {
    "dynamic, rotation vectors": dict(
        params=dict(rho_A=2.0, I11=1e-3, I22=1e-3), model="hyperelastic"),
    "quasi-static creep, quaternions": dict(
        params=dict(A_d=(1.0, 1.0, 1.0), B_d=(10.0, 10.0, 10.0), M_d=(1.0, 1.0, 1.0),
                    N_d=(1.0, 1.0, 1.0)), model="evolving", rotations="quaternion"),
    "unshearable, uniform variant": dict(
        params=dict(A_d=(1.0, 1.0, 1.0), B_d=(10.0, 10.0, 10.0), M_d=(1.0, 1.0, 1.0),
                    N_d=(1.0, 1.0, 1.0)), model="evolving", variant="uniform",
        constraint="unshearable"),
}


def compiled_strains(model: RodModel) -> tuple[np.ndarray, np.ndarray]:
    """u, v of the current state at the reference strains' points, by fem.Expression."""
    out = []
    for expr, field in zip((model.u, model.v), model.reference):
        g = fem.Function(field.function_space)
        g.interpolate(fem.Expression(expr, compat.interpolation_points(g.function_space)))
        out.append(g.x.array.copy())
    return out[0], out[1]


@pytest.mark.mpi
@pytest.mark.parametrize("case", CASES)
def test_straight_reference_strains_equal_the_compiled_strains(case):
    """Bit-identical: u_ref = 0 and v_ref = e_3 are what the strain kernels give for a
    straight rod (q = 1, x = 0 at every node), so every later number is unchanged."""
    spec = CASES[case]
    params = RodParameters(A=(2.0, 3.0, 4.0), B=(50.0, 60.0, 70.0), **spec["params"])
    model = RodModel(params, n_cells=4, model=spec["model"],
                     variant=spec.get("variant", "local"),
                     constraint=spec.get("constraint"), rotations=spec.get("rotations", "auto"),
                     distributed_loads=[DistributedLoad("force", (1.0, 0.0, 0.0))],
                     comm=MPI.COMM_WORLD)
    model.set_initial_state()
    u, v = compiled_strains(model)
    u_ref, v_ref = (f.x.array for f in model.reference)
    assert np.array_equal(u_ref, u) and np.array_equal(v_ref, v)
    assert np.array_equal(v.reshape(-1, 3), np.tile([0.0, 0.0, 1.0], (len(v) // 3, 1)))


def test_a_curved_rod_keeps_the_compiled_strains():
    """A helix (reference curvature) is not straight: its reference strains are the
    compiled ones, and they differ from (0, e_3)."""
    params = RodParameters(A=(2.0, 3.0, 4.0), B=(50.0, 60.0, 70.0),
                           reference_curvature=(0.0, 1.0, 0.5))
    model = RodModel(params, n_cells=4, model="hyperelastic", comm=MPI.COMM_WORLD)
    model.set_initial_state()
    u, v = compiled_strains(model)
    assert np.array_equal(model.reference[0].x.array, u)
    assert np.abs(u.reshape(-1, 3)[:, 1] - 1.0).max() < 0.05   # discrete curvature ~ u0
