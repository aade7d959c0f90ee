"""Friction at the rod's surface (issue 26, rod/contact.py, docs/contact.md "Rolling"):
a thick rod lying across a slope or thrown on a floor rolls.

The obstacle's friction acts at the contact point c = -r n on the rod's surface (n the
obstacle's outward normal), whose velocity is v + w x c, with the couple c x f on the
rod.  References, a rigid solid circular rod (mass m per length, polar inertia
m r^2 / 2 per length) on a plane:
- across a slope of angle a, mu >= tan(a) / 3: it rolls without slipping, the centre
  line's acceleration (2/3) g sin a and the angular one (2/3) g sin a / r;
- mu < tan(a) / 3: it slides and spins, a = g (sin a - mu cos a), angular acceleration
  2 mu g cos a / r;
- on a floor, thrown sideways at v0 without spin: it slides with deceleration mu g, the
  friction spins it up at 2 mu g / r, and from t* = v0 / (3 mu g) it rolls at (2/3) v0
  (the angular momentum about the contact line, m v r + I w, is kept: the friction
  passes through that line), whatever the smoothed law does near t*;
- spinning at w0 about its axis, laid on the floor at rest: it ends rolling at w0 r / 3
  (the same momentum, I w0 at the start).
The centre line's accelerations and speeds are the integrator's to round-off (1e-6);
the rotation angle read from the tip's quaternion differs from the integrator's angular
velocity by O((w dt)^2) (measured 7.1e-4 relative at dt = 2e-3 and 1.8e-4 at 1e-3: 4.0x
per halving), hence its tolerances.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from dolfin_rod import TimeStepper
from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters
from dolfin_rod.rod.contact import ContactLaw, Obstacle, barrier_derivatives, default_stiffness
from dolfin_rod.rod.start import StartingState

G, R, DELTA, RHO_A = 9.81, 0.05, 1e-3, 1.0
N_CELLS, EPS = 4, 1e-4
ROD = RodParameters(length=0.5, A=(1e-1,) * 3, B=(1e2,) * 3, density=RHO_A,
                    section_inertia=RHO_A * R**2 / 4)       # solid circle: J = m r^2 / 2
OPTIONS = {"snes_rtol": 1e-10, "snes_atol": 1e-12, "snes_linesearch_type": "bt"}


def _resting_gap(kappa: float, weight: float) -> float:
    """The gap g at which the barrier carries ``weight`` per length: -kappa b'(g) = weight."""
    return brentq(lambda g: -kappa * barrier_derivatives(g, DELTA)[1] - weight,
                  1e-3 * DELTA, DELTA * (1 - 1e-12))


def _rod_on_plane(slope: float, mu: float, dt: float, velocity=(0.0, 0.0, 0.0),
                  spin: float = 0.0, rotations: str = "auto", torque: float = 0.0
                  ) -> RodModel:
    """The rod along e_3 lying on the plane of normal e_1 (its axis across the slope),
    gravity at ``slope`` from the normal towards -e_2, started at the gap that carries it
    with ``velocity`` and angular velocity ``spin`` e_3; a couple ``torque`` per length
    about its axis e_3."""
    kappa = default_stiffness(RHO_A, ROD.A, ROD.length, N_CELLS, dt)
    law = ContactLaw(R, DELTA, kappa, slip_tolerance=EPS)
    gap = _resting_gap(kappa, RHO_A * G * np.cos(slope))
    plane = Obstacle("plane", point=(-(R + gap), 0.0, 0.0), normal=(1.0, 0.0, 0.0),
                     friction=mu)
    gravity = (-RHO_A * G * np.cos(slope), -RHO_A * G * np.sin(slope), 0.0)
    loads = [DistributedLoad("force", gravity)] + (
        [DistributedLoad("couple", (0.0, 0.0, torque))] if torque else [])
    rod = RodModel(ROD, n_cells=N_CELLS, model="hyperelastic", start="free", end="free",
                   distributed_loads=loads,
                   obstacles=[plane], contact=law, rotations=rotations)
    rod.set_initial_state(start=StartingState(velocity=velocity,
                                              angular_velocity=(0.0, 0.0, spin)))
    return rod


def _motion(rod: RodModel, dt: float, t_end: float, scheme: str = "generalized_alpha:0.0"):
    """(t, y of the tip, its rotation angle about e_3 (unwrapped), the rows)."""
    stepper = TimeStepper(rod.problem, scheme, OPTIONS)
    rows = []
    for k in range(int(round(t_end / dt))):
        stepper.run(k * dt, (k + 1) * dt, dt)
        rows.append(rod.diagnostics((k + 1) * dt))
    t = np.array([d["time"] for d in rows])
    y = np.array([d["tip_position_y"] for d in rows])
    angle = np.unwrap([2 * np.arctan2(d["tip_quaternion_3"], d["tip_quaternion_0"])
                       for d in rows])
    return t, y, angle, rows


def _accelerations(t, y, angle, after: float):
    late = t > after
    return (2 * np.polyfit(t[late], y[late], 2)[0],
            2 * np.polyfit(t[late], angle[late], 2)[0])


@pytest.mark.mpi
@pytest.mark.parametrize("rotations, scheme", [
    ("rotation_vector", "generalized_alpha:0.0"), ("quaternion", "generalized_alpha:0.0"),
    ("quaternion", "bdf2")])
def test_a_rod_across_a_slope_rolls_without_slipping(rotations, scheme):
    """30 deg, mu = 0.5 >= tan(a) / 3 = 0.19: the centre line accelerates down the slope
    at (2/3) g sin a (to 1e-9: measured 2e-15 to 3e-14, the fit's round-off), the rod
    turns at (2/3) g sin a / r (to 5e-4: the angle's O((w dt)^2), above; measured
    1.4e-4 for each rotation form and scheme); the
    friction dissipates nothing beyond the slip tolerance's creep (dissipation >= 0 at
    every step, and its rate < mu N eps)."""
    a, mu, dt = np.radians(30.0), 0.5, 2e-3
    t, y, angle, rows = _motion(_rod_on_plane(a, mu, dt, rotations=rotations), dt, 0.3,
                                scheme)
    accel, turn = _accelerations(t, y, angle, 0.05)
    assert accel == pytest.approx(-2 / 3 * G * np.sin(a), rel=1e-9)
    assert turn == pytest.approx(-2 / 3 * G * np.sin(a) / R, rel=5e-4)
    D = [d["friction_dissipation"] for d in rows]
    assert min(D) >= 0.0
    assert max(D) < mu * RHO_A * G * np.cos(a) * ROD.length * EPS


@pytest.mark.mpi
def test_a_rod_across_a_steep_slope_slides_and_spins():
    """30 deg, mu = 0.1 < tan(a) / 3: it slides, a = g (sin a - mu cos a) (to 1e-9:
    measured 1e-13), and the friction's couple spins it up at 2 mu g cos a / r (to 5e-4,
    the angle's error: measured 3.8e-5)."""
    a, mu, dt = np.radians(30.0), 0.1, 2e-3
    t, y, angle, _ = _motion(_rod_on_plane(a, mu, dt), dt, 0.3)
    accel, turn = _accelerations(t, y, angle, 0.05)
    assert accel == pytest.approx(-G * (np.sin(a) - mu * np.cos(a)), rel=1e-9)
    assert turn == pytest.approx(-2 * mu * G * np.cos(a) / R, rel=5e-4)


def _speed(t, y, after: float) -> float:
    late = t > after
    return np.polyfit(t[late], y[late], 1)[0]


@pytest.mark.mpi
def test_a_rod_thrown_sideways_on_a_floor_ends_rolling():
    """v0 = 1 m/s, mu = 0.3, no spin: it decelerates at mu g while it slides (over
    t < t*/2), and from t* = v0 / (3 mu g) = 0.113 s it rolls on at (2/3) v0 (its speed
    over t > 1.5 t*; the momentum about the contact line is the integrator's to
    round-off): both to 1e-9 (measured 1e-12 and 1e-14)."""
    mu, v0, dt = 0.3, 1.0, 2e-3
    t_star = v0 / (3 * mu * G)
    t, y, _, _ = _motion(_rod_on_plane(0.0, mu, dt, velocity=(0.0, v0, 0.0)), dt, 0.25)
    early = t < t_star / 2
    assert 2 * np.polyfit(t[early], y[early], 2)[0] == pytest.approx(-mu * G, rel=1e-9)
    assert _speed(t, y, 1.5 * t_star) == pytest.approx(2 / 3 * v0, rel=1e-9)


@pytest.mark.mpi
def test_a_spinning_rod_laid_on_a_floor_rolls_off_at_a_third():
    """w0 = 20 rad/s about its axis, at rest on the floor (mu = 0.3): it rolls off at
    w0 r / 3 once the slip has ended (t* = w0 r / (3 mu g) = 0.113 s), to 1e-9 (measured
    2e-14)."""
    mu, w0, dt = 0.3, 20.0, 2e-3
    t_star = w0 * R / (3 * mu * G)
    t, y, _, _ = _motion(_rod_on_plane(0.0, mu, dt, spin=w0), dt, 0.25)
    assert _speed(t, y, 1.5 * t_star) == pytest.approx(w0 * R / 3, rel=1e-9)


@pytest.mark.mpi
def test_a_rod_twisted_on_a_floor_rolls_against_friction():
    """A couple tau = 0.02 N m/m about its axis on a rod lying on a floor (mu = 0.3):
    friction holds its contact line (the force it needs, 2 tau / (3 r) = 0.27 N/m, is
    below mu m g = 2.9 N/m), so it rolls: angular acceleration tau / (J + m r^2) =
    tau / (3/2 m r^2) and the centre line's r times it, 2 tau / (3 m r) (without the
    surface point it spun in place at tau / J, 3x faster, and did not move).  The
    centre line to 1e-9 (measured 2e-15), the angle to 1e-5 (its O((w dt)^2), with
    w dt <= 2.6e-3 here: measured 6.9e-7)."""
    mu, tau, dt = 0.3, 0.02, 2e-3
    t, y, angle, _ = _motion(_rod_on_plane(0.0, mu, dt, torque=tau), dt, 0.25)
    accel, turn = _accelerations(t, y, angle, 0.05)
    assert accel == pytest.approx(2 * tau / (3 * RHO_A * R), rel=1e-9)
    assert turn == pytest.approx(tau / (1.5 * RHO_A * R**2), rel=1e-5)


@pytest.mark.mpi
@pytest.mark.parametrize("slip", [0.3 * EPS, 30 * EPS])
def test_friction_jacobian_is_the_residuals_derivative(slip):
    """Taylor test of the assembled friction terms (force and couple rows) in the
    centre line's position and velocity and the rotation increment and its rate, at a
    state sliding at ``slip`` (within the smoothed law, y < 1, and beyond it): the
    remainder |R(u + h du) - R(u) - h J du| falls 4-fold per halving of h (O(h^2); 10 %
    for the O(h^3) terms), as Newton needs for quadratic convergence."""
    import dolfinx.fem as fem
    import dolfinx.fem.petsc as fem_petsc
    import ufl
    from petsc4py import PETSc
    rod = _rod_on_plane(0.0, 0.5, 1e-2)
    rod.contact.update_normal_forces()
    rng = np.random.default_rng(7)
    block = rod.contact.spin.block
    fields = [rod.f["displacement"], rod.f[block], rod.r["displacement"], rod.r[block]]
    scales = [1e-2 * DELTA, 1e-3, slip, slip / R]
    for g, scale in zip(fields, scales):
        g.x.array[:] += 0.1 * scale * rng.standard_normal(g.x.array.size)
    rod.r["displacement"].x.array[1::3] += slip         # sliding along e_2 at ``slip``
    steps = []
    for g, scale in zip(fields, scales):
        step = fem.Function(g.function_space)
        step.x.array[:] = 0.1 * scale * rng.standard_normal(g.x.array.size)
        steps.append(step)
    F = {"displacement": 0, block: 0}
    rod.contact.add_to(F, rod.t["displacement"])
    def assembled(form):
        vector = fem_petsc.assemble_vector(form)
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return vector

    for name in ("displacement", block):
        R_form = fem.form(F[name])
        J_form = fem.form(sum(ufl.derivative(F[name], g, dg) for g, dg in zip(fields, steps)))
        start = [g.x.array.copy() for g in fields]
        r0, Jdu = assembled(R_form), assembled(J_form)
        remainders = []
        for h in (0.4, 0.2, 0.1):
            for g, g0, dg in zip(fields, start, steps):
                g.x.array[:] = g0 + h * dg.x.array
            r = assembled(R_form)
            r.axpy(-1.0, r0)
            r.axpy(-h, Jdu)
            remainders.append(r.norm())
        for g, g0 in zip(fields, start):
            g.x.array[:] = g0
        for coarse, fine in zip(remainders, remainders[1:]):
            assert coarse / fine == pytest.approx(4.0, rel=0.1)
