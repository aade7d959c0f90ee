"""Closed-form stress relaxation and creep of quasi-static homogeneous torsion (Section 5).

With homogeneous twist ``u(t)`` and natural twist ``u_d(t)`` and no inertia (nu = 0) the
isolated-torsion model reduces to the 2x2 linear system

    mu u' + alpha u - alpha u_d = m(t),                    (eq. ``twist``)
    mu_d u_d' - alpha u + (alpha + alpha_d) u_d = 0,       (eq. ``nattwist``)

in the paper's dimensionless variables: stiffnesses ``alpha`` (elastic) and ``alpha_d``
(natural configuration), viscosities ``mu`` (Kelvin-Voigt, may vanish) and ``mu_d``
(evolution of the natural configuration). The rod is quiescent before t = 0:
``u = u_d = 0`` for t < 0, so every response below is zero for negative times, and at
t = 0 it takes its right limit (the idealised steps use H(0) = 1).

The creep formulas use the matrix exponential as corrected in docs/corrections.md, item 2; the
mu = 0 convolution is the corrected one of docs/corrections.md, item 3.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import quad
from ..checks import finite as _finite, positive as _positive, nonnegative as _nonnegative

__all__ = [
    "creep",
    "creep_exponential",
    "creep_inviscid",
    "creep_matrix",
    "creep_response",
    "equilibrium_twists",
    "p1_twist",
    "relaxation",
    "relaxation_impulse",
    "relaxed_torsion",
]

FloatOrArray = float | NDArray[np.float64]


# --- input validation ------------------------------------------------------------------


def _times(t: ArrayLike) -> NDArray[np.float64]:
    """Return the times ``t`` as a float array, or raise ValueError if any is not finite."""
    times = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(times)):
        raise ValueError("t must be finite")
    return times


def _shaped(values: NDArray[np.float64], t: ArrayLike) -> FloatOrArray:
    """Return a float for a scalar time ``t``, the array ``values`` otherwise."""
    return float(values) if np.ndim(t) == 0 else values


# --- limits ----------------------------------------------------------------------------


def equilibrium_twists(m0: float, alpha: float, alpha_d: float) -> tuple[float, float]:
    """Long-time twist and natural twist ``(u(inf), u_d(inf))`` under a constant torsion m0.

    ``u = (alpha + alpha_d) m0 / (alpha alpha_d)``, ``u_d = m0 / alpha_d``
    (eq. ``nattwistasymp``); the same for every mu >= 0 and mu_d > 0.
    """
    m0 = _finite("m0", m0)
    alpha = _positive("alpha", alpha)
    alpha_d = _positive("alpha_d", alpha_d)
    return (alpha + alpha_d) * m0 / (alpha * alpha_d), m0 / alpha_d


def relaxed_torsion(u0: float, alpha: float, alpha_d: float) -> float:
    """Long-time torsion ``m(inf) = alpha alpha_d u0 / (alpha + alpha_d)`` at held twist u0.

    Limit of eq. ``stressrelax``; the natural twist then is ``alpha u0 / (alpha + alpha_d)``.
    """
    u0 = _finite("u0", u0)
    alpha = _positive("alpha", alpha)
    alpha_d = _positive("alpha_d", alpha_d)
    return alpha * alpha_d * u0 / (alpha + alpha_d)


# --- stress relaxation -----------------------------------------------------------------


def p1_twist(u0: float, length: float, n_cells: int) -> tuple[float, float]:
    """The 3-D rod's discrete counterpart of a uniform twist u0 (rod/, P1 rotations):
    ``(u_h, factor)``.  Nodal rotations dphi = u0 L/N apart about the axis give every
    element the midpoint twist u_h = 4 tan(dphi/4)/h (= u0 (1 + dphi^2/48 + ...)); the
    end reaction couple, the residual at the end node, is d/dphi of h psi(u_h) = m(u_h)
    du_h/d(dphi) h, i.e. the element torque m(u_h) times factor = sec^2(dphi/4)
    (= 1 + dphi^2/16 + ...).  So a closed form m(t) of the continuum becomes the
    reaction factor * m(t; u0 -> u_h) of the discrete rod."""
    dphi = _finite("u0", u0) * length / n_cells
    h = length / n_cells
    return 4.0 * np.tan(dphi / 4.0) / h, 1.0 / np.cos(dphi / 4.0) ** 2


def relaxation_impulse(u0: float, mu: float) -> float:
    """Weight ``mu u0`` of the Dirac impulse ``mu u0 delta(t)`` in the torsion of eq. ``stressrelax``.

    A step twist ``u0 H(t)`` needs, besides the regular torsion returned by
    :func:`relaxation`, this impulse at t = 0 to move the Kelvin-Voigt dashpot; it is
    the limit of ``int m_n dt`` over the ramp-up of the smooth twists ``u_n``.
    """
    return _nonnegative("mu", mu) * _finite("u0", u0)


def relaxation(
    t: ArrayLike, u0: float, alpha: float, alpha_d: float, mu_d: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """Natural twist and torsion ``(u_d(t), m(t))`` after a step twist ``u(t) = u0 H(t)``.

    Regular part of eq. ``stressrelax`` (t >= 0, zero for t < 0):

        u_d(t) = alpha u0 / (alpha + alpha_d) (1 - exp(-k t)),
        m(t)   = alpha alpha_d u0 / (alpha + alpha_d) + alpha^2 u0 / (alpha + alpha_d) exp(-k t),

    with ``k = (alpha + alpha_d) / mu_d``. It does not depend on mu: the Kelvin-Voigt
    viscosity only adds the impulse ``mu u0 delta(t)`` at t = 0, given separately by
    :func:`relaxation_impulse`. ``m(0+) = alpha u0`` decreases to :func:`relaxed_torsion`.
    """
    times = _times(t)
    u0 = _finite("u0", u0)
    alpha = _positive("alpha", alpha)
    alpha_d = _positive("alpha_d", alpha_d)
    mu_d = _positive("mu_d", mu_d)

    rate = (alpha + alpha_d) / mu_d
    after = times >= 0.0
    elapsed = np.where(after, times, 0.0)
    relaxed = -np.expm1(-rate * elapsed)                           # 1 - exp(-k t), accurate for small k t
    # eq. stressrelax, regular part
    natural_twist = np.where(after, alpha * u0 / (alpha + alpha_d) * relaxed, 0.0)
    torsion = np.where(after, alpha * u0 * (alpha_d + alpha * np.exp(-rate * elapsed)) / (alpha + alpha_d), 0.0)
    return _shaped(natural_twist, t), _shaped(torsion, t)


# --- creep, mu > 0 ---------------------------------------------------------------------


def creep_matrix(alpha: float, alpha_d: float, mu: float, mu_d: float) -> NDArray[np.float64]:
    """Matrix A of ``d/dt (u, u_d) = -A (u, u_d) + (m/mu, 0)``, eqs. ``twist``, ``nattwist``.

    ``A = [[alpha/mu, -alpha/mu], [-alpha/mu_d, (alpha + alpha_d)/mu_d]]``, with
    ``det A = alpha alpha_d / (mu mu_d) > 0``. Needs mu > 0.
    """
    alpha = _positive("alpha", alpha)
    alpha_d = _positive("alpha_d", alpha_d)
    mu = _positive("mu", mu)
    mu_d = _positive("mu_d", mu_d)
    return np.array([[alpha / mu, -alpha / mu], [-alpha / mu_d, (alpha + alpha_d) / mu_d]])


def _exponential_coefficients(
    times: NDArray[np.float64], alpha: float, alpha_d: float, mu: float, mu_d: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Return ``(1 - c, c, s)`` with ``exp(-tA) = c(t) I - s(t) B`` (docs/corrections.md, item 2).

    ``tau = tr(A)/2``, ``B = A - tau I``, ``delta = sqrt(-det B)``,
    ``c = exp(-tau t) cosh(delta t)`` and ``s = exp(-tau t) sinh(delta t) / delta``.
    Written with the eigenvalues ``lambda_1 = tau - delta = det A / (tau + delta)`` and
    ``lambda_2 = tau + delta`` of A so that nothing overflows for large t, ``1 - c``
    keeps its digits for small t, and ``sinh(delta t)/delta -> t`` as delta -> 0 with no
    division by zero. Parameters are assumed validated.
    """
    tau = 0.5 * (alpha / mu + (alpha + alpha_d) / mu_d)
    half_gap = 0.5 * (alpha / mu - (alpha + alpha_d) / mu_d)
    delta = math.sqrt(half_gap**2 + alpha**2 / (mu * mu_d))       # sqrt(-det B), a sum of squares
    lambda_1 = alpha * alpha_d / (mu * mu_d) / (tau + delta)      # det A / (tau + delta) = tau - delta
    lambda_2 = tau + delta

    c = 0.5 * (np.exp(-lambda_1 * times) + np.exp(-lambda_2 * times))
    one_minus_c = -0.5 * (np.expm1(-lambda_1 * times) + np.expm1(-lambda_2 * times))
    # s = t exp(-lambda_1 t) (1 - exp(-2 delta t)) / (2 delta t); the last factor -> 1 as delta t -> 0.
    x = 2.0 * delta * times
    safe_x = np.where(x != 0.0, x, 1.0)
    shrink = np.where(x != 0.0, -np.expm1(-safe_x) / safe_x, 1.0)
    s = times * np.exp(-lambda_1 * times) * shrink
    return one_minus_c, c, s


def creep_exponential(t: ArrayLike, alpha: float, alpha_d: float, mu: float, mu_d: float) -> NDArray[np.float64]:
    """Matrix exponential ``exp(-t A)`` of the creep problem, shape ``t.shape + (2, 2)``.

    Corrected formula after eq. ``creepform`` (docs/corrections.md, item 2):
    ``exp(-tA) = exp(-tau t) [cosh(delta t) I - (sinh(delta t)/delta) B]``, valid for all
    real t, including the nearly degenerate case delta -> 0.
    """
    times = _times(t)
    matrix = creep_matrix(alpha, alpha_d, mu, mu_d)
    _, c, s = _exponential_coefficients(times, alpha, alpha_d, mu, mu_d)
    tau = 0.5 * np.trace(matrix)
    traceless = matrix - tau * np.eye(2)                           # B = A - tau I
    return c[..., None, None] * np.eye(2) - s[..., None, None] * traceless


def creep(
    t: ArrayLike, m0: float, alpha: float, alpha_d: float, mu: float, mu_d: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """Twist and natural twist ``(u(t), u_d(t))`` under a step torsion ``m0 H(t)``, mu > 0.

    Eq. ``creepform``: ``(u, u_d) = (I - exp(-tA)) A^{-1} (m0/mu, 0)``, where
    ``A^{-1} (m0/mu, 0)`` is :func:`equilibrium_twists`. Both start at 0 and tend to
    those limits. Zero for t < 0. For mu = 0 use :func:`creep_inviscid`.
    """
    times = _times(t)
    matrix = creep_matrix(alpha, alpha_d, mu, mu_d)                # validates the parameters
    limits = np.array(equilibrium_twists(m0, alpha, alpha_d))      # A^{-1} (m0/mu, 0)
    after = times >= 0.0
    one_minus_c, _, s = _exponential_coefficients(np.where(after, times, 0.0), alpha, alpha_d, mu, mu_d)
    traceless = matrix - 0.5 * np.trace(matrix) * np.eye(2)        # B = A - tau I
    b_limits = traceless @ limits
    # (I - exp(-tA)) w = (1 - c) w + s B w
    twist = np.where(after, one_minus_c * limits[0] + s * b_limits[0], 0.0)
    natural_twist = np.where(after, one_minus_c * limits[1] + s * b_limits[1], 0.0)
    return _shaped(twist, t), _shaped(natural_twist, t)


# --- creep, mu = 0 ---------------------------------------------------------------------


def creep_inviscid(
    t: ArrayLike, m0: float, alpha: float, alpha_d: float, mu_d: float
) -> tuple[FloatOrArray, FloatOrArray]:
    """Twist and natural twist ``(u(t), u_d(t))`` under a step torsion ``m0 H(t)``, mu = 0.

    Step response after docs/corrections.md, item 3 (the paper's step formulas), for t >= 0:

        u_d(t) = m0 / alpha_d (1 - exp(-alpha_d t / mu_d)),    u(t) = m0 / alpha + u_d(t).

    Without Kelvin-Voigt viscosity the twist jumps to ``m0/alpha`` at t = 0; zero for t < 0.
    """
    times = _times(t)
    m0 = _finite("m0", m0)
    alpha = _positive("alpha", alpha)
    alpha_d = _positive("alpha_d", alpha_d)
    mu_d = _positive("mu_d", mu_d)
    after = times >= 0.0
    natural_twist = np.where(after, -m0 / alpha_d * np.expm1(-alpha_d / mu_d * np.where(after, times, 0.0)), 0.0)
    twist = np.where(after, m0 / alpha + natural_twist, 0.0)      # alpha (u - u_d) = m
    return _shaped(twist, t), _shaped(natural_twist, t)


def creep_response(
    t: ArrayLike,
    m: Callable[[float], float],
    alpha: float,
    alpha_d: float,
    mu_d: float,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-14,
) -> tuple[FloatOrArray, FloatOrArray]:
    """Twist and natural twist ``(u(t), u_d(t))`` under a torsion history ``m``, mu = 0.

    Convolution form (docs/corrections.md, item 3), for t >= 0:

        u_d(t) = (1/mu_d) int_0^t exp(-(alpha_d/mu_d)(t - tau)) m(tau) dtau,
        u(t)   = m(t)/alpha + u_d(t).

    Only ``m`` on [0, t] is used (the rod is at rest before t = 0); zero for t < 0.
    ``m`` is called with one float at a time (any ``loads.LoadHistory`` or plain function).
    The integral is accumulated over the sorted times, ``I(t_i) = exp(-k (t_i - t_{i-1}))
    I(t_{i-1}) + int_{t_{i-1}}^{t_i} ...``, each piece by adaptive Gauss-Kronrod
    quadrature (``scipy.integrate.quad``) to the tolerances ``rtol``, ``atol``; the factor
    exp(-k dt) <= 1 keeps earlier errors from growing.
    """
    times = _times(t)
    alpha = _positive("alpha", alpha)
    alpha_d = _positive("alpha_d", alpha_d)
    mu_d = _positive("mu_d", mu_d)
    rtol = _positive("rtol", rtol)
    atol = _positive("atol", atol)
    rate = alpha_d / mu_d

    stops = np.unique(times[times >= 0.0])                        # sorted, t >= 0
    natural_twists = np.empty_like(stops)
    previous, integral = 0.0, 0.0
    for i, stop in enumerate(stops):
        piece, _ = quad(lambda tau: math.exp(-rate * (stop - tau)) * float(m(tau)),
                        previous, stop, epsabs=atol, epsrel=rtol, limit=200)
        integral = math.exp(-rate * (stop - previous)) * integral + piece
        natural_twists[i] = integral / mu_d                        # docs/corrections.md item 3
        previous = stop

    twist = np.zeros_like(times)
    natural_twist = np.zeros_like(times)
    for i, stop in enumerate(stops):
        at = times == stop
        natural_twist[at] = natural_twists[i]
        twist[at] = float(m(float(stop))) / alpha + natural_twists[i]   # alpha (u - u_d) = m
    return _shaped(twist, t), _shaped(natural_twist, t)
