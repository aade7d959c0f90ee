"""One-step and two-step schemes as coefficient tables on F(t, y, dy/dt) = 0.

A stage evaluates the residual at
    Y    = a0 y + a1 y_n + a2 y_{n-1}
    Ydot = (b0 y + b1 y_n + b2 y_{n-1}) / dt + g ydot_n
    t    = t_n + c dt
and a step solves sum_k w_k F(t_k, Y_k, Ydot_k) = 0 for y = y_{n+1}.  After the step
ydot_{n+1} = (r0 y + r1 y_n + r2 y_{n-1}) / dt + rg ydot_n is stored (diagnostics and
the schemes that carry the rate).  Constant dt is assumed by the two-step formulas;
the integrator restarts them with their ``startup`` scheme after a step change.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Stage:
    w: float
    c: float
    a: tuple[float, float, float]
    b: tuple[float, float, float]
    g: float = 0.0

    def state(self, y, y_n, y_nm1):
        """Y = a0 y + a1 y_n + a2 y_{n-1} (UFL expressions or arrays)."""
        return self.a[0] * y + self.a[1] * y_n + self.a[2] * y_nm1

    def rate(self, y, y_n, y_nm1, ydot_n, dt):
        """Ydot = (b0 y + b1 y_n + b2 y_{n-1}) / dt + g ydot_n."""
        return (self.b[0] * y + self.b[1] * y_n + self.b[2] * y_nm1) / dt + self.g * ydot_n


@dataclass(frozen=True)
class Scheme:
    name: str
    order: int
    stages: tuple[Stage, ...]
    rate: tuple[float, float, float, float]  # r0, r1, r2, rg
    explicit: bool = False
    l_stable: bool = False
    startup: str | None = None  # first step (two-step schemes, and those carrying ydot_n)
    second: str | None = None   # second step, if it differs (a rate rule that needs ydot_n)

    def for_step(self, history: int, same_step: bool = True) -> "Scheme":
        """The scheme of the next step after ``history`` accepted steps (0: first step,
        or a restart): the startup scheme on the first, the second-step scheme (if any)
        on the second, this one after that; ``same_step`` False (the step's size differs
        from the last one's: a cut, a clipped final step) restarts one that reads
        y_{n-1} (its constant-dt formula would take y_{n-1} at the wrong time)."""
        if history == 0 and self.startup:
            return get_scheme(self.startup)
        chosen = get_scheme(self.second) if history == 1 and self.second else self
        return self.for_step(0) if chosen.uses_previous and not same_step else chosen

    @property
    def uses_previous(self) -> bool:
        """The step or its rate rule reads y_{n-1}: valid only after a step of the same
        size (constant-dt formulas), else the integrator restarts (``startup``)."""
        return self.rate[2] != 0 or any(st.a[2] or st.b[2] for st in self.stages)

    def rate_after_step(self, y, y_n, y_nm1, ydot_n, dt):
        """ydot_{n+1} = (r0 y + r1 y_n + r2 y_{n-1}) / dt + rg ydot_n (arrays)."""
        r0, r1, r2, rg = self.rate
        return (r0 * y + r1 * y_n + r2 * y_nm1) / dt + rg * ydot_n


def generalized_alpha(rho_inf: float = 0.5) -> Scheme:
    """Jansen-Whiting-Hulbert generalized-alpha for first-order systems.

    alpha_m = (3 - rho)/(2(1 + rho)), alpha_f = 1/(1 + rho), gamma = 1/2 + alpha_m -
    alpha_f: second order, unconditionally stable, high-frequency damping rho_inf.
    """
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf))
    af = 1.0 / (1.0 + rho_inf)
    gm = 0.5 + am - af
    k = am / gm
    return Scheme(
        name=f"generalized_alpha(rho_inf={rho_inf:g})", order=2,
        stages=(Stage(1.0, af, (af, 1.0 - af, 0.0), (k, -k, 0.0), 1.0 - k),),
        rate=(1.0 / gm, -1.0 / gm, 0.0, -(1.0 - gm) / gm),
        l_stable=rho_inf == 0.0,
        startup="backward_euler")  # rates start at 0: one BE step makes ydot_1 O(dt)-exact


# Rates after a step of the one-step second-order rules (their steps do not use ydot_n).
# From the third step on, the trapezoidal recurrence ydot_{n+1} = 2 (y_{n+1} - y_n)/dt
# - ydot_n: it keeps F(t_{n+1}, y_{n+1}, ydot_{n+1}) = -F(t_n, y_n, ydot_n) for the
# trapezoidal rule, so an inconsistent ydot_n is carried for ever as (-1)^n times its
# defect, and it cannot start from ydot_0 (0 after a step load: the 0+ rate is unknown
# to a FE model; issue 13 item 6).  It starts instead from (y_1 - y_0)/dt after the
# first step (O(dt) at t_1) and the derivative at t_2 of the quadratic through y_0, y_1,
# y_2 (BDF2_RATE, O(dt^2)) after the second, whose O(dt^2) defect it then carries.
RECURRENCE_RATE = (2.0, -2.0, 0.0, -1.0)
BDF2_RATE = (1.5, -2.0, 0.5, 0.0)
FIRST_STEP_RATE = (1.0, -1.0, 0.0, 0.0)
MIDPOINT = (Stage(1.0, 0.5, (0.5, 0.5, 0), (1, -1, 0)),)
TRAPEZOIDAL = (Stage(0.5, 1.0, (1, 0, 0), (1, -1, 0)), Stage(0.5, 0.0, (0, 1, 0), (1, -1, 0)))

SCHEMES: dict[str, Scheme] = {
    s.name: s for s in (
        Scheme("backward_euler", 1, (Stage(1.0, 1.0, (1, 0, 0), (1, -1, 0)),),
               rate=FIRST_STEP_RATE, l_stable=True),
        Scheme("bdf2", 2, (Stage(1.0, 1.0, (1, 0, 0), (1.5, -2.0, 0.5)),),
               rate=BDF2_RATE, l_stable=True, startup="backward_euler"),
        Scheme("implicit_midpoint", 2, MIDPOINT, rate=RECURRENCE_RATE,
               startup="implicit_midpoint_first_step", second="implicit_midpoint_second_step"),
        Scheme("implicit_midpoint_first_step", 2, MIDPOINT, rate=FIRST_STEP_RATE),
        Scheme("implicit_midpoint_second_step", 2, MIDPOINT, rate=BDF2_RATE),
        Scheme("crank_nicolson", 2, TRAPEZOIDAL, rate=RECURRENCE_RATE,
               startup="crank_nicolson_first_step", second="crank_nicolson_second_step"),
        Scheme("crank_nicolson_first_step", 2, TRAPEZOIDAL, rate=FIRST_STEP_RATE),
        Scheme("crank_nicolson_second_step", 2, TRAPEZOIDAL, rate=BDF2_RATE),
        Scheme("explicit_euler", 1, (Stage(1.0, 0.0, (0, 1, 0), (1, -1, 0)),),
               rate=(1, -1, 0, 0), explicit=True),
    )
}


def alpha_rho_inf(name: str) -> float:
    """rho_inf of 'generalized_alpha' (0.5) or 'generalized_alpha:RHO'; ValueError else."""
    _, colon, rho = name.partition(":")
    try:
        rho_inf = float(rho) if colon else 0.5
    except ValueError:
        rho_inf = None
    if name != "generalized_alpha" + colon + rho or rho_inf is None \
            or not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"unknown time scheme '{name}': write generalized_alpha or "
                         "generalized_alpha:RHO with rho_inf = RHO a number in [0, 1]")
    return rho_inf


def get_scheme(name: str) -> Scheme:
    """A scheme by name; 'generalized_alpha' or 'generalized_alpha:0.3' sets rho_inf."""
    if name.startswith("generalized_alpha"):
        return generalized_alpha(alpha_rho_inf(name))
    try:
        return SCHEMES[name]
    except KeyError:
        known = ", ".join([*SCHEMES, "generalized_alpha[:rho_inf]"])
        raise ValueError(f"unknown time scheme '{name}' (known: {known})") from None
