"""The rod's finite elements: mesh of [0, L] (several rods: layout.py), end measures, quadrature rules, spaces and
the unknowns (fields, rates, test functions) of each block.

Two kinds of rotation unknowns (``validation.ROTATIONS``):

"quaternion"       blocks (in this order): displacement x (P1, 3), quaternion q (P1, 4),
                   gauge multiplier (P1), natural curvature u_d and natural stretch v_d
                   (DG0, or one real vector for the uniform variant; v_d scalar if
                   unshearable, absent if inextensible; evolving model only), constraint
                   multiplier (DG0, 2 or 3), velocity V and material angular velocity W
                   (P1, 3; dynamic rods only): a first-order system for any scheme.
"rotation_vector"  displacement x, rotation increment theta (P1, 3 each) on stored nodal
                   quaternions (rotation_vector.py), natural strains (DG0): 6 unknowns
                   per node, no saddle point; velocities and accelerations are the
                   integrator's (integrators/lie_alpha.py): dynamic rods, local variant,
                   no constraint.  The default for those (``validation.choose_rotations``).

Locking: the strain-dependent terms are integrated with the 1-point Gauss rule ``dx_r``,
where the P1 element's 6 strains are independent functions of its 6 deformation modes
(no spurious modes, no shear locking); the DG0 natural strains live at the same points.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import dolfinx
import dolfinx.fem as fem
import numpy as np
import ufl

from ..theory import constraints
from ..theory.evolution import real_space
from ..fem import shared_mesh
from ..fem.fe_model import vertex_measure
from ..theory.rotations import material_derivative_vector
from .layout import Pieces, RodLayout
from .rotation_vector import RotationVectorChart


@dataclass
class Discretisation:
    """Mesh, the coordinate s, the rods' places on it (layout.py), the end points and the
    three quadrature rules."""

    mesh: dolfinx.mesh.Mesh
    length: float         # a single rod's length (the longest rod of a system)
    s: ufl.core.expr.Expr
    pieces: Pieces        # per-rod indicators and coefficients
    ds: ufl.Measure       # the two end points (the exterior facets of the interval)
    end_weight: dict      # per end an expression 1 there and 0 at the other end
    dx: ufl.Measure       # inertia, loads, drag: degree 4 (quaternions), or the 2-point
                          # Gauss rule (rotation vectors: exact for the P1 mass matrix)
    dx_r: ufl.Measure     # 1-point Gauss: strains, psi, xi, evolution, constraints
    dx_v: ufl.Measure     # vertex rule: gauge and kinematic equations hold nodally


def discretise(comm, layout: RodLayout, rotations: str) -> Discretisation:
    """The discretisation of ``layout``; its mesh that of an earlier model of the same
    layout in this process (fem/shared_mesh.py)."""
    mesh = shared_mesh.mesh(layout, comm, lambda: layout.mesh(comm))
    degree = 2 if rotations == "rotation_vector" else 4
    s = ufl.SpatialCoordinate(mesh)[0]
    # the outward normal is -1 at s = 0 and +1 at s = L: untagged end points (a form with
    # tagged subdomains cannot be shared by the form cache) and no L in the forms
    normal = ufl.FacetNormal(mesh)[0]
    end_weight = {"start": (1.0 - normal) / 2, "end": (1.0 + normal) / 2}
    return Discretisation(
        mesh, max(layout.lengths), s, Pieces(layout, mesh, s), ufl.Measure("ds", domain=mesh),
        end_weight,
        ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": degree}),
        ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1}),
        vertex_measure(mesh))


def function_spaces(mesh, evolving: bool, variant: str, constraint: str | None,
                    dynamic: bool, rotations: str = "quaternion", n_rods: int = 1) -> dict:
    """One space object per block (blocks sharing an element still get their own: the
    assembly finds a Dirichlet condition's block by its space).  The uniform variant of
    several rods: one real vector of every rod's global natural strains in turn
    (layout.Pieces.of_rods).  Made once per mesh and kind (fem/shared_mesh.py)."""
    return dict(shared_mesh.space(mesh, ("blocks", evolving, variant, constraint, dynamic,
                                         rotations, n_rods), lambda: _function_spaces(
        mesh, evolving, variant, constraint, dynamic, rotations, n_rods)))


def _function_spaces(mesh, evolving, variant, constraint, dynamic, rotations, n_rods) -> dict:
    def natural_space(shape):
        if variant == "uniform":
            return real_space(mesh, shape if n_rods == 1 else (n_rods * int(np.prod(shape)),))
        return fem.functionspace(mesh, ("DG", 0, shape) if shape else ("DG", 0))

    spaces = {"displacement": fem.functionspace(mesh, ("Lagrange", 1, (3,)))}
    if rotations == "rotation_vector":
        spaces["rotation_increment"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
    else:
        spaces["quaternion"] = fem.functionspace(mesh, ("Lagrange", 1, (4,)))
        spaces["gauge_multiplier"] = fem.functionspace(mesh, ("Lagrange", 1))
    if evolving:
        spaces["natural_curvature"] = natural_space((3,))
        if constraint is None:
            spaces["natural_stretch"] = natural_space((3,))
        elif constraint == "unshearable":
            spaces["natural_stretch"] = natural_space(())
    k = constraints.multiplier_size(constraint)
    if k:
        spaces["constraint_multiplier"] = fem.functionspace(mesh, ("DG", 0, (k,)))
    if dynamic and rotations == "quaternion":
        spaces["velocity"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
        spaces["angular_velocity"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
    return spaces


@dataclass
class Unknowns:
    """Per block: field f, rate placeholder r, test function t, acceleration placeholder
    acc (rotation vectors: displacement and rotation increment); the velocities V and
    material angular velocity W (fields of a dynamic quaternion rod; the rates otherwise:
    x_t and 2 vec(conj(q) q_t)/|q|^2, or the rotation increment's rate, which the
    integrator treats as W); the rotation block's name, ``rotation_ufl`` making (q, dTheta),
    the rotation q at any point and the material virtual rotation dTheta of the rotation
    block's test function (UFL, made at the first read of ``q`` or ``dTheta``: a second
    model of a structure, whose forms are compiled, reads neither; 0.5 ms of its
    set-up, docs/performance.md); the chart of the stored rotations (rotation vectors)
    or None; ``natural_field`` (the uniform variant of several rods: each rod's global
    values on its cells, layout.py)."""

    spaces: dict
    f: dict
    r: dict
    t: dict
    V: ufl.core.expr.Expr
    W: ufl.core.expr.Expr
    rotation: str
    rotation_ufl: Callable[[], tuple]
    acc: dict
    chart: RotationVectorChart | None
    natural_field: Callable = lambda g: g     # a natural-strain block as a field along s

    @functools.cached_property
    def _rotation_expressions(self) -> tuple:
        return self.rotation_ufl()

    @property
    def q(self) -> ufl.core.expr.Expr:
        return self._rotation_expressions[0]

    @property
    def dTheta(self) -> ufl.core.expr.Expr:
        return self._rotation_expressions[1]

    @property
    def names(self) -> list[str]:
        return list(self.spaces)

    @property
    def dynamic(self) -> bool:
        return "velocity" in self.spaces or bool(self.acc)


def unknowns(spaces: dict, dynamic: bool, natural_field: Callable | None = None) -> Unknowns:
    f = {n: fem.Function(S, name=n) for n, S in spaces.items()}
    r = {n: fem.Function(S, name=f"{n}_rate") for n, S in spaces.items()}
    t = {n: ufl.TestFunction(S) for n, S in spaces.items()}
    if "rotation_increment" in spaces:
        name = "rotation_increment"
        chart = RotationVectorChart(spaces[name].mesh, f[name])
        acc = {n: fem.Function(spaces[n], name=f"{n}_acceleration")
               for n in ("displacement", name)} if dynamic else {}
        return Unknowns(spaces, f, r, t, r["displacement"], r[name], name,
                        lambda: (chart.q, chart.virtual_rotation(t[name])), acc, chart,
                        natural_field or (lambda g: g))
    q, qt = f["quaternion"], t["quaternion"]
    V = f["velocity"] if dynamic else r["displacement"]
    W = f["angular_velocity"] if dynamic else material_derivative_vector(q, r["quaternion"])
    return Unknowns(spaces, f, r, t, V, W, "quaternion",
                    lambda: (q, material_derivative_vector(q, qt)), {}, None,
                    natural_field or (lambda g: g))
