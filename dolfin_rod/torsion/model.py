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

from .. import loads as load_histories
from ..checks import DEGREE, N_CELLS, VARIANT, check_n_cells, profile_violation, sample_points
from ..fem import compat, form_cache
from ..fem.fe_model import FEModel, end_measures, scalar_coefficient, vertex_measure
from ..fem.problem import SecondOrderProblem, SemiDiscreteProblem, TimeDependentValue
from ..fem.solvers import default_lu
from ..theory.dissipation import dissipation_rate
from ..theory.energy import derivatives, quadratic_energy
from ..theory.evolution import check_variant, evolution_residual, real_space

Coefficient = float | Callable
NAMES = ("twist_angle", "natural_twist", "angular_velocity")


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
        s = sample_points(1.0)
        for name in ("alpha", "alpha_d", "mu_d", "mu", "nu"):
            value = getattr(self, name)
            reason = profile_violation(value(s) if callable(value) else value, s,
                                       strict=name not in ("mu", "nu"))
            if reason:
                raise ValueError(f"{name} {reason}")
        if variant == "uniform" and callable(self.mu_d):
            raise ValueError("mu_d must be a constant for the uniform variant "
                             "(M_d is one tensor for the whole rod, eq. unatevolunif)")

    def is_zero(self, name: str) -> bool:
        value = getattr(self, name)
        return (not callable(value)) and value == 0.0


class TorsionModel(FEModel):
    """The isolated-torsion rod as a SemiDiscreteProblem (see module docstring).

    Exactly one of ``end_torsion`` (applied m(t)) and ``end_rotation`` (prescribed
    Phi(t)) is given; both are load histories (dolfin_rod.loads) or plain callables.
    """

    def __init__(self, params: TorsionParameters, n_cells: int = N_CELLS, variant: str = VARIANT,
                 end_torsion: Callable | None = None, end_rotation: Callable | None = None,
                 degree: int = DEGREE, comm: MPI.Comm = MPI.COMM_WORLD):
        self._validate(params, n_cells, variant, end_torsion, end_rotation, degree, comm.size)
        self.params, self.variant, self.degree = params, variant, degree
        self.end_torsion, self.end_rotation = end_torsion, end_rotation
        self.dynamic = not params.is_zero("nu")
        self.viscous = not params.is_zero("mu")
        super().__init__(dolfinx.mesh.create_unit_interval(comm, n_cells))
        s = ufl.SpatialCoordinate(self.mesh)[0]
        self.coefficients = {n: scalar_coefficient(getattr(params, n), self.mesh, s)
                             for n in ("alpha", "alpha_d", "mu", "mu_d", "nu")}
        self._couple = None if params.couple is None else params.couple(s)
        self.ds_end = end_measures(self.mesh, 1.0)["end"]   # the end s = 1
        self._fields()
        F, self.loads = self._residual(ufl.Measure("dx", domain=self.mesh))
        self._dirichlet_conditions()
        self.problem = SemiDiscreteProblem(self.fields, self.rates, F, self.loads, self.bcs,
                                           self._set_bcs)
        if self.dynamic and self.end_rotation is not None:     # (integrators' check_run)
            self.problem.prescribed_motions = {"end_rotation": self.end_rotation}
        self._diagnostic_forms(ufl.Measure("dx", domain=self.mesh))

    @staticmethod
    def _validate(params, n_cells, variant, end_torsion, end_rotation, degree, ranks):
        check_variant(variant)
        params.validate(variant)
        if (end_torsion is None) == (end_rotation is None):
            raise ValueError("give exactly one of end_torsion (applied torsion m(t)) and "
                             "end_rotation (prescribed Phi(t)) at s = 1")
        check_n_cells(n_cells, ranks)
        if degree not in (1, 2, 3):
            raise ValueError(f"degree must be 1, 2 or 3, got {degree!r}")
        jumps = [] if end_rotation is None else [t for t, size in getattr(
            end_rotation, "jumps", ()) if size] + ([0.0] if _jump(end_rotation) else [])
        if not params.is_zero("nu") and jumps:
            raise ValueError(f"end_rotation has a step at t = {min(jumps):g} but nu > 0: a "
                             "rod with inertia cannot follow a jump in rotation; use "
                             "loads.smooth_step or loads.ramp")

    def _fields(self) -> None:
        """phi in P_k, u_d in DG_{k-1} (local) or a real space (uniform), w in P_k.
        Blocked assembly finds a condition's block by its space object, hence w's own space."""
        mesh, k = self.mesh, self.degree
        spaces = [fem.functionspace(mesh, ("Lagrange", k)),
                  real_space(mesh) if self.variant == "uniform"
                  else fem.functionspace(mesh, ("DG", k - 1))]
        if self.dynamic:
            spaces.append(fem.functionspace(mesh, ("Lagrange", k)))
        self.spaces = dict(zip(NAMES, spaces))
        self.fields = [fem.Function(S, name=n) for n, S in self.spaces.items()]
        self.rates = [fem.Function(S, name=f"{n}_rate") for n, S in self.spaces.items()]
        self.phi, self.u_d = self.fields[0], self.fields[1]
        self.w = self.fields[2] if self.dynamic else self.rates[0]   # angular velocity phi_t

    def _residual(self, dx):
        """Eqs. phieq and upeq (or errata 1), and phi_t = w at the vertices."""
        c, w = self.coefficients, self.w
        eta, zeta, *w_test = [ufl.TestFunction(S) for S in self.spaces.values()]
        u = self.phi.dx(0)                              # twist u = phi_s
        psi_fn = quadratic_energy(c["alpha"], c["alpha_d"])
        self.psi, dpsi_du, _, self.dpsi_dud, _ = derivatives(psi_fn, self.u_d, None, u, None)
        self.torsion = dpsi_du + c["mu"] * w.dx(0)      # m = dpsi/du + M du/dt (eq. mconsteq)
        loads: list[TimeDependentValue] = []
        F_phi = self.torsion * eta.dx(0) * dx
        if self.dynamic:
            F_phi += c["nu"] * self.rates[2] * eta * dx
        if self._couple is not None:
            l_t = fem.Constant(self.mesh, 0.0)
            loads.append(TimeDependentValue(l_t, self.params.couple_history))
            self._couple = self._couple * l_t
            F_phi -= self._couple * eta * dx
        self.m_applied = None
        if self.end_torsion is not None:
            self.m_applied = fem.Constant(self.mesh, 0.0)
            loads.append(TimeDependentValue(self.m_applied, self.end_torsion))
            F_phi -= self.m_applied * eta * self.ds_end
        F = [F_phi, evolution_residual(c["mu_d"], self.rates[1], self.dpsi_dud, zeta,
                                       self.variant, 1.0, dx)]
        if self.dynamic:  # phi_t = w at the vertices (lumped kinematic equation)
            F.append((self.rates[0] - w) * w_test[0] * vertex_measure(self.mesh))
        return F, loads

    def _dirichlet_conditions(self) -> None:
        """phi(0) = 0, phi(1) = Phi(t); w(0) = 0, w(1) = Phi'(t)."""
        self._end_values = {}
        for name in ("twist_angle", "angular_velocity")[:1 + self.dynamic]:
            S = self.spaces[name]
            self.dirichlet(name, S, "start", 1.0, fem.Constant(self.mesh, 0.0))
            if self.end_rotation is not None:
                self._end_values[name] = fem.Constant(self.mesh, 0.0)
                self.dirichlet(name, S, "end", 1.0, self._end_values[name])

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
        bcs = self.bcs_of("twist_angle")

        def sync():
            w.x.array[:] = phi_t.x.array
            p.rates[2].x.array[:] = phi_tt.x.array

        return SecondOrderProblem(
            p.fields[:2], p.rates[:2], [ufl.replace(F, mapping) for F in p.residual[:2]],
            p.loads, bcs, p.set_bcs, accelerations=[phi_tt, u_d_tt], after_step=sync,
            prescribed_motions=p.prescribed_motions)

    # -- time-dependent boundary values ----------------------------------------------
    def _set_bcs(self, t: float) -> None:
        if self.end_rotation is not None:
            self._end_values["twist_angle"].value = float(self.end_rotation(t))
            if self.dynamic:
                self._end_values["angular_velocity"].value = float(
                    load_histories.rate(self.end_rotation, t))

    # -- diagnostics ------------------------------------------------------------------
    def _diagnostic_forms(self, dx) -> None:
        s_fn = fem.Function(self.phi.function_space)
        s_fn.interpolate(lambda x: x[0])  # test function s: the end reaction (see reaction)
        c, w, rates = self.coefficients, self.w, self.rates
        self.xi = dissipation_rate([(w.dx(0), c["mu"])], [(rates[1], self.dpsi_dud)])
        reaction = self.torsion * dx
        if self.dynamic:
            reaction += c["nu"] * rates[2] * s_fn * dx
        if self._couple is not None:
            reaction -= self._couple * s_fn * dx
        forms = {
            "end_rotation": self.phi * self.ds_end,
            "end_rotation_rate": w * self.ds_end,
            "free_energy": self.psi * dx,
            "kinetic_energy": 0.5 * c["nu"] * w * w * dx,
            "dissipation_rate": self.xi * dx,
            "mean_natural_twist": self.u_d * dx,
            "reaction_torsion": reaction,
        }
        if self._couple is not None:
            forms["couple_power"] = self._couple * w * dx
        self.set_diagnostic_forms(forms)

    def diagnostics(self, t: float) -> dict[str, float]:
        """Scalars at time t from the current state and rate estimates.

        end_torsion is the applied m(t) or, under a prescribed rotation, the reaction
        int [m + nu phi_tt s - l s] ds (the discrete residual tested with eta = s).
        """
        d = self.assembled_diagnostics(t)
        reaction = d.pop("reaction_torsion")
        d["end_torsion"] = reaction if self.end_torsion is None else float(self.end_torsion(t))
        d["load_power"] = d["end_torsion"] * d["end_rotation_rate"] + d.pop("couple_power", 0.0)
        return d

    def observables(self) -> dict:
        """What a reader of Section 5 looks at, as UFL expressions of the current state:
        twist angle phi, twist u = phi_s, natural twist u_d, torsion m (eq. mconsteq) and
        dissipation rate xi.  Used by the run outputs (line_fields.py)."""
        return {"phi": self.phi, "u": self.phi.dx(0), "u_d": self.u_d, "m": self.torsion,
                "xi": self.xi}

    def pointwise_dissipation(self) -> np.ndarray:
        """xi at the cell midpoints (owned cells) for the current state and rates."""
        return self.pointwise(self.xi)[:, 0].copy()

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
        bcs = self.bcs_of("twist_angle")
        solver = compat.linear_problem(a, L, bcs, self.phi, {
            "ksp_type": "preonly", "pc_type": "lu",
            "pc_factor_mat_solver_type": default_lu(self.mesh.comm)})
        solver.solve()
        if self.viscous:  # the impulse of the end torsion: int mu dphi_s ds
            return self.mesh.comm.allreduce(
                fem.assemble_scalar(form_cache.jit_form(self.coefficients["mu"] * self.phi.dx(0) * dx)),
                op=MPI.SUM)
        return 0.0


def _jump(history: Callable) -> float:
    """history(0+) - history(0-) for LoadHistory objects; plain callables: h(0) - 0."""
    if hasattr(history, "left_limit"):
        return float(load_histories.jump_at(history, 0.0))
    return float(history(0.0))
