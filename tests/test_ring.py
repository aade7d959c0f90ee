"""Closed rods (dolfin_rod/rod/ring.py) against closed forms: a straight rod closed into
a circle of radius R (bending couple EI/R, no force, energy pi EI/R), the twisted ring
(shear force C Tw/R^2 along the axis, twist couple C Tw/R), Michell's instability of the
twisted ring (critical twist sqrt(3) A/C turns, Michell 1889, Zajac 1962) at second
order in h, the free ring's weld at rest; serial = 2 ranks; bad input named.

The rings are tests/rings.py's: L = 1, A = 1, C = A/1.3, B = 1e5 (A/(B R^2) = 4e-4)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rings import (BEND, LENGTH, MICHELL, RADIUS, RING, TWIST, critical_link, free_ring,
                   free_ring_in_system, hanging_ring, mechanism, michell_count,
                   pinched_in_system, pulled_ring, ring, ring_fields, swinging_ring,
                   writhing_ring)
from serial_reference import serial

from dolfin_rod import RodModel, RodParameters, Rod, RodSystem, StartingState
from dolfin_rod.rod.start import Arc

E2 = np.array([0.0, 1.0, 0.0])
CELLS = (16, 32, 64)


def orders(errors) -> list[float]:
    return [math.log2(a / b) for a, b in zip(errors, errors[1:])]


def tangents(centre: np.ndarray) -> np.ndarray:
    t = np.diff(centre, axis=0)
    return t / np.linalg.norm(t, axis=1)[:, None]


@pytest.mark.mpi
def test_straight_rod_closed_into_a_circle():
    """A straight rod closed into a ring (clamped at its weld, quasi-static): in every
    cell no force (the ring's start, the n-gon of unstretched cells, is the discrete
    equilibrium: the weld's reaction force and the cells' forces are round-off of B =
    1e5, measured <= 5e-12 and 7e-10 against EI/R^2 = 39.5) and the bending couple EI/R
    about the ring's axis e_2, no twist; the energy pi EI/R.  Measured: couple 1 + 3.2e-3, 8.0e-4, 2.0e-4 of
    EI/R, energy 6.46e-3, 1.61e-3, 4.02e-4 of pi EI/R at 16, 32, 64 cells: order 2.00
    (the 1-point rule's curvature of the P1 rotations, O(h^2)); 2 ranks give the serial
    numbers to 1e-12."""
    energy, couple = [], []
    for n in CELLS:
        f = ring_fields(ring(n))
        m, force = np.array(f["m"]), np.array(f["n"])
        # round-off of B = 1e5 times the strains' (measured <= 5e-12 at the weld)
        assert np.abs(f["weld_force"]).max() < 1e-10 * BEND / RADIUS ** 2
        assert np.abs(force).max() < 1e-8 * BEND / RADIUS ** 2
        t = tangents(np.array(f["centre"]))
        assert np.abs(np.einsum("ij,ij->i", m, t)).max() < 1e-12     # no twist
        along = m @ E2
        assert np.ptp(along) < 1e-12 * BEND / RADIUS                 # uniform
        couple.append(abs(along[0] / (BEND / RADIUS) - 1))
        energy.append(abs(f["free_energy"] / (math.pi * BEND / RADIUS) - 1))
    assert couple[0] < 4e-3 and energy[0] < 7e-3, (couple, energy)
    for order in orders(couple) + orders(energy):
        assert abs(order - 2) < 0.05, (couple, energy)
    here, reference = ring_fields(ring(16)), serial("ring_fields", 16, 0.0)
    assert np.allclose(here["m"], reference["m"], rtol=0, atol=1e-12)
    assert here["free_energy"] == pytest.approx(reference["free_energy"], rel=1e-12)


@pytest.mark.mpi
def test_twisted_ring_carries_its_closed_form_shear_and_twist():
    """The ring closed with Tw = 1 turn of twist (tau = Tw/R), settled: Kirchhoff's
    equilibrium m = A/R b + C tau t needs the constant force F = C tau/R b (m' = C tau/R
    n balanced by t x F), F = C Tw/R^2 = 30.37 along the axis; twist couple C Tw/R;
    energy pi A/R + pi C Tw^2/R.  With B = 1e6 (the shearable rod's own correction
    O(A/(B R^2)) = 4e-5; with B = 1e5 it bends the 64-cell orders to 1.89-2.10),
    measured relative errors at 16, 32, 64 cells: force 2.63e-2, 6.47e-3, 1.62e-3
    (orders 2.02, 2.00), twist couple 1.31e-2, 3.23e-3, 8.1e-4 (2.01, 1.99), energy
    2.63e-2, 6.45e-3, 1.60e-3 (2.03, 2.01): orders within 0.05 of 2.  2 ranks = serial:
    energy and axial force to 1e-9 (Newton's tolerance)."""
    link = 1.0
    shear, twist, energy = [], [], []
    for n in CELLS:
        f = ring_fields(ring(n, link, stiff=1e6))
        force, m = np.array(f["n"]), np.array(f["m"])
        t = tangents(np.array(f["centre"]))
        assert np.abs(np.einsum("ij,ij->i", force, t)).max() < 1e-8 * BEND / RADIUS ** 2
        shear.append(abs(np.mean(force @ E2) / (TWIST * link / RADIUS ** 2) - 1))
        twist.append(abs(np.mean(np.einsum("ij,ij->i", m, t)) / (TWIST * link / RADIUS) - 1))
        energy.append(abs(f["free_energy"] / (math.pi * (BEND + TWIST * link ** 2) / RADIUS)
                          - 1))
    for errors in (shear, twist, energy):
        assert errors[0] < 3e-2, errors
        for order in orders(errors):
            assert abs(order - 2) < 0.05, (shear, twist, energy)
    here, reference = ring_fields(ring(16, link)), serial("ring_fields", 16, link)
    assert here["free_energy"] == pytest.approx(reference["free_energy"], rel=1e-9)
    # the weld's axial force to 1e-9; not its small in-plane components (the clamp's
    # O(A/(B R^2)) imperfection, docs/systems.md): they lie along K's neutral direction
    # (the isotropic ring's spin), where Newton's stopping point decides them (measured
    # 2e-5 serially, -5e-5 and 5e-4 on 2 ranks with two versions of Newton's test)
    assert here["weld_force"][1] == pytest.approx(reference["weld_force"][1], rel=1e-9)


@pytest.mark.mpi
def test_michell_counts_below_and_above_the_critical_twist():
    """The settled twisted ring is stable (no negative eigenvalue of the tangent
    stiffness) below Michell's sqrt(3) A/C turns and unstable above (2: the n = 2
    out-of-plane pair); at 32 cells the discrete critical twist is 1.0052 of Michell's
    (test below), so 0.95 and 1.05 of it decide.  2 ranks give the serial counts."""
    links = [0.0, 0.95 * MICHELL, 1.05 * MICHELL, 1.3 * MICHELL]
    counts = [michell_count(32, link) for link in links]
    assert counts == [0, 0, 2, 2], counts
    assert counts == serial("michell_counts", 32, links)


@pytest.mark.slow
def test_michell_critical_twist_converges_at_second_order():
    """The twist at which the count leaves 0 (bisection, 16 halvings: 2.7e-5 of it),
    with B = 1e6 (the shearable rod's own shift O(A/(B R^2)) = 4e-5; with B = 1e5 it is
    4e-4, which bends the 64-cell order to 2.47: errors 1.76e-2, 4.68e-3, 8.5e-4):
    relative to Michell's sqrt(3) A/C = 2.2517 turns 1.81e-2, 5.13e-3, 1.30e-3 at 16,
    32, 64 cells (orders 1.82, 1.99; the 16-cell mesh, a 22-degree cell turn, is
    pre-asymptotic: 128 cells give 2.03 at B = 1e5, L = 2 pi).  Tolerances: the 64-cell
    error below 2e-3, the last order within 0.05 of 2, the first above 1.75."""
    errors = [abs(critical_link(n, stiff=1e6) / MICHELL - 1) for n in CELLS]
    assert errors[2] < 2e-3, errors
    assert abs(orders(errors)[1] - 2) < 0.05 and orders(errors)[0] > 1.75, errors


@pytest.mark.mpi
def test_a_clamped_ring_pulled_quasi_statically_stretches_as_the_closed_form():
    """TimeStepper's quasi-static steps on a ring (tests/rings.pulled_ring): clamped at
    its weld, pulled at s = L/2 along the diameter by P = +-0.01 EI/R^2 ramped over 4
    steps, then held for 2 steps that start at the equilibrium.  A ring's residual at
    an equilibrium is round-off far above snes_atol (1e-10 F*): Newton stops by the step
    test, and after it the check accepts a residual that grew from the step's first one
    only up to the round-off floor's estimate (fem/solvers.py).  That estimate, eps
    || |J| h ||, left out the unknowns' own rounding (displacements ~ L from the straight
    reference, unit quaternions): the untwisted unloaded ring (B = 1e5) failed its
    second step at 1.02e-9 from 1.008e-9 (estimate 8.6e-10; 1.07e-8 against 1.7e-9 at
    128 cells), and here the residuals lie 1.05-1.4 (32 cells) and 2.3-3.0 (64 cells)
    times above it.  Now eps || |J| (|y| + h) ||: they lie at 0.07-0.14 of it.
    Closed form (the pinched ring, Kirchhoff's inextensible rod): the diameter grows by
    (pi/4 - 2/pi) P R^3/EI; with B = 1e7 the rod's stretch and shear add only 4.2e-5 of
    it (Castigliano's pi R/(4 EA) + pi R/(4 GA), tests/test_pinched_ring.py; the 32/64/
    128-cell errors extrapolate to 3.8e-5), and the mean of +-P removes the O(P)
    nonlinearity (+-1.1e-3).  Measured
    relative errors at 32, 64 cells 2.94e-2, 7.39e-3 (order 1.99; 1.82e-3 at 128).  The
    held steps keep the ramp's end state to snes_stol's 1e-10 L (measured 2e-13 L)."""
    closed_form = (math.pi / 4 - 2 / math.pi) * 0.01 * RADIUS
    errors = []
    for n in (32, 64):
        (pulled, floors), (pushed, more) = (pulled_ring(n, pull) for pull in (0.01, -0.01))
        # each accepted residual within the floor's estimate (it is one: Newton stopped
        # there), which stays a round-off level, not a tolerance: below 1e-4 of the load
        # P = 0.39 (measured 2.8e-6 P, 7.7e-6 P at 32, 64 cells: B = 1e7 times eps)
        assert all(norm <= floor < 1e-4 * 0.01 * BEND / RADIUS ** 2
                   for norm, floor in floors + more), floors + more
        for changes in (pulled, pushed):                 # t = 0, 4 ramp steps, 2 held
            assert len(changes) == 7, changes
            assert max(abs(c - changes[4]) for c in changes[5:]) < 1e-10 * LENGTH
        errors.append(abs(0.5 * (pulled[-1] - pushed[-1]) / closed_form - 1))
    assert errors[1] < 7.5e-3, errors
    assert abs(orders(errors)[0] - 2) < 0.05, errors


def turning_stiffness(difference: float) -> float:
    """The Rayleigh quotient of the mechanism (rings.mechanism) with A_1 - A_2 =
    ``difference``: spinning the sections back by alpha turns the curvature 1/R from d2
    towards d1, psi = (A_1 sin^2 alpha + A_2 cos^2 alpha)/(2 R^2) per length, so
    v^T K v = (A_1 - A_2) L/R^2; v^T G v = int |e_3 x r|^2 + L^2 |e_3 - d_3|^2 ds =
    3 pi R^3 + 4 pi R L^2.  The lowest eigenvalue lies at or below it."""
    return difference * LENGTH / RADIUS ** 2 / (3 * math.pi * RADIUS ** 3
                                                 + 4 * math.pi * RADIUS * LENGTH ** 2)


@pytest.mark.mpi
def test_a_clamped_isotropic_ring_is_a_mechanism():
    """The untwisted ring clamped at its weld, isotropic (A_1 = A_2) and straight when
    stress-free: its tangent stiffness has an exact zero eigenvalue (measured 2.5e-11,
    -6.9e-11 at 16, 32 cells against the next, 15.7: round-off of B = 1e5), whose mode
    is the rigid turn about the weld's tangent with every section spinning back
    (rod/ring.py; measured 2e-11 from it, scaled to a displacement of 1).  A section
    stiffer about d1 by 1 % (A_1 = 1.01) holds it: the lowest eigenvalue is positive and
    at most the mechanism's Rayleigh quotient 0.1937 (measured 0.19); softer (A_2 =
    1.01, the axis the ring bends about) the ring flips its sections: at most -0.1937
    (measured -0.1962).  2 ranks: the same numbers (one eigen-solve, MUMPS)."""
    quotient = turning_stiffness(0.01)
    for n in (16, 32):
        isotropic = mechanism(n)
        zero, next_one = isotropic["values"]
        assert abs(zero) < 1e-9 * next_one and next_one > 15.0, isotropic
        assert isotropic["misfit"] < 1e-9, isotropic       # measured 2e-11
    stiff, soft = mechanism(16, (1.01, 1.0, TWIST)), mechanism(16, (1.0, 1.01, TWIST))
    assert 0.5 * quotient < stiff["values"][0] <= quotient * (1 + 1e-9), stiff
    assert soft["values"][0] <= -quotient * (1 - 1e-9), soft
    assert soft["values"][0] > -1.1 * quotient, soft


def test_a_load_turning_a_clamped_ring_is_refused_naming_its_support():
    """A quasi-static load with a moment about the weld's tangent on the mechanism (a
    force out of the ring's plane at s = L/2: Q = 2 R F; Newton diverged at t = 0,
    DIVERGED_DTOL) is refused when the model is made, naming ``start``; a symmetric pair
    (Q = R F - R F), an in-plane pull (Q = 0), a dynamic ring and a section stiffer about
    d1 are not."""
    from dolfin_rod.rod.external_forces import DistributedLoad, PointLoad
    out_of_plane = PointLoad("force", (0.0, 1.0, 0.0), 0.5)
    with pytest.raises(ValueError, match=r"start: a quasi-static ring clamped at its weld "
                       r".* point_loads\[0\] \(force at s = 0.5\) has a moment 0.31831"):
        RodModel(RING, 16, model="hyperelastic", closed=True, point_loads=[out_of_plane])
    with pytest.raises(ValueError, match=r"distributed_loads\[0\] \(force\) has a moment"):
        RodModel(RING, 16, model="hyperelastic", closed=True,
                 distributed_loads=[DistributedLoad("force", (0.0, -1.0, 0.0))])
    pair = [PointLoad("force", (0.0, 1.0, 0.0), 0.25), PointLoad("force", (0.0, -1.0, 0.0), 0.75)]
    RodModel(RING, 16, model="hyperelastic", closed=True, point_loads=pair)
    RodModel(RING, 16, model="hyperelastic", closed=True, distributed_loads=[
        DistributedLoad("force", (0.0, 0.0, -1.0))])                  # gravity in its plane
    stiff = RodParameters(length=LENGTH, A=(1.01, 1.0, TWIST), B=(1e5, 1e5, 1e5))
    RodModel(stiff, 16, model="hyperelastic", closed=True, point_loads=[out_of_plane])
    dynamic = RodParameters(length=LENGTH, B=(1e5, 1e5, 1e5), density=1.0)
    RodModel(dynamic, 16, model="hyperelastic", closed=True, point_loads=[out_of_plane])


@pytest.mark.mpi
def test_drag_lets_a_clamped_ring_swing_to_its_equilibrium():
    """The regularised mechanism: with drag (c = 1) the quasi-static clamped ring pulled
    out of its plane at s = L/2 turns at a viscous rate about the weld's tangent to the
    pendulum's equilibrium, hanging along the force: at t = 4 its loaded node is the
    in-plane pulled ring's (no drag, an equilibrium at the first solve) turned by a
    quarter turn about e_3 (measured 2.6e-14 off the plane x = 0, the diameter equal
    to 1e-13).  2 ranks = serial to 1e-9."""
    pulled = swinging_ring(16, 0, 0.0, t_end=1.0, dt=1.0)
    with pytest.warns(RuntimeWarning, match="cut"):                 # the swing's steps
        swung = swinging_ring(16, 1, 1.0)
    assert pulled[1] == 0.0 and pulled[0] > 2 * RADIUS
    assert np.allclose(swung, [0.0, pulled[0], pulled[2]], rtol=0, atol=1e-10 * LENGTH), \
        (swung, pulled)
    assert np.allclose(swung, serial("swinging_ring", 16, 1, 1.0), rtol=0, atol=1e-9)


@pytest.mark.mpi
def test_free_ring_weld_holds_the_ring_at_rest():
    """A free dynamic ring (start = "free": its end node tied to its start node by the
    weld's exact links) closed untwisted starts in its discrete equilibrium: after 20
    steps its kinetic energy is 0 (measured 0.0 exactly) and its free energy pi EI/R to
    the 16-cell error (6.5e-3 here with B = 1e4); 2 ranks = serial to 1e-12."""
    d = free_ring(16, 0.0)
    assert d["kinetic_energy"] < 1e-20
    assert d["free_energy"] == pytest.approx(math.pi * BEND / RADIUS, rel=7e-3)
    reference = serial("free_ring", 16, 1.0, 1e-3)
    here = free_ring(16, 1.0, push=1e-3)
    for key in ("free_energy", "kinetic_energy", "tip_position_x", "tip_position_y"):
        assert here[key] == pytest.approx(reference[key], rel=1e-9, abs=1e-12), key


@pytest.mark.mpi
def test_writhing_ring_keeps_its_link():
    """Calugareanu-White for the ring (rod/ring.ring_linking): a free ring closed with
    Tw = 1.5 turns, pushed out of its plane (velocity 2 cos(2 phi) along its axis), 20
    steps: its writhe grows from 0 to 2.9e-4 while Tw + Wr stays 1.5 to 8.5e-12 (the
    discrete twist's parallel transport makes the identity exact for the polygon: the
    weld keeps the link); at the start Tw = 1.5 to 1e-12, Wr = 0 (planar).  2 ranks =
    serial to 1e-9."""
    link = 1.5
    pairs = writhing_ring(16, link)
    assert pairs[0][0] == pytest.approx(link, abs=1e-12) and abs(pairs[0][1]) < 1e-12
    assert abs(pairs[-1][1]) > 1e-4, pairs[-1]           # it writhes (measured 2.9e-4)
    assert max(abs(tw + wr - link) for tw, wr in pairs) < 1e-10, pairs
    reference = serial("writhing_ring", 16, link)
    assert np.allclose(pairs, reference, rtol=0, atol=1e-9)


@pytest.mark.mpi
def test_a_pinched_ring_inside_a_system_is_the_ring_alone():
    """Rings in a RodSystem: the pinched ring (tests/test_pinched_ring.py's, clamped at
    its weld, stress-free as its circle) as the second rod of a system, after a loaded
    cantilever, placed at (3, 0, 0): delta/P = 0.1449296 at 32 cells, the ring alone's to
    round-off (measured 1.5e-12 relative; the system's dofs are numbered otherwise), and
    the closed form 0.149087 P R^3/EI to the 32-cell error of the pinched ring's test
    (-2.789e-2)."""
    from test_pinched_ring import flexibility
    alone, inside = pinched_in_system(32, False), pinched_in_system(32, True)
    assert inside == pytest.approx(alone, rel=1e-10)
    assert inside / flexibility() - 1 == pytest.approx(-2.789e-2, abs=1e-5)


@pytest.mark.mpi
def test_a_free_ring_inside_a_system_moves_as_alone():
    """A free ring (its weld's exact links, on the nodes at its offset in the system's
    layout) closed with 1 turn and pushed, as the second rod of a system after a
    cantilever at rest, placed at (2, 0, 0): after 20 steps its energies and weld point
    are the ring alone's (rings.free_ring) to round-off (measured 7e-15 of the energy
    35.79, 5e-14 of the positions), the cantilever at rest."""
    alone, inside = free_ring(16, 1.0, push=1e-3), free_ring_in_system(16, 1.0, 1e-3)
    for key in ("free_energy", "kinetic_energy"):
        assert inside[key] == pytest.approx(alone[key], rel=1e-12), key
    for c, shift in zip("xyz", (2.0, 0.0, 0.0)):
        assert inside[f"ring.tip_position_{c}"] == pytest.approx(
            alone[f"tip_position_{c}"] + shift, abs=1e-12), c
    assert inside["beam.tip_position_z"] == 1.0 and inside["beam.tip_position_x"] == 0.0


@pytest.mark.mpi
def test_a_ring_hanging_by_a_ball_joint_carries_its_weight():
    """A free ring of weight 1 hanging by a ball joint at its node s = L/2 from a
    cantilever's tip, settled and run 10 steps: the joint carries the weight (global
    equilibrium of the ring: force (0, 0, 1), no couple at a ball joint) and so does the
    cantilever's clamp, to the settle's Newton tolerance (measured 2.5e-10)."""
    d = hanging_ring(16)
    force = [d[f"joint_hook_force_{c}"] for c in "xyz"]
    clamp = [d[f"beam.reaction_force_start_{c}"] for c in "xyz"]
    assert np.allclose(force, (0.0, 0.0, 1.0), rtol=0, atol=1e-8), force
    assert np.allclose(clamp, (0.0, 0.0, 1.0), rtol=0, atol=1e-8), clamp
    assert np.abs([d[f"joint_hook_couple_{c}"] for c in "xyz"]).max() < 1e-10
    assert d["kinetic_energy"] < 1e-20


@pytest.mark.parametrize("keywords, start, message", [
    (dict(end="clamped"), None, "end: a closed rod's end is welded"),
    (dict(start="pinned"), None, "start: a closed rod's start is its weld"),
    (dict(start="free"), None, "start: a quasi-static closed rod is clamped"),
    (dict(end_rotation={"end": lambda t: (0.0, 0.0, t)}), None, "end_rotation: a closed"),
    (dict(n_cells=3), None, "excess_link: a ring of 3 cells"),
    (dict(excess_link=float("nan")), None, "excess_link must be a finite"),
    ({}, StartingState(shape=Arc(radius=0.2)), "start.shape: a closed rod starts as its ring"),
])
def test_bad_closed_rods_are_refused_naming_the_key(keywords, start, message):
    n_cells = keywords.pop("n_cells", 8)
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        model = RodModel(RING, n_cells, model="hyperelastic", closed=True, **keywords)
        model.set_initial_state(start=start)


def test_excess_link_of_an_open_rod_and_a_joint_at_a_weld_are_refused():
    from dolfin_rod.rod.joint_points import Joint
    with pytest.raises(ValueError, match="excess_link: the turns a ring is closed with"):
        RodModel(RING, 8, model="hyperelastic", excess_link=1.0)
    with pytest.raises(ValueError, match=r"joints\[0\]: the node of rod 'a' at the point "
                                         "is its weld"):
        p = RodParameters(length=LENGTH, density=1.0, section_inertia=1e-4)
        RodSystem([Rod(p, 8, name="a", closed=True, start="free"),
                   Rod(p, 8, name="b", position=(0.0, 0.0, -1.0))],
                  [Joint("ball", ("a", "b"), (0.0, 0.0, 0.0))], model="hyperelastic")
    p = RodParameters(length=LENGTH, density=1.0)
    with pytest.raises(ValueError, match="free ring's weld"):
        RodModel(p, 8, closed=True, start="free", rotations="quaternion")


RING_SCENE = """[geometry]
length = 1.0
n_cells = 16
closed = true
excess_link = 1.0

[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 0.8], B = [1e4, 1e4, 1e4] }

[time]
t_end = 1.0
dt = 0.5
"""


@pytest.mark.parametrize("extra, key", [
    ("\n[boundary]\nend = \"clamped\"\n", "[boundary.end]: a closed rod's end is welded"),
    ("\n[boundary]\nstart = \"free\"\n", "[boundary.start]: a quasi-static closed rod"),
    ("\n[initial]\nshape = { type = \"arc\", radius = 0.2 }\n", "[initial.shape]: a closed rod"),
    ("\n[boundary]\nend_rotation = { type = \"ramp\", value = [0.0, 0.0, 1.0], "
     "duration = 1.0 }\n",
     "[boundary.end_rotation]: a closed rod's ends are its weld"),
])
def test_bad_closed_scenes_exit_2_naming_the_key(tmp_path, capsys, extra, key):
    """`dolfin-rod check` refuses them before any model is built (exit 2), naming the key."""
    from dolfin_rod.cli import main
    scene = tmp_path / "ring.toml"
    scene.write_text(RING_SCENE + extra)
    assert main(["check", str(scene)]) == 2
    assert key in capsys.readouterr().err


def test_excess_link_of_an_open_rod_scene_is_refused(tmp_path, capsys):
    from dolfin_rod.cli import main
    scene = tmp_path / "open.toml"
    scene.write_text(RING_SCENE.replace("closed = true\n", ""))
    assert main(["check", str(scene)]) == 2
    assert "[geometry.excess_link]: the turns a ring is closed with" in capsys.readouterr().err
    scene.write_text(RING_SCENE)
    assert main(["check", str(scene)]) == 0


def test_a_scene_turning_a_clamped_ring_is_refused_naming_boundary_start(tmp_path):
    """The scene of a quasi-static ring clamped at its weld, pulled out of its plane at
    s = L/2 (its mechanism, rod/ring.check_mechanism): a SceneError naming
    [boundary.start] before any solve (it diverged at t = 0 with DIVERGED_DTOL)."""
    from dolfin_rod import SceneError, run
    scene = tmp_path / "turn.toml"
    scene.write_text(RING_SCENE.replace("excess_link = 1.0\n", "") + (
        "\n[loads]\npoint_force = { s = 0.5, type = \"ramp\", value = [0.0, 1.0, 0.0], "
        "duration = 1.0 }\n"))
    with pytest.raises(SceneError, match=r"\[boundary.start\]: a quasi-static ring clamped "
                                         r"at its weld .* is a mechanism"):
        run(str(scene), {"outputs.directory": str(tmp_path / "out")})


# a free ring (weight 1) hanging by a ball joint at its node s = L/2 from a cantilever
# (weight 1) pointing down: the n-gon's diameter 2 L/(2 n sin(pi/n)) below the hook
HANGING_SCENE = """[scene]
name = "hanging_ring"
units = "dimensionless"

[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 0.7692307692307692], B = [1e4, 1e4, 1e4] }
density = 1.0
section_inertia = 1e-4
drag = 1.0

[loads]
gravity = [0.0, 0.0, -1.0]

[boundary]
end = "free"

[[rods]]
name = "beam"
orientation = [3.141592653589793, 0.0, 0.0]
geometry = { length = 1.0, n_cells = 8 }
boundary = { start = "clamped" }
initial = { equilibrium = true }

[[rods]]
name = "ring"
position = [0.0, 0.0, -1.3203644309676883]
orientation = [0.0, -1.5707963267948966, 0.0]
geometry = { length = 1.0, n_cells = 16, closed = true }
boundary = { start = "free" }

[[joints]]
kind = "ball"
rods = ["beam", "ring"]
point = [0.0, 0.0, -1.0]
name = "hook"

[time]
t_end = 0.1
dt = 0.01

[outputs]
animation = false
plots = false
fields = false
"""


@pytest.mark.mpi
def test_a_scene_ring_hangs_from_a_rod_by_a_ball_joint(tmp_path, capsys):
    """A ring in a scene's [[rods]] (geometry.closed), joined by a ball joint at its node
    s = L/2 to a cantilever's tip, the system settled (initial.equilibrium) and run 10
    steps: the joint carries the ring's weight (0, 0, 1) and the clamp both rods' (0, 0,
    2), to the settle's Newton tolerance (1e-8; measured 2.5e-10); the ball no couple.
    The same ring joined at its weld is refused by `dolfin-rod check` naming
    [joints[0]]."""
    from mpi4py import MPI
    from dolfin_rod import run
    from dolfin_rod.cli import main
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path), root=0))       # rank 0's, on every rank
    scene, weld = folder / "hanging_ring.toml", folder / "weld.toml"
    if comm.rank == 0:
        scene.write_text(HANGING_SCENE)
        weld.write_text(HANGING_SCENE      # the ring's weld (s = 0) at the hook
                        .replace("[0.0, 0.0, -1.3203644309676883]", "[0.0, 0.0, -1.0]")
                        .replace("[0.0, -1.5707963267948966, 0.0]", "[0.0, 1.5707963267948966, 0.0]"))
    comm.barrier()
    result = run(str(scene), {"outputs.directory": str(folder / "out")})
    assert result.status == "completed", result.status
    series = result.series
    for key, value in (("joint_hook_force", (0.0, 0.0, 1.0)),
                       ("beam.reaction_force_start", (0.0, 0.0, 2.0))):
        got = [series[f"{key}_{c}"][-1] for c in "xyz"]
        assert np.allclose(got, value, rtol=0, atol=1e-8), (key, got)
    assert max(abs(series[f"joint_hook_couple_{c}"][-1]) for c in "xyz") < 1e-10
    assert main(["check", str(weld)]) == 2
    if comm.rank == 0:                                   # errors are printed on rank 0
        assert "[joints[0]]: the node of rod 'ring' at the point is its weld" in \
            capsys.readouterr().err
