"""Joints between rods (dolfin_rod.rod.joints, fem/multipoint.py): exact rigid and ball
joints against a rod without a joint, the closed-form L-frame, the rigid double pendulum
ODE; serial = 2 ranks; bad joints named."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI
from rod_systems import (FRAME, ROUND_OFF, double_pendulum, rigid_double_pendulum,
                         run_system, solve_frame, swing)
from serial_reference import serial

from dolfin_rod import EndLoad, Rod, RodModel, RodParameters, RodSystem, TimeStepper
from dolfin_rod.rod.joints import Joint
from dolfin_rod.theory.rotations import np_rotation_vector

XYZ = "xyz"


def vector(d: dict, key: str) -> np.ndarray:
    return np.array([d[f"{key}_{c}"] for c in XYZ])


def test_rigid_joint_of_a_split_rod_is_the_rod():
    """A dynamic helical rod (curvature and twist), split at its middle node into two
    rods joined rigidly there, placed where the halves were: the same discrete equations
    (the joint ties the nodes exactly), so the same motion to round-off (measured
    1.2e-15 on the tip after 10 steps, Newton to 1e-13)."""
    p = RodParameters(length=1.0, density=1.0, section_inertia=0.01,
                      reference_curvature=(0.8, 0.0, 0.3))
    load = [EndLoad("force", (1.0, 0.5, 0.0))]
    whole = RodModel(p, n_cells=8, end_loads=load, model="hyperelastic")
    r, q = whole.stress_free(np.array([0.5]))
    half = replace(p, length=0.5)
    split = RodSystem([Rod(half, 4, name="a"),
                       Rod(half, 4, "free", end="free", end_loads=load, name="b", position=r[0],
                           orientation=np_rotation_vector(q[0]))],
                      joints=[Joint("rigid", ("a", "b"), r[0])], model="hyperelastic")
    d_whole, d_split = run_system(whole), run_system(split)
    assert np.allclose(vector(d_split, "b.tip_position"), vector(d_whole, "tip_position"),
                       rtol=0, atol=1e-13)
    for key in ("free_energy", "kinetic_energy", "load_power"):
        assert d_split[key] == pytest.approx(d_whole[key], rel=1e-12, abs=1e-14)
    assert abs(d_whole["tip_position_x"]) > 0.01


@pytest.mark.parametrize("n_cells", [4, 8])
def test_l_frame_small_load_closed_form(n_cells):
    """L-frame (tests/rod_systems.l_frame), tip force P e_3 down, P = 1e-6 (linear
    regime): beam tip displacement
        w = -(P L2^3/(3 EI) (1 - 1/(4 N^2)) + P L2^2 L1/EI + P L1/EA + P L2/(k GA)),
        u = P L2 L1^2/(2 EI)
    (beam bending, with the discrete factor of the 1-point rule for its linear moment,
    tests/test_rod.py; the column's constant moment P L2 turns the knee by P L2 L1/EI
    and moves it sideways; column shortening; beam shear).  The knee's reactions on the
    beam: force P e_3, couple -P L2 e_2.  Measured relative errors 3e-7 (the rotations'
    second-order terms, ~ w/L), tolerance 2e-6."""
    f, P = FRAME, 1e-6
    d = solve_frame(n_cells, P)
    tip = vector(d, "beam.tip_position") - np.array([f["L2"], 0.0, f["L1"]])
    w = -(P * f["L2"] ** 3 / (3 * f["EI"]) * (1 - 1 / (4 * n_cells ** 2))
          + P * f["L2"] ** 2 * f["L1"] / f["EI"] + P * f["L1"] / f["EA"] + P * f["L2"] / f["GA"])
    u = P * f["L2"] * f["L1"] ** 2 / (2 * f["EI"])
    assert tip == pytest.approx([u, 0.0, w], rel=2e-6, abs=1e-18)
    # residual round-off ~ 1e-14 against stiffnesses ~ 1e3: abs 2e-12 (= 2e-6 P)
    assert vector(d, "joint_knee_force") == pytest.approx([0, 0, P], rel=2e-6, abs=2e-12)
    assert vector(d, "joint_knee_couple") == pytest.approx([0, -P * f["L2"], 0], rel=2e-6,
                                                           abs=2e-12)
    # the clamp carries the same: force P e_3, couple -P L2 e_2
    assert vector(d, "column.reaction_force_start") == pytest.approx([0, 0, P], rel=2e-6,
                                                                   abs=2e-12)


def test_l_frame_large_load_second_order():
    """Tip force 1.5 (beam tip lowered by 0.4 L1): the tip converges at second order in
    h against 64 cells per rod.  Measured errors 4.5e-3, 1.13e-3, 2.7e-4 at 4, 8, 16
    cells: rates 2.01, 2.07 (the last includes the reference's error, ~1/16 of it); the
    knee force equals the load (1.5) to Newton's tolerance."""
    tips = {}
    for n in (4, 8, 16, 64):
        d = solve_frame(n, 1.5, steps=4)
        tips[n] = vector(d, "beam.tip_position")
        assert d["joint_knee_force_z"] == pytest.approx(1.5, rel=1e-8)
    errors = np.array([np.linalg.norm(tips[n] - tips[64]) for n in (4, 8, 16)])
    rates = np.log2(errors[:-1] / errors[1:])
    assert np.all((rates > 1.9) & (rates < 2.2)), rates
    assert tips[64][2] < 0.45          # large: the tip fell by more than half its length


def test_l_frame_joint_either_way_round():
    """The large-load frame with the joint's rods named the other way round (the
    column's top node tied to the beam's, R_rel turned the other way): the same
    solution, the rigid joint exact both ways (measured: the same tip to the last digit,
    the knee forces opposite to 4e-13 of 1.5); the knee's
    reaction is then the one on the column, the beam's opposite."""
    from rod_systems import l_frame
    results = []
    for swap in (False, True):
        model = l_frame(6, 1.5, steps_to_full_load=True)
        if swap:
            joint = model.joints[0]
            model = RodSystem(model.rods, joints=[Joint("rigid", joint.rods[::-1], joint.point,
                                                        name="knee")], model="hyperelastic")
        model.set_initial_state()
        TimeStepper(model.problem, solver_options=ROUND_OFF).run(0.0, 1.0, 1.0 / 3)
        results.append(model.diagnostics(1.0))
    beam, column = results
    assert vector(column, "beam.tip_position") == pytest.approx(
        vector(beam, "beam.tip_position"), rel=0, abs=1e-12)
    assert vector(column, "joint_knee_force") == pytest.approx(
        -vector(beam, "joint_knee_force"), rel=1e-9, abs=1e-9)


@pytest.mark.mpi
def test_joint_frame_serial_equals_two_ranks():
    """The large-load frame on the ranks of the run and serially: the same numbers to
    Newton's tolerance (1e-10 of values ~1)."""
    from rod_systems import solve_frame as frame
    here = frame(6, 1.5, steps=3, comm=MPI.COMM_WORLD)
    reference = serial("joint_frame")
    assert set(here) == set(reference)
    for key, value in reference.items():
        assert here[key] == pytest.approx(value, rel=1e-9, abs=1e-10), key


def test_double_pendulum_against_rigid_ode():
    """Two stiff rods (E = 1e6: strains ~ 1e-5) hung by a ball joint, swinging under
    gravity for 0.5 s (generalized-alpha, its default rho_inf 0.8, 8 cells per rod):
    their chords' angles follow the rigid double pendulum's ODE (solve_ivp, 1e-12).
    Measured angle errors 4.5e-5, 1.5e-5, 1.1e-5 at dt = 4e-3, 2e-3, 1e-3 (the last
    two at the rods' compliance, ~1e-5): tolerance 2.5e-5.  The total energy K + Psi +
    rho_A g int z ds drifts by 1.5e-4, 6.9e-5, 1.39e-5 (of a potential swing ~ 3):
    order 2.3 between the last two, the integrator's order 2 (at 4e-3 the
    unresolved axial vibrations the release starts still add their damped energy)."""
    errors, drifts = zip(*(swing(double_pendulum(8), 0.5, dt) for dt in (2e-3, 1e-3)))
    assert max(errors) < 2.5e-5, errors
    assert np.log2(drifts[0] / drifts[1]) > 1.8, drifts
    assert abs(rigid_double_pendulum(0.5).sol(0.5)[1] - 1.1) > 0.2      # it swung


@pytest.mark.parametrize("joint, message", [
    (Joint("rigid", ("a", "b"), (0.0, 0.0, 0.5)), "joints[0].point [0.0, 0.0, 0.5] is not on rod 'b'"),
    (Joint("glue", ("a", "b"), (0.0, 0.0, 1.0)), "joints[0].kind must be one of"),
    (Joint("ball", ("a", "c"), (0.0, 0.0, 1.0)), "joints[0].rods must name two different"),
    (Joint("ball", ("a", "b"), (1.0, 0.0, 1.0)), "joints[0]: rod 'b' is supported at its start"),
])
def test_bad_joints_are_named(joint, message):
    p = RodParameters(density=1.0, section_inertia=0.01)
    b_ends = ("clamped", "free") if "supported" in message else ("free", "free")
    b_start = (1.0, 0.0, 1.0) if "supported" in message else (0.0, 0.0, 1.0)
    rods = [Rod(p, 4, name="a"), Rod(p, 4, b_ends[0], end=b_ends[1], name="b",
                                          position=b_start)]
    if "supported" in message:
        rods[0] = Rod(p, 4, name="a", position=(1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("(", r"\(")):
        RodSystem(rods, joints=[joint])


@pytest.mark.parametrize("factor, unstable", [(0.5, 0), (1.5, 2)])
def test_split_column_buckles_as_the_column(factor, unstable):
    """The stability check (analysis/stability.py) of a system with a joint counts the
    negative eigenvalues of K on the free dofs (P^T K P): a clamped column split at its
    middle into two rods joined rigidly, compressed by factor x the Euler load pi^2 EI /
    (4 L^2), has the whole column's count: 0 below the load, 2 above (the two bending
    planes).  Without the joint's reduction the free second rod's rigid motions would
    count (the frame scene reported an unstable equilibrium)."""
    from dolfin_rod import loads
    from dolfin_rod.analysis.stability import TangentStiffness
    p = RodParameters(length=1.0, A=(1.0, 1.0, 1.0), B=(1e4, 1e4, 1e4))
    load = [EndLoad("force", (0, 0, -factor * np.pi ** 2 / 4), loads.ramp(1.0, 1.0))]
    half = replace(p, length=0.5)
    whole = RodModel(p, 8, model="hyperelastic", end_loads=load)
    split = RodSystem([Rod(half, 4, name="a"),
                       Rod(half, 4, "free", end="free", end_loads=load, name="b",
                           position=(0.0, 0.0, 0.5))],
                      joints=[Joint("rigid", ("a", "b"), (0.0, 0.0, 0.5))], model="hyperelastic")
    for model in (whole, split):
        model.set_initial_state()
        TimeStepper(model.problem).run(0.0, 1.0, 0.25)
        assert TangentStiffness(model).inertia(1.0).negative == unstable
