"""The rod's finite elements: mesh of [0, L], end measures, quadrature rules, spaces and
the unknowns (fields, rates, test functions) of each block.

Blocks (in this order): displacement x (P1, 3), quaternion q (P1, 4), gauge multiplier
(P1), natural curvature u_d and natural stretch v_d (DG0, or one real vector for the
uniform variant; v_d scalar if unshearable, absent if inextensible; evolving model only),
constraint multiplier (DG0, 2 or 3), velocity V and material angular velocity W (P1, 3;
dynamic rods only).

Locking: the strain-dependent terms are integrated with the 1-point Gauss rule ``dx_r``,
where the P1 element's 6 strains are independent functions of its 6 deformation modes
(no spurious modes, no shear locking); the DG0 natural strains live at the same points.
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx
import dolfinx.fem as fem
import ufl

from .. import constraints
from ..evolution import real_space
from ..rotations import material_derivative_vector
from ..model_base import end_measures, vertex_measure


@dataclass
class Discretisation:
    """Mesh, the coordinate s, end measures and the three quadrature rules."""

    mesh: dolfinx.mesh.Mesh
    length: float
    s: ufl.core.expr.Expr
    ds_end: dict
    dx: ufl.Measure       # degree 4: inertia, loads, drag
    dx_r: ufl.Measure     # 1-point Gauss: strains, psi, xi, evolution, constraints
    dx_v: ufl.Measure     # vertex rule: gauge and kinematic equations hold nodally


def discretise(comm, n_cells: int, length: float) -> Discretisation:
    mesh = dolfinx.mesh.create_interval(comm, n_cells, [0.0, length])
    return Discretisation(
        mesh, length, ufl.SpatialCoordinate(mesh)[0], end_measures(mesh, length),
        ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 4}),
        ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1}),
        vertex_measure(mesh))


def function_spaces(mesh, evolving: bool, variant: str, constraint: str | None,
                    dynamic: bool) -> dict:
    """One space object per block (blocks sharing an element still get their own: the
    assembly finds a Dirichlet condition's block by its space)."""
    def natural_space(shape):
        if variant == "uniform":
            return real_space(mesh, shape)
        return fem.functionspace(mesh, ("DG", 0, shape) if shape else ("DG", 0))

    spaces = {"displacement": fem.functionspace(mesh, ("Lagrange", 1, (3,))),
              "quaternion": fem.functionspace(mesh, ("Lagrange", 1, (4,))),
              "gauge_multiplier": fem.functionspace(mesh, ("Lagrange", 1))}
    if evolving:
        spaces["natural_curvature"] = natural_space((3,))
        if constraint is None:
            spaces["natural_stretch"] = natural_space((3,))
        elif constraint == "unshearable":
            spaces["natural_stretch"] = natural_space(())
    k = constraints.multiplier_size(constraint)
    if k:
        spaces["constraint_multiplier"] = fem.functionspace(mesh, ("DG", 0, (k,)))
    if dynamic:
        spaces["velocity"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
        spaces["angular_velocity"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
    return spaces


@dataclass
class Unknowns:
    """Per block: field f, rate placeholder r, test function t; and the velocities V
    (= x_t when quasi-static) and W (= 2 vec(conj(q) q_t)/|q|^2 when quasi-static)."""

    spaces: dict
    f: dict
    r: dict
    t: dict
    V: ufl.core.expr.Expr
    W: ufl.core.expr.Expr

    @property
    def names(self) -> list[str]:
        return list(self.spaces)


def unknowns(spaces: dict) -> Unknowns:
    f = {n: fem.Function(S, name=n) for n, S in spaces.items()}
    r = {n: fem.Function(S, name=f"{n}_rate") for n, S in spaces.items()}
    t = {n: ufl.TestFunction(S) for n, S in spaces.items()}
    dynamic = "velocity" in spaces
    V = f["velocity"] if dynamic else r["displacement"]
    W = f["angular_velocity"] if dynamic else material_derivative_vector(
        f["quaternion"], r["quaternion"])
    return Unknowns(spaces, f, r, t, V, W)
