"""Scene -> running model: a registry of builders, one per model name.

Every built model is a :class:`Simulation`: ``start()`` puts it at t0 (returns the end
torsion impulse of an idealised step, eq. ``stressrelax``), ``advance(t, t_next)``
integrates one output interval, ``diagnostics(t)`` gives the scalars of
``TorsionModel.diagnostics`` (same keys for every model), ``fields`` the FE functions
to write (none for the ODE), ``state()``/``restore(...)`` what a checkpoint needs.

The ODE model of quasi-static homogeneous torsion (eqs. ``twist``, ``nattwist``) is here:

    mu u' + alpha (u - u_d) = m(t),          mu_d u_d' = alpha u - (alpha + alpha_d) u_d,

with u = Phi(t) prescribed instead when the end rotation is given (phi = Phi s, so
phi(1) = u).  ``ode_solution = "exact"``: the closed forms of closed_forms.py for steps
at t = 0 from rest, otherwise scipy ``solve_ivp`` (Radau, stiff) between the load's
breakpoints.  ``ode_solution = "scheme"``: the FE model's time scheme applied to the
same 2x2 system (coefficient tables of integrators.schemes, the TimeStepper's startup
and rate rules), so that ODE and PDE agree to solver tolerance, not only to O(dt^p).
"""

from __future__ import annotations

import math
from typing import Callable, Protocol

import numpy as np

from .. import closed_forms
from ..integrators.schemes import get_scheme
from .schema import Scene, SceneError

__all__ = ["Simulation", "MODELS", "register_model", "build", "OdeTorsion", "FESimulation"]


class Simulation(Protocol):
    name: str
    fields: list
    comm: object

    def start(self) -> float: ...
    def advance(self, t: float, t_next: float) -> None: ...
    def diagnostics(self, t: float) -> dict[str, float]: ...
    def state(self) -> dict: ...
    def restore(self, state: dict) -> None: ...


MODELS: dict[str, Callable[[Scene], Simulation]] = {}


def register_model(name: str):
    """Decorator: ``@register_model("rod")`` makes ``build`` dispatch the name to it."""
    def wrap(builder):
        MODELS[name] = builder
        return builder
    return wrap


def build(scene: Scene, model: str, comm=None) -> Simulation:
    if model not in MODELS:
        raise scene.error("scene.model", f"no builder registered for model {model!r} "
                                         f"(registered: {', '.join(MODELS)})")
    try:
        return MODELS[model](scene, comm)
    except SceneError:
        raise
    except (ValueError, TypeError) as err:   # a model's own validation (architecture.md)
        raise scene.error("scene.model", f"the {model!r} model rejected the scene: {err}") from err


# --- the ODE of quasi-static homogeneous torsion -------------------------------------------


class OdeTorsion:
    """Eqs. ``twist``/``nattwist`` for a prescribed end torsion or end rotation."""

    name = "ode"
    fields: list = []

    def __init__(self, scene: Scene, comm=None):
        from mpi4py import MPI
        self.comm = comm or MPI.COMM_WORLD
        mat = scene["material"]
        self.alpha, self.alpha_d = mat["alpha"].constant, mat["alpha_d"].constant
        self.mu, self.mu_d = mat["mu"].constant, mat["mu_d"].constant
        self.u_d0 = scene["geometry"]["reference_twist"]
        self.rotation = scene["boundary"]["end"] == "rotation"
        spec = scene["boundary"]["end_rotation"] if self.rotation else scene["loads"]["end_torsion"]
        self.spec = spec
        self.history = spec.build() if spec is not None else None   # None: free, unloaded end
        self.t_end, self.dt = scene["time"]["t_end"], scene["time"]["dt"]
        self.rtol, self.atol = scene["time"]["rtol"], scene["time"]["atol"]
        self.mode = scene["time"]["ode_solution"]
        self.scheme = get_scheme(scene["time"]["scheme"])
        self.method = ""

    # load values
    def _load(self, t: float) -> float:
        return 0.0 if self.history is None else float(self.history(t))

    def _load_rate(self, t: float) -> float:
        """Phi'(t) by central differences (as TorsionModel._set_bcs)."""
        h = 1e-7 * max(1.0, abs(t))
        return (self._load(t + h) - self._load(t - h)) / (2 * h)

    def _jump0(self) -> float:
        if self.history is None:
            return 0.0
        return float(self.history(0.0) - self.history.left_limit(0.0))

    def start(self) -> float:
        """State at 0+ as TorsionModel.set_initial_state; returns the torsion impulse."""
        a, mu = self.alpha, self.mu
        impulse = 0.0
        if self.rotation:
            u = self._load(0.0) if (mu == 0.0 or self._jump0() != 0.0) else 0.0
            impulse = mu * u if mu > 0.0 else 0.0
        else:
            u = 0.0 if mu > 0.0 else self.u_d0 + self._load(0.0) / a
        self.y = np.array([u, self.u_d0])
        self.ydot = np.zeros(2)
        self.y_nm1 = self.y.copy()
        self.history_ok = False
        if self.mode == "exact":
            self._solve_exact()
        self.impulse = impulse
        return impulse

    # -- exact: closed forms or solve_ivp ----------------------------------------------
    def _rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """(u', u_d') from eqs. twist, nattwist (y = (u, u_d) or (u_d,) when u is algebraic)."""
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        if self.rotation:
            u, ud = self._load(t), y[-1]
            return np.array([self._load_rate(t), (a * u - (a + ad) * ud) / mud])
        if mu == 0.0:   # u = m/alpha + u_d algebraic
            ud = y[-1]
            return np.array([np.nan, (self._load(t) - ad * ud) / mud])
        u, ud = y
        return np.array([(self._load(t) - a * (u - ud)) / mu, (a * u - (a + ad) * ud) / mud])

    def _solve_exact(self) -> None:
        from scipy.integrate import solve_ivp
        n = max(1, math.ceil(self.t_end / self.dt - 1e-9))
        self.times = np.minimum(np.arange(n + 1) * self.dt, self.t_end)
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        spec, t = self.spec, self.times
        closed = (spec is not None and spec.jumps_at_start and self.u_d0 == 0.0)
        if closed and self.rotation:
            u0 = spec.value
            ud, m = closed_forms.relaxation(t, u0, a, ad, mud)
            u = np.full_like(t, u0)
            self.method = "closed form: closed_forms.relaxation (eq. stressrelax)"
        elif closed and mu > 0.0:
            u, ud = closed_forms.creep(t, spec.value, a, ad, mu, mud)
            self.method = "closed form: closed_forms.creep (eq. creepform, errata 2)"
        elif closed:
            u, ud = closed_forms.creep_inviscid(t, spec.value, a, ad, mud)
            self.method = "closed form: closed_forms.creep_inviscid (errata 3)"
        else:
            u, ud = self._solve_ivp(solve_ivp)
            self.method = "scipy solve_ivp (Radau, stiff) between the load's breakpoints"
        u, ud = np.asarray(u, float), np.asarray(ud, float)
        if self.rotation and not closed:
            u = np.array([self._load(s) for s in t])
        if not self.rotation and mu == 0.0:
            u = np.array([self._load(s) for s in t]) / a + ud
        self.u_series, self.ud_series = u, ud

    def _solve_ivp(self, solve_ivp):
        t = self.times
        algebraic = self.rotation or self.mu == 0.0
        y = np.array([self.y[1]]) if algebraic else self.y.copy()
        breaks = sorted({0.0, self.t_end, *[b for b in (self.spec.breakpoints() if self.spec
                                                          else ()) if 0.0 < b < self.t_end]})
        out = np.empty((len(t), len(y)))
        out[0] = y
        rhs = lambda s, z: self._rhs(s, z)[-len(z):]   # noqa: E731
        for lo, hi in zip(breaks[:-1], breaks[1:]):
            sol = solve_ivp(rhs, (lo, hi), y, method="Radau", rtol=self.rtol, atol=self.atol,
                            dense_output=True, first_step=min(1e-6, (hi - lo) / 10))
            if not sol.success:
                raise RuntimeError(f"solve_ivp failed on [{lo:g}, {hi:g}]: {sol.message}")
            mask = (t > lo) & (t <= hi)
            if mask.any():
                out[mask] = sol.sol(t[mask]).T
            y = sol.y[:, -1]
        if algebraic:
            return np.zeros(len(t)), out[:, 0]
        return out[:, 0], out[:, 1]

    # -- scheme: the FE model's time discretisation on the 2x2 system ------------------
    def _matrices(self):
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        M = np.array([[mu, 0.0], [0.0, mud]])
        K = np.array([[a, -a], [-a, a + ad]])
        return M, K

    def _scheme_step(self, t: float, dt: float) -> None:
        """One step of the scheme (as TimeStepper's: same stages, startup and rate rule)
        on the linear system M y' + K y = f: J y = -r with r the residual at y = 0."""
        scheme = self.scheme.for_step(self.history_ok)
        M, K = self._matrices()
        y_n, y_nm1, ydot_n = self.y, self.y_nm1, self.ydot
        zero = np.zeros(2)
        J, r = np.zeros((2, 2)), np.zeros(2)
        for st in scheme.stages:
            f = np.array([0.0 if self.rotation else self._load(t + st.c * dt), 0.0])
            J += st.w * (M * st.b[0] / dt + K * st.a[0])
            r += st.w * (M @ st.rate(zero, y_n, y_nm1, ydot_n, dt)
                         + K @ st.state(zero, y_n, y_nm1) - f)
        if self.rotation:   # Dirichlet row: u = Phi(t_{n+1})
            J[0] = (1.0, 0.0)
            r[0] = -self._load(t + dt)
        y = np.linalg.solve(J, -r)
        self.ydot = scheme.rate_after_step(y, y_n, y_nm1, ydot_n, dt)
        self.y_nm1, self.y = y_n, y
        self.history_ok = True

    def advance(self, t: float, t_next: float) -> None:
        if self.mode == "scheme":
            self._scheme_step(t, t_next - t)
            self.method = f"the {self.scheme.name} scheme on the 2x2 system"
        self._t = t_next

    # -- outputs -------------------------------------------------------------------------
    def _state_at(self, t: float) -> tuple[float, float, float, float]:
        """u, u_d and their rates at t."""
        if self.mode == "scheme":
            return self.y[0], self.y[1], self.ydot[0], self.ydot[1]
        k = int(np.argmin(np.abs(self.times - t)))
        u, ud = self.u_series[k], self.ud_series[k]
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        ud_t = (a * u - (a + ad) * ud) / mud
        if self.rotation:
            u_t = self._load_rate(t)
        elif mu > 0.0:
            u_t = (self._load(t) - a * (u - ud)) / mu
        else:
            u_t = self._load_rate(t) / a + ud_t
        return u, ud, u_t, ud_t

    def diagnostics(self, t: float) -> dict[str, float]:
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        u, ud, u_t, ud_t = (float(x) for x in self._state_at(t))
        m = a * (u - ud) + mu * u_t if self.rotation else self._load(t)
        return {
            "end_rotation": u, "end_rotation_rate": u_t,
            "free_energy": 0.5 * a * (u - ud) ** 2 + 0.5 * ad * ud ** 2,
            "kinetic_energy": 0.0,
            "dissipation_rate": mu * u_t ** 2 + mud * ud_t ** 2,
            "mean_natural_twist": ud, "time": float(t), "end_torsion": float(m),
            "load_power": float(m) * u_t,
        }

    def state(self) -> dict:
        return {"y": self.y.tolist(), "y_nm1": self.y_nm1.tolist(), "ydot": self.ydot.tolist(),
                "history_ok": self.history_ok}

    def restore(self, state: dict) -> None:
        self.y, self.y_nm1 = np.array(state["y"]), np.array(state["y_nm1"])
        self.ydot, self.history_ok = np.array(state["ydot"]), bool(state["history_ok"])

    def describe(self) -> str:
        return self.method


register_model("ode")(OdeTorsion)


# --- FE models: torsion PDE and the 3-D rod ---------------------------------------------------


class FESimulation:
    """A model with ``.problem`` advanced by TimeStepper (or the PETSc TS integrator)."""

    def __init__(self, name: str, model, scene: Scene, initial_state: Callable[[], float]):
        from ..integrators.stepper import TimeStepper
        tim = scene["time"]
        self.name, self.model, self.scene = name, model, scene
        self.problem = model.problem
        self.comm = self.problem.comm
        self.fields = list(self.problem.fields)
        self._initial_state = initial_state
        options = {"snes_rtol": tim["rtol"], "snes_atol": tim["atol"]}
        self.stepper = TimeStepper(self.problem, tim["scheme"], options,
                                   max_cuts=tim["max_step_cuts"])
        self.integrator = tim["integrator"]
        self.ts = None
        if self.integrator == "ts":
            from ..integrators.ts import TSIntegrator
            self.ts = TSIntegrator(self.problem, ts_type(scene), solver_options=options)

    def run_all(self, t0: float, t_end: float, dt: float, on_step: Callable[[float], None]):
        """PETSc TS over the whole run (its multistep history must not restart at every
        output time); ``on_step(t)`` after each accepted step."""
        self.ts.run(t0, t_end, dt, observer=lambda t, _: on_step(t) if t > t0 else None)

    def start(self) -> float:
        return float(self._initial_state() or 0.0)

    def advance(self, t: float, t_next: float) -> None:
        self.stepper.run(t, t_next, t_next - t)

    def diagnostics(self, t: float) -> dict[str, float]:
        return self.model.diagnostics(t)

    def state(self) -> dict:
        """Functions a checkpoint stores (besides problem.fields) and the stepper flags."""
        return {"functions": {**{f"rate_{i}": r for i, r in enumerate(self.problem.rates)},
                              **{f"previous_{i}": p for i, p in enumerate(self.stepper.y_nm1)}},
                "history_ok": self.stepper.history_ok}

    def restore(self, state: dict) -> None:
        self.stepper.history_ok = bool(state["history_ok"])

    def describe(self) -> str:
        if self.ts is not None:
            return f"PETSc TS ({self.ts.method})"
        return f"TimeStepper with {self.stepper.scheme.name}"


def ts_type(scene: Scene) -> str:
    """The PETSc TS type (integrators.ts) of a scheme name of integrators.schemes."""
    name = scene["time"]["scheme"]
    if name.startswith("generalized_alpha"):
        return "alpha" + name[len("generalized_alpha"):]
    mapping = {"bdf2": "bdf:2", "backward_euler": "backward_euler",
               "crank_nicolson": "crank_nicolson", "implicit_midpoint": "implicit_midpoint"}
    if name not in mapping:
        raise scene.error("time.scheme", f"{name} has no PETSc TS counterpart "
                                         f"(use one of {', '.join(mapping)}, generalized_alpha)")
    return mapping[name]


@register_model("torsion")
def build_torsion(scene: Scene, comm=None) -> FESimulation:
    from mpi4py import MPI

    from ..torsion import TorsionModel, TorsionParameters
    mat, geo, lds = scene["material"], scene["geometry"], scene["loads"]
    kwargs = {}
    couple = lds["distributed_couple"]
    if couple is not None:
        profile = couple["profile"]
        kwargs["couple"] = (lambda s, c=profile.constant: c + 0.0 * s) if profile.is_constant \
            else profile
        kwargs["couple_history"] = couple["history"].build()
    params = TorsionParameters(**{k: mat[k].value() for k in ("alpha", "alpha_d", "mu", "mu_d",
                                                              "nu")}, **kwargs)
    if scene["boundary"]["end"] == "rotation":
        ends = {"end_rotation": scene["boundary"]["end_rotation"].build()}
    else:
        spec = lds["end_torsion"]
        ends = {"end_torsion": spec.build() if spec is not None else (lambda t: 0.0)}
    model = TorsionModel(params, n_cells=geo["n_cells"], variant=mat["variant"],
                         degree=geo["degree"], comm=comm or MPI.COMM_WORLD, **ends)
    return FESimulation("torsion", model, scene,
                        lambda: model.set_initial_state(geo["reference_twist"]))


@register_model("rod")
def build_rod(scene: Scene, comm=None) -> FESimulation:
    """The 3-D rod (dolfin_rod.rod.RodModel): clamped at s = 0, end loads at s = L."""
    from dataclasses import replace

    from mpi4py import MPI
    from ..rod import EndLoad, RodModel, RodParameters

    mat, geo, lds = scene["material"], scene["geometry"], scene["loads"]
    stiff, visc = mat["stiffness"], mat["viscosity"]
    kelvin_voigt = mat["energy"] == "kelvin_voigt"
    params = RodParameters(
        length=geo["length"], A=stiff["A"], B=stiff["B"], A_d=stiff["A_d"], B_d=stiff["B_d"],
        M=visc["M"] if any(visc["M"]) else None, N=visc["N"] if any(visc["N"]) else None,
        M_d=visc["M_d"], N_d=visc["N_d"], rho_A=mat["density"], I11=mat["section_inertia"],
        I22=mat["section_inertia"], reference_curvature=geo["reference_curvature"])
    end_loads = [EndLoad(kind, spec.value, replace(spec, value=1.0).build())
                 for kind, spec in (("force", lds["end_force"]), ("couple", lds["end_couple"]))
                 if spec is not None]
    constraint = None if mat["constraints"] == "none" else mat["constraints"]
    model = RodModel(params, n_cells=geo["n_cells"],
                     model="kelvin_voigt" if kelvin_voigt else "evolving",
                     variant=mat["variant"], constraint=constraint, ends=("clamped", "free"),
                     end_loads=end_loads, comm=comm or MPI.COMM_WORLD)
    return FESimulation("rod", model, scene, lambda: model.set_initial_state())
