"""What every integrator shares: argument checks, the clipping of the final step, the
step-cut and growth rules, the statistics and the error of a run that stopped early.

TimeStepper (per-step schemes) drives its own loop with these rules; TSIntegrator hands
them to PETSc TS through its post-step callback (TS cuts a failed step itself, by
``ts_adapt_scale_solve_failed``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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


@dataclass
class StepStats:
    """Counters of a run: accepted steps, rejected steps (step cuts), SNES failures
    (PETSc TS) and Newton iterations."""

    steps: int = 0
    newton_iterations: int = 0
    rejected: int = 0
    snes_failures: int = 0


def check_run(t0: float, t_end: float, dt: float) -> None:
    """ValueError unless dt > 0 and t_end > t0."""
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    if not t_end > t0:
        raise ValueError(f"t_end must be > t0 = {t0}, got {t_end}")


def nominal_steps(t0: float, t_end: float, dt: float) -> int:
    """Number of steps of size dt that reach t_end (the last one clipped)."""
    return math.ceil((t_end - t0) / dt - ROUND_OFF)


def reached(t: float, t_end: float, dt: float) -> bool:
    """t is t_end up to the round-off of summing steps of size dt."""
    return t_end - t <= ROUND_OFF * dt


def clip_to_end(t: float, t_end: float, h: float) -> float:
    """The step from t: h, or the remaining interval if h reaches (or nearly reaches) it."""
    remaining = t_end - t
    return remaining if remaining < h * (1 + ROUND_OFF) else h


def grown(h: float, dt: float) -> float:
    """The step after a success that followed a cut: back towards the nominal dt."""
    return min(GROWTH_FACTOR * h, dt)
