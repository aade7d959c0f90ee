"""Load histories t -> value for end torsions, end rotations and forces.

A load history is right-continuous, ``f(t) = f(t+)``, so an idealised step ``v H(t - t0)``
already has its new value at ``t0`` (H(0) = 1, as in Section 5). Each history knows its
jumps, so a solver can tell the idealised step of eqs. ``stressrelax`` and ``creepform``
(a jump at t = 0, i.e. an impulse for a Kelvin-Voigt dashpot) from the smooth
regularisations ``u_n``, ``m_n`` that the paper uses to define it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from .checks import finite as _finite, positive as _positive

__all__ = [
    "LoadHistory",
    "PiecewiseSmoothLoad",
    "VectorHistory",
    "constant",
    "from_callable",
    "jump_at",
    "jumps",
    "rate",
    "ramp",
    "resolution_problem",
    "smooth_step",
    "step",
    "table",
]

FloatOrArray = float | NDArray[np.float64]


@runtime_checkable
class LoadHistory(Protocol):
    """A right-continuous load history ``t -> value``, vectorised on numpy arrays."""

    def __call__(self, t: ArrayLike) -> FloatOrArray:
        """Value ``f(t) = f(t+)``: a float for a scalar t, an array of t's shape otherwise."""
        ...

    def left_limit(self, t: ArrayLike) -> FloatOrArray:
        """Value just before t, ``f(t-)``."""
        ...

    @property
    def start_limits(self) -> tuple[float, float]:
        """Values ``(f(0-), f(0+))`` just before and just after t = 0."""
        ...

    @property
    def is_step(self) -> bool:
        """True if the history jumps at t = 0 (an idealised step), False if continuous there."""
        ...


def _times(t: ArrayLike) -> NDArray[np.float64]:
    """Return the times ``t`` as a float array (+-inf allowed), or raise ValueError on NaN."""
    times = np.asarray(t, dtype=float)
    if np.any(np.isnan(times)):
        raise ValueError("load time t must not be NaN")
    return times


@dataclass(frozen=True)
class PiecewiseSmoothLoad:
    """A load history given by its right-continuous values and its list of jumps.

    ``values`` maps a float array of times to an array of the same shape; ``jumps`` holds
    the pairs ``(time, f(time+) - f(time-))``; ``slopes`` (if known) maps times to the
    right derivative f'(t+) (0 at a jump: its impulse is not a rate); ``shortest_change``
    the shortest time over which it changes between its jumps (a ramp's or smooth step's
    duration, a table's shortest changing segment; inf if it only jumps or is constant;
    None: unknown, for a wrapped callable). Build one with the constructors below.
    """

    values: Callable[[NDArray[np.float64]], NDArray[np.float64]]
    jumps: tuple[tuple[float, float], ...] = ()
    description: str = "load history"
    slopes: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None
    shortest_change: float | None = math.inf

    def derivative(self, t: ArrayLike) -> FloatOrArray:
        """The right derivative f'(t+), analytic (``slopes``) or by central differences."""
        if self.slopes is None:
            return central_difference(self, t)
        times = _times(t)
        out = np.broadcast_to(np.asarray(self.slopes(times), dtype=float), times.shape).copy()
        return float(out) if out.ndim == 0 else out

    def __call__(self, t: ArrayLike) -> FloatOrArray:
        if isinstance(t, float):     # one time (an ODE's right-hand side): no array checks
            if math.isnan(t):
                raise ValueError("load time t must not be NaN")
            value = np.asarray(self.values(np.asarray(t)), dtype=float)
            if value.shape == ():
                return float(value)
        times = _times(t)
        out = np.broadcast_to(np.asarray(self.values(times), dtype=float), times.shape).copy()
        return float(out) if out.ndim == 0 else out

    def left_limit(self, t: ArrayLike) -> FloatOrArray:
        times = _times(t)
        out = np.asarray(self(times), dtype=float)
        for time, size in self.jumps:
            out = out - size * (times == time)
        return float(out) if out.ndim == 0 else out

    @property
    def start_limits(self) -> tuple[float, float]:
        return float(self.left_limit(0.0)), float(self(0.0))

    @property
    def is_step(self) -> bool:
        before, after = self.start_limits
        return before != after

    def __repr__(self) -> str:
        return f"<{self.description}>"


@dataclass(frozen=True)
class VectorHistory:
    """t -> the vector of its components' values (histories of this module): a rod's
    prescribed end motion that knows its components' jumps and shortest change
    (resolution_problem), e.g. ``VectorHistory((constant(0), constant(0),
    smooth_step(1.0, 0.2)))``."""

    parts: tuple

    def __call__(self, t: float) -> NDArray[np.float64]:
        return np.array([float(h(t)) for h in self.parts])

    @property
    def jumps(self) -> tuple[tuple[float, float], ...]:
        return tuple(j for h in self.parts for j in getattr(h, "jumps", ()))

    @property
    def shortest_change(self) -> float | None:
        changes = [getattr(h, "shortest_change", None) for h in self.parts]
        return None if None in changes else min(changes)


def rate(motion: Callable, t: float):
    """d/dt of a load history or a prescribed motion t -> value (float or array), the one
    rate rule of every model: the history's own ``derivative`` where it has one (the
    constructors below), else central differences."""
    derivative = getattr(motion, "derivative", None)
    return derivative(t) if derivative is not None else central_difference(motion, t)


def central_difference(motion: Callable, t: float):
    """(f(t + h) - f(t - h))/(2h), h = 1e-6 max(1, |t|) (truncation O(h^2) ~ 1e-12,
    round-off eps/h ~ 1e-10 relative)."""
    h = 1e-6 * max(1.0, abs(t))
    return (np.asarray(motion(t + h), float) - np.asarray(motion(t - h), float)) / (2 * h)


def jump_at(history: LoadHistory, t: ArrayLike) -> FloatOrArray:
    """Jump ``f(t+) - f(t-)`` of a load history at time(s) t (0 where it is continuous)."""
    return history(t) - history.left_limit(t)


def jumps(motion: Callable) -> bool:
    """Whether a prescribed motion (or load) starting from rest jumps: nonzero at t = 0
    (it is 0 before) or with jumps (PiecewiseSmoothLoad); other jumps of a callable
    cannot be detected."""
    return bool(np.any(np.asarray(motion(0.0), float) != 0.0)
                or any(size for _, size in getattr(motion, "jumps", ())))


def constant(v: float) -> PiecewiseSmoothLoad:
    """The constant history ``f(t) = v`` for all t (also before t = 0: no jump)."""
    v = _finite("v", v)
    return PiecewiseSmoothLoad(lambda t: np.full_like(t, v), (), f"constant {v}",
                               np.zeros_like)


def step(v: float, t0: float = 0.0) -> PiecewiseSmoothLoad:
    """The idealised step ``f(t) = v H(t - t0)`` with H(0) = 1 (a jump v at t0)."""
    v = _finite("v", v)
    t0 = _finite("t0", t0)
    return PiecewiseSmoothLoad(lambda t: np.where(t >= t0, v, 0.0), ((t0, v),) if v != 0.0 else (), f"step {v} at t = {t0}",
                               np.zeros_like)


def ramp(v: float, t_ramp: float, t0: float = 0.0) -> PiecewiseSmoothLoad:
    """The linear ramp starting at t0: 0 for t < t0, ``v (t - t0) / t_ramp`` on
    [t0, t0 + t_ramp], v afterwards (continuous)."""
    v = _finite("v", v)
    t_ramp = _positive("t_ramp", t_ramp)
    t0 = _finite("t0", t0)
    return PiecewiseSmoothLoad(lambda t: v * np.clip((t - t0) / t_ramp, 0.0, 1.0), (),
                               f"ramp to {v} over {t_ramp}" + (f" from t = {t0}" if t0 else ""),
                               lambda t: np.where((t >= t0) & (t < t0 + t_ramp), v / t_ramp, 0.0),
                               t_ramp if v != 0.0 else math.inf)


def smooth_step(v: float, width: float, t0: float = 0.0) -> PiecewiseSmoothLoad:
    """A C^1 regularisation of the step ``v H(t - t0)``, like the paper's ``u_n``, ``m_n``
    (width 1/n).

    ``f(t) = v S((t - t0) / width)`` with the cubic Hermite "smoothstep" ``S(x) = x^2 (3 -
    2x)`` on [0, 1], S = 0 for x < 0 and S = 1 for x > 1: S(0) = S'(0) = S'(1) = 0,
    S(1) = 1 and S' >= 0, so f is continuously differentiable and monotone
    (non-decreasing for v >= 0).
    """
    v = _finite("v", v)
    width = _positive("width", width)
    t0 = _finite("t0", t0)

    def values(t: NDArray[np.float64]) -> NDArray[np.float64]:
        x = np.clip((t - t0) / width, 0.0, 1.0)
        return v * x * x * (3.0 - 2.0 * x)

    def slopes(t: NDArray[np.float64]) -> NDArray[np.float64]:
        x = np.clip((t - t0) / width, 0.0, 1.0)
        return v * 6.0 * x * (1.0 - x) / width

    return PiecewiseSmoothLoad(values, (), f"smooth step to {v} over {width}"
                               + (f" from t = {t0}" if t0 else ""), slopes,
                               width if v != 0.0 else math.inf)


def table(times: ArrayLike, values: ArrayLike) -> PiecewiseSmoothLoad:
    """Piecewise-linear interpolation of ``(times, values)``, constant beyond both ends."""
    knots = np.array(times, dtype=float)
    heights = np.array(values, dtype=float)
    if knots.ndim != 1 or heights.ndim != 1:
        raise ValueError("load table times and values must be one-dimensional")
    if knots.size != heights.size:
        raise ValueError(f"load table times and values must have the same length, got {knots.size} and {heights.size}")
    if knots.size == 0:
        raise ValueError("load table needs at least one point")
    if not (np.all(np.isfinite(knots)) and np.all(np.isfinite(heights))):
        raise ValueError("load table times and values must be finite")
    if np.any(np.diff(knots) <= 0.0):
        raise ValueError("load table times must be strictly increasing")
    def slopes(t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Slope of the segment starting at or before t (right derivative), 0 outside."""
        if knots.size == 1:
            return np.zeros_like(t)
        k = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, knots.size - 2)
        slope = np.diff(heights)[k] / np.diff(knots)[k]
        return np.where((t >= knots[0]) & (t < knots[-1]), slope, 0.0)

    changing = np.diff(knots)[np.diff(heights) != 0.0]
    return PiecewiseSmoothLoad(lambda t: np.interp(t, knots, heights), (), f"table of {knots.size} points",
                               slopes, float(changing.min()) if changing.size else math.inf)


def from_callable(f: Callable[[float], float], jumps: Mapping[float, float] | None = None) -> PiecewiseSmoothLoad:
    """Wrap a right-continuous function ``f(t)`` as a load history.

    ``f`` may be vectorised (numpy in, numpy out) or scalar only (``math.sin``); it is
    then evaluated point by point. It is taken as continuous except at the times given in
    ``jumps`` (``{time: f(time+) - f(time-)}``), which cannot be detected numerically.
    """
    if not callable(f):
        raise TypeError(f"f must be callable, got {f!r}")
    jump_list = tuple((_finite("jump time", time), _finite("jump size", size)) for time, size in (jumps or {}).items())

    def values(t: NDArray[np.float64]) -> NDArray[np.float64]:
        try:
            out = np.asarray(f(t), dtype=float)
        except (TypeError, ValueError):
            out = None
        if out is None or out.shape != t.shape:                    # scalar-only f: point by point
            out = np.array([float(f(float(time))) for time in t.ravel()]).reshape(t.shape)
        return out

    return PiecewiseSmoothLoad(values, jump_list, f"callable {getattr(f, '__name__', repr(f))}",
                               shortest_change=None)


# A step's change of a prescribed motion its rates at the step's ends do not account for
# (|change - dt (rate_n + rate_n+1) / 2| above this fraction of the change): the change
# happens inside the step.  A smooth step lasting 2 dt, aligned with the steps, is at
# 0.25; a ramp lasting dt / 2 at 0.5 .. 1, a jump at 1.
UNACCOUNTED = 0.6
# A change inside an interval this short (relative to max(1, |t|)) is taken as a jump.
JUMP_WIDTH = 1e-9


def resolution_problem(motion: Callable, t0: float, t_end: float, dt: float,
                       adaptive: bool = False) -> str | None:
    """Why steps of size dt from t0 to t_end cannot follow a prescribed ``motion`` of a
    body with inertia (its end would take an impulse the scheme cannot represent,
    issue 28 item 5), or None: a jump after t0 (one at t0 is the start), or (unless the
    steps adapt) a change faster than dt.  A history of this module knows its ``jumps``
    and ``shortest_change``; any other
    callable is sampled at the steps t0 + k dt (its rates by one-sided differences inside
    each step): a step whose change the rates at its ends do not account for is narrowed
    by bisection to the change's duration."""
    later = [time for time, size in getattr(motion, "jumps", ()) if size and t0 < time <= t_end]
    shortest = getattr(motion, "shortest_change", None)
    when = f" at t = {min(later):.6g}" if later else ""
    if later:
        shortest = 0.0
    elif shortest is None:
        found = _unaccounted_change(motion, t0, t_end, dt)
        if found is None:
            return None
        start, shortest = found
        when = f" near t = {start:.6g}"
    if shortest <= JUMP_WIDTH * max(1.0, abs(t_end)):
        within = f" (changes within {shortest:.3g})" if shortest > 0.0 else ""
        return (f"jumps{when}{within}: a body with inertia cannot "
                "follow a jump; let it change smoothly (loads.smooth_step, loads.ramp) "
                "over at least dt")
    if shortest < dt and not adaptive:
        return (f"changes{when} within {shortest:.3g}, faster than the time step "
                f"dt = {dt:.3g} resolves (the end would take an impulse); let it last at "
                f"least dt, or take dt <= {shortest:.3g}")
    return None


def _unaccounted_change(motion: Callable, t0: float, t_end: float,
                        dt: float) -> tuple[float, float] | None:
    """(start, duration) of the first change between the steps t0 + k dt that the rates
    at the step's ends (one-sided, inside the step: the motion is read on [t0, t_end]
    only) do not account for, or None."""
    steps = max(1, math.ceil((t_end - t0) / dt - 1e-9))
    times = [min(t0 + k * dt, t_end) for k in range(steps + 1)]
    values = [np.asarray(motion(t), float) for t in times]
    for k in range(steps):
        a, b = times[k], times[k + 1]
        delta = 1e-6 * (b - a)
        start = (np.asarray(motion(a + delta), float) - values[k]) / delta
        end = (values[k + 1] - np.asarray(motion(b - delta), float)) / delta
        change = values[k + 1] - values[k]
        size = float(np.max(np.abs(change)))
        missing = float(np.max(np.abs(change - 0.5 * (b - a) * (start + end))))
        if size > 0.0 and missing > UNACCOUNTED * size:
            return _narrowed(motion, a, b)
    return None


def _narrowed(motion: Callable, a: float, b: float) -> tuple[float, float]:
    """Where and how fast the change inside [a, b] happens: [a, b] halved while one half
    holds 90 % of its change (down to JUMP_WIDTH: a jump), then sampled at 65 points: the
    time between 5 % and 95 % of the change's variation, over 0.9; (its start, duration)."""
    ga, gb = np.asarray(motion(a), float), np.asarray(motion(b), float)
    while b - a > 0.5 * JUMP_WIDTH * max(1.0, abs(b)):
        m = 0.5 * (a + b)
        gm = np.asarray(motion(m), float)
        left, right = float(np.max(np.abs(gm - ga))), float(np.max(np.abs(gb - gm)))
        if max(left, right) < 0.9 * (left + right):
            break
        a, b, ga, gb = (a, m, ga, gm) if left > right else (m, b, gm, gb)
    times = np.linspace(a, b, 65)
    values = np.array([np.asarray(motion(t), float).ravel() for t in times])
    variation = np.concatenate(([0.0], np.cumsum(np.abs(np.diff(values, axis=0)).max(axis=1))))
    start, end = (times[np.searchsorted(variation, f * variation[-1])] for f in (0.05, 0.95))
    return float(start), float(end - start) / 0.9
