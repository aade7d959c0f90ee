"""Hinge joints (dolfin_rod.rod.joints.Hinge, fem/multipoint.NodeMap): the nonlinear
map of the slave's rotation increment; a hinged double pendulum and a hinged door
against their rigid ODEs (solve_ivp); the hinge's reactions; serial = 2 ranks; bad
hinges named."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from rod_systems import (DOOR, double_pendulum, door_angle, hinged_door,
                         rigid_double_pendulum, swing)
from serial_reference import serial

from dolfin_rod import Rod, RodParameters, RodSystem, TimeStepper
from dolfin_rod.rod.joints import Hinge, Joint
from dolfin_rod.rod.rotation_vector import np_cayley
from dolfin_rod.theory.rotations import np_qmul

XYZ = "xyz"


def vector(d: dict, key: str) -> np.ndarray:
    return np.array([d[f"{key}_{c}"] for c in XYZ])


def random_hinge(seed: int) -> Hinge:
    rng = np.random.default_rng(seed)
    q_a, q_b = rng.normal(size=4), rng.normal(size=4)
    axis = rng.normal(size=3)
    hinge = Hinge(axis / np.linalg.norm(axis), stored_rotations=lambda: (q_a, q_b))
    hinge.refresh()
    return hinge


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hinge_law_is_the_turn_about_its_axis(seed):
    """c(theta_b) = c(R(Q)^T theta_a) c(psi n) as quaternions (the composition of the
    Cayley map, against np_qmul: round-off, 1e-15); ``parameters`` inverts ``value``;
    the derivative matches central differences (step 1e-6: error ~1e-11, tolerance
    1e-8), and so does the curvature (the second derivative: the derivative's central
    differences); the tangent at 0 is the exact map's derivative there."""
    hinge = random_hinge(seed)
    rng = np.random.default_rng(10 + seed)
    theta_a, psi = 0.3 * rng.normal(size=3), 0.4 * rng.normal()
    theta_b, derivative = hinge.value(theta_a, [psi])
    composed = np_qmul(np_cayley(hinge.Q.T @ theta_a), np_cayley(psi * hinge.axis))
    assert np_cayley(theta_b) == pytest.approx(composed, abs=1e-15)
    assert hinge.parameters(theta_a, theta_b)[0] == pytest.approx(psi, abs=1e-14)
    args, h = np.array([*theta_a, psi]), 1e-6
    for j in range(4):
        step = np.eye(4)[j] * h
        plus = hinge.value((args + step)[:3], (args + step)[3:])[0]
        minus = hinge.value((args - step)[:3], (args - step)[3:])[0]
        assert derivative[:, j] == pytest.approx((plus - minus) / (2 * h), abs=1e-8)
    curvature = hinge.curvature(theta_a, [psi])
    for j in range(4):       # the derivative's central differences (step 1e-6: ~1e-10)
        step = np.eye(4)[j] * h
        plus = hinge.value((args + step)[:3], (args + step)[3:])[1]
        minus = hinge.value((args - step)[:3], (args - step)[3:])[1]
        assert curvature[:, :, j] == pytest.approx((plus - minus) / (2 * h), abs=1e-8)
    assert curvature == pytest.approx(curvature.transpose(0, 2, 1), abs=1e-14)
    zero = hinge.value(np.zeros(3), [0.0])[1]
    assert hinge.value(theta_a, [psi], exact=False)[1] == pytest.approx(zero, abs=1e-15)
    assert hinge.parameters(theta_a, theta_b, exact=False)[0] == pytest.approx(
        hinge.axis @ (theta_b - hinge.Q.T @ theta_a), abs=1e-15)


def hinged_double_pendulum(n_cells: int) -> RodSystem:
    """tests/rod_systems.double_pendulum with its ball joint replaced by a hinge about
    e_2 (normal to the plane of the swing)."""
    model = double_pendulum(n_cells)
    joint = model.joints[0]
    return RodSystem(model.rods, joints=[Joint("hinge", joint.rods, joint.point,
                                               name="elbow", axis=(0.0, 1.0, 0.0))],
                     model="hyperelastic")


def test_hinged_double_pendulum_against_rigid_ode():
    """The double pendulum of test_joints' ball joint with a hinge about e_2: the same
    rigid ODE (solve_ivp, 1e-12).  Measured angle errors 1.5e-5, 1.1e-5 at dt = 2e-3,
    1e-3 (the rods' compliance, ~1e-5, as with the ball): tolerance 2.5e-5; the energy
    K + Psi + rho_A g int z drifts by 6.9e-5 and 1.4e-5: order 2.3 (generalized-alpha,
    order 2).  The hinge's couple about its axis is 0 (free), to Newton's tolerance
    (measured 6e-8 of forces ~10)."""
    errors, drifts = [], []
    for dt in (2e-3, 1e-3):
        model = hinged_double_pendulum(8)
        error, drift = swing(model, 0.5, dt)
        errors.append(error)
        drifts.append(drift)
        assert abs(model.diagnostics(0.5)["joint_elbow_couple_y"]) < 1e-6
    assert max(errors) < 2.5e-5, errors
    assert np.log2(drifts[0] / drifts[1]) > 1.8, drifts
    assert abs(rigid_double_pendulum(0.5).sol(0.5)[1] - 1.1) > 0.2      # it swung


def test_hinged_door_against_rigid_ode():
    """The door of tests/rod_systems.hinged_door, pushed sideways for 1 s: a hinge about
    e_3 lets it turn only about e_3 (a ball joint would let it fall), by the angle of
    I phi'' = F L cos(phi) (measured 8.9e-6 rad at dt = 4e-3: the rods' compliance;
    tolerance 2e-5 of phi = 0.74).  Its reactions on the door: no couple about e_3
    (measured 4e-7, Newton's tolerance, of couples ~5); the couple across the axis
    carries the weight, rho_A g L^2/2 d x e_3 with d = (cos phi, sin phi, 0); the force
    is m a_G - F e_2 + rho_A g L e_3 (a_G of the rigid door's centre): measured
    relative 3e-5 (the droop, ~1e-5), tolerance 1e-3."""
    p, t_end = DOOR, 1.0
    phi, rate = door_angle(t_end).sol(t_end)
    model = hinged_door(8)
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, t_end, 4e-3)
    d = model.diagnostics(t_end)
    tip = vector(d, "door.tip_position")
    assert np.arctan2(tip[1], tip[0]) == pytest.approx(phi, abs=2e-5)
    assert tip[2] == pytest.approx(p["post"], abs=1e-4)         # it did not fall
    couple, force = vector(d, "joint_hinge_couple"), vector(d, "joint_hinge_force")
    L, mass = p["width"], p["rho_A"] * p["width"]
    assert abs(couple[2]) < 1e-6 * np.linalg.norm(couple)
    along = np.array([np.cos(phi), np.sin(phi), 0.0])
    across = np.array([-np.sin(phi), np.cos(phi), 0.0])
    weight = p["rho_A"] * p["g"] * L
    assert couple == pytest.approx(weight * L / 2 * np.cross(along, [0, 0, 1]), rel=1e-3,
                                   abs=1e-3 * weight * L / 2)
    inertia = p["rho_A"] * L ** 3 / 3 + p["rho_I"] * L
    acceleration = p["push"] * L * np.cos(phi) / inertia
    a_centre = L / 2 * (acceleration * across - rate ** 2 * along)
    expected = mass * a_centre - np.array([0.0, p["push"], -weight])
    assert force == pytest.approx(expected, rel=1e-3, abs=1e-3 * weight)


@pytest.mark.mpi
def test_hinged_door_serial_equals_two_ranks():
    """The door for 0.1 s (tests/cases.hinged_door) on the ranks of the run and
    serially: the same numbers to Newton's tolerance (Newton to round-off: 1e-9 of
    values ~1; the joint's reactions are its slave node's residual, which Newton leaves
    at the stiff rods' round-off floor, ~1e-8: measured 2.2e-9 on joint_hinge_force_x,
    tolerance 1e-8 absolute for them)."""
    from cases import hinged_door as door
    here = door(comm=MPI.COMM_WORLD)
    reference = serial("hinged_door")
    assert set(here) == set(reference)
    for key, value in reference.items():
        floor = 1e-8 if key.startswith("joint_") else 1e-9
        assert here[key] == pytest.approx(value, rel=1e-8, abs=floor), key


@pytest.mark.parametrize("joint, message", [
    (Joint("hinge", ("a", "b"), (0.0, 0.0, 1.0)), "joints[0].axis is missing"),
    (Joint("hinge", ("a", "b"), (0.0, 0.0, 1.0), axis=(0.0, 2.0, 0.0)),
     "joints[0].axis must be a unit vector"),
    (Joint("hinge", ("a", "b"), (0.0, 0.0, 1.0), axis=(0.0, np.nan, 0.0)),
     "joints[0].axis must be a finite 3-vector"),
    (Joint("rigid", ("a", "b"), (0.0, 0.0, 1.0), axis=(0.0, 1.0, 0.0)),
     "joints[0].axis is a hinge's"),
])
def test_bad_hinges_are_named(joint, message):
    p = RodParameters(density=1.0, section_inertia=0.01)
    rods = [Rod(p, 4, name="a"), Rod(p, 4, "free", end="free", name="b", position=(0, 0, 1))]
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("(", r"\(")):
        RodSystem(rods, joints=[joint])


def test_hinge_node_in_another_joint_is_named():
    """Three rods at one point, a hinge among them: refused naming the hinge (its slave
    rotation is a nonlinear map of a free master node)."""
    p = RodParameters(density=1.0, section_inertia=0.01)
    top = (0.0, 0.0, 1.0)
    rods = [Rod(p, 4, name="a"), Rod(p, 4, "free", end="free", name="b", position=top),
            Rod(p, 4, "free", end="free", name="c", position=top)]
    joints = [Joint("rigid", ("a", "b"), top), Joint("hinge", ("a", "c"), top,
                                                     axis=(1.0, 0.0, 0.0))]
    with pytest.raises(ValueError, match=r"joints\[1\]: a hinge joins two nodes"):
        RodSystem(rods, joints=joints)


@pytest.mark.mpi
def test_newton_converges_quadratically_through_a_hinge():
    """The constrained Jacobian is exact (fem/multipoint.py: P^T J P plus the slave
    residual times the hinge map's curvature), so Newton converges quadratically: a
    soft quasi-static frame (EI = 1, L = 1, 4 cells per rod) of a column clamped at its
    foot and a beam clamped at its far end, hinged at the knee about e_2, loaded there by
    (0.6, 0.6, 0) in one step from rest (large rotations; the hinge carries couples
    across its axis of ~0.5 = 2 EI/h / 16).  Measured residual norms 0.85, 0.11,
    3.3e-4, 1.6e-8, 8.7e-15: each at most the square of the one before once below 0.2
    and above the round-off floor (r_k+1 <= r_k^2 for r_k in [1e-7, 0.2]), 1e-13 after 4
    iterations.  Without the
    curvature term (measured): 6.4e-4, 2.4e-5, 1.2e-6, ... a linear rate of ~0.04,
    which breaks r_k+1 <= r_k^2 at the third iterate and needs 8 iterations."""
    from dolfin_rod import EndLoad
    from dolfin_rod.fem import solvers
    p = RodParameters(length=1.0, A=(1.0, 1.0, 1.0), B=(10.0, 10.0, 10.0))
    rods = [Rod(p, 4, "clamped", end="free", name="a",
                end_loads=[EndLoad("force", (0.6, 0.6, 0.0))]),
            Rod(p, 4, "free", end="clamped", name="b", position=(0.0, 0.0, 1.0),
                orientation=(0.0, np.pi / 2, 0.0))]
    model = RodSystem(rods, joints=[Joint("hinge", ("a", "b"), (0.0, 0.0, 1.0),
                                          axis=(0.0, 1.0, 0.0))], model="hyperelastic")
    model.set_initial_state()
    norms, residual = [], solvers.BlockSNES._residual

    def recorded(self, snes, x, b):
        residual(self, snes, x, b)
        norms.append(self._residual_norm)

    options = {"snes_rtol": 1e-14, "snes_atol": 1e-14, "snes_lag_jacobian": 1,
               "snes_linesearch_type": "basic"}        # one residual per iteration
    solvers.BlockSNES._residual = recorded
    try:
        TimeStepper(model.problem, "backward_euler", solver_options=options).run(0, 1, 1)
    finally:
        solvers.BlockSNES._residual = residual
    assert len(norms) <= 5 and norms[-1] < 1e-13, norms
    pairs = [(r, r_next) for r, r_next in zip(norms, norms[1:]) if 1e-7 <= r <= 0.2]
    assert len(pairs) >= 2 and all(r_next <= r ** 2 for r, r_next in pairs), norms
