"""The model "ode" of a scene: quasi-static homogeneous torsion (eqs. ``twist``, ``nattwist``),

    mu u' + alpha (u - u_d) = m(t),          mu_d u_d' = alpha u - (alpha + alpha_d) u_d,

with u = Phi(t) prescribed instead when the end rotation is given (phi = Phi s, so
phi(1) = u).  ``ode_solution = "exact"``: the closed forms of closed_forms.py for steps
at t = 0 from rest, otherwise scipy ``solve_ivp`` (Radau, stiff) between the load's
breakpoints.  ``ode_solution = "scheme"``: the FE model's time scheme applied to the
same 2x2 system (coefficient tables of integrators.schemes, the TimeStepper's startup
and rate rules), so that ODE and PDE agree to solver tolerance, not only to O(dt^p).
Built from numbers (scenes/builders.py reads them from a scene).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..checks import ODE_SOLUTION, SCHEME
from ..integrators.schemes import get_scheme
from ..integrators.step_control import output_times, same_step
from ..loads import rate as load_rate
from . import closed_forms

__all__ = ["OdeTorsion", "EndCondition", "OdeTime"]


@dataclass(frozen=True)
class EndCondition:
    """The end s = 1: its rotation (``rotation``) or its torsion prescribed by
    ``history`` (None: a free, unloaded end); ``step_at_start`` the size of a step at
    t = 0 (then the closed forms apply from rest), ``breakpoints`` the times where the
    history is not smooth."""

    rotation: bool
    history: Callable | None = None
    step_at_start: float | None = None
    breakpoints: tuple[float, ...] = ()


@dataclass(frozen=True)
class OdeTime:
    """The output times (every dt up to t_end), solve_ivp's tolerances, the solution
    ("exact" or "scheme") and the scheme's name (integrators/schemes.py)."""

    t_end: float
    dt: float
    rtol: float
    atol: float
    solution: str = ODE_SOLUTION
    scheme: str = SCHEME


class OdeTorsion:
    """Eqs. ``twist``/``nattwist`` for a prescribed end torsion or end rotation."""

    name = "ode"
    fields: list = []

    def __init__(self, alpha: float, alpha_d: float, mu: float, mu_d: float,
                 end: EndCondition, time: OdeTime, natural_twist: float = 0.0, comm=None):
        from mpi4py import MPI
        self.comm = comm or MPI.COMM_WORLD
        self.alpha, self.alpha_d, self.mu, self.mu_d = alpha, alpha_d, mu, mu_d
        self.u_d0 = natural_twist
        self.rotation, self.end = end.rotation, end
        self.history = end.history
        self.t_end, self.dt = time.t_end, time.dt
        self.rtol, self.atol = time.rtol, time.atol
        self.mode = time.solution
        self.scheme = get_scheme(time.scheme)
        self.method = ""

    # load values
    def _load(self, t: float) -> float:
        return 0.0 if self.history is None else float(self.history(t))

    def _load_rate(self, t: float) -> float:
        """Phi'(t), as the torsion PDE's end condition on w."""
        return 0.0 if self.history is None else float(load_rate(self.history, t))

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
        self.history_steps, self.last_step = 0, None
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
        self.times = np.array(output_times(self.t_end, self.dt))
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        step, t = self.end.step_at_start, self.times
        closed = step is not None and self.u_d0 == 0.0
        if closed and self.rotation:
            u0 = step
            ud, m = closed_forms.relaxation(t, u0, a, ad, mud)
            u = np.full_like(t, u0)
            self.method = "closed form: closed_forms.relaxation (eq. stressrelax)"
        elif closed and mu > 0.0:
            u, ud = closed_forms.creep(t, step, a, ad, mu, mud)
            self.method = "closed form: closed_forms.creep (eq. creepform, errata 2)"
        elif closed:
            u, ud = closed_forms.creep_inviscid(t, step, a, ad, mud)
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
        breaks = sorted({0.0, self.t_end,
                         *[b for b in self.end.breakpoints if 0.0 < b < self.t_end]})
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
        scheme = self.scheme.for_step(self.history_steps, same_step(dt, self.last_step))
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
        self.history_steps, self.last_step = min(self.history_steps + 1, 2), dt

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
        k = self._index(t)
        u, ud = self.u_series[k], self.ud_series[k]
        return (u, ud, *self._rates(u, ud, self._load(t), self._load_rate(t)))

    def _rates(self, u, ud, load, load_rate):
        """u' and u_d' (eqs. twist, nattwist) of states and loads (numbers or arrays)."""
        a, ad, mu, mud = self.alpha, self.alpha_d, self.mu, self.mu_d
        ud_t = (a * u - (a + ad) * ud) / mud
        if self.rotation:
            u_t = load_rate
        elif mu > 0.0:
            u_t = (load - a * (u - ud)) / mu
        else:
            u_t = load_rate / a + ud_t
        return u_t, ud_t

    def _index(self, t: float) -> int:
        """The output time t's index: a bisection, O(log N) (an argmin over all output
        times made a run O(N^2)); ValueError for a time off the output grid."""
        k = min(int(np.searchsorted(self.times, t - 1e-9 * self.dt)), len(self.times) - 1)
        if abs(self.times[k] - t) > 1e-9 * self.dt:
            raise ValueError(f"t = {t!r} is not an output time (multiples of dt = {self.dt:g})")
        return k

    def diagnostics(self, t: float) -> dict[str, float]:
        with np.errstate(over="ignore", invalid="ignore"):   # overflow -> inf, as in FE
            u, ud, u_t, ud_t = (np.float64(x) for x in self._state_at(t))
            d = self._quantities(t, u, ud, u_t, ud_t, np.float64(self._load(t)))
        return {k: float(v) for k, v in d.items()}

    def series(self) -> dict[str, np.ndarray] | None:
        """Every diagnostic at every output time at once (arrays; the closed forms and
        solve_ivp only: a fit of 1e5 samples without a Python step loop), or None (the
        scheme, which steps)."""
        if self.mode == "scheme":
            return None
        t = self.times
        if self.history is None:
            load = rate = np.zeros_like(t)
        else:                              # (histories take arrays of times)
            load = np.asarray(self.history(t), float)
            rate = np.asarray(load_rate(self.history, t), float)
        with np.errstate(over="ignore", invalid="ignore"):
            u, ud = self.u_series, self.ud_series
            return self._quantities(t, u, ud, *self._rates(u, ud, load, rate), load)

    def _quantities(self, t, u, ud, u_t, ud_t, load) -> dict:
        """The diagnostics of states, rates and loads (numbers or arrays)."""
        a, ad, mu = self.alpha, self.alpha_d, self.mu
        m = a * (u - ud) + mu * u_t if self.rotation else load
        return {"end_rotation": u, "end_rotation_rate": u_t,
                "free_energy": 0.5 * a * (u - ud) ** 2 + 0.5 * ad * ud ** 2,
                "kinetic_energy": 0.0 * u,   # eq. disspw: xi = mu u'^2 - dpsi/du_d u_d'
                "dissipation_rate": mu * u_t ** 2 + (a * (u - ud) - ad * ud) * ud_t,
                "mean_natural_twist": ud, "time": t, "end_torsion": m,
                "load_power": m * u_t}

    def state(self) -> dict:
        return {"y": self.y.tolist(), "y_nm1": self.y_nm1.tolist(), "ydot": self.ydot.tolist(),
                "history_steps": self.history_steps, "last_step": self.last_step}

    def restore(self, state: dict) -> None:
        self.y, self.y_nm1 = np.array(state["y"]), np.array(state["y_nm1"])
        self.ydot, self.history_steps = np.array(state["ydot"]), int(state["history_steps"])
        self.last_step = state.get("last_step")

    def describe(self) -> str:
        return self.method
