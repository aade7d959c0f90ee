"""Starting states of the rods of a system (RodSystem.set_initial_state(start={name:
StartingState}), rod/start.RodStarts): a double pendulum set swinging by a rigid
rotation about its pin follows the rigid ODE from that rate; the kinetic energy per rod
at t = 0 is the closed form; starts that break a joint are named; jointed rods whose
clamp is turned at t = 0 (past 2 pi) start at rest in equilibrium (closed forms)."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from rod_systems import (FRAME, PENDULUM, ROUND_OFF, double_pendulum, pendulum_angles,
                         rigid_double_pendulum)
from serial_reference import serial

from dolfin_rod import EndLoad, Rod, RodParameters, RodSystem, StartingState, TimeStepper
from dolfin_rod.rod.joints import Joint
from dolfin_rod.rod.start import Polyline
from dolfin_rod.theory.rotations import np_quaternion_from_rotation_vector, np_rotation_matrix
from dolfin_rod.torsion.closed_forms import p1_twist

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


def frame_turned(angle: float, comm=MPI.COMM_WORLD) -> RodSystem:
    """A dynamic L-frame (column along e_3 clamped at the origin, beam along e_1 from
    its top, welded there) whose clamp is turned at t = 0 by ``angle`` about e_2."""
    f = FRAME
    params = [RodParameters(length=length, A=(f["EI"], f["EI"], 1.5),
                            B=(f["GA"], f["GA"], f["EA"]), density=1.0, section_inertia=0.01)
              for length in (f["L1"], f["L2"])]
    top = (0.0, 0.0, f["L1"])
    rods = [Rod(params[0], 6, name="column",
                end_rotation={"start": lambda t: (0.0, angle, 0.0)}),
            Rod(params[1], 6, "free", end="free", name="beam", position=top,
                orientation=(0.0, np.pi / 2, 0.0))]
    return RodSystem(rods, joints=[Joint("rigid", ("column", "beam"), top)],
                     model="hyperelastic", comm=comm)


def split_shaft(kind: str, angle: float, comm=MPI.COMM_WORLD) -> RodSystem:
    """A shaft along e_3 of two rods of length 1/2 and 4 cells each, clamped at both
    outer ends, joined at z = 1/2 (``kind``: rigid, or a hinge about e_3); the clamp at
    z = 0 turned at t = 0 by ``angle`` about e_3."""
    params = RodParameters(length=0.5, A=(1.0, 1.0, 1.0), B=(40.0, 40.0, 60.0), density=2.0,
                           section_inertia=0.01)
    middle = (0.0, 0.0, 0.5)
    rods = [Rod(params, 4, name="a", end_rotation={"start": lambda t: (0.0, 0.0, angle)}),
            Rod(params, 4, "free", end="clamped", name="b", position=middle)]
    axis = {"axis": (0.0, 0.0, 1.0)} if kind == "hinge" else {}
    return RodSystem(rods, joints=[Joint(kind, ("a", "b"), middle, **axis)],
                     model="hyperelastic", comm=comm)


def run_rows(model, t_end: float = 0.1, dt: float = 0.05) -> list[dict]:
    model.set_initial_state()
    rows = []
    TimeStepper(model.problem, solver_options=ROUND_OFF).run(
        0.0, t_end, dt, observer=lambda t, _: rows.append(model.diagnostics(t)))
    return rows


@pytest.mark.mpi
def test_jointed_frame_turned_at_the_start_beyond_two_pi_starts_at_rest():
    """Rods joined by a joint get the consistent start of a prescribed motion at t = 0
    (lie_alpha's start, in parts: the joints held by the constrained Newton): the
    frame's clamp turned by 7 rad about e_2 turns the welded frame rigidly, beam tip at
    R (L2, 0, L1), no energy, at rest.  Tolerance: Newton's (round-off options; the tip
    measured 1.7e-11 off, the kinetic energy 2e-23)."""
    f = FRAME
    rows = run_rows(frame_turned(7.0))
    assert max(r["kinetic_energy"] for r in rows) < 1e-16
    turn = np_rotation_matrix(np_quaternion_from_rotation_vector((0.0, 7.0, 0.0)))
    tip = [rows[-1][f"beam.tip_position_{c}"] for c in "xyz"]
    assert tip == pytest.approx(turn @ [f["L2"], 0.0, f["L1"]], abs=1e-9)
    assert rows[-1]["free_energy"] < 1e-18


@pytest.mark.mpi
@pytest.mark.parametrize("kind", ["rigid", "hinge"])
def test_split_shaft_twisted_at_the_start_through_its_joint(kind):
    """The shaft of two jointed rods (split_shaft), its clamp turned by 8 rad (past
    2 pi) at t = 0.  Rigid joint: the shaft of 8 cells twisted uniformly, the clamps'
    couples the discrete twist's GJ u_h sec^2(dphi/4) (closed_forms.p1_twist, the
    split rod is the rod: docs/systems.md) and the energy GJ u_h^2 L/2, to 1e-9.
    Hinge about the shaft's axis: rod a turns freely with its clamp, no couple, no
    energy; its end at the hinge turned by 8 rad, i.e. 8 - 2 pi about e_3 (the
    quaternion's sign is that of the path: cos 4, sin 4).  At rest (kinetic energy <
    1e-16) in both.  Tolerance: Newton's (round-off options)."""
    angle, L, N, GJ = 8.0, 1.0, 8, 1.0
    rows = run_rows(split_shaft(kind, angle))
    d = rows[-1]
    assert max(r["kinetic_energy"] for r in rows) < 1e-16
    if kind == "rigid":
        u_h, factor = p1_twist(angle / L, L, N)
        assert d["a.reaction_couple_start_z"] == pytest.approx(GJ * u_h * factor, rel=1e-9)
        assert d["b.reaction_couple_end_z"] == pytest.approx(-GJ * u_h * factor, rel=1e-9)
        assert d["free_energy"] == pytest.approx(0.5 * GJ * u_h ** 2 * L, rel=1e-9)
    else:
        assert abs(d["a.reaction_couple_start_z"]) < 1e-9
        assert d["free_energy"] < 1e-18
        q = [d[f"a.tip_quaternion_{i}"] for i in range(4)]
        assert q == pytest.approx([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)], abs=1e-9)



@pytest.mark.mpi
def test_jointed_frame_started_in_equilibrium_is_the_closed_form_at_rest():
    """A dynamic L-frame (the welded frame of tests/rod_systems.l_frame with density 1,
    section inertia 0.01, 4 cells a rod) under a constant tip force P e_3 down, P =
    1e-6, started in equilibrium (StartingState(equilibrium=True) for one rod settles
    the whole system, the knee held): the beam tip at t = 0 is the closed form of
    tests/test_joints.py (measured 1.9e-7 relative: the rotations' second-order terms;
    tolerance 2e-6) and the frame stays at rest (kinetic energy measured 1.9e-28 over
    0.1 s, asserted < 1e-22; released straight it swings: 1.9e-14, asserted > 1e-15)."""
    f, P, N = FRAME, 1e-6, 4

    def frame(equilibrium: bool):
        params = [RodParameters(length=length, A=(f["EI"], f["EI"], 1.5),
                                B=(f["GA"], f["GA"], f["EA"]), density=1.0,
                                section_inertia=0.01) for length in (f["L1"], f["L2"])]
        top = (0.0, 0.0, f["L1"])
        model = RodSystem([Rod(params[0], N, name="column"),
                           Rod(params[1], N, "free", end="free", name="beam", position=top,
                               orientation=(0.0, np.pi / 2, 0.0),
                               end_loads=[EndLoad("force", (0.0, 0.0, -P))])],
                          joints=[Joint("rigid", ("column", "beam"), top)],
                          model="hyperelastic")
        start = {"column": StartingState(equilibrium=True)} if equilibrium else None
        model.set_initial_state(start=start)
        rows = []
        TimeStepper(model.problem, solver_options=ROUND_OFF).run(
            0.0, 0.1, 0.02, observer=lambda t, _: rows.append(model.diagnostics(t)))
        return rows

    rows = frame(True)
    tip = np.array([rows[0][f"beam.tip_position_{c}"] for c in "xyz"]) - [f["L2"], 0.0, f["L1"]]
    w = -(P * f["L2"] ** 3 / (3 * f["EI"]) * (1 - 1 / (4 * N ** 2))
          + P * f["L2"] ** 2 * f["L1"] / f["EI"] + P * f["L1"] / f["EA"] + P * f["L2"] / f["GA"])
    u = P * f["L2"] * f["L1"] ** 2 / (2 * f["EI"])
    assert tip == pytest.approx([u, 0.0, w], rel=2e-6, abs=1e-18)
    assert max(r["kinetic_energy"] for r in rows) < 1e-22
    assert max(r["kinetic_energy"] for r in frame(False)) > 1e-15
