"""What every integrator shares: argument checks, the clipping of the final step, the
step-cut and growth rules, the local-error step controller, the statistics and the error
of a run that stopped early.

TimeStepper (per-step schemes) drives its own loop with these rules; TSIntegrator hands
them to PETSc TS through its post-step callback (TS cuts a failed step itself, by
``ts_adapt_scale_solve_failed``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

from ..fem.solvers import SolverError
from ..loads import resolution_problem

# Relative round-off of a time summed from steps: a remaining interval below
# ROUND_OFF * dt is "at t_end", and a step within (1 + ROUND_OFF) of the remaining
# interval is clipped to it (no sliver step after it).
ROUND_OFF = 1e-9
CUT_FACTOR = 0.5      # TimeStepper: a failed step is retried with half the step
GROWTH_FACTOR = 2.0   # after a success the step grows back towards the nominal dt


class IntegrationError(RuntimeError):
    """The run stopped early; ``t`` is the last accepted time (its state is kept)."""

    def __init__(self, message: str, t: float):
        super().__init__(message)
        self.t = t


def load_path(solve: Callable[[float], None], max_cuts: int, unknowns: Sequence) -> None:
    """A static problem's loads approached on a load path, where Newton failed under all
    of them at once and a smaller step would not lessen them (a load constant in time is
    all on the start of a quasi-static run): ``solve(factor)`` solves with that part of
    them (0 < factor <= 1) from the last part's state in ``unknowns`` (Functions), or
    raises SolverError; a failed part's unknowns are set back to the last part's state
    here.  The first part is a half, the next twice as large after a success, half as
    large after a failure; SolverError when a part would be halved below
    1/2^(max_cuts + 1) of the loads."""
    done, part = 0.0, 0.5
    while done < 1.0:
        factor = min(done + part, 1.0)
        state = [u.x.array.copy() for u in unknowns]
        try:
            solve(factor)
        except SolverError:
            for u, array in zip(unknowns, state):
                u.x.array[:] = array
            part /= 2
            if part < 0.5 ** (max_cuts + 1):
                raise
            continue
        done, part = factor, 2 * part


def step_failure(t: float, cuts: int, h: float, err: Exception, problem) -> IntegrationError:
    """The error of a step that still failed after ``cuts`` step cuts (last step h), with
    where the problem says it failed (``problem.where_failed``: e.g. a rod's segment pair
    nearest to touching at Newton's last iterate: "PLACE: what", left out when the
    error names that place already)."""
    where = getattr(problem, "where_failed", lambda: None)()
    said = where is not None and where.partition(": ")[0] in str(err)
    return IntegrationError(f"time step failed at t = {t:.6g} after {cuts} step cuts (last "
                            f"dt = {h:.3g}): {err}" + (f"; where: {where}" if where and
                                                       not said else ""), t)


@dataclass(frozen=True)
class StepControl:
    """The standard step-size controller of a local error estimate of order ``order``
    (err ~ h^order per step; Hairer, Norsett & Wanner, Solving ODE I, sec. II.4):
    ``err`` is the estimate in the weighted norm of rtol and atol (err <= 1 accepts), the
    next step is h min(max_growth, max(min_growth, safety err^(-1/order))); after a
    rejected step the next one does not grow (growth capped at 1).  ``rtol``, ``atol``:
    the integrator documents what they scale (lie_alpha.LocalError).  ``max_step``: the
    largest step (None: unbounded; loads are sampled at the step ends only, so a pulse
    shorter than the step can be stepped over in a quiet phase where steps grow)."""

    rtol: float
    atol: float
    order: int = 3
    safety: float = 0.9
    min_growth: float = 0.2
    max_growth: float = 2.0
    max_step: float | None = None

    def __post_init__(self):
        for name in ("rtol", "atol"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value < 1):
                raise ValueError(f"{name} (the local error tolerance) must be in (0, 1), "
                                 f"got {value!r}")

    def growth(self, err: float, after_rejection: bool = False) -> float:
        """The factor of the next step after a step with weighted error ``err``."""
        top = 1.0 if after_rejection else self.max_growth
        if err <= 0.0:
            return top
        return min(top, max(self.min_growth, self.safety * err ** (-1.0 / self.order)))

    def limited(self, h: float) -> float:
        """h within max_step."""
        return h if self.max_step is None else min(h, self.max_step)


@dataclass
class StepStats:
    """Counters of a run: accepted steps, rejected steps (step cuts), SNES failures
    (PETSc TS) and Newton iterations."""

    steps: int = 0
    newton_iterations: int = 0
    rejected: int = 0
    snes_failures: int = 0


def check_run(t0: float, t_end: float, dt: float, problem=None, adaptive: bool = False) -> None:
    """ValueError unless dt > 0, t_end > t0, the problem's initial state is set and its
    steps resolve its prescribed motions (no jump; unless ``adaptive``, no change faster
    than dt)."""
    if problem is not None and problem.unset_state:
        raise ValueError(f"the initial state is not set: call {problem.unset_state} before "
                         "integrating (its fields are still zero, e.g. a rod's quaternions: "
                         "DIVERGED_FNORM_NAN at the first step)")
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    if not t_end > t0:
        raise ValueError(f"t_end must be > t0 = {t0}, got {t_end}")
    for name, motion in (problem.prescribed_motions if problem is not None else {}).items():
        why = resolution_problem(motion, t0, t_end, dt, adaptive)
        if why:
            raise ValueError(f"{name} {why}")


def nominal_steps(t0: float, t_end: float, dt: float) -> int:
    """Number of steps of size dt that reach t_end (the last one clipped)."""
    return math.ceil((t_end - t0) / dt - ROUND_OFF)


def output_times(t_end: float, dt: float) -> list[float]:
    """The output times 0, dt, 2 dt, ..., t_end of a scene (the last one clipped): a
    run's rows, the ODE's grid and a fit's samples."""
    n_steps = max(1, math.ceil(t_end / dt - ROUND_OFF))
    return [min(k * dt, t_end) for k in range(n_steps + 1)]


def reached(t: float, t_end: float, dt: float) -> bool:
    """t is t_end up to the round-off of summing steps of size dt."""
    return t_end - t <= ROUND_OFF * dt


def clip_to_end(t: float, t_end: float, h: float) -> float:
    """The step from t: h, or the remaining interval if h reaches (or nearly reaches) it."""
    remaining = t_end - t
    return remaining if remaining < h * (1 + ROUND_OFF) else h


def same_step(h: float, last: float | None) -> bool:
    """h is the last accepted step's size (None: no step yet) up to round-off."""
    return last is not None and abs(h - last) <= ROUND_OFF * h


def grown(h: float, dt: float) -> float:
    """The step after a success that followed a cut: back towards the nominal dt."""
    return min(GROWTH_FACTOR * h, dt)


def march(t: float, t_end: float, h: float, attempt: Callable[[float, float], object],
          failed: Callable, succeeded: Callable, max_attempts: int | None = None,
          scale: float | None = None) -> tuple[float, float]:
    """The loop of a per-step integrator from t to t_end: steps of h, each clipped to
    t_end (clip_to_end).  ``attempt(t, h_try)`` takes a step (SolverError: it failed, the
    state at t restored); ``failed(t, h_try, err)`` returns the step to retry with (or
    raises IntegrationError), ``succeeded(t_new, h_try, h)`` the next step.  t_end is
    reached up to ROUND_OFF * ``scale`` (default: the current step).  Returns (t, the
    next step); IntegrationError after ``max_attempts`` attempts."""
    attempts = 0
    while not reached(t, t_end, scale or h):
        if max_attempts is not None and attempts >= max_attempts:
            raise IntegrationError(f"step budget exhausted at t = {t:.6g}", t)
        attempts += 1
        h_try = clip_to_end(t, t_end, h)
        try:
            attempt(t, h_try)
        except SolverError as err:
            h = failed(t, h_try, err)
            continue
        t = t_end if h_try == t_end - t else t + h_try
        h = succeeded(t, h_try, h)
    return t, h
