"""Starting states of the rods of a system (RodSystem.set_initial_state(start={name:
StartingState}), rod/start.RodStarts): a double pendulum set swinging by a rigid
rotation about its pin follows the rigid ODE from that rate; the kinetic energy per rod
at t = 0 is the closed form; starts that break a joint are named."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from rod_systems import PENDULUM, double_pendulum, pendulum_angles, rigid_double_pendulum
from serial_reference import serial

from dolfin_rod import RodSystem, StartingState, TimeStepper
from dolfin_rod.rod.joints import Joint
from dolfin_rod.rod.start import Polyline

OMEGA = 1.5           # rad/s about e_2 through the pin: the angles (from -e_3 towards
                      # e_1) fall at OMEGA


def spun(kind: str = "ball", comm=MPI.COMM_WORLD) -> RodSystem:
    """tests/rod_systems.double_pendulum (its joint a ``kind`` one, a hinge about e_2),
    both rods started by the rigid rotation OMEGA e_2 about the pin."""
    model = double_pendulum(8, comm=comm)
    if kind == "hinge":
        joint = model.joints[0]
        model = RodSystem(model.rods, joints=[Joint("hinge", joint.rods, joint.point,
                                                    axis=(0.0, 1.0, 0.0))],
                          model="hyperelastic", comm=comm)
    start = StartingState(angular_velocity=(0.0, OMEGA, 0.0), rotation_centre=(0.0, 0.0, 0.0))
    model.set_initial_state(start={"upper": start, "lower": start})
    return model


def test_spun_pendulum_energy_at_start():
    """Each rod's kinetic energy at t = 0 is the rigid rotation's, 1/2 OMEGA^2 (rho_A
    int |r x e_2|^2 ds + rho_I l): the upper rod's rho_A l1^3/3, the lower rod's
    rho_A (l2 |k|^2 + l2^2 k.d + l2^3/3) (k the knee, d its direction) with the rotary
    inertia (the P1 velocity is linear in s: the inertia's quadrature is exact;
    round-off, 1e-13); their sum the system's."""
    p = PENDULUM
    d = spun().diagnostics(0.0)
    a1, a2 = p["angles"]
    knee = p["l1"] * np.array([np.sin(a1), -np.cos(a1)])
    along = np.array([np.sin(a2), -np.cos(a2)])
    l1, l2 = p["l1"], p["l2"]
    upper = p["rho_A"] * l1 ** 3 / 3 + p["rho_I"] * l1
    lower = p["rho_A"] * (l2 * knee @ knee + l2 ** 2 * knee @ along + l2 ** 3 / 3) \
        + p["rho_I"] * l2
    assert d["upper.kinetic_energy"] == pytest.approx(0.5 * OMEGA ** 2 * upper, rel=1e-13)
    assert d["lower.kinetic_energy"] == pytest.approx(0.5 * OMEGA ** 2 * lower, rel=1e-13)
    assert d["kinetic_energy"] == pytest.approx(d["upper.kinetic_energy"]
                                                + d["lower.kinetic_energy"], rel=1e-14)


@pytest.mark.parametrize("kind", ["ball", "hinge"])
def test_spun_pendulum_against_rigid_ode(kind):
    """The spun double pendulum, ball or hinge knee, for 0.3 s at dt = 1e-3: its chords'
    angles follow the rigid ODE started at the rates -(OMEGA, OMEGA) (solve_ivp,
    1e-12).  Measured 8.4e-5, 3.8e-5, 2.9e-5 rad at dt = 2e-3, 1e-3, 5e-4, both knees
    (a floor ~3e-5: the rods' compliance, stretched by the spin; from rest 1.5e-5,
    test_joints): tolerance 5e-5; the same run from rest differs by more than 0.3 rad."""
    t_end = 0.3
    exact = rigid_double_pendulum(t_end, rates=(-OMEGA, -OMEGA)).sol(t_end)[:2]
    model = spun(kind)
    TimeStepper(model.problem).run(0.0, t_end, 1e-3)
    error = np.abs(pendulum_angles(model.diagnostics(t_end)) - exact).max()
    assert error < 5e-5, error
    at_rest = rigid_double_pendulum(t_end).sol(t_end)[:2]
    assert np.abs(at_rest - exact).max() > 0.3


@pytest.mark.mpi
def test_spun_pendulum_serial_equals_two_ranks():
    """The spun pendulum for 0.02 s on the ranks of the run and serially (Newton's rtol
    1e-4 of a step's tiny residual under another partition: 1e-8 relative)."""
    from cases import spun_pendulum
    here = spun_pendulum(comm=MPI.COMM_WORLD)
    reference = serial("spun_pendulum")
    for key, value in reference.items():
        assert here[key] == pytest.approx(value, rel=1e-8, abs=1e-8), key


@pytest.mark.parametrize("starts, message", [
    ({"lower": StartingState(angular_velocity=(0.0, OMEGA, 0.0),
                             rotation_centre=(0.0, 0.0, 0.0))},
     r"start: joints\[0\] \(upper-lower\): the starting states give its two rods a "
     r"different velocity"),
    ({"upper": StartingState(orientation=(0.0, 0.2, 0.0))},
     r"start: joints\[0\] \(upper-lower\): .* different position"),
    ({"middle": StartingState()}, r"start: a system's starting states are"),
    ({"lower": StartingState(shape=Polyline(((0, 0, 0), (0, 0, 1.0))))},
     r"start\['lower'\].shape.points: the polyline's length 1"),
])
def test_starts_that_break_a_joint_are_named(starts, message):
    model = double_pendulum(4)
    with pytest.raises(ValueError, match=message):
        model.set_initial_state(start=starts)
