"""The tangent stiffness of analysis/ with segment contact (issue 26/27; docs/stability.md,
docs/contact.md): the pairs' energy Hessians are part of K (analysis/stability.py
TangentStiffness), so the stability monitor's count and lowest eigenvalue and the
vibration and buckling modes see the contact's stiffness.

References: a cantilever whose tip rests on a stiff crossing rod vibrates as a
cantilever on an elastic tip support of the barrier's stiffness at the equilibrium gap,
k = kappa w b''(g) (rod/contact.py's law, in series with the crossing rod's
192 EI_B / L_B^3), its frequency from the Euler-Bernoulli frequency equation (a 2x2
determinant, brentq), and buckles under an axial load as a column on that tip spring
(its own 2x2 determinant); the monitor's lowest eigenpairs against a central difference of
the residual (forms and pairs) along the eigenvector.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from dolfin_rod import TimeStepper
from dolfin_rod.analysis.eigen import eigenpairs
from dolfin_rod.analysis.stability import LowestEigenvalues, StabilityMonitor
from dolfin_rod.analysis.buckling import buckling_modes
from dolfin_rod.analysis.vibration import vibration_modes
from dolfin_rod.rod import EndLoad, RodParameters, StartingState
from dolfin_rod.rod.contact import ContactLaw, barrier_derivatives
from dolfin_rod.rod.rods import Rod
from dolfin_rod.rod.system import RodSystem

R, DELTA, KAPPA, EI, P, L = 0.01, 2e-3, 1e2, 1.0, 0.05, 1.0
B_LENGTH, B_EI, B_CELLS = 0.5, 1e3, 5      # A's tip over the middle of B's third segment


def _resting(n_cells: int, dynamic: bool, stiff_plane: float = EI,
             axial: float = 0.0, push: float = P) -> RodSystem:
    """Rod A along e_1 (EI = 1 towards B, ``stiff_plane`` in the other plane, clamped at
    0), its tip pressed by -push e_3 (and -axial t e_1) onto the stiff clamped-clamped rod
    B along e_2 at x = L, B's centre line 2 r + 1.5 delta below A's; dynamic: the start
    settled in static equilibrium (pairs included); quasi-static: the push ramped over t
    in [0, 1] in 4 steps (the state at t = 1)."""
    mass = dict(density=1.0, section_inertia=1e-8) if dynamic else {}
    beam = RodParameters(length=L, A=(stiff_plane, EI, EI), B=(1e4,) * 3, **mass)
    prop = RodParameters(length=B_LENGTH, A=(B_EI,) * 3, B=(1e6,) * 3, **mass)
    ramp = (lambda t: 1.0) if dynamic else (lambda t: min(t, 1.0))
    loads = [EndLoad("force", (0, 0, -push), ramp)]
    if axial:
        loads.append(EndLoad("force", (-axial, 0, 0), lambda t: t))
    rods = [Rod(beam, n_cells, "clamped", loads,
                orientation=(0, np.pi / 2, 0), name="A"),
            Rod(prop, B_CELLS, "clamped", end="clamped",
                position=(L, -B_LENGTH / 2, -(2 * R + 1.5 * DELTA)),
                orientation=(-np.pi / 2, 0, 0), name="B")]
    system = RodSystem(rods, model="hyperelastic",
                       contact=ContactLaw(R, DELTA, KAPPA, between_rods=True))
    start = StartingState(equilibrium=True) if dynamic else None
    system.set_initial_state(start={"A": start, "B": start} if start else None)
    if not dynamic:
        stepper = TimeStepper(system.problem)
        for k in range(4):
            stepper.run(k / 4, (k + 1) / 4, 1 / 4)
    return system


def _tip_spring(system, n_cells: int) -> float:
    """k L^3 / EI of the tip's support: the barrier's stiffness kappa w b''(g) at the
    equilibrium gap g (one pair, w = (h_A + h_B) / 2) in series with B's midspan
    stiffness 192 EI_B / L_B^3 (A's tip is over B's middle)."""
    d = system.diagnostics(1.0)
    assert d["contact_pairs"] == 1 and 0 < d["min_pair_gap"] < DELTA
    _, _, b2 = barrier_derivatives(np.array([d["min_pair_gap"]]), DELTA)
    k = KAPPA * 0.5 * (L / n_cells + B_LENGTH / B_CELLS) * b2[0]
    return L**3 / EI / (1 / k + B_LENGTH**3 / (192 * B_EI))


def _frequency_equation(beta_L: float, spring: float) -> float:
    """Cantilever with a tip spring (spring = k L^3/EI): w = a (cos - cosh) + b (sin -
    sinh)(beta x) meets w''(L) = 0 and EI w'''(L) = k w(L) where this determinant
    vanishes (spring = 0: cos cosh = -1, beta L = 1.8751; spring -> infinity: the
    propped cantilever's tan = tanh, 3.9266)."""
    c, s, ch, sh = np.cos(beta_L), np.sin(beta_L), np.cosh(beta_L), np.sinh(beta_L)
    q = spring / beta_L**3
    return np.linalg.det(np.array([[-c - ch, -s - sh],
                                   [s - sh - q * (c - ch), -c - ch - q * (s - sh)]]))


def test_frequency_equation_limits():
    """The reference's two limits: free cantilever and propped cantilever."""
    assert brentq(_frequency_equation, 1.5, 2.2, args=(0.0,)) == pytest.approx(
        1.8751040687, rel=1e-9)
    assert brentq(_frequency_equation, 3.5, 4.2, args=(1e12,)) == pytest.approx(
        3.9266023120, rel=1e-8)


@pytest.mark.mpi
def test_vibration_of_a_cantilever_resting_on_a_rod():
    """A (16 cells) rests with its tip on B: its first bending mode normal to the
    contact is that of a cantilever on a tip spring k = kappa w b''(g) (k L^3/EI =
    108.8 at the settled gap 0.34 delta), omega = (beta L)^2 sqrt(EI / rho A L^4);
    measured relative error 4.8e-3 at 16 cells (2.2e-2 at 8, 4.7e-4 at 32: the
    discretisation's; asserted 1e-2); the mode in the other plane is the free
    cantilever's 1.8751^2 (contact acts along e_3 only; 16-cell error 2.4e-4, asserted
    2e-3).  Without the pairs in K both would be 3.5169."""
    n = 16
    system = _resting(n, dynamic=True)
    spring = _tip_spring(system, n)
    roots = np.linspace(1.0, 5.0, 401)
    values = [_frequency_equation(x, spring) for x in roots]
    k = next(i for i in range(len(roots) - 1) if values[i] * values[i + 1] < 0)
    exact = brentq(_frequency_equation, roots[k], roots[k + 1], args=(spring,)) ** 2
    omega = vibration_modes(system, 0.0, 2).omega
    assert 30 < spring < 300        # between the free (0) and the propped (inf) limits
    assert omega[0] == pytest.approx(1.8751040687 ** 2, rel=2e-3)
    assert omega[1] == pytest.approx(exact, rel=1e-2)
    assert omega[1] > 3 * omega[0]


def _residual_difference(system, vector, eps):
    """(F(y + eps v) - F(y - eps v)) / (2 eps) of the tangent's system (forms at rest
    and the pairs), y its current state (kept)."""
    y = system.x.copy()
    system.get(0, y)
    out = []
    for sign in (1.0, -1.0):
        z = y.copy()
        z.axpy(sign * eps, vector)
        system.set(0, z)
        b = z.duplicate()
        system.residual(z, b)
        out.append(b)
    system.set(0, y)
    out[0].axpy(-1.0, out[1])
    out[0].scale(0.5 / eps)
    return out[0]


@pytest.mark.mpi
def test_stability_monitor_counts_with_the_pairs():
    """The quasi-static A resting on B: the monitor counts 0 negative eigenvalues; the
    four lowest eigenpairs of K v = lambda G v (LowestEigenvalues) satisfy
    (F(y + e v) - F(y - e v)) / 2e = lambda G v, the residual's central difference
    (forms and pairs), e = 1e-4: measured 2.6e-5 to 1.8e-4 of |lambda G v| (e = 1e-3:
    truncation, up to 8e-3; e = 1e-5: round-off of B's stiff forces, up to 1.2e-3);
    asserted 1e-3, while K without the pairs misses the barrier's stiffness at A's tip
    (k = 109 EI/L^3 against lambda G v of order 1).  The contact splits A's two bending
    planes (EI the same in both): the two lowest eigenvalues 2.069 and 2.460."""
    system = _resting(8, dynamic=False)
    monitor = StabilityMonitor(system, lowest=True)
    assert monitor.check(1.0) == 0
    tangent = monitor.tangent
    lowest = LowestEigenvalues(tangent)
    K = tangent.matrix(1.0)
    pairs = eigenpairs(K, lowest.G, 4, target=0.0)
    assert monitor.lowest == pytest.approx(min(pairs.values), rel=1e-9)
    for value, v in zip(pairs.values, pairs.vectors):
        v.array_w[tangent.system.bc_rows] = 0.0
        Gv = v.duplicate()
        lowest.G.mult(v, Gv)
        Gv.scale(value)
        difference = _residual_difference(tangent.system, v, 1e-4)
        difference.array_w[tangent.system.bc_rows] = 0.0
        difference.axpy(-1.0, Gv)
        assert difference.norm() < 1e-3 * Gv.norm(), (value, difference.norm())
    values = sorted(pairs.values)
    assert values[0] > 0 and values[1] > 1.1 * values[0]


def _buckling_equation(lam_L: float, spring: float) -> float:
    """Column clamped at x = 0, free at L under the axial dead load P = EI lam^2, its tip
    on a lateral spring (spring = k L^3 / EI): w = a + b x + c cos + d sin(lam x) with
    w(0) = w'(0) = 0 meets w''(L) = 0 and EI w''' + P w' = k w at L where this
    determinant vanishes (spring = 0: lam L = pi / 2; infinite: tan = id, 4.4934)."""
    c, s, q = np.cos(lam_L), np.sin(lam_L), lam_L
    w, slope, third = (c - 1, s - q), (-q * s, q * c - q), (q**3 * s, -q**3 * c)
    return np.linalg.det(np.array([[c, s], [third[i] + q**2 * slope[i] - spring * w[i]
                                            for i in range(2)]]))


def test_buckling_equation_limits():
    assert brentq(_buckling_equation, 1.0, 2.0, args=(0.0,)) == pytest.approx(np.pi / 2)
    assert brentq(_buckling_equation, 4.0, 4.6, args=(1e12,)) == pytest.approx(
        4.4934094579, rel=1e-9)


@pytest.mark.mpi
def test_buckling_of_a_column_resting_on_a_rod():
    """A (16 cells, EI = 1 for bending towards B, 1e3 in the other plane) pressed by
    1e-3 e_3 onto B and compressed along its axis by 5 t: buckling_modes at t = 1 (the
    pairs' stiffness in K, frozen along the path: K' has the stress rates only) against
    the column on a tip spring k = kappa w b''(g) at the gap of t = 1 (k L^3/EI = 24.9:
    P_cr = 16.61 EI/L^2, between the free column's 2.47 and the propped one's 20.19);
    measured relative error 3.0e-2, 6.4e-3, 2.4e-4 at 8, 16, 32 cells (the gap, so k,
    changes with the mesh too); asserted 1.5e-2 at 16."""
    n, axial = 16, 5.0
    system = _resting(n, dynamic=False, stiff_plane=1e3, axial=axial, push=1e-3)
    spring = _tip_spring(system, n)
    roots = np.linspace(1.0, 4.6, 361)
    values = [_buckling_equation(x, spring) for x in roots]
    k = next(i for i in range(len(roots) - 1) if values[i] * values[i + 1] < 0)
    exact = brentq(_buckling_equation, roots[k], roots[k + 1], args=(spring,)) ** 2
    assert 10 < exact < 19
    factors = buckling_modes(system, 1.0, 1).load_factors
    assert axial * factors[0] == pytest.approx(exact, rel=1.5e-2)
