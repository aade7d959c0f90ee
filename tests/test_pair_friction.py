"""Coulomb friction between segments in contact (issue 26, rod/pair_friction.py,
docs/contact.md): between rods and within a rod.

References: a rod lying across another, pressed by its weight N = rho_A L g and pulled
along the other by a uniform load of total P: below mu N it creeps at the speed y eps
of the smoothed law phi(y) = 3y/2 - y^3/2 = P / (mu N) (solved here by brentq), below the
slip tolerance eps; above it slides with the acceleration a of Newton's second law, so
the friction force P - m a equals Coulomb's mu N.  A ring whose ends collide and slide
across each other (self-contact with friction, no numerical damping): K + Psi + E_c +
the dissipated energy int D dt stays E(0) to the integrator's second order, and D >= 0
at every step.  mu = 0 is the frictionless code (bit for bit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from scipy.optimize import brentq

from dolfin_rod import TimeStepper
from dolfin_rod.rod import RodModel, RodParameters
from dolfin_rod.rod.contact import ContactLaw
from dolfin_rod.rod.external_forces import DistributedLoad
from dolfin_rod.rod.rods import Rod
from dolfin_rod.rod.start import StartingState
from dolfin_rod.rod.system import RodSystem
from dolfin_rod.scenes import SceneError, build, parse_scene

R, DELTA, RHO_A, G, L = 0.005, 5e-4, 0.1, 10.0, 0.2
MU, EPS, N_CELLS, DT = 0.5, 1e-3, 9, 1e-3
WEIGHT = RHO_A * L * G                  # the normal force N (0.2 N)
OPTIONS = {"snes_rtol": 1e-8, "snes_linesearch_type": "bt",
           "snes_divergence_tolerance": -1.0}
# A, stiff (its bending modes are far above 1 / dt: damped by rho_inf = 0 at once)
UPPER = RodParameters(length=L, A=(5.0,) * 3, B=(1e5,) * 3, density=RHO_A,
                      section_inertia=(6.25e-7, 6.25e-7))
LOWER = RodParameters(length=0.2, A=(50.0,) * 3, B=(1e6,) * 3, density=RHO_A,
                      section_inertia=(6.25e-7, 6.25e-7))


def _smooth(t, t0, t1):
    x = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
    return x * x * (3 - 2 * x)


def _crossing(pull: float, mu: float = MU, friction_key: bool = True, steps: int = 80):
    """Rod A (along e_2, free, 9 cells: the crossing is at the middle of a segment of
    both rods) lies across rod B (along e_1, clamped at both ends, 10x stiffer) under its
    weight; the load P = pull (total, along e_1, uniform) rises smoothly over t in
    [0.01, 0.03] s.  Kappa puts the barrier's gap at rest near delta / 2 (b'(delta / 2)
    = -1.19 delta), where A starts.  Returns the rows (t, A's tip x, the pairs' normal
    and friction forces, friction dissipation, smallest gap)."""
    loads = [DistributedLoad("force", (0, 0, -RHO_A * G)),
             DistributedLoad("force", (pull / L, 0, 0), lambda t: _smooth(t, 0.01, 0.03))]
    rods = [Rod(UPPER, N_CELLS, start="free", end="free", distributed_loads=loads,
                position=(0, -L / 2, 2 * R + 0.5 * DELTA), orientation=(-np.pi / 2, 0, 0),
                name="A"),
            Rod(LOWER, N_CELLS, start="clamped", end="clamped", position=(-0.1, 0, 0),
                orientation=(0, np.pi / 2, 0), name="B")]
    kappa = WEIGHT / (L / N_CELLS * 1.19 * DELTA)
    friction = {"between_rods_friction": mu} if friction_key else {}
    law = ContactLaw(R, DELTA, kappa, EPS, between_rods=True, **friction)
    system = RodSystem(rods, model="hyperelastic", contact=law)
    system.set_initial_state()
    stepper = TimeStepper(system.problem, "generalized_alpha:0.0", OPTIONS)
    rows = []
    for k in range(steps):
        stepper.run(k * DT, (k + 1) * DT, DT)
        d = system.diagnostics((k + 1) * DT)
        rows.append(((k + 1) * DT, d["A.tip_position_x"], d["pair_contact_force"],
                     d.get("pair_friction_force", 0.0), d.get("friction_dissipation", 0.0),
                     d["min_pair_gap"]))
    return system, np.array(rows)


@pytest.mark.mpi
def test_static_friction_between_rods_holds():
    """P = mu N / 2: A creeps at y eps with phi(y) = 1/2 (y = 0.3473), measured over
    t in [0.05, 0.08] s (the pull constant since 0.03 s) to 1 % (the lagged normal force
    oscillates by +-1 % about N in the barrier's vertical mode, a ~0.4 % swing of y;
    measured 3.4705e-4 m/s against 3.4730e-4); the creep is below eps; the friction
    force balances the pull (1e-3); its dissipation is >= 0 at every step and equals the
    friction force times the creep speed (1 %)."""
    _, rows = _crossing(0.5 * MU * WEIGHT)
    late = rows[:, 0] > 0.05 - 1e-9
    t, x = rows[late, 0], rows[late, 1]
    speed = (x[-1] - x[0]) / (t[-1] - t[0])
    y = brentq(lambda y: 1.5 * y - 0.5 * y**3 - 0.5, 0.0, 1.0)
    assert speed == pytest.approx(y * EPS, rel=1e-2)
    assert speed < EPS
    assert np.mean(rows[late, 3]) == pytest.approx(0.5 * MU * WEIGHT, rel=1e-3)
    assert rows[:, 4].min() >= 0.0
    assert np.mean(rows[late, 4]) == pytest.approx(0.5 * MU * WEIGHT * speed, rel=1e-2)
    assert 0.0 < rows[:, 5].min() < DELTA


@pytest.mark.mpi
def test_kinetic_friction_between_rods_is_mu_n():
    """P = 2 mu N: A slides along B with a = (P - mu N) / m; from a quadratic fit of its
    tip's x over t in [0.04, 0.08] s (slip speeds 0.06-0.26 m/s >> eps: the law is
    exactly Coulomb's) the friction force P - m a = mu N to 2e-3 (measured 1.8e-4: the
    lagged normal force's +-1 % oscillation averages out over the fit's 40 steps; B's
    slope under A over the 5 mm slide, ~1e-4 rad, tilts the normal by that); the pairs'
    friction force diagnostic is mu times their lagged normal force (mean within 1 %),
    the dissipation is >= 0 and equals it times the slip speed."""
    _, rows = _crossing(2 * MU * WEIGHT)
    late = rows[:, 0] > 0.04 - 1e-9
    t, x = rows[late, 0], rows[late, 1]
    a = 2 * np.polyfit(t, x, 2)[0]
    assert 2 * MU * WEIGHT - RHO_A * L * a == pytest.approx(MU * WEIGHT, rel=2e-3)
    assert np.mean(rows[late, 3]) == pytest.approx(MU * WEIGHT, rel=1e-2)
    assert np.mean(rows[late, 2]) == pytest.approx(WEIGHT, rel=1e-2)
    assert rows[:, 4].min() >= 0.0
    speed = np.gradient(x, t)
    assert rows[late, 4][1:-1] == pytest.approx((rows[late, 3] * speed)[1:-1], rel=2e-2)


@pytest.mark.mpi
def test_zero_friction_is_the_frictionless_contact():
    """mu = 0 and the key absent: no friction term, and the runs are bit-identical
    serially (also to main's code before friction: checked by hand, docs/contact.md).
    Under 2 ranks two identical runs already differ at round-off (1e-37 in components
    of size 1e-23: MUMPS' parallel sums), so there: to 1e-15 of the state's size 0.6."""
    off, rows_off = _crossing(0.02, mu=0.0, steps=20)
    absent, rows_absent = _crossing(0.02, friction_key=False, steps=20)
    assert off.segment_contact.friction is None
    x_off, x_absent = (m.unknowns.f["displacement"].x.array for m in (off, absent))
    if MPI.COMM_WORLD.size == 1:
        assert np.array_equal(x_off, x_absent)
        assert np.array_equal(rows_off, rows_absent)
    else:
        assert np.allclose(x_off, x_absent, rtol=0.0, atol=1e-15)
        assert np.allclose(rows_off, rows_absent, rtol=1e-12, atol=1e-15)


def _ring(dt: float, t_end: float = 0.5):
    """A free ring (0.95 of a circle, 40 cells, r = 1 cm, test_pair_contact's) whose ends
    approach each other at 0.1 m/s and across each other out of the ring's plane at
    0.02 m/s: they collide and slide across each other with self-friction mu = 0.5;
    generalized-alpha with rho_inf = 1 (no numerical dissipation).  Returns (largest
    |W(t) - W(0)| of W = K + Psi + E_c + int_0^t D, the energy friction dissipated, the
    smallest friction dissipation rate of a step)."""
    params = RodParameters(length=1.0, A=(1e-2,) * 3, B=(10.0,) * 3, density=0.1,
                           section_inertia=(1e-6, 1e-6),
                           reference_curvature=(2 * np.pi * 0.95, 0, 0))
    rod = RodModel(params, 40, model="hyperelastic", start="free", end="free",
                   contact=ContactLaw(0.01, 0.002, 1e3, EPS, self=True,
                                      self_friction=0.5))
    ends, _ = rod.stress_free(np.array([0.0, 1.0]))
    chord = (ends[0] - ends[1]) / np.linalg.norm(ends[0] - ends[1])
    across = np.array([1.0, 0.0, 0.0])      # normal to the ring's plane (e_2, e_3)
    rod.set_initial_state(start=StartingState(
        velocity=lambda s: (2 * np.asarray(s) - 1)[:, None] * (0.1 * chord + 0.02 * across)))
    stepper = TimeStepper(rod.problem, "generalized_alpha:1.0",
                          {**OPTIONS, "snes_rtol": 1e-10, "snes_atol": 1e-12})
    balance, dissipated, previous, lowest = [], 0.0, None, np.inf
    for k in range(int(round(t_end / dt)) + 1):
        if k:
            stepper.run((k - 1) * dt, k * dt, dt)
        d = rod.diagnostics(k * dt)
        if previous is not None:
            dissipated += 0.5 * dt * (d["dissipation_rate"] + previous)
        previous = d["dissipation_rate"]
        lowest = min(lowest, d["friction_dissipation"])
        balance.append(d["kinetic_energy"] + d["free_energy"] + d["contact_energy"]
                       + dissipated)
    return np.max(np.abs(np.array(balance) - balance[0])), dissipated, lowest


@pytest.mark.mpi
def test_self_friction_dissipates_and_the_power_balance_closes():
    """The sliding ring: friction dissipates 4.7e-7, 4.2e-7, 3.8e-7 J (E = 1.7e-4 J;
    the only dissipation: no drag, rho_inf = 1, hyperelastic) at dt = 4, 2, 1 ms, D >= 0
    at every step, and K + Psi + E_c + int D drifts by 3.0e-7, 7.4e-8, 1.9e-8 J: ratios
    4.07 and 3.84, the integrator's second order (asserted > 3.5 for dt = 4, 2 ms;
    without int D the drift would stay at the dissipated ~4e-7 J)."""
    coarse, dissipated, lowest = _ring(4e-3)
    fine, dissipated_fine, lowest_fine = _ring(2e-3)
    assert min(lowest, lowest_fine) >= 0.0
    assert dissipated_fine > 4 * fine
    assert coarse / fine > 3.5, (coarse, fine)


SCENE = Path(__file__).resolve().parents[1] / "scenes" / "ropes_pulled_over_each_other.toml"


@pytest.mark.parametrize("old, new, key", [
    ("between_rods_friction = 0.5 ", "between_rods_friction = -0.5",
     "contact.between_rods_friction"),
    ("between_rods_friction = 0.5 ", "between_rods_friction = 0.5\nself_friction = -1.0",
     "contact.self_friction"),
    ("between_rods_friction = 0.5 ", "between_rods_friction = 0.5\nself_friction = 0.3",
     "contact.self_friction"),          # self-contact is off
    ("density = 1150.0 ", "", "contact.between_rods_friction"),   # quasi-static
    ("between_rods_friction = 0.5 ", 'between_rods_friction = 0.5\npair_curve = "smooth"',
     "contact.between_rods_friction"),  # smooth pairs have no friction
])
def test_bad_friction_input_names_the_key(old, new, key):
    """One SceneError naming the key, before any solve: a negative coefficient, friction
    without its kind of contact, friction on a quasi-static rod (no velocity), friction
    with smooth pairs (contact.pair_curve)."""
    text = SCENE.read_text()
    assert old in text
    text = text.replace(old, new, 1).replace("gravity = [0.0, 0.0, -9.81]", "")
    with pytest.raises(SceneError) as err:
        build(parse_scene(text), "rod")
    assert err.value.key == key


def test_negative_friction_exits_2_naming_the_key(tmp_path):
    """As a user runs it: dolfin-rod check, exit 2, the key on the one error line."""
    from test_cli import cli
    path = tmp_path / "scene.toml"
    path.write_text(SCENE.read_text().replace("between_rods_friction = 0.5 ",
                                              "between_rods_friction = -0.5", 1))
    proc = cli("check", path)
    assert proc.returncode == 2
    assert "contact.between_rods_friction" in proc.stderr and "must be >= 0" in proc.stderr


def test_friction_needs_generalized_alpha_velocities():
    """Quaternion unknowns (per-step schemes: no step velocities for the friction) and a
    quasi-static rod are refused, naming the key."""
    params = RodParameters(length=1.0, A=(1e-2,) * 3, B=(10.0,) * 3, density=0.1,
                           section_inertia=(1e-6, 1e-6))
    law = ContactLaw(0.01, 0.002, 1e3, EPS, self=True, self_friction=0.5)
    with pytest.raises(ValueError, match="contact.self_friction needs rotation-vector"):
        RodModel(params, 40, model="hyperelastic", rotations="quaternion", contact=law)
    still = RodParameters(length=1.0, A=(1e-2,) * 3, B=(10.0,) * 3)
    with pytest.raises(ValueError, match="contact.self_friction needs a dynamic rod"):
        RodModel(still, 40, model="hyperelastic", contact=law)
