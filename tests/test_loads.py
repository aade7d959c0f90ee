"""Load histories (dolfin_rod.loads) against hand-computed values.

Values of piecewise-linear and polynomial histories at chosen points are exact up to one
or two roundings, so they are compared to 1e-15 relative; derivative checks use
one-sided difference quotients with step h, whose error is O(h).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dolfin_rod import loads
from dolfin_rod.loads import LoadHistory, jump_at

EXACT = 1e-15


@pytest.mark.parametrize("history, start_limits, is_step", [
    (loads.constant(1.0), (1.0, 1.0), False),                    # also before t = 0
    (loads.step(1.0), (0.0, 1.0), True),                         # H(0) = 1
    (loads.step(1.0, 0.5), (0.0, 0.0), False),                   # jumps later, not at 0
    (loads.ramp(1.0, 2.0), (0.0, 0.0), False),
    (loads.smooth_step(1.0, 0.5), (0.0, 0.0), False),
    (loads.table([0.0, 1.0], [2.0, 1.0]), (2.0, 2.0), False),    # constant beyond the ends
    (loads.from_callable(math.cos), (1.0, 1.0), False),
    (loads.from_callable(lambda t: 1.0 if t >= 0 else 0.0, {0.0: 1.0}), (0.0, 1.0), True),
])
def test_every_constructor_keeps_the_load_history_contract(history, start_limits, is_step):
    """Not only the protocol's attributes: the values (f(0-), f(0+)) and is_step each
    constructor must give, derived by hand from its definition."""
    assert isinstance(history, LoadHistory)
    assert history.start_limits == start_limits and history.is_step is is_step


@pytest.mark.parametrize("history", [loads.constant(2.0), loads.step(2.0), loads.ramp(2.0, 1.0),
                                     loads.smooth_step(2.0, 1.0), loads.table([0.0, 1.0], [0.0, 2.0]),
                                     loads.from_callable(math.sin)])
def test_vectorised_on_arrays_and_float_on_scalars(history):
    t = np.array([[-1.0, 0.0, 0.25], [0.5, 1.0, 3.0]])
    values = history(t)
    assert values.shape == t.shape
    assert isinstance(history(0.25), float)
    for index in np.ndindex(t.shape):
        assert values[index] == history(float(t[index]))


def test_constant_is_continuous_everywhere():
    h = loads.constant(-3.5)
    np.testing.assert_array_equal(h(np.array([-10.0, 0.0, 7.0])), -3.5)
    assert h.start_limits == (-3.5, -3.5)
    assert not h.is_step
    assert jump_at(h, 0.0) == 0.0


def test_step_is_a_heaviside_with_h0_equal_one():
    h = loads.step(2.0, t0=1.5)
    assert h(1.5) == 2.0                                   # H(0) = 1
    assert h(np.nextafter(1.5, -np.inf)) == 0.0
    assert h.left_limit(1.5) == 0.0
    assert jump_at(h, 1.5) == 2.0
    np.testing.assert_array_equal(jump_at(h, np.array([0.0, 1.0, 1.5, 2.0])), [0.0, 0.0, 2.0, 0.0])
    assert not h.is_step                                   # no jump at t = 0 itself
    at_zero = loads.step(-0.7)
    assert at_zero.start_limits == (0.0, -0.7)
    assert at_zero.is_step


def test_ramp_values():
    h = loads.ramp(3.0, 2.0)
    np.testing.assert_allclose(h(np.array([-1.0, 0.0, 0.5, 1.0, 2.0, 5.0])), [0.0, 0.0, 0.75, 1.5, 3.0, 3.0], rtol=EXACT)
    assert not h.is_step
    assert jump_at(h, 2.0) == 0.0


def test_smooth_step_is_a_monotone_c1_regularisation_of_the_step():
    v, width = 2.0, 0.4
    h = loads.smooth_step(v, width)
    # cubic smoothstep v x^2 (3 - 2x), x = t / width: hand values at x = 0, 1/4, 1/2, 1
    np.testing.assert_allclose(h(np.array([-1.0, 0.0, 0.1, 0.2, 0.4, 9.0])),
                               [0.0, 0.0, v * 5.0 / 32.0, v / 2.0, v, v], rtol=EXACT)
    t = np.linspace(-0.1, 0.5, 2001)
    assert np.all(np.diff(h(t)) >= 0.0)
    # C^1: one-sided slopes agree at the junctions (slope 0 there) and at a middle point
    h_step = 1e-6
    for t0 in (0.0, width):
        left = (h(t0) - h(t0 - h_step)) / h_step
        right = (h(t0 + h_step) - h(t0)) / h_step
        assert abs(left) < 1e-4 and abs(right) < 1e-4
    slope_mid = 6.0 * v * 0.5 * 0.5 / width                 # v S'(1/2) / width, S' = 6x(1 - x)
    assert (h(0.2 + h_step) - h(0.2 - h_step)) / (2 * h_step) == pytest.approx(slope_mid, rel=1e-8)
    assert not h.is_step
    assert h.start_limits == (0.0, 0.0)


def test_table_interpolates_linearly_and_is_constant_beyond_the_ends():
    h = loads.table([1.0, 2.0, 4.0], [3.0, -1.0, 0.0])
    np.testing.assert_allclose(h(np.array([-5.0, 1.0, 1.25, 2.0, 3.0, 4.0, 10.0])),
                               [3.0, 3.0, 2.0, -1.0, -0.5, 0.0, 0.0], rtol=EXACT)
    assert not h.is_step
    assert jump_at(h, 2.0) == 0.0
    assert loads.table([0.5], [7.0])(np.array([0.0, 1.0])).tolist() == [7.0, 7.0]


def test_from_callable_accepts_scalar_and_vectorised_functions():
    t = np.array([0.0, 0.3, 1.2])
    np.testing.assert_allclose(loads.from_callable(math.sin)(t), np.sin(t), rtol=EXACT)
    np.testing.assert_allclose(loads.from_callable(np.cos)(t), np.cos(t), rtol=EXACT)
    np.testing.assert_array_equal(loads.from_callable(lambda s: 2.0)(t), 2.0)
    assert not loads.from_callable(math.cos).is_step


def test_from_callable_with_declared_jump():
    h = loads.from_callable(lambda s: np.where(s >= 0.0, 1.0 + s, 0.0), jumps={0.0: 1.0})
    assert h.start_limits == (0.0, 1.0)
    assert h.is_step
    assert jump_at(h, 0.0) == 1.0
    assert jump_at(h, 0.5) == 0.0


BAD_CALLS = [
    (lambda: loads.constant(math.nan), ValueError, r"^v must be finite"),
    (lambda: loads.step(math.inf), ValueError, r"^v must be finite"),
    (lambda: loads.step(1.0, t0=math.nan), ValueError, r"^t0 must be finite"),
    (lambda: loads.ramp(1.0, 0.0), ValueError, r"^t_ramp must be > 0, got 0\.0"),
    (lambda: loads.smooth_step(1.0, -1.0), ValueError, r"^width must be > 0, got -1\.0"),
    (lambda: loads.table([0.0, 1.0, 1.0], [0.0, 1.0, 2.0]), ValueError, r"^load table times must be strictly increasing"),
    (lambda: loads.table([0.0, 2.0, 1.0], [0.0, 1.0, 2.0]), ValueError, r"^load table times must be strictly increasing"),
    (lambda: loads.table([0.0, 1.0], [0.0]), ValueError, r"^load table times and values must have the same length, got 2 and 1"),
    (lambda: loads.table([], []), ValueError, r"^load table needs at least one point"),
    (lambda: loads.table([0.0, math.nan], [0.0, 1.0]), ValueError, r"^load table times and values must be finite"),
    (lambda: loads.table([[0.0, 1.0]], [[0.0, 1.0]]), ValueError, r"^load table times and values must be one-dimensional"),
    (lambda: loads.step(1.0)(np.array([0.0, math.nan])), ValueError, r"^load time t must not be NaN"),
    (lambda: loads.step(1.0)(math.nan), ValueError, r"^load time t must not be NaN"),
    (lambda: loads.from_callable(3.0), TypeError, r"^f must be callable"),
    (lambda: loads.constant("1"), TypeError, r"^v must be a real number"),
]


@pytest.mark.parametrize("call, error, message", BAD_CALLS)
def test_bad_input_names_the_parameter_and_the_rule(call, error, message):
    with pytest.raises(error, match=message):
        call()


def test_a_time_as_a_number_gives_the_value_at_it_in_an_array():
    """A history called with one time (a float: an ODE's right-hand side, 2e5 calls in a
    fit) takes a path without array checks: its value is the array call's, bit for bit,
    as a float."""
    t = np.linspace(-1.0, 3.0, 81)
    for h in (loads.step(2.0, 0.5), loads.ramp(1.5, 0.7, t0=0.2), loads.smooth_step(3.0, 1.0),
              loads.table([0.0, 0.5, 2.0], [0.0, 1.0, -0.5]), loads.constant(0.25),
              loads.from_callable(math.sin), loads.from_callable(np.cos)):
        scalar = [h(float(x)) for x in t] + [h(x) for x in t]     # float and np.float64
        assert all(type(v) is float for v in scalar)
        assert scalar == [*h(t).tolist(), *h(t).tolist()], h


def test_ramp_and_smooth_step_start_at_t0():
    """Shifted by t0: ramp v (t - t0)/T on [t0, t0 + T] with slope v/T there and 0
    outside; the smooth step v S((t - t0)/w), S(1/2) = 1/2, S'(1/2) = 3/2."""
    r = loads.ramp(2.0, 0.5, t0=1.0)
    assert r(np.array([0.5, 1.0, 1.25, 1.5, 3.0])) == pytest.approx([0, 0, 1.0, 2.0, 2.0],
                                                                     rel=EXACT)
    assert loads.rate(r, 1.25) == 4.0 and loads.rate(r, 0.9) == 0.0 and loads.rate(r, 1.6) == 0.0
    assert r.start_limits == (0.0, 0.0) and not loads.jumps(r)
    s = loads.smooth_step(2.0, 0.4, t0=1.0)
    assert s(1.2) == pytest.approx(1.0, rel=EXACT) and s(0.99) == 0.0 and s(1.5) == 2.0
    assert loads.rate(s, 1.2) == pytest.approx(2.0 * 1.5 / 0.4, rel=EXACT)
    assert loads.ramp(2.0, 0.5)(0.25) == loads.ramp(2.0, 0.5, t0=0.0)(0.25) == 1.0
