"""The rod's block residuals F_i(t, y, dy/dt; v_i): balance of momentum (eqs. linmom,
angmom, balance.py), the quaternion gauge, the constraints (Section 4.5), the evolution
of the natural strains (eqs. dotmfupeq, dotmfvpeq or their uniform forms, evolution.py)
and, for a dynamic rod, inertia and the kinematic equations.  Loads and drag are added
by external_forces.py.
"""

from __future__ import annotations

import dolfinx.fem as fem
import ufl

from ..theory import balance, constraints
from ..theory.evolution import evolution_residual
from ..fem.gathered_form import as_form
from .constitutive import SectionResponse
from .discretisation import Discretisation, Unknowns


def internal_forces(unk: Unknowns, resp: SectionResponse, constraint, disc: Discretisation):
    """int m . delta u + n . delta v ds on the (displacement, quaternion) blocks, with the
    multiplier's contact force for a constrained rod, and the constraint block.  Returns
    the blocks and the total material contact force n (constitutive + multiplier)."""
    x, q = unk.f["displacement"], unk.f[unk.rotation]
    xt, qt = unk.t["displacement"], unk.t[unk.rotation]
    m, n, dx_r = resp.m, resp.n, disc.dx_r
    F = {"displacement": balance.internal_work(m, n, resp.u, resp.v_eff, [x], [xt], dx_r),
         unk.rotation: balance.internal_work(m, n, resp.u, resp.v_eff, [q], [qt], dx_r)}
    if constraints.multiplier_size(constraint):    # quaternion rods only (discretisation.py)
        n_c = constraints.multiplier_force(unk.f["constraint_multiplier"], constraint)
        F["displacement"] += ufl.inner(n_c, ufl.derivative(resp.v, x, xt)) * dx_r
        F["quaternion"] += ufl.inner(n_c, ufl.derivative(resp.v, q, qt)) * dx_r
        F["constraint_multiplier"] = ufl.inner(constraints.constraint_value(resp.v, constraint),
                                               unk.t["constraint_multiplier"]) * dx_r
        n = n_c if n is None else n + n_c
    return F, n


def gauge(F: dict, unk: Unknowns, disc: Discretisation) -> None:
    """|q| = 1 at the vertices: d/d(q, lam) of int lam (|q|^2 - 1)/2 (vertex quadrature);
    nothing for rotation vectors (unit nodal quaternions by construction)."""
    if unk.rotation != "quaternion":
        return
    F_q, F["gauge_multiplier"] = balance.gauge(
        unk.f["quaternion"], unk.f["gauge_multiplier"], unk.t["quaternion"],
        unk.t["gauge_multiplier"], disc.dx_v)
    F["quaternion"] += F_q


def evolution(F: dict, unk: Unknowns, resp: SectionResponse, c: dict, variant: str,
              constraint, disc: Discretisation) -> list:
    """The natural-strain blocks; returns [(natural rate, dpsi/d natural strain)] for xi."""
    pairs = []
    blocks = [("natural_curvature", c["M_d"], resp.dpsi_dud)]
    if "natural_stretch" in unk.f:
        # unshearable: scalar v_d,3 only, evolving with N_d,33 (the stretch viscosity).
        # Deviation from the paper: eq. dotmfvpequ prints M_d,33 (the twist viscosity),
        # which mixes the torsional and axial laws; docs/rod.md, "Deviations".
        unshearable = constraint == "unshearable"
        blocks.append(("natural_stretch", c["N_d"][2, 2] if unshearable else c["N_d"],
                       resp.dpsi_dvd[2] if unshearable else resp.dpsi_dvd))
    for name, M_d, dpsi in blocks:
        rate = unk.natural_field(unk.r[name])
        F[name] = evolution_residual(M_d, rate, dpsi, unk.natural_field(unk.t[name]), variant,
                                     disc.pieces.length(), disc.dx_r)
        pairs.append((rate, dpsi))
    return pairs


def inertia(F: dict, unk: Unknowns, c: dict, disc: Discretisation) -> None:
    """rhoA r_tt and d/dt[(rho J) w] (eqs. linmom, angmom).  Quaternions: first order in
    time, with the kinematic equations x_t = V, W = 2 vec(conj(q) q_t)/|q|^2 at the
    vertices; rotation vectors: second order, the integrator's accelerations."""
    if unk.acc:
        accelerations = unk.acc["displacement"], unk.acc[unk.rotation]
    else:
        accelerations = unk.r["velocity"], unk.r["angular_velocity"]
    F_x, F_q = balance.inertia(c["rho_A"], c["J"], accelerations[0], unk.W, accelerations[1],
                               unk.t["displacement"], unk.dTheta, disc.dx)
    F["displacement"] += F_x
    F[unk.rotation] += F_q
    if unk.acc:
        return
    q = unk.f["quaternion"]
    F["velocity"], F["angular_velocity"] = balance.kinematic_equations(
        unk.r["displacement"], unk.V, q, unk.r["quaternion"], unk.W, unk.t["velocity"],
        unk.t["angular_velocity"], disc.dx_v)


def diagonal_zero(unk: Unknowns, disc: Discretisation):
    """The Constant 0 of zero_diagonals (None for rotation vectors: the mixed layout only,
    one rule)."""
    return fem.Constant(disc.mesh, 0.0) if unk.chart is None else None


def zero_diagonals(F: dict, unk: Unknowns, disc: Discretisation, zero) -> None:
    """Adds 0 * (y_i, v_i) at the vertices to the P1 blocks (``zero``: diagonal_zero).
    Still needed: without it the blocked layout (assembly.BlockedSystem, the uniform
    variant) assembles the quaternion residual 2e-4 off the mixed layout, which splits
    its kernels by quadrature rule (tests/test_assembly.py; DOLFINx 0.9 / FFCx, a kernel
    with the vertex rule and Gauss rules together).  Drop it once BlockedSystem splits its
    forms by rule as well."""
    if zero is None:
        return
    for name in ("displacement", "quaternion", "gauge_multiplier", "velocity",
                 "angular_velocity"):
        if name in F:
            F[name] += zero * ufl.inner(unk.f[name], unk.t[name]) * disc.dx_v


def one_quadrature_rule(F: dict, unk: Unknowns, disc: Discretisation) -> None:
    """Each block's terms as one ufl.Form (fem/gathered_form.py); rotation vectors: the
    2-point Gauss integrals (inertia, loads, drag) as 1-point integrals of their values at
    the Gauss points (RotationVectorChart.one_point_rule, the same quadrature), so that
    each block's cell integrals form one kernel."""
    for name, form in F.items():
        F[name] = (unk.chart.one_point_rule(form.integrals(), disc.dx_r)
                   if unk.chart is not None else as_form(form))
