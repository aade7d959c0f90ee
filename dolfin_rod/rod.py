"""The 3-D special Cosserat rod with evolving natural configuration (Sections 2-4).

Unknowns on s in [0, L] (blocks of one SemiDiscreteProblem, in this order):

    displacement x        P1, 3 comps    centre line r = X + x, X = s e_3
    quaternion q          P1, 4 comps    R = R(q/|q|) (rotations.py)
    gauge multiplier      P1             |q| = 1 at the vertices (vertex quadrature)
    natural curvature u_d DG0 (local) or one real 3-vector (uniform)      [evolving]
    natural stretch v_d   same; scalar v_d,3 if unshearable, absent if inextensible
    shear multiplier      DG0, 2 or 3 comps                                [constraints]
    velocity V, material angular velocity W   P1, 3 comps each            [rho_A > 0]

Constitutive laws (eqs. mfmeq, mfneq) m = dpsi/du + M du/dt, n = dpsi/dv + N dv/dt, and
the evolution laws (eqs. dotmfupeq, dotmfvpeq or their uniform forms) from
evolution.evolution_residual; balance laws from balance.py.

Locking: the strain-dependent terms (internal work, evolution, constraints, psi, xi)
are integrated with the 1-point Gauss rule, where the P1 element's 6 strains are
independent functions of its 6 deformation modes (no spurious modes, no shear locking;
the cantilever tip deflection is (1 + 1/(4 N^2)) times the Timoshenko bending part,
for any slenderness).  The natural strains are DG0, i.e. evaluated at the same points.

Models by name: "evolving" (the paper's), "kelvin_voigt" (psi independent of natural
strains: psi(u_ref, v_ref, u, v), viscosities M, N) and "hyperelastic" (no viscosity).

Reference strains u_ref, v_ref: the discrete strains of the initial configuration (DG0,
set by set_initial_state), so an initially curved/twisted rod (reference_curvature) is
exactly unstressed at t = 0.  The default energy is eq. quadenergy with the natural part
centred there: 1/2 (u_d - u_ref).A_d(u_d - u_ref) + 1/2 (v_d - v_ref).B_d(v_d - v_ref)
(the paper's form for a straight reference, u_ref = 0, v_ref = e_3).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import dolfinx
import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from . import balance, compat, constraints
from .dissipation import dissipation_rate
from .energy import derivatives, quadratic_energy
from .evolution import check_variant, evolution_residual, real_space
from .kinematics import material_curvature, material_stretch, strain_rates
from .problem import SemiDiscreteProblem, TimeDependentValue
from .rotations import (material_derivative_vector, np_qmul, np_quaternion_from_rotation_vector,
                        qmul)

MODELS = ("evolving", "kelvin_voigt", "hyperelastic")
END_TYPES = ("clamped", "pinned", "free")
ENDS = ("left", "right")
Tensor = Sequence | np.ndarray | Callable | None


@dataclass
class EndLoad:
    """A force or couple at an end: value(3,) * history(t); dead (spatial components)
    or follower (material components, i.e. rotating with the end section)."""

    kind: str                        # "force" or "couple"
    value: Sequence[float]
    history: Callable = field(default=lambda t: 1.0)
    end: str = "right"
    follower: bool = False


@dataclass
class DistributedLoad:
    """A force or couple per unit reference length: value(s) * history(t)."""

    kind: str                        # "force" or "couple"
    value: Sequence[float] | Callable
    history: Callable = field(default=lambda t: 1.0)
    follower: bool = False


@dataclass
class RodParameters:
    """Material data (tensors: 3 diagonal entries, a 3x3 SPD matrix, or a callable of s
    returning either, usable on floats and on UFL expressions)."""

    length: float = 1.0
    A: Tensor = (1.0, 1.0, 1.0)      # bending/torsion stiffness (EI_1, EI_2, GJ)
    B: Tensor = (1.0, 1.0, 1.0)      # shear/axial stiffness (GA_1, GA_2, EA)
    A_d: Tensor = (1.0, 1.0, 1.0)    # natural-curvature stiffness (eq. quadenergy)
    B_d: Tensor = (1.0, 1.0, 1.0)    # natural-stretch stiffness
    M: Tensor = None                 # Kelvin-Voigt viscosities (eq. xichoice); None: 0
    N: Tensor = None
    M_d: Tensor = (1.0, 1.0, 1.0)    # natural-configuration viscosities
    N_d: Tensor = (1.0, 1.0, 1.0)
    rho_A: float | Callable = 0.0    # mass per length; 0: quasi-static
    I11: float | Callable = 0.0      # section mass moments (rho J, Section 2.2)
    I22: float | Callable = 0.0
    drag: float | Callable = 0.0     # linear drag f = -c dr/dt
    energy: Callable | None = None   # psi(u_d, v_d, u, v); None: quadratic_energy
    reference_curvature: Sequence[float] = (0.0, 0.0, 0.0)  # stress-free strains at t = 0
    reference_stretch: Sequence[float] = (0.0, 0.0, 1.0)


def _sample(name, value, L):
    s = np.linspace(0.0, L, 17)
    try:
        vals = [np.asarray(value(si) if callable(value) else value, dtype=float) for si in s]
    except Exception as err:  # noqa: BLE001 - reported with the parameter's name
        raise ValueError(f"{name}: cannot evaluate ({err})") from err
    return s, vals


def _check_tensor(name, value, L, semidefinite=False):
    s, vals = _sample(name, value, L)
    for si, a in zip(s, vals):
        if a.shape == (3,):
            a = np.diag(a)
        if a.shape != (3, 3):
            raise ValueError(f"{name} must have 3 diagonal entries or be 3x3, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (s = {si:g})")
        if not np.allclose(a, a.T, rtol=1e-12, atol=1e-14 * np.abs(a).max()):
            raise ValueError(f"{name} must be symmetric (s = {si:g})")
        eig = np.linalg.eigvalsh(a)
        if (eig.min() < 0) if semidefinite else (eig.min() <= 0):
            rule = "positive semidefinite" if semidefinite else "positive definite (SPD)"
            raise ValueError(f"{name} must be {rule}; eigenvalue {eig.min():g} at s = {si:g}")


def _check_scalar(name, value, L):
    _, vals = _sample(name, value, L)
    for a in vals:
        if a.shape != () or not np.isfinite(a) or a < 0:
            raise ValueError(f"{name} must be a finite scalar >= 0, got {a}")


def _ufl_tensor(value, mesh, s):
    if callable(value):
        a = value(s)
        if np.shape(np.asarray(value(0.0), dtype=float)) == (3,):
            return ufl.diag(ufl.as_vector(list(a)))
        return ufl.as_matrix([list(row) for row in a])
    a = np.asarray(value, dtype=float)
    return fem.Constant(mesh, np.diag(a) if a.shape == (3,) else a)


def _ufl_scalar(value, mesh, s):
    return value(s) if callable(value) else fem.Constant(mesh, float(value))


def _is_zero(value):
    if value is None:
        return True
    if callable(value):
        return False
    return not np.any(np.asarray(value, dtype=float))


def _helix(s, u0, v0):
    """Stress-free configuration of constant strains: q(s) = exp(s u0/2), r = int R v0."""
    u0, v0 = np.asarray(u0, float), np.asarray(v0, float)
    a = np.linalg.norm(u0)
    U = np.array([[0, -u0[2], u0[1]], [u0[2], 0, -u0[0]], [-u0[1], u0[0], 0]])
    r = np.zeros((len(s), 3))
    for i, si in enumerate(s):
        if a * si < 1e-4:  # series of (1 - cos)/a^2 and (a s - sin)/a^3 (no 0/0)
            c1 = si**2 / 2 - a**2 * si**4 / 24
            c2 = si**3 / 6 - a**2 * si**5 / 120
        else:
            c1 = (1 - np.cos(a * si)) / a**2
            c2 = (a * si - np.sin(a * si)) / a**3
        r[i] = (si * np.eye(3) + c1 * U + c2 * U @ U) @ v0
    q = np_quaternion_from_rotation_vector(np.outer(s, u0))
    return r, q


class RodModel:
    """The 3-D rod as a SemiDiscreteProblem (see module docstring).

    ends: (left, right), each "clamped", "pinned" or "free".
    end_displacement, end_rotation: {end: history t -> 3-vector}: prescribed motion of an
    end (displacement from its initial position; rotation vector superposed on its
    initial rotation).  end_loads, distributed_loads: lists of EndLoad, DistributedLoad.
    """

    def __init__(self, params: RodParameters, n_cells: int = 32, model: str = "evolving",
                 variant: str = "local", constraint: str | None = None,
                 ends: tuple[str, str] = ("clamped", "free"),
                 end_loads: Sequence[EndLoad] = (),
                 distributed_loads: Sequence[DistributedLoad] = (),
                 end_displacement: dict | None = None, end_rotation: dict | None = None,
                 comm: MPI.Comm = MPI.COMM_WORLD):
        self._validate(params, n_cells, model, variant, constraint, ends, end_loads,
                       distributed_loads, end_displacement, end_rotation)
        self.params, self.model, self.variant, self.constraint = params, model, variant, constraint
        self.ends = tuple(ends)
        self.end_displacement = dict(end_displacement or {})
        self.end_rotation = dict(end_rotation or {})
        self.end_loads, self.distributed_loads = list(end_loads), list(distributed_loads)
        L = float(params.length)
        self.length = L
        self.evolving = model == "evolving"
        self.dynamic = not _is_zero(params.rho_A)

        self.mesh = mesh = dolfinx.mesh.create_interval(comm, n_cells, [0.0, L])
        s = ufl.SpatialCoordinate(mesh)[0]
        facets = {}
        for tag, end_s in ((1, 0.0), (2, L)):
            facets[tag] = dolfinx.mesh.locate_entities_boundary(
                mesh, 0, lambda x, e=end_s: np.isclose(x[0], e))
        idx = np.concatenate([facets[1], facets[2]]).astype(np.int32)
        val = np.concatenate([np.full(len(facets[1]), 1),
                              np.full(len(facets[2]), 2)]).astype(np.int32)
        order = np.argsort(idx)
        tags = dolfinx.mesh.meshtags(mesh, 0, idx[order], val[order])
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
        self.ds_end = {"left": ds(1), "right": ds(2)}
        dx = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 4})
        dx_r = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1})  # 1-point Gauss
        dx_v = ufl.Measure("dx", domain=mesh, metadata={"quadrature_rule": "vertex",
                                                        "quadrature_degree": 1})
        self.dx, self.dx_r = dx, dx_r

        # -- spaces and fields ------------------------------------------------------------
        def natural_space(shape):
            if variant == "uniform":
                return real_space(mesh, shape)
            return fem.functionspace(mesh, ("DG", 0, shape) if shape else ("DG", 0))

        spaces = {"displacement": fem.functionspace(mesh, ("Lagrange", 1, (3,))),
                  "quaternion": fem.functionspace(mesh, ("Lagrange", 1, (4,))),
                  "gauge_multiplier": fem.functionspace(mesh, ("Lagrange", 1))}
        if self.evolving:
            spaces["natural_curvature"] = natural_space((3,))
            if constraint is None:
                spaces["natural_stretch"] = natural_space((3,))
            elif constraint == "unshearable":
                spaces["natural_stretch"] = natural_space(())
        k = constraints.multiplier_size(constraint)
        if k:
            spaces["constraint_multiplier"] = fem.functionspace(mesh, ("DG", 0, (k,)))
        if self.dynamic:
            spaces["velocity"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
            spaces["angular_velocity"] = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
        self.names = list(spaces)
        self.f = {n: fem.Function(S, name=n) for n, S in spaces.items()}
        self.r = {n: fem.Function(S, name=f"{n}_rate") for n, S in spaces.items()}
        self.t = {n: ufl.TestFunction(S) for n, S in spaces.items()}
        x, q = self.f["displacement"], self.f["quaternion"]
        x_t, q_t = self.r["displacement"], self.r["quaternion"]
        V = self.f["velocity"] if self.dynamic else x_t
        W = self.f["angular_velocity"] if self.dynamic else material_derivative_vector(q, q_t)
        self.V, self.W = V, W

        # -- coefficients -----------------------------------------------------------------
        c = {n: _ufl_tensor(getattr(params, n), mesh, s)
             for n in ("A", "B", "A_d", "B_d", "M", "N", "M_d", "N_d")
             if not _is_zero(getattr(params, n))}
        for n in ("rho_A", "I11", "I22", "drag"):
            c[n] = _ufl_scalar(getattr(params, n), mesh, s)
        self.coefficients = c
        # Stress-free strains: DG0 fields set by set_initial_state to the discrete strains
        # of the initial configuration, so an initially curved rod is exactly unstressed.
        S_ref = fem.functionspace(mesh, ("DG", 0, (3,)))
        u_ref, v_ref = fem.Function(S_ref, name="u_ref"), fem.Function(S_ref, name="v_ref")
        self._reference = (u_ref, v_ref)

        # -- strains and constitutive laws (eqs. mfmeq, mfneq) ----------------------------
        u = material_curvature(q)
        v = material_stretch(q, ufl.as_vector((0.0, 0.0, 1.0)) + x.dx(0))
        v_eff = constraints.constrained_stretch(v, constraint)
        if self.evolving:
            u_d = self.f["natural_curvature"]
            v_d = self.f.get("natural_stretch")
            if constraint == "unshearable":
                v_d = ufl.as_vector((0.0, 0.0, v_d))
        else:
            u_d = u_ref
            v_d = None if v_eff is None else constraints.constrained_stretch(v_ref, constraint)
        psi_fn = self._energy_callable(params, c, u_ref, v_ref)
        psi, dpsi_du, dpsi_dv, dpsi_dud, dpsi_dvd = derivatives(psi_fn, u_d, v_d, u, v_eff)
        u_t, v_t = strain_rates(u, v_eff if v_eff is not None else v, [x, q], [x_t, q_t])
        m = dpsi_du + ufl.dot(c["M"], u_t) if "M" in c else dpsi_du
        n = None
        if v_eff is not None:
            n = dpsi_dv + ufl.dot(c["N"], v_t) if "N" in c else dpsi_dv
        self.psi, self.m, self.n, self.u, self.v = psi, m, n, u, v

        # -- residuals per block --------------------------------------------------------------
        xt, qt = self.t["displacement"], self.t["quaternion"]
        dTheta = balance.virtual_rotation(q, qt)
        F = {name: 0 for name in self.names}
        F["displacement"] = balance.internal_work(m, n, u, v_eff, [x], [xt], dx_r)
        F["quaternion"] = balance.internal_work(m, n, u, v_eff, [q], [qt], dx_r)
        lam_c = None
        if k:
            lam_c = self.f["constraint_multiplier"]
            n_c = constraints.multiplier_force(lam_c, constraint)
            F["displacement"] += ufl.inner(n_c, ufl.derivative(v, x, xt)) * dx_r
            F["quaternion"] += ufl.inner(n_c, ufl.derivative(v, q, qt)) * dx_r
            F["constraint_multiplier"] = ufl.inner(
                constraints.constraint_value(v, constraint), self.t["constraint_multiplier"]) * dx_r
            self.n = n_c if n is None else n + n_c
        # |q| = 1 at the vertices: d/d(q, lam) of int lam (|q|^2 - 1)/2 (vertex quadrature)
        F_gauge_q, F["gauge_multiplier"] = balance.gauge(
            q, self.f["gauge_multiplier"], qt, self.t["gauge_multiplier"], dx_v)
        F["quaternion"] += F_gauge_q
        natural_pairs = []
        if self.evolving:  # eqs. dotmfupeq/dotmfvpeq (local) or their integral forms (uniform)
            ud_t = self.r["natural_curvature"]
            F["natural_curvature"] = evolution_residual(
                c["M_d"], ud_t, dpsi_dud, self.t["natural_curvature"], variant, L, dx_r)
            natural_pairs.append((ud_t, dpsi_dud))
            if "natural_stretch" in self.f:
                vd_t = self.r["natural_stretch"]
                if constraint == "unshearable":
                    F["natural_stretch"] = evolution_residual(
                        c["N_d"][2, 2], vd_t, dpsi_dvd[2], self.t["natural_stretch"], variant,
                        L, dx_r)
                    natural_pairs.append((vd_t, dpsi_dvd[2]))
                else:
                    F["natural_stretch"] = evolution_residual(
                        c["N_d"], vd_t, dpsi_dvd, self.t["natural_stretch"], variant, L, dx_r)
                    natural_pairs.append((vd_t, dpsi_dvd))
        J = ufl.diag(ufl.as_vector((c["I22"], c["I11"], c["I11"] + c["I22"])))
        self.J = J
        if self.dynamic:
            F["displacement"] += c["rho_A"] * ufl.inner(self.r["velocity"], xt) * dx
            F["quaternion"] += ufl.inner(ufl.dot(J, self.r["angular_velocity"])
                                         + ufl.cross(W, ufl.dot(J, W)), dTheta) * dx
            F["velocity"], F["angular_velocity"] = balance.kinematic_equations(
                x_t, V, q, q_t, W, self.t["velocity"], self.t["angular_velocity"], dx_v)
        if not _is_zero(params.drag):
            F["displacement"] += c["drag"] * ufl.inner(V, xt) * dx

        # Zero diagonal blocks, so that blocked assembly puts 1 on the rows of Dirichlet
        # dofs (it only does so where the diagonal block form exists; e.g. x of an
        # inextensible rod or the gauge multiplier have none).
        zero = fem.Constant(mesh, 0.0)
        for name in ("displacement", "quaternion", "gauge_multiplier", "velocity",
                     "angular_velocity"):
            if name in F:
                F[name] += zero * ufl.inner(self.f[name], self.t[name]) * dx_v

        # -- loads -------------------------------------------------------------------------
        self.loads: list[TimeDependentValue] = []
        power = 0
        for load in self.end_loads:
            amp = fem.Constant(mesh, 0.0)
            self.loads.append(TimeDependentValue(amp, load.history))
            val = amp * fem.Constant(mesh, np.asarray(load.value, float))
            dsl = self.ds_end[load.end]
            if load.kind == "force":
                F["displacement"] -= balance.force_work(val, q, xt, load.follower) * dsl
                power += balance.force_work(val, q, V, load.follower) * dsl
            else:
                F["quaternion"] -= balance.couple_work(val, q, dTheta, load.follower) * dsl
                power += balance.couple_work(val, q, W, load.follower) * dsl
        for load in self.distributed_loads:
            amp = fem.Constant(mesh, 0.0)
            self.loads.append(TimeDependentValue(amp, load.history))
            raw = load.value(s) if callable(load.value) else fem.Constant(
                mesh, np.asarray(load.value, float))
            val = amp * (ufl.as_vector(list(raw)) if callable(load.value) else raw)
            if load.kind == "force":
                F["displacement"] -= balance.force_work(val, q, xt, load.follower) * dx
                power += balance.force_work(val, q, V, load.follower) * dx
            else:
                F["quaternion"] -= balance.couple_work(val, q, dTheta, load.follower) * dx
                power += balance.couple_work(val, q, W, load.follower) * dx

        # -- Dirichlet conditions ----------------------------------------------------------
        self._bc_values: dict = {}
        bcs = []

        def add_bc(block, end, shape):
            S = spaces[block]
            dofs = fem.locate_dofs_geometrical(
                S, lambda X, e=(0.0 if end == "left" else L): np.isclose(X[0], e))
            const = fem.Constant(mesh, np.zeros(shape) if shape else 0.0)
            self._bc_values[(block, end)] = const
            bcs.append(fem.dirichletbc(const, dofs, S))

        for end, kind in zip(ENDS, self.ends):
            fix_x = kind in ("clamped", "pinned") or end in self.end_displacement
            fix_q = kind == "clamped" or end in self.end_rotation
            if fix_x:
                add_bc("displacement", end, (3,))
                if self.dynamic:
                    add_bc("velocity", end, (3,))
            if fix_q:
                add_bc("quaternion", end, (4,))
                add_bc("gauge_multiplier", end, ())
                if self.dynamic:
                    add_bc("angular_velocity", end, (3,))
        self._end_state = {"left": (np.zeros(3), np.array([1.0, 0, 0, 0])),
                           "right": (np.zeros(3), np.array([1.0, 0, 0, 0]))}

        fields = [self.f[n] for n in self.names]
        rates = [self.r[n] for n in self.names]
        self.problem = SemiDiscreteProblem(fields, rates, [F[n] for n in self.names],
                                           self.loads, bcs, self._set_bcs)
        self.residual = F

        # -- diagnostics ---------------------------------------------------------------------
        viscous = ([(u_t, c["M"])] if "M" in c else []) + (
            [(v_t, c["N"])] if "N" in c and n is not None else [])
        xi = dissipation_rate(viscous, natural_pairs) if (viscous or natural_pairs) else 0 * psi
        self.xi = xi
        kinetic = 0.5 * (c["rho_A"] * ufl.inner(V, V) + ufl.inner(W, ufl.dot(J, W)))
        forms = {"free_energy": psi * dx_r,
                 "dissipation_rate": xi * dx_r + c["drag"] * ufl.inner(V, V) * dx,
                 "kinetic_energy": kinetic * dx if self.dynamic else 0 * psi * dx_r,
                 "load_power": 0 * psi * dx_r + power}
        rtip = ufl.as_vector((0.0, 0.0, s)) + x
        for i, comp in enumerate("xyz"):
            forms[f"tip_position_{comp}"] = rtip[i] * self.ds_end["right"]
        for i in range(4):
            forms[f"tip_quaternion_{i}"] = q[i] * self.ds_end["right"]
        # Reactions at prescribed ends: the residual tested with a unit virtual
        # translation / spatial rotation of that end node only (hat function of the node).
        self._hat = {}
        for end in ENDS:
            hat = fem.Function(spaces["gauge_multiplier"])
            e_s = 0.0 if end == "left" else L
            hat.interpolate(lambda X, e=e_s: np.isclose(X[0], e).astype(float))
            self._hat[end] = hat
            for i, comp in enumerate("xyz"):
                e_i = ufl.unit_vector(i, 3)
                if ("displacement", end) in self._bc_values:
                    forms[f"reaction_force_{end}_{comp}"] = ufl.replace(
                        F["displacement"], {xt: hat * e_i})
                if ("quaternion", end) in self._bc_values:
                        dq = 0.5 * hat * qmul(ufl.as_vector((0.0, e_i[0], e_i[1], e_i[2])), q)
                        forms[f"reaction_couple_{end}_{comp}"] = ufl.replace(
                            F["quaternion"], {qt: dq})
        self._forms = {key: fem.form(val) for key, val in forms.items()}

    # -- validation ------------------------------------------------------------------------
    @staticmethod
    def _validate(params, n_cells, model, variant, constraint, ends, end_loads,
                  distributed_loads, end_displacement, end_rotation):
        if model not in MODELS:
            raise ValueError(f"unknown model '{model}' (known: {', '.join(MODELS)})")
        check_variant(variant)
        constraints.check_constraint(constraint)
        if not (isinstance(n_cells, (int, np.integer)) and n_cells >= 1):
            raise ValueError(f"n_cells must be a positive integer, got {n_cells!r}")
        if not (np.isfinite(params.length) and params.length > 0):
            raise ValueError(f"length must be > 0, got {params.length}")
        if len(ends) != 2 or any(e not in END_TYPES for e in ends):
            raise ValueError(f"ends must be two of {END_TYPES}, got {ends!r}")
        L = params.length
        for name in ("A", "B"):
            _check_tensor(name, getattr(params, name), L)
        if model == "evolving":
            for name in ("A_d", "B_d", "M_d", "N_d"):
                _check_tensor(name, getattr(params, name), L)
            if variant == "uniform":
                for name in ("M_d", "N_d"):
                    if callable(getattr(params, name)):
                        raise ValueError(f"{name} must be constant for the uniform variant "
                                         "(one tensor for the whole rod, eq. dotmfupequnif)")
        for name in ("M", "N"):
            value = getattr(params, name)
            if value is not None:
                if model == "hyperelastic" and not _is_zero(value):
                    raise ValueError(f"{name} must be None for the hyperelastic model")
                _check_tensor(name, value, L, semidefinite=True)
        if model == "kelvin_voigt" and _is_zero(params.M) and _is_zero(params.N):
            raise ValueError("kelvin_voigt needs a viscosity M or N (else use 'hyperelastic')")
        for name in ("rho_A", "I11", "I22", "drag"):
            _check_scalar(name, getattr(params, name), L)
        for name in ("reference_curvature", "reference_stretch"):
            if np.shape(getattr(params, name)) != (3,):
                raise ValueError(f"{name} must be a 3-vector")
        if params.reference_stretch[2] <= 0:
            raise ValueError("reference_stretch[2] (v_3) must be > 0 (eq. v3pos)")
        for load in list(end_loads) + list(distributed_loads):
            if load.kind not in ("force", "couple"):
                raise ValueError(f"load kind must be 'force' or 'couple', got {load.kind!r}")
            if not callable(load.value) and np.shape(load.value) != (3,):
                raise ValueError(f"load value must be a 3-vector, got {load.value!r}")
        for load in end_loads:
            if load.end not in ENDS:
                raise ValueError(f"load end must be 'left' or 'right', got {load.end!r}")
        for name, motion in (("end_displacement", end_displacement),
                             ("end_rotation", end_rotation)):
            for end in (motion or {}):
                if end not in ENDS:
                    raise ValueError(f"{name}: unknown end {end!r}")

    def _energy_callable(self, params, c, u_ref, v_ref):
        if params.energy is None:
            if self.evolving:
                base = quadratic_energy(c["A"], c["A_d"], c["B"], c["B_d"], v_ref=v_ref)
                return lambda ud, vd, u, v: base(ud - u_ref, vd, u - u_ref, v)
            zero = ufl.as_matrix(np.zeros((3, 3)).tolist())
            return quadratic_energy(c["A"], zero, c["B"], zero)
        psi = params.energy
        if not callable(psi):
            raise ValueError("energy must be a callable psi(u_d, v_d, u, v)")
        probe = [ufl.as_vector((0.1, 0.2, 0.3))] * 4
        try:
            val = psi(*probe)
        except Exception as err:  # noqa: BLE001
            raise ValueError(f"energy callable failed on UFL 3-vectors: {err}") from err
        if not isinstance(val, ufl.core.expr.Expr) or ufl.shape(val) != ():
            raise ValueError("energy must return a scalar UFL expression, got "
                             f"shape {getattr(val, 'ufl_shape', type(val))}")
        return psi

    # -- boundary values -------------------------------------------------------------------
    def _prescribed(self, end, t):
        x0, q0 = self._end_state[end]
        d = np.asarray(self.end_displacement[end](t), float) if end in self.end_displacement \
            else np.zeros(3)
        if end in self.end_rotation:
            qr = np_quaternion_from_rotation_vector(np.asarray(self.end_rotation[end](t), float))
            qe = np_qmul(qr, q0)
        else:
            qe = q0
        return x0 + d, qe

    def _set_bcs(self, t: float) -> None:
        for end in ENDS:
            xe, qe = self._prescribed(end, t)
            if ("displacement", end) in self._bc_values:
                self._bc_values[("displacement", end)].value[:] = xe
            if ("quaternion", end) in self._bc_values:
                self._bc_values[("quaternion", end)].value[:] = qe
            if self.dynamic:
                h = 1e-6 * max(1.0, abs(t))
                xp, qp = self._prescribed(end, t + h)
                xm, qm = self._prescribed(end, t - h)
                if ("velocity", end) in self._bc_values:
                    self._bc_values[("velocity", end)].value[:] = (xp - xm) / (2 * h)
                if ("angular_velocity", end) in self._bc_values:
                    qdot = (qp - qm) / (2 * h)
                    conj = qe * np.array([1, -1, -1, -1])
                    self._bc_values[("angular_velocity", end)].value[:] = \
                        2 * np_qmul(conj, qdot)[1:] / (qe @ qe)

    # -- initial state ----------------------------------------------------------------------
    def set_initial_state(self, natural_curvature=None, natural_stretch=None) -> None:
        """Rest in the stress-free configuration of the reference strains (a straight rod
        along e_3, or the helix/circle of constant reference_curvature), natural strains
        equal to the reference strains unless given (3-vectors), rates zero."""
        for g in list(self.f.values()) + list(self.r.values()):
            g.x.array[:] = 0.0
        u0 = np.asarray(self.params.reference_curvature, float)
        v0 = np.asarray(self.params.reference_stretch, float)

        def config(X):
            r, qq = _helix(X[0], u0, v0)
            return r, qq

        self.f["displacement"].interpolate(
            lambda X: (config(X)[0] - np.outer(X[0], [0, 0, 1.0])).T)
        self.f["quaternion"].interpolate(lambda X: config(X)[1].T)
        for end, e_s in (("left", 0.0), ("right", self.length)):
            r, qq = _helix(np.array([e_s]), u0, v0)
            self._end_state[end] = (r[0] - np.array([0, 0, e_s]), qq[0])
        for g in self.f.values():
            g.x.scatter_forward()
        u_ref, v_ref = self._reference
        pts = compat.interpolation_points(u_ref.function_space)
        u_ref.interpolate(fem.Expression(self.u, pts))
        v_ref.interpolate(fem.Expression(self.v, pts))
        if self.evolving:
            # natural strains: given constants, else the discrete strains (local variant:
            # unstressed at t = 0) or the reference strains (uniform variant)
            self._fill_natural("natural_curvature", natural_curvature, u_ref, u0)
            if "natural_stretch" in self.f:
                self._fill_natural("natural_stretch", natural_stretch, v_ref, v0)
            for g in self.f.values():
                g.x.scatter_forward()
        self._set_bcs(0.0)

    def _fill_natural(self, name, given, discrete, reference):
        g = self.f[name]
        if given is not None:
            val = np.broadcast_to(np.asarray(given, float), (g.x.array.size // 3 or 1, 3))
        elif self.variant == "local":
            val = discrete.x.array.reshape(-1, 3)
        else:
            val = np.atleast_2d(reference)
        if self.constraint == "unshearable" and name == "natural_stretch":
            g.x.array[:] = np.broadcast_to(val[:, 2], g.x.array.shape)
        else:
            g.x.array[:] = np.broadcast_to(val, (g.x.array.size // 3, 3)).ravel()

    # -- diagnostics -------------------------------------------------------------------------
    def _assemble(self, key: str) -> float:
        return self.mesh.comm.allreduce(fem.assemble_scalar(self._forms[key]), op=MPI.SUM)

    def diagnostics(self, t: float) -> dict[str, float]:
        """MPI-reduced scalars at time t: tip position and quaternion, tip rotation angle
        (of the rotation path, in [0, 2 pi]), free and kinetic energy, dissipation rate
        (incl. drag), power of the applied loads, reactions at supported ends."""
        self.problem.set_loads(t)
        d = {key: self._assemble(key) for key in self._forms}
        d["time"] = t
        qt = np.array([d[f"tip_quaternion_{i}"] for i in range(4)])
        d["tip_rotation_angle"] = float(2 * np.arctan2(np.linalg.norm(qt[1:]), qt[0]))
        return d

    def pointwise(self, expr) -> np.ndarray:
        """Values of a UFL expression at the cell midpoints (owned cells), (n, ...)."""
        pts = np.array([[0.5]])
        e = fem.Expression(expr, pts)
        n = self.mesh.topology.index_map(1).size_local
        return e.eval(self.mesh, np.arange(n, dtype=np.int32)).reshape(n, -1)
