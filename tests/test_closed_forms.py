"""Section 5's closed forms (dolfin_rod.closed_forms) against independent computations.

References: ``scipy.linalg.expm`` for the matrix exponential, and ``solve_ivp`` of the
ODEs ``twist``, ``nattwist`` written out again here (not taken from the module), with
rtol = 1e-10 and an absolute tolerance of 1e-12 times each component's scale.

Tolerances: expm and the closed forms are both accurate to a few ulps of the largest
entry, so they must agree to 1e-12 relative. An explicit Runge-Kutta run at local
rtol = 1e-10 accumulates a global error of a few 1e-9 relative (at most 3.7e-9 measured)
over the runs used here, so closed forms vs solve_ivp must agree to 1e-8 relative (of each
component's scale); a wrong formula misses by O(1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from dolfin_rod import closed_forms as cf
from dolfin_rod import loads

RTOL_EXPM = 1e-12     # closed form vs expm, relative to the largest entry
RTOL_IVP = 1e-8       # closed form vs solve_ivp(rtol=1e-10), relative to each component's scale

# (alpha, alpha_d, mu, mu_d)
CREEP_PARAMETERS = {
    "unit": (1.0, 1.0, 1.0, 1.0),
    "fast Kelvin-Voigt": (2.0, 0.5, 0.3, 4.0),
    "fast evolution": (0.7, 3.0, 2.5, 0.4),
    "stiff": (10.0, 0.1, 0.2, 5.0),
    # alpha_d >> alpha and alpha/mu = (alpha + alpha_d)/mu_d: delta/tau ~ sqrt(alpha/alpha_d)
    "nearly degenerate, delta ~ 1e-4": (1.0, 1e8, 1.0, 1e8),
    "nearly degenerate, delta ~ 1e-7": (1.0, 1e14, 1.0, 1e14),
}
TIMES = np.concatenate([[0.0], np.geomspace(1e-3, 20.0, 14)])


def paper_matrix(alpha: float, alpha_d: float, mu: float, mu_d: float) -> np.ndarray:
    """A of Section 5, read off eqs. twist, nattwist: d/dt (u, u_d) = -A (u, u_d) + (m/mu, 0)."""
    return np.array([[alpha / mu, -alpha / mu], [-alpha / mu_d, (alpha + alpha_d) / mu_d]])


def delta_of(matrix: np.ndarray) -> float:
    """delta = sqrt(-det(A - tr(A)/2 I))."""
    traceless = matrix - 0.5 * np.trace(matrix) * np.eye(2)
    return math.sqrt(-np.linalg.det(traceless))


def integrate_twist(params, m, t_eval, scale, breaks=()):
    """solve_ivp of eqs. twist, nattwist from rest, across the load's kinks ``breaks``."""
    alpha, alpha_d, mu, mu_d = params

    def rhs(t, y):
        u, u_d = y
        return [(m(t) - alpha * (u - u_d)) / mu,                    # eq. twist
                (alpha * u - (alpha + alpha_d) * u_d) / mu_d]       # eq. nattwist

    return _piecewise_ivp(rhs, [0.0, 0.0], t_eval, scale, breaks)


def _piecewise_ivp(rhs, y0, t_eval, scale, breaks=()):
    """Integrate with DOP853 from t = 0, restarting at each t_eval and each load kink in ``breaks``.

    Every output is the end point of a run (never solve_ivp's dense interpolant, whose
    error can exceed rtol), and no step straddles a kink of the load.
    """
    stops = np.union1d(np.union1d(t_eval, list(breaks)), [0.0])
    stops = stops[(stops >= 0.0) & (stops <= np.max(t_eval))]
    states = {0.0: np.asarray(y0, dtype=float)}
    y = states[0.0]
    for a, b in zip(stops[:-1], stops[1:]):
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-10, atol=1e-12 * np.asarray(scale))
        assert sol.success
        y = sol.y[:, -1]
        states[float(b)] = y
    return np.array([states[float(t)] for t in t_eval]).T


def scaled_error(closed, reference, scale) -> float:
    """max |closed - reference| / scale."""
    return float(np.max(np.abs(np.asarray(closed) - np.asarray(reference))) / scale)


# --- the matrix exponential ------------------------------------------------------------


def test_creep_matrix_is_the_matrix_of_twist_and_nattwist():
    np.testing.assert_array_equal(cf.creep_matrix(2.0, 0.5, 0.3, 4.0), paper_matrix(2.0, 0.5, 0.3, 4.0))
    assert np.linalg.det(cf.creep_matrix(2.0, 0.5, 0.3, 4.0)) == pytest.approx(2.0 * 0.5 / (0.3 * 4.0), rel=1e-14)


@pytest.mark.parametrize("params", CREEP_PARAMETERS.values(), ids=CREEP_PARAMETERS.keys())
def test_corrected_exponential_matches_expm(params):
    A = paper_matrix(*params)
    closed = cf.creep_exponential(TIMES, *params)
    reference = np.array([expm(-t * A) for t in TIMES])
    assert closed.shape == (TIMES.size, 2, 2)
    assert scaled_error(closed, reference, 1.0) < RTOL_EXPM    # entries of exp(-tA) are O(1)


def test_exponential_has_no_division_by_zero():
    # t = 0 makes delta t = 0 exactly, and delta ~ 1e-15 makes delta t ~ 1e-14: the
    # sinh(delta t)/delta factor must tend to t without any 0/0 or overflow.
    params = (1.0, 1e30, 1.0, 1e30)
    A = paper_matrix(*params)
    assert delta_of(A) < 1e-12
    with np.errstate(all="raise"):
        closed = cf.creep_exponential(np.array([0.0, 0.5, 3.0]), *params)
    np.testing.assert_array_equal(closed[0], np.eye(2))
    reference = np.array([expm(-t * A) for t in (0.0, 0.5, 3.0)])
    assert scaled_error(closed, reference, 1.0) < RTOL_EXPM


def test_paper_uncorrected_exponential_is_wrong():
    """docs/corrections.md item 2: without the division by delta the paper's formula is not exp(-tA)."""
    params = CREEP_PARAMETERS["fast Kelvin-Voigt"]
    A = paper_matrix(*params)
    tau = 0.5 * np.trace(A)
    B = A - tau * np.eye(2)
    delta = delta_of(A)
    assert abs(delta - 1.0) > 0.5             # the typo is harmless only when delta = 1
    t = 0.8
    paper = np.exp(-tau * t) * (np.cosh(delta * t) * np.eye(2) - np.sinh(delta * t) * B)
    corrected = np.exp(-tau * t) * (np.cosh(delta * t) * np.eye(2) - np.sinh(delta * t) / delta * B)
    reference = expm(-t * A)
    assert scaled_error(corrected, reference, 1.0) < RTOL_EXPM
    assert scaled_error(paper, reference, 1.0) > 0.1
    assert scaled_error(cf.creep_exponential(t, *params), reference, 1.0) < RTOL_EXPM


# --- creep, mu > 0 ---------------------------------------------------------------------


@pytest.mark.parametrize("params", CREEP_PARAMETERS.values(), ids=CREEP_PARAMETERS.keys())
def test_creep_matches_solve_ivp(params):
    m0 = 1.3
    alpha, alpha_d, _, _ = params
    scale = np.array(cf.equilibrium_twists(m0, alpha, alpha_d))
    twist, natural_twist = cf.creep(TIMES, m0, *params)
    reference = integrate_twist(params, lambda t: m0, TIMES, scale)
    assert scaled_error(twist, reference[0], scale[0]) < RTOL_IVP
    assert scaled_error(natural_twist, reference[1], scale[1]) < RTOL_IVP


@pytest.mark.parametrize("params", CREEP_PARAMETERS.values(), ids=CREEP_PARAMETERS.keys())
def test_creep_matches_duhamel_with_expm(params):
    # eq. creepform: (I - exp(-tA)) A^{-1} (m0/mu, 0), with expm and a linear solve
    m0 = -0.6
    A = paper_matrix(*params)
    w = np.linalg.solve(A, [m0 / params[2], 0.0])
    reference = np.array([(np.eye(2) - expm(-t * A)) @ w for t in TIMES]).T
    closed = np.array(cf.creep(TIMES, m0, *params))
    # relative to |w|: (I - expm) @ w loses digits of the tiny u_d ~ 1e-8 |w| (degenerate sets)
    assert scaled_error(closed, reference, np.max(np.abs(w))) < RTOL_EXPM


@pytest.mark.parametrize("params", CREEP_PARAMETERS.values(), ids=CREEP_PARAMETERS.keys())
def test_creep_starts_at_rest_and_tends_to_the_paper_limits(params):
    m0 = 2.0
    alpha, alpha_d, _, _ = params
    u_inf, u_d_inf = (alpha + alpha_d) * m0 / (alpha * alpha_d), m0 / alpha_d    # eq. nattwistasymp
    assert cf.equilibrium_twists(m0, alpha, alpha_d) == pytest.approx((u_inf, u_d_inf), rel=1e-15)
    slowest = min(np.linalg.eigvals(paper_matrix(*params)).real)
    assert cf.creep(0.0, m0, *params) == (0.0, 0.0)
    late = cf.creep(60.0 / slowest, m0, *params)                  # exp(-60) ~ 1e-26
    assert late == pytest.approx((u_inf, u_d_inf), rel=1e-13)


def test_creep_is_zero_before_the_load_and_keeps_the_shape_of_t():
    params = CREEP_PARAMETERS["unit"]
    t = np.array([[-2.0, -1e-9], [0.0, 1.0]])
    twist, natural_twist = cf.creep(t, 1.0, *params)
    assert twist.shape == natural_twist.shape == (2, 2)
    np.testing.assert_array_equal(twist[0], 0.0)
    np.testing.assert_array_equal(natural_twist[0], 0.0)
    assert isinstance(cf.creep(1.0, 1.0, *params)[0], float)


def test_creep_tends_to_inviscid_creep_as_mu_vanishes():
    # For t >> mu/alpha the Kelvin-Voigt boundary layer is gone; the difference is O(mu).
    alpha, alpha_d, mu_d, m0 = 1.5, 0.8, 2.0, 1.0
    t = np.array([1.0, 3.0, 10.0])
    viscous = np.array(cf.creep(t, m0, alpha, alpha_d, 1e-7, mu_d))
    inviscid = np.array(cf.creep_inviscid(t, m0, alpha, alpha_d, mu_d))
    assert scaled_error(viscous, inviscid, 1.0) < 1e-5


# --- creep, mu = 0 ---------------------------------------------------------------------

INVISCID_PARAMETERS = [(1.0, 1.0, 1.0), (2.0, 0.5, 4.0), (0.3, 7.0, 0.05)]   # (alpha, alpha_d, mu_d)


def inviscid_reference(alpha, alpha_d, mu_d, m, t_eval, scale, breaks=()):
    """mu = 0 by substitution: mu_d u_d' + alpha_d u_d = m, then alpha (u - u_d) = m."""
    def rhs(t, y):
        return [(m(t) - alpha_d * y[0]) / mu_d]

    natural_twist = _piecewise_ivp(rhs, [0.0], t_eval, [scale], breaks)[0]
    return m(t_eval) / alpha + natural_twist, natural_twist


@pytest.mark.parametrize("params", INVISCID_PARAMETERS)
def test_inviscid_creep_matches_solve_ivp(params):
    alpha, alpha_d, mu_d = params
    m0 = 0.9
    scale = abs(m0) * (alpha + alpha_d) / (alpha * alpha_d)
    twist, natural_twist = cf.creep_inviscid(TIMES, m0, *params)
    ref_twist, ref_natural_twist = inviscid_reference(alpha, alpha_d, mu_d, lambda t: m0 * np.ones_like(t), TIMES, scale)
    assert scaled_error(twist, ref_twist, scale) < RTOL_IVP
    assert scaled_error(natural_twist, ref_natural_twist, scale) < RTOL_IVP


@pytest.mark.parametrize("params", INVISCID_PARAMETERS)
def test_inviscid_creep_jumps_then_tends_to_the_paper_limits(params):
    alpha, alpha_d, mu_d = params
    m0 = -1.7
    assert cf.creep_inviscid(-1.0, m0, *params) == (0.0, 0.0)
    assert cf.creep_inviscid(0.0, m0, *params) == pytest.approx((m0 / alpha, 0.0), abs=1e-15)
    late = cf.creep_inviscid(60.0 * mu_d / alpha_d, m0, *params)
    assert late == pytest.approx(cf.equilibrium_twists(m0, alpha, alpha_d), rel=1e-13)


HISTORIES = {
    "step": (loads.step(1.2), ()),
    "ramp": (loads.ramp(1.5, 0.7), (0.7,)),
    "smooth step": (loads.smooth_step(-2.0, 0.3), (0.3,)),
    "table": (loads.table([0.0, 1.0, 2.0, 4.0], [0.0, 1.0, -0.5, 0.25]), (1.0, 2.0, 4.0)),
    "sine": (loads.from_callable(math.sin), ()),
}


@pytest.mark.parametrize("history, breaks", HISTORIES.values(), ids=HISTORIES.keys())
def test_convolution_creep_matches_solve_ivp(history, breaks):
    """docs/corrections.md item 3: u = m/alpha + (1/mu_d) int exp(-(alpha_d/mu_d)(t - s)) m(s) ds."""
    alpha, alpha_d, mu_d = 2.0, 0.5, 1.5
    t = np.linspace(0.0, 6.0, 13)
    scale = 2.0 * (alpha + alpha_d) / (alpha * alpha_d)          # |m| <= 2
    twist, natural_twist = cf.creep_response(t, history, alpha, alpha_d, mu_d)
    ref_twist, ref_natural_twist = inviscid_reference(alpha, alpha_d, mu_d, history, t, scale, breaks)
    assert scaled_error(twist, ref_twist, scale) < RTOL_IVP
    assert scaled_error(natural_twist, ref_natural_twist, scale) < RTOL_IVP


def test_paper_uncorrected_convolution_is_wrong():
    """docs/corrections.md item 3: the paper's u = m + (alpha/mu_d) int exp(-alpha_d mu_d (t - s)) m ds is not the solution."""
    alpha, alpha_d, mu_d, m0, t = 2.0, 0.5, 1.5, 1.0, 3.0
    paper = m0 + alpha / mu_d * m0 * (1.0 - math.exp(-alpha_d * mu_d * t)) / (alpha_d * mu_d)
    twist, _ = cf.creep_response(t, loads.step(m0), alpha, alpha_d, mu_d)
    ref_twist, _ = inviscid_reference(alpha, alpha_d, mu_d, loads.step(m0), np.array([t]), 1.0)
    assert abs(twist - ref_twist[0]) < RTOL_IVP
    assert abs(paper - ref_twist[0]) > 0.1


# --- stress relaxation -----------------------------------------------------------------

RELAXATION_PARAMETERS = [(1.0, 1.0, 1.0), (2.0, 0.5, 4.0), (0.3, 7.0, 0.05), (5.0, 1e-6, 1.0)]  # (alpha, alpha_d, mu_d)


@pytest.mark.parametrize("params", RELAXATION_PARAMETERS)
def test_relaxation_matches_solve_ivp(params):
    # u = u0 for t > 0: nattwist is mu_d u_d' = alpha u0 - (alpha + alpha_d) u_d, and
    # twist with u' = 0 gives the torsion m = alpha (u0 - u_d).
    alpha, alpha_d, mu_d = params
    u0 = 0.4
    natural_twist, torsion = cf.relaxation(TIMES, u0, *params)
    ref = _piecewise_ivp(lambda t, y: [(alpha * u0 - (alpha + alpha_d) * y[0]) / mu_d], [0.0], TIMES, [u0])[0]
    assert scaled_error(natural_twist, ref, u0) < RTOL_IVP
    assert scaled_error(torsion, alpha * (u0 - ref), alpha * u0) < RTOL_IVP


@pytest.mark.parametrize("params", RELAXATION_PARAMETERS)
def test_relaxation_decreases_from_alpha_u0_to_the_relaxed_torsion(params):
    alpha, alpha_d, mu_d = params
    u0 = 1.1
    natural_twist, torsion = cf.relaxation(np.linspace(0.0, 60.0 * mu_d / (alpha + alpha_d), 200), u0, *params)
    assert torsion[0] == pytest.approx(alpha * u0, rel=1e-15)               # m(0+) = alpha u0
    assert natural_twist[0] == 0.0
    assert np.all(np.diff(torsion) <= 0.0)
    assert cf.relaxed_torsion(u0, alpha, alpha_d) == pytest.approx(alpha * alpha_d * u0 / (alpha + alpha_d), rel=1e-15)
    assert torsion[-1] == pytest.approx(cf.relaxed_torsion(u0, alpha, alpha_d), rel=1e-12)
    assert natural_twist[-1] == pytest.approx(alpha * u0 / (alpha + alpha_d), rel=1e-12)
    assert cf.relaxation(-0.5, u0, *params) == (0.0, 0.0)


def test_relaxation_impulse_is_the_limit_of_regularised_steps():
    """The impulse of the idealised step is defined (Section 5) as the limit of
    int_0^eps m dt for the ramp u = u0 t/eps: computed here from that definition
    (eq. twist m = alpha (u - u_d) + mu u', eq. nattwist for u_d by solve_ivp, quad for
    the integral).  Since 0 <= u - u_d <= u on [0, eps], the integral exceeds mu u0 by
    between 0 and alpha u0 eps/2: that bound is the tolerance, and it shrinks with eps."""
    from scipy.integrate import quad, solve_ivp
    alpha, alpha_d, mu, mu_d, u0 = 2.0, 1.0, 2.5, 0.5, 0.4
    for eps in (1e-2, 1e-3):
        u = lambda t: u0 * t / eps  # noqa: E731
        sol = solve_ivp(lambda t, y: [(alpha * u(t) - (alpha + alpha_d) * y[0]) / mu_d],
                        (0.0, eps), [0.0], rtol=1e-12, atol=1e-15, dense_output=True)
        elastic, _ = quad(lambda t: alpha * (u(t) - sol.sol(t)[0]), 0.0, eps, epsabs=1e-15)
        impulse = elastic + mu * (u(eps) - u(0.0))
        excess = impulse - cf.relaxation_impulse(u0, mu)
        assert 0.0 <= excess <= alpha * u0 * eps / 2, (eps, excess)
    assert cf.relaxation_impulse(0.4, 0.0) == 0.0


# --- bad input -------------------------------------------------------------------------

BAD_CALLS = [
    (lambda: cf.creep_matrix(-1.0, 1.0, 1.0, 1.0), r"^alpha must be > 0, got -1\.0"),
    (lambda: cf.creep_matrix(1.0, 0.0, 1.0, 1.0), r"^alpha_d must be > 0, got 0\.0"),
    (lambda: cf.creep_matrix(1.0, 1.0, 0.0, 1.0), r"^mu must be > 0"),
    (lambda: cf.creep(1.0, 1.0, 1.0, 1.0, 0.0, 1.0), r"^mu must be > 0"),
    (lambda: cf.creep(1.0, 1.0, 1.0, 1.0, 1.0, -2.0), r"^mu_d must be > 0"),
    (lambda: cf.creep(1.0, math.inf, 1.0, 1.0, 1.0, 1.0), r"^m0 must be finite"),
    (lambda: cf.creep([0.0, math.nan], 1.0, 1.0, 1.0, 1.0, 1.0), r"^t must be finite"),
    (lambda: cf.creep_exponential(1.0, 1.0, 1.0, 1.0, math.nan), r"^mu_d must be finite"),
    (lambda: cf.creep_inviscid(1.0, 1.0, 0.0, 1.0, 1.0), r"^alpha must be > 0"),
    (lambda: cf.creep_inviscid(1.0, 1.0, 1.0, 1.0, 0.0), r"^mu_d must be > 0"),
    (lambda: cf.creep_response(1.0, loads.step(1.0), 1.0, -1.0, 1.0), r"^alpha_d must be > 0"),
    (lambda: cf.relaxation(1.0, math.nan, 1.0, 1.0, 1.0), r"^u0 must be finite"),
    (lambda: cf.relaxation(1.0, 1.0, 1.0, 1.0, 0.0), r"^mu_d must be > 0"),
    (lambda: cf.relaxation_impulse(1.0, -0.1), r"^mu must be >= 0, got -0\.1"),
    (lambda: cf.relaxed_torsion(1.0, 1.0, -3.0), r"^alpha_d must be > 0"),
    (lambda: cf.equilibrium_twists(1.0, -1.0, 1.0), r"^alpha must be > 0"),
]


@pytest.mark.parametrize("call, message", BAD_CALLS)
def test_bad_input_names_the_parameter_and_the_rule(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_non_numeric_parameter_is_a_type_error():
    with pytest.raises(TypeError, match="alpha must be a real number"):
        cf.creep_matrix("1", 1.0, 1.0, 1.0)
