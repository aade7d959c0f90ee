"""Segment contact on the C^1 centre line (contact.pair_curve = "smooth"; issue 26,
rod/smooth_pairs.py, docs/contact.md "Smooth pairs").

References: Taylor tests of the pair energy's gradient and Hessian (second-order
remainders: ratio 4 per halving); the Catmull-Rom curve through collinear nodes is their
line (it reproduces quadratics), so a straight rod crossing another straight rod has
the line-to-line distance, and so the same energy, wherever the crossing lies along
the segments and across their nodes (the segment pairs count a crossing on a node
twice or four times); the tangent stiffness of cosseratbench's crossing ropes
(tests/test_crossing_ropes.py) counts its negative eigenvalues.
"""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod.analysis.stability import TangentStiffness
from dolfin_rod.rod.contact import ContactLaw, check_contact
from dolfin_rod.rod.segments import closest_points
from dolfin_rod.rod.smooth_pairs import Stencils, closest, smooth_pair_energy

R, DELTA = 0.005, 0.02          # the barrier acts below 2 R + DELTA = 0.03


def _two_rods(a, b):
    """Stencils of two open rods with nodes a (n, 3) and b (m, 3): positions, Stencils."""
    n, m = len(a), len(b)
    ends = np.array([[k, k + 1] for k in range(n - 1)]
                    + [[n + k, n + k + 1] for k in range(m - 1)])
    rod = np.repeat([0, 1], [n - 1, m - 1])
    return np.vstack([a, b]), Stencils(ends, rod)


def _terms(P, st, pair, free=None):
    """(E, G, H) of segment pair (i, j) at positions P and its closest points."""
    pair = np.asarray(pair)[None]
    Y = P[st.nodes[pair].reshape(1, 8)]
    wa, wb = ((lambda rows, u: st.weights(pair[rows, 0], u)),
              (lambda rows, u: st.weights(pair[rows, 1], u)))
    s0, t0, _ = closest_points(Y[:, 1], Y[:, 2], Y[:, 5], Y[:, 6])
    s, t, d, _, _ = closest(Y, wa, wb, s0, t0)
    free = ((s > 0) & (s < 1), (t > 0) & (t < 1)) if free is None else free
    E, G, H = smooth_pair_energy(Y, wa, wb, s, t, free, R, DELTA, 1.0, [1.0])
    return E[0], G[0], H[0], s[0], t[0]


def _curved(beyond_start=False):
    """A bent rod along e_1 (from x = -0.5) and one along e_2 crossing it from above
    (6 nodes each), or passing just beyond its start."""
    u = np.arange(6) * 0.2 - 0.5
    a = np.column_stack([u, 0.05 * np.sin(3 * u), -0.3 * u**2])
    if beyond_start:
        b = np.column_stack([-0.51 + 0.1 * u**2, u + 0.03, -0.06 + 0.1 * u**2])
    else:
        b = np.column_stack([0.3 * np.cos(2 * u) - 0.2, u + 0.03, 0.012 + 0.2 * u**2])
    return _two_rods(a, b)


@pytest.mark.parametrize("pair, where", [((2, 7), "inside both segments"),
                                         ((0, 7), "beyond the first rod's start")])
def test_smooth_pair_gradient_and_hessian_are_consistent(pair, where):
    """Energy, gradient and Hessian (24 x 24: the two segments' four stencil nodes each)
    of a pair of curved rods crossing inside both segments, and of a pair whose closest
    point is held at a rod's end: the Taylor remainders of E and of the gradient fall
    4x per halving (exact derivatives; a wrong Hessian gives 2x).  Tolerance 0.05: the
    next order's share at these steps."""
    P, st = _curved(beyond_start=where.endswith("start"))
    nodes = st.nodes[np.asarray(pair)].ravel()
    E0, G0, H0, s, t = _terms(P, st, pair)
    assert E0 > 0 and 0 < t < 1 and (0 < s < 1 if where.startswith("inside") else s == 0)
    dY = np.random.default_rng(5).standard_normal((8, 3)) * 1e-3
    remainders = []
    for k in range(5):
        e = 0.05 / 2**k
        Q = P.copy()
        np.add.at(Q, nodes, e * dY)             # a stencil node may appear twice
        E1, G1, _, _, _ = _terms(Q, st, pair)
        step = np.zeros((len(P), 3))
        np.add.at(step, nodes, e * dY)
        dy = step[nodes].ravel()
        remainders.append((abs(E1 - E0 - G0 @ dy), np.linalg.norm(G1 - G0 - H0 @ dy)))
    remainders = np.array(remainders)
    ratios = remainders[:-1] / remainders[1:]
    assert np.allclose(ratios, 4.0, atol=0.05), ratios


RADIUS, GAP = 0.01, 0.002       # the straight crossing's contact law


def _straight_crossing(x0, y0, pair_curve, gap=GAP / 2):
    """Rod A (8 cells of 0.125) along e_1 from 0, rod B along e_2 crossing it at (x0,
    y0) with its centre line 2 R + gap above: the system's SegmentContact."""
    from dolfin_rod.rod import RodParameters
    from dolfin_rod.rod.rods import Rod
    from dolfin_rod.rod.system import RodSystem
    params = RodParameters(length=1.0, A=(1.0,) * 3, B=(1e3,) * 3)
    rods = [Rod(params, 8, "clamped", orientation=(0, np.pi / 2, 0), name="A"),
            Rod(params, 8, "clamped", position=(x0, y0 - 0.5, 2 * RADIUS + gap),
                orientation=(-np.pi / 2, 0, 0), name="B")]
    system = RodSystem(rods, model="hyperelastic", contact=ContactLaw(
        RADIUS, GAP, 1.0, between_rods=True, pair_curve=pair_curve))
    system.set_initial_state()
    return system.segment_contact


def _pairs_at(x0, y0, pair_curve):
    contact = _straight_crossing(x0, y0, pair_curve)
    return contact.evaluate(contact.owned_displacement())


@pytest.mark.mpi
def test_a_straight_crossing_has_one_energy_wherever_it_lies():
    """Two straight rods crossing at right angles, the crossing moved along A across its
    node at x = 0.5 (and B's at y = 0): with smooth pairs one pair carries kappa w
    b(g), w = h = 0.125, the line-to-line gap's barrier, at every position (to round-off:
    the curves through collinear nodes are the lines); the segment pairs count the
    crossing on a node twice (on two nodes four times)."""
    from dolfin_rod.rod.contact import barrier_derivatives
    exact = 0.125 * barrier_derivatives(np.array([GAP / 2]), GAP)[0][0]
    for x0, y0 in [(0.45, 0.0625), (0.5 - 1e-7, 0.0625), (0.5, 0.0625), (0.53, 0.0625),
                   (0.5, 0.0), (0.56, 1e-9)]:
        terms = _pairs_at(x0, y0, "smooth")
        assert len(terms.pairs) == 1 and terms.energy.sum() == pytest.approx(
            exact, rel=1e-12), (x0, y0, terms.pairs, terms.energy)
    assert _pairs_at(0.5, 0.0625, "segments").energy.sum() == pytest.approx(
        2 * exact, rel=1e-12)
    assert _pairs_at(0.5, 0.0, "segments").energy.sum() == pytest.approx(
        4 * exact, rel=1e-12)


def test_bad_pair_curve_is_named():
    with pytest.raises(ValueError, match="contact.pair_curve"):
        check_contact([], ContactLaw(RADIUS, GAP, 1.0, between_rods=True,
                                     pair_curve="hermite"))


@pytest.mark.mpi
@pytest.mark.parametrize("pair_curve", ["segments", "smooth"])
def test_the_continuous_check_sees_the_curves_pass_through(pair_curve):
    """Rod B moved straight down through rod A by 8 R (it ends 2 R + 2.9 delta below A:
    no overlap at the end, only the path shows the passage): the path check names a
    pair (the segment pairs missed it before the round-off margin: the distance is a V
    of exactly the bound's slope); moved sideways along A, none.  Newton's update limit
    along the path down: the largest 2^-k at which the gap stays above a tenth of its
    start, the gap delta / 2 closing at 8 R tau: tau < 0.9 (delta / 2) / (8 R) =
    0.01125, so 1/128 (the curves through collinear nodes are the lines: the same for
    both)."""
    contact = _straight_crossing(0.53, 0.0625, pair_curve)
    P0 = contact.line.positions(contact.owned_displacement())
    on_b = np.unique(contact.line.ends[contact.line.rod == 1])
    down, along = P0.copy(), P0.copy()
    down[on_b, 2] -= 8 * RADIUS
    along[on_b, 0] += 0.3
    assert contact.crossed(P0, down) is not None
    assert contact.crossed(P0, along) is None
    assert contact.step_fraction(P0, down) == 1 / 128
