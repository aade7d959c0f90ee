"""Isolated torsion (Section 5): the reduced, dimensionless model on s in [0, 1].

    nu phi_tt = d/ds[ alpha (phi_s - u_d) + mu phi_st ] + l(s, t),  phi(0, t) = 0,  (eq. phieq)
    local:   mu_d du_d/dt = alpha (phi_s - u_d) - alpha_d u_d,                      (eq. upeq)
    uniform: mu_d du_d/dt = int alpha (phi_s - u_d) ds - (int alpha_d ds) u_d,      (errata 1)

with, at s = 1, either an applied torsion m(t) = alpha (phi_s - u_d) + mu phi_st or a
prescribed end rotation Phi(t) (the reaction torsion is then an output).  This is the
quadratic energy psi = alpha/2 (u - u_d)^2 + alpha_d/2 u_d^2 (eq. quadenergy, torsion part)
with M = mu, M_d = mu_d; residuals come from energy.py, evolution.py and dissipation.py.

Unknowns: twist angle phi (P_k), natural twist u_d (DG_{k-1} for the local variant, one
global real unknown for the uniform variant) and, when nu > 0, the angular velocity
w = phi_t (P_k, kinematic equation with vertex quadrature so that it holds nodally).
The coefficients may vary along s (floats or callables of s usable on numpy arrays and
on UFL expressions, e.g. ``lambda s: 1 + s**2``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import dolfinx
import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from . import compat
from . import loads as load_histories
from .dissipation import dissipation_rate
from .energy import derivatives, quadratic_energy
from .evolution import check_variant, evolution_residual, real_space
from .problem import SecondOrderProblem, SemiDiscreteProblem, TimeDependentValue

Coefficient = float | Callable


def _check_coefficient(name: str, value: Coefficient, strict: bool) -> None:
    s = np.linspace(0.0, 1.0, 257)
    vals = np.broadcast_to(np.asarray(value(s) if callable(value) else value, dtype=float),
                           s.shape)
    bad = ~np.isfinite(vals) | ((vals <= 0) if strict else (vals < 0))
    if bad.any():
        rule = "> 0" if strict else ">= 0"
        raise ValueError(f"{name} must be {rule} on [0, 1]; got {vals[bad][0]:g} "
                         f"at s = {s[bad][0]:g}")


@dataclass
class TorsionParameters:
    """Dimensionless torsion coefficients (Section 5.1 with errata item 5)."""

    alpha: Coefficient = 1.0      # torsional stiffness A_33 T^2/((rho A) L^4)
    alpha_d: Coefficient = 1.0    # natural-twist stiffness A_d,33 (same scaling)
    mu: Coefficient = 0.0         # Kelvin-Voigt viscosity T M_33/((rho A) L^4)
    mu_d: Coefficient = 1.0       # natural-configuration viscosity T M_d,33/((rho A) L^4)
    nu: Coefficient = 0.0         # rotary inertia (I_11 + I_22)/((rho A) L^2); 0: quasi-static
    couple: Callable | None = None  # distributed couple l(s, t) = couple(s) * couple_history(t)
    couple_history: Callable = field(default=lambda t: 1.0)

    def validate(self, variant: str) -> None:
        for name in ("alpha", "alpha_d", "mu_d"):
            _check_coefficient(name, getattr(self, name), strict=True)
        for name in ("mu", "nu"):
            _check_coefficient(name, getattr(self, name), strict=False)
        if variant == "uniform" and callable(self.mu_d):
            raise ValueError("mu_d must be a constant for the uniform variant "
                             "(M_d is one tensor for the whole rod, eq. unatevolunif)")
        for name in ("mu", "nu"):
            value = getattr(self, name)
            if callable(value):
                vals = np.asarray(value(np.linspace(0, 1, 257)), dtype=float)
                if (vals == 0).any() and (vals > 0).any():
                    raise ValueError(f"{name} must be either > 0 everywhere or 0 everywhere")

    def is_zero(self, name: str) -> bool:
        value = getattr(self, name)
        return (not callable(value)) and value == 0.0


class TorsionModel:
    """The isolated-torsion rod as a SemiDiscreteProblem (see module docstring).

    Exactly one of ``end_torsion`` (applied m(t)) and ``end_rotation`` (prescribed
    Phi(t)) is given; both are load histories (dolfin_rod.loads) or plain callables.
    """

    def __init__(self, params: TorsionParameters, n_cells: int = 64, variant: str = "local",
                 end_torsion: Callable | None = None, end_rotation: Callable | None = None,
                 degree: int = 1, comm: MPI.Comm = MPI.COMM_WORLD):
        check_variant(variant)
        params.validate(variant)
        if (end_torsion is None) == (end_rotation is None):
            raise ValueError("give exactly one of end_torsion (applied torsion m(t)) and "
                             "end_rotation (prescribed Phi(t)) at s = 1")
        if not (isinstance(n_cells, (int, np.integer)) and n_cells >= 1):
            raise ValueError(f"n_cells must be a positive integer, got {n_cells!r}")
        if degree not in (1, 2, 3):
            raise ValueError(f"degree must be 1, 2 or 3, got {degree!r}")
        self.params, self.variant, self.degree = params, variant, degree
        self.end_torsion, self.end_rotation = end_torsion, end_rotation
        self.dynamic = not params.is_zero("nu")
        self.viscous = not params.is_zero("mu")
        if self.dynamic and end_rotation is not None and _jump(end_rotation) != 0.0:
            raise ValueError("end_rotation has a step at t = 0 but nu > 0: a rod with "
                             "inertia cannot follow a jump in rotation; use "
                             "loads.smooth_step or loads.ramp")

        self.mesh = dolfinx.mesh.create_unit_interval(comm, n_cells)
        mesh = self.mesh
        s = ufl.SpatialCoordinate(mesh)[0]
        coef = {n: (getattr(params, n)(s) if callable(getattr(params, n))
                    else fem.Constant(mesh, float(getattr(params, n))))
                for n in ("alpha", "alpha_d", "mu", "mu_d", "nu")}
        self.coefficients = coef

        V = fem.functionspace(mesh, ("Lagrange", degree))
        Q = (real_space(mesh) if variant == "uniform"
             else fem.functionspace(mesh, ("DG", degree - 1)))
        spaces = [V, Q] + ([fem.functionspace(mesh, ("Lagrange", degree))]
                           if self.dynamic else [])
        names = ["twist_angle", "natural_twist", "angular_velocity"][:len(spaces)]
        fields = [fem.Function(S, name=n) for S, n in zip(spaces, names)]
        rates = [fem.Function(S, name=f"{n}_rate") for S, n in zip(spaces, names)]
        self.phi, self.u_d = fields[0], fields[1]
        phi_t, ud_t = rates[0], rates[1]
        w = fields[2] if self.dynamic else phi_t  # angular velocity
        tests = [ufl.TestFunction(S) for S in spaces]
        eta, zeta = tests[0], tests[1]

        # End s = 1 as a boundary measure: point values and point loads in parallel.
        right = dolfinx.mesh.locate_entities_boundary(mesh, 0, lambda x: np.isclose(x[0], 1.0))
        tags = dolfinx.mesh.meshtags(mesh, 0, right, np.full(len(right), 1, dtype=np.int32))
        self.ds_end = ufl.Measure("ds", domain=mesh, subdomain_data=tags, subdomain_id=1)
        dx = ufl.Measure("dx", domain=mesh)

        u = self.phi.dx(0)                              # twist u = phi_s
        psi_fn = quadratic_energy(coef["alpha"], coef["alpha_d"])
        psi, dpsi_du, _, dpsi_dud, _ = derivatives(psi_fn, self.u_d, None, u, None)
        u_t = w.dx(0)
        torsion = dpsi_du + coef["mu"] * u_t            # m = dpsi/du + M du/dt (eq. mconsteq)

        self.loads: list[TimeDependentValue] = []
        F_phi = torsion * eta.dx(0) * dx
        if self.dynamic:
            F_phi += coef["nu"] * rates[2] * eta * dx
        if params.couple is not None:
            l_t = fem.Constant(mesh, 0.0)
            self.loads.append(TimeDependentValue(l_t, params.couple_history))
            F_phi -= params.couple(s) * l_t * eta * dx
            self._couple = params.couple(s) * l_t
        else:
            self._couple = None
        self.m_applied = None
        if end_torsion is not None:
            self.m_applied = fem.Constant(mesh, 0.0)
            self.loads.append(TimeDependentValue(self.m_applied, end_torsion))
            F_phi -= self.m_applied * eta * self.ds_end
        F = [F_phi, evolution_residual(coef["mu_d"], ud_t, dpsi_dud, zeta, variant, 1.0, dx)]
        if self.dynamic:  # phi_t = w at the vertices (lumped kinematic equation)
            dx_v = ufl.Measure("dx", domain=mesh, metadata={"quadrature_rule": "vertex",
                                                            "quadrature_degree": 1})
            F.append((phi_t - w) * tests[2] * dx_v)

        # Dirichlet conditions: phi(0) = 0, phi(1) = Phi(t); w(0) = 0, w(1) = Phi'(t).
        # Blocked assembly finds a condition's block by its space object, hence W != V.
        self._phi_end = fem.Constant(mesh, 0.0)
        self._w_end = fem.Constant(mesh, 0.0)
        bcs = []
        for S, end_value in [(V, self._phi_end)] + ([(spaces[2], self._w_end)]
                                                   if self.dynamic else []):
            left = fem.locate_dofs_geometrical(S, lambda x: np.isclose(x[0], 0.0))
            bcs.append(fem.dirichletbc(fem.Constant(mesh, 0.0), left, S))
            if end_rotation is not None:
                right_dofs = fem.locate_dofs_geometrical(S, lambda x: np.isclose(x[0], 1.0))
                bcs.append(fem.dirichletbc(end_value, right_dofs, S))

        self.problem = SemiDiscreteProblem(fields, rates, F, self.loads, bcs, self._set_bcs)
        self._diagnostic_forms(psi, dpsi_dud, torsion, w, rates, coef, dx)

    def second_order_problem(self) -> SecondOrderProblem:
        """The dynamic model as nu phi_tt + ... = 0 in (phi, u_d) for TSALPHA2.

        The first-order residual with w -> phi_t and w_t -> phi_tt; the kinematic block
        is dropped.  After each accepted step w is set to phi_t, so diagnostics() holds.
        """
        if not self.dynamic:
            raise ValueError("second_order_problem needs nu > 0 (a dynamic rod)")
        p = self.problem
        w, phi_t = p.fields[2], p.rates[0]
        phi_tt = fem.Function(self.phi.function_space, name="twist_angle_acceleration")
        u_d_tt = fem.Function(self.u_d.function_space, name="natural_twist_acceleration")
        mapping = {w: phi_t, p.rates[2]: phi_tt}
        V = self.phi.function_space
        bcs = [bc for bc in p.bcs if compat.contains(V, bc)]

        def sync():
            w.x.array[:] = phi_t.x.array
            p.rates[2].x.array[:] = phi_tt.x.array

        return SecondOrderProblem(
            p.fields[:2], p.rates[:2], [ufl.replace(F, mapping) for F in p.residual[:2]],
            p.loads, bcs, p.set_bcs, accelerations=[phi_tt, u_d_tt], after_step=sync)

    # -- time-dependent boundary values ----------------------------------------------
    def _set_bcs(self, t: float) -> None:
        if self.end_rotation is not None:
            self._phi_end.value = float(self.end_rotation(t))
            if self.dynamic:
                h = 1e-7 * max(1.0, abs(t))  # Phi'(t) by central differences
                self._w_end.value = float(
                    (self.end_rotation(t + h) - self.end_rotation(t - h)) / (2 * h))

    # -- diagnostics ------------------------------------------------------------------
    def _diagnostic_forms(self, psi, dpsi_dud, torsion, w, rates, coef, dx):
        s_fn = fem.Function(self.phi.function_space)
        s_fn.interpolate(lambda x: x[0])  # test function s: the end reaction (see reaction)
        kinetic = 0.5 * coef["nu"] * w * w
        xi = dissipation_rate([(w.dx(0), coef["mu"])], [(rates[1], dpsi_dud)])
        self.xi = xi
        reaction = torsion * dx
        if self.dynamic:
            reaction += coef["nu"] * rates[2] * s_fn * dx
        if self._couple is not None:
            reaction -= self._couple * s_fn * dx
        forms = {
            "end_rotation": self.phi * self.ds_end,
            "end_rotation_rate": w * self.ds_end,
            "free_energy": psi * dx,
            "kinetic_energy": kinetic * dx,
            "dissipation_rate": xi * dx,
            "mean_natural_twist": self.u_d * dx,
            "reaction_torsion": reaction,
        }
        if self._couple is not None:
            forms["couple_power"] = self._couple * w * dx
        self._forms = {k: fem.form(v) for k, v in forms.items()}

    def _assemble(self, key: str) -> float:
        local = fem.assemble_scalar(self._forms[key])
        return self.mesh.comm.allreduce(local, op=MPI.SUM)

    def diagnostics(self, t: float) -> dict[str, float]:
        """Scalars at time t from the current state and rate estimates.

        end_torsion is the applied m(t) or, under a prescribed rotation, the reaction
        int [m + nu phi_tt s - l s] ds (the discrete residual tested with eta = s).
        """
        self.problem.set_loads(t)
        d = {k: self._assemble(k) for k in self._forms}
        d["time"] = t
        if self.end_torsion is not None:
            d["end_torsion"] = float(self.end_torsion(t))
        else:
            d["end_torsion"] = d["reaction_torsion"]
        d.pop("reaction_torsion")
        d["load_power"] = d["end_torsion"] * d["end_rotation_rate"] + d.pop("couple_power", 0.0)
        return d

    def pointwise_dissipation(self) -> np.ndarray:
        """xi at the cell midpoints (owned cells) for the current state and rates."""
        Q = fem.functionspace(self.mesh, ("DG", 0))
        xi = fem.Function(Q)
        xi.interpolate(fem.Expression(self.xi, compat.interpolation_points(Q)))
        n = Q.dofmap.index_map.size_local
        return xi.x.array[:n].copy()

    # -- initial state ----------------------------------------------------------------
    def set_initial_state(self, natural_twist: float = 0.0) -> float:
        """State at t = 0+ from rest (phi = 0, u_d = natural_twist) at t = 0-.

        An idealised step at t = 0 is resolved exactly: with mu > 0 the rod's response
        to a rotation step is the viscous one, d/ds(mu d(dphi)/ds) = 0, and the end
        torsion carries the impulse int_0^1 mu dphi_s ds * delta(t) (mu u0 delta(t) in
        eq. stressrelax); that impulse is returned, and the time series starts at 0+.
        A torsion step moves nothing when mu > 0 or nu > 0.  With mu = nu = 0 the twist
        is algebraic and the state at 0+ is the elastic equilibrium with u_d frozen.
        Rates start at zero.
        """
        for f in self.problem.fields + self.problem.rates:
            f.x.array[:] = 0.0
        self.u_d.x.array[:] = natural_twist
        if self.dynamic:
            return 0.0
        V = self.phi.function_space
        phi, eta = ufl.TrialFunction(V), ufl.TestFunction(V)
        dx = ufl.Measure("dx", domain=self.mesh)
        if self.viscous:
            if self.end_rotation is None or _jump(self.end_rotation) == 0.0:
                return 0.0
            a = self.coefficients["mu"] * phi.dx(0) * eta.dx(0) * dx
            L = fem.Constant(self.mesh, 0.0) * eta * dx
        else:
            self.problem.set_loads(0.0)
            a = self.coefficients["alpha"] * phi.dx(0) * eta.dx(0) * dx
            L = self.coefficients["alpha"] * self.u_d * eta.dx(0) * dx
            if self.m_applied is not None:
                L += self.m_applied * eta * self.ds_end
            if self._couple is not None:
                L += self._couple * eta * dx
        self._set_bcs(0.0)
        bcs = [bc for bc in self.problem.bcs if compat.contains(V, bc)]
        solver = compat.linear_problem(a, L, bcs, self.phi, {
            "ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"})
        solver.solve()
        if self.viscous:  # the impulse of the end torsion: int mu dphi_s ds
            return self.mesh.comm.allreduce(
                fem.assemble_scalar(fem.form(self.coefficients["mu"] * self.phi.dx(0) * dx)),
                op=MPI.SUM)
        return 0.0


def _jump(history: Callable) -> float:
    """history(0+) - history(0-) for LoadHistory objects; plain callables: h(0) - 0."""
    if hasattr(history, "left_limit"):
        return float(load_histories.jump_at(history, 0.0))
    return float(history(0.0))
