"""A stress-free shape given as a curve (RodParameters.reference_shape, rod/start.py
curves): an arc equals the reference curvature of its circle bit for bit; an L-frame as
one rod with a corner in its stress-free shape, at a node or between nodes, is split
there into straight pieces joined rigidly (rod/kinks.py): the frame of two rods and a
rigid joint to round-off, second order in h; bad shapes named."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from rod_systems import FRAME, kinked_frame

from dolfin_rod import EndLoad, RodModel, RodParameters, TimeStepper
from dolfin_rod.rod.start import Arc, Polyline, StartingState

ROOT = Path(__file__).resolve().parents[1]


def tip(d: dict) -> np.ndarray:
    return np.array([d[f"tip_position_{c}"] for c in "xyz"])


def test_arc_shape_is_the_reference_curvature():
    """reference_shape = Arc(R) and reference_curvature = (0, 1/R, 0) give the same
    stress-free configuration (the same helix), so the same dynamic run bit for bit."""
    results = []
    for shape in ({"reference_shape": Arc(0.7)}, {"reference_curvature": (0.0, 1 / 0.7, 0.0)}):
        p = RodParameters(length=1.0, density=1.0, section_inertia=0.01, **shape)
        model = RodModel(p, 8, model="hyperelastic", end_loads=[EndLoad("force", (0, 1, 0))])
        model.set_initial_state()
        TimeStepper(model.problem).run(0.0, 0.05, 0.01)
        results.append(model.diagnostics(0.05))
    assert results[0] == results[1]
    assert abs(results[0]["tip_position_y"]) > 1e-4


@pytest.mark.parametrize("force", [1e-6, 1.5])
def test_kinked_rod_is_the_joined_frame(force):
    """The L-frame (tests/rod_systems.FRAME, 5 and 4 cells per 0.2 of column and beam)
    as ONE rod with a corner in its stress-free polyline is split at the corner into two
    pieces joined rigidly (rod/kinks.py): the frame of two rods and a rigid knee, the
    same equations, so the same tip to round-off (measured: equal to the last digit, and
    the clamp's reaction too).  Before the split the corner was spread over its node's two
    cells (each turned by 45 deg), and the tips differed at first order in h: 1.9e-2,
    9.9e-3, 5.1e-3 of the displacement at h = 0.2, 0.1, 0.05 (small load), 1.3e-2,
    6.4e-3, 3.1e-3 under the tip force 1.5 (rates 0.92-1.04)."""
    steps = 1 if force < 1 else 4
    for k in (1, 2):
        one, two = (kinked_frame(5 * k, 4 * k, force, steps, joined) for joined in (False, True))
        moved = np.linalg.norm(tip(two) - np.array([FRAME["L2"], 0.0, FRAME["L1"]]))
        assert np.linalg.norm(tip(one) - tip(two)) < 1e-12 * moved
        assert one["reaction_force_start_z"] == pytest.approx(
            two["column.reaction_force_start_z"], rel=1e-12)


def test_kinked_rod_large_load_second_order():
    """The kinked L-frame under the tip force 1.5 (beam tip lowered by 0.6 L1) converges
    at second order in h, the smooth rod's, against 16 x (5 + 4) cells (h = 0.0125).
    Measured errors 3.94e-3, 9.81e-4, 2.33e-4 at h = 0.2, 0.1, 0.05: rates 2.00, 2.07
    (the last includes the reference's error, ~1/16 of it); first order before the
    split (test above).  Asserted: rates in [1.9, 2.2]."""
    tips = {k: tip(kinked_frame(5 * k, 4 * k, 1.5, 4)) for k in (1, 2, 4, 16)}
    errors = np.array([np.linalg.norm(tips[k] - tips[16]) for k in (1, 2, 4)])
    rates = np.log2(errors[:-1] / errors[1:])
    assert np.all((rates > 1.9) & (rates < 2.2)), (errors, rates)


def test_corner_between_nodes_is_split_exactly():
    """The L-frame (column 1, beam 0.8) as ONE rod of n = 10 k cells: its corner at
    s = 1 falls between nodes (n/1.8 = 5.56 k).  The rod is split there anyway
    (rod/kinks.py), its n cells shared in proportion to the pieces' lengths, largest
    remainder first: 10 -> 5.56, 4.44 -> (6, 4); 20 -> (11, 9); 40 -> (22, 18); 80 ->
    (44, 36); 320 -> 177.8, 142.2 -> (178, 142) (by hand).  So it is the welded frame of
    those cells to round-off (measured: equal to the last digit), and it converges at
    second order under the tip force 1.5: errors against 320 cells 2.31e-3, 6.32e-4,
    1.56e-4, 3.72e-5 at n = 10, 20, 40, 80, rates 1.87 (the cells are not halved
    from 10 to 20), 2.02, 2.07 (the last includes the reference's error, ~1/16 of it).
    Asserted: rates from n = 20 on in [1.9, 2.2].  Before the split (the corner kept in
    one rod, spread over its cell) the errors were 8.8e-3, 3.7e-3, 1.5e-3, 5.2e-4:
    rates 1.26, 1.31, 1.51 (first order, against a first-order reference)."""
    from dolfin_rod import EndLoad, loads
    from dolfin_rod.rod.kinks import piece_cells
    from rod_systems import FRAME
    assert piece_cells([1.0, 0.8], 10) == [6, 4] and piece_cells([1.0, 0.8], 320) == [178, 142]
    f = FRAME
    shape = Polyline(((0.0, 0.0, 0.0), (0.0, 0.0, f["L1"]), (f["L2"], 0.0, f["L1"])))
    params = RodParameters(length=f["L1"] + f["L2"], A=(f["EI"], f["EI"], 1.5),
                           B=(f["GA"], f["GA"], f["EA"]), reference_shape=shape)
    model = RodModel(params, 10, model="hyperelastic",
                     end_loads=[EndLoad("force", (0.0, 0.0, -1.5), loads.ramp(1.0, 1.0))])
    assert [rod.n_cells for rod in model.rods] == [6, 4]
    for cells in ((6, 4), (11, 9)):
        one, two = (kinked_frame(*cells, 1.5, 4, joined) for joined in (False, True))
        moved = np.linalg.norm(tip(two) - np.array([f["L2"], 0.0, f["L1"]]))
        assert np.linalg.norm(tip(one) - tip(two)) < 1e-12 * moved
    cells = {20: (11, 9), 40: (22, 18), 80: (44, 36), 320: (178, 142)}
    tips = {n: tip(kinked_frame(*c, 1.5, 4)) for n, c in cells.items()}
    errors = np.array([np.linalg.norm(tips[n] - tips[320]) for n in (20, 40, 80)])
    rates = np.log2(errors[:-1] / errors[1:])
    assert np.all((rates > 1.9) & (rates < 2.2)), (errors, rates)


@pytest.mark.parametrize("force", [1e-6, 1.5])
def test_corner_reactions_are_the_statics(force):
    """A split rod's diagnostics carry the force and couple its corner transmits (the
    internal rigid joint's reactions, joint_rod-corner1_*: on the piece after the
    corner).  The kinked L-frame (corner between nodes, 6 + 4 cells) under the tip force
    -P e_3: the beam piece alone is in equilibrium with its tip load and the corner, so
    the corner force is P e_3 and its couple -(r_tip - r_corner) x (-P e_3), whose y
    component is -P (x_tip - x_corner) (-P L2 for a small load), with r_corner the
    welded frame's column tip; all to Newton's tolerance (measured: force 5.6e-8 and
    1.1e-10 relative at P = 1e-6 and 1.5, couple 8e-9 and 2.7e-10), asserted 1e-7 and 1e-9.
    The same numbers as the welded frame's knee to the last digit."""
    steps = 1 if force < 1 else 4
    one = kinked_frame(6, 4, force, steps)
    two = kinked_frame(6, 4, force, steps, joined=True)
    tol = 1e-7 if force < 1 else 1e-9
    corner = np.array([two[f"column.tip_position_{c}"] for c in "xyz"])
    f = np.array([one[f"joint_rod-corner1_force_{c}"] for c in "xyz"])
    m = np.array([one[f"joint_rod-corner1_couple_{c}"] for c in "xyz"])
    assert np.linalg.norm(f - [0.0, 0.0, force]) < tol * force
    arm = tip(one) - corner
    assert np.linalg.norm(m + np.cross(arm, [0.0, 0.0, -force])) < tol * force * np.linalg.norm(arm)
    if force < 1:
        from rod_systems import FRAME
        assert m[1] == pytest.approx(-force * FRAME["L2"], rel=tol)
    for c in "xyz":
        for what in ("force", "couple"):
            assert one[f"joint_rod-corner1_{what}_{c}"] == two[f"joint_column-beam_{what}_{c}"]


def test_kinks_between_nodes_and_loads_along_the_pieces():
    """A polyline cornering at a node (s = 1) and between nodes (s = 1.55, h = 0.1),
    under a distributed load that varies along s and a point load: split at both
    corners into three straight pieces of 10, 6, 4 cells (shares 10, 5.5, 4.5: the tie
    to the earlier piece), it equals the three rods it is made of, each carrying the
    rod's loads at its own s + offset, joined rigidly at the corners (the same
    equations: to round-off, measured 0)."""
    from dolfin_rod import DistributedLoad, PointLoad, Rod, RodSystem
    from dolfin_rod.rod.joints import Joint
    from dolfin_rod.theory.quaternions import np_quaternion_from_matrix, np_rotation_vector
    params = RodParameters(length=2.0, A=(2.0, 2.0, 1.5), B=(500.0, 500.0, 1e3),
                           reference_shape=Polyline(((0, 0, 0), (0, 0, 1.0), (0.55, 0, 1.0),
                                                     (0.55, 0.45, 1.0))))
    weight = DistributedLoad("force", lambda s: (0.0, 0.0, -0.3 * (1.0 + s)))
    one = RodModel(params, 20, model="hyperelastic", distributed_loads=[weight],
                   point_loads=[PointLoad("force", (0.0, 0.2, 0.0), s=1.5)])
    assert [rod.n_cells for rod in one.rods] == [10, 6, 4]
    one.set_initial_state()
    TimeStepper(one.problem).run(0.0, 1.0, 1.0)
    d_one = one.diagnostics(1.0)
    straight = RodParameters(length=1.0, A=(2.0, 2.0, 1.5), B=(500.0, 500.0, 1e3))
    # the pieces' frames (d1, d2, d3) as columns: d1 = e1 carried by parallel transport
    along_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])   # (-e3, e2, e1)
    along_y = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])  # (-e3, -e1, e2)

    def shifted(offset):
        return DistributedLoad("force", lambda s: (0.0, 0.0, -0.3 * (1.0 + offset + s)))

    knee, elbow = (0.0, 0.0, 1.0), (0.55, 0.0, 1.0)
    three = RodSystem(
        [Rod(straight, 10, name="a", distributed_loads=[weight]),
         Rod(replace(straight, length=0.55), 6, "free", end="free", name="b", position=knee,
             orientation=tuple(np_rotation_vector(np_quaternion_from_matrix(along_x))),
             distributed_loads=[shifted(1.0)],
             point_loads=[PointLoad("force", (0.0, 0.2, 0.0), s=0.5)]),
         Rod(replace(straight, length=0.45), 4, "free", end="free", name="c",
             position=elbow,
             orientation=tuple(np_rotation_vector(np_quaternion_from_matrix(along_y))),
             distributed_loads=[shifted(1.55)])],
        joints=[Joint("rigid", ("a", "b"), knee), Joint("rigid", ("b", "c"), elbow)],
        model="hyperelastic")
    three.set_initial_state()
    TimeStepper(three.problem).run(0.0, 1.0, 1.0)
    d_three = three.diagnostics(1.0)
    tip_three = np.array([d_three[f"c.tip_position_{c}"] for c in "xyz"])
    moved = tip_three - np.array([0.55, 0.45, 1.0])
    assert np.linalg.norm(moved) > 1e-2
    assert np.linalg.norm(tip(d_one) - tip_three) < 1e-12 * np.linalg.norm(moved), (
        tip(d_one), tip_three)
    assert d_one["reaction_couple_start_y"] == pytest.approx(
        d_three["a.reaction_couple_start_y"], rel=1e-12)


def test_a_kinked_rod_placed_and_spun_at_the_start():
    """A dynamic kinked L-frame (column 1, beam 0.8 along e_1, 9 cells) started placed
    at p with the orientation Q and spun rigidly (angular velocity w about c = p): its
    pieces start as the rod does (rod/kinks.piece_starts).  At t = 0 the tip is
    p + Q (0.8, 0, 1) and the kinetic energy the rigid rotation's, rho_A/2 int
    |w x (r - c)|^2 ds over both members (Gauss, exact for the P1 velocities) + the
    sections' spin 1/2 w.(rho I) w per length (rho I = 1e-10, below the tolerance):
    to 1e-12 and 1e-9 relative."""
    p, theta, w = np.array([0.3, -0.2, 0.5]), np.array([0.2, 0.4, -0.1]), np.array([0.4, 1.5, -0.3])
    params = RodParameters(length=1.8, A=(2.0, 2.0, 1.5), B=(500.0, 500.0, 1e3), density=1.0,
                           section_inertia=1e-10, reference_shape=Polyline(
                               ((0, 0, 0), (0, 0, 1.0), (0.8, 0, 1.0))))
    model = RodModel(params, 9, model="hyperelastic")
    assert model.kinked
    model.set_initial_state(start=StartingState(position=tuple(p), orientation=tuple(theta),
                                                angular_velocity=tuple(w),
                                                rotation_centre=tuple(p)))
    d = model.diagnostics(0.0)
    from dolfin_rod.theory.quaternions import (np_quaternion_from_rotation_vector,
                                               np_rotation_matrix)
    Q = np_rotation_matrix(np_quaternion_from_rotation_vector(theta))
    assert tip(d) == pytest.approx(p + Q @ [0.8, 0.0, 1.0], abs=1e-12)
    x, weights = np.polynomial.legendre.leggauss(4)
    energy = 0.0
    for a, b in (((0, 0, 0), (0, 0, 1.0)), ((0, 0, 1.0), (0.8, 0, 1.0))):
        a, b = Q @ np.array(a, float), Q @ np.array(b, float)
        half = np.linalg.norm(b - a) / 2
        r = (a + b) / 2 + np.outer(x, (b - a) / 2)
        energy += 0.5 * half * weights @ np.sum(np.cross(w, r) ** 2, axis=1)
    assert d["kinetic_energy"] == pytest.approx(energy, rel=1e-9)
    with pytest.raises(ValueError, match="start.shape: a rod split at its corners .* not on a "
                                         "smooth arc"):
        model.set_initial_state(start=StartingState(shape=Arc(1.0)))


def test_a_kinked_rod_starts_on_a_polyline():
    """The kinked L-frame (column 1, beam 0.8, 10 cells: the corner between nodes, 6 + 4)
    started on a polyline with its corner, stretched by 1 % (points x 1.01 at the rest
    arc lengths 0, 1, 1.8) and placed (p, Q): each piece starts on its part of the
    polyline (kinks.piece_starts), so at t = 0 the tip is p + Q (0.808, 0, 1.01) to
    1e-12 and the corner transmits the beam's tension EA 0.01 = 10 along the beam,
    -10 Q e_1 on it (the nodal residual of a uniform stretch: exact, to 1e-9).  A
    polyline whose corner has another angle, and one cornering elsewhere, are
    ValueErrors naming start.shape."""
    p, theta = np.array([0.3, -0.2, 0.5]), np.array([0.2, 0.4, -0.1])
    params = RodParameters(length=1.8, A=(2.0, 2.0, 1.5), B=(500.0, 500.0, 1e3),
                           reference_shape=Polyline(((0, 0, 0), (0, 0, 1.0), (0.8, 0, 1.0))))
    model = RodModel(params, 10, model="hyperelastic")
    assert [rod.n_cells for rod in model.rods] == [6, 4]
    stretched = Polyline(((0, 0, 0), (0, 0, 1.01), (0.808, 0, 1.01)), (0.0, 1.0, 1.8))
    model.set_initial_state(start=StartingState(shape=stretched, position=tuple(p),
                                                orientation=tuple(theta)))
    d = model.diagnostics(0.0)
    from dolfin_rod.theory.quaternions import (np_quaternion_from_rotation_vector,
                                               np_rotation_matrix)
    Q = np_rotation_matrix(np_quaternion_from_rotation_vector(theta))
    assert tip(d) == pytest.approx(p + Q @ [0.808, 0.0, 1.01], abs=1e-12)
    force = np.array([d[f"joint_rod-corner1_force_{c}"] for c in "xyz"])
    assert np.linalg.norm(force + 10.0 * Q[:, 0]) < 1e-9 * 10.0, force
    for bad in (Polyline(((0, 0, 0), (0, 0, 1.0), (0.64, 0, 1.48))),       # another angle
                Polyline(((0, 0, 0), (0, 0, 1.1), (0.7, 0, 1.1)))):       # elsewhere
        with pytest.raises(ValueError, match="start.shape: the starting polyline does not "
                                             "keep the rod's rigid corners"):
            model.set_initial_state(start=StartingState(shape=bad))


@pytest.mark.parametrize("params, message", [
    (dict(length=1.5, reference_shape=Polyline(((0, 0, 0), (0, 0, 1), (1, 0, 1)))),
     "reference_shape.points: the polyline's length 2 differs"),
    (dict(length=2.0, reference_shape=Polyline(((0, 0, 0), (0, 0, 1), (1e-5, 0, 0)))),
     "reference_shape.points: turns back on itself at point 1"),     # by pi - 1e-5 rad
    (dict(reference_shape=Arc(-1.0)), "reference_shape.radius: must be > 0"),
    (dict(reference_shape=Arc(1.0), reference_curvature=(0, 1, 0)),
     "reference_shape: the stress-free shape is a curve or"),
    (dict(reference_shape=((0, 0, 0), (0, 0, 1))), "reference_shape: must be a Straight"),
])
def test_bad_reference_shapes_are_named(params, message):
    with pytest.raises(ValueError, match=message):
        RodModel(RodParameters(**params), 4)


def test_kinked_rod_with_quaternions_is_refused_naming_its_corners():
    """A kinked rod is split into pieces joined rigidly, and joints need rotation-vector
    unknowns: quaternions asked for, or a rod that needs them (uniform variant), are a
    ValueError that says it is the polyline's corners, before any mesh."""
    params = RodParameters(length=2.0, reference_shape=Polyline(((0, 0, 0), (0, 0, 1), (1, 0, 1))))
    for how in (dict(rotations="quaternion"), dict(variant="uniform")):
        with pytest.raises(ValueError, match=r"a stress-free polyline with corners \(split "
                                             r"there into pieces joined rigidly"):
            RodModel(params, 5, **how)


def test_bent_frame_scene_is_the_frame_scene(tmp_path):
    """scenes/bent_frame.toml (one rod, a corner in its stress-free polyline) against
    scenes/frame.toml (two rods welded), the same steel frame and load, 16 + 12 cells:
    the tips after the load ramp agree to 1e-9 of the 1.3 m deflection (measured 4.7
    mm before the split at the corner; now the same equations: to round-off).
    `dolfin-rod check` says how the rod is split (28 cells: 16 + 12, the corner at a
    node; 27: 15 + 12, between nodes).  A polyline of the wrong length: exit 2 naming
    geometry.reference_shape.points."""
    from dolfin_rod import run
    quiet = {"outputs.animation": False, "outputs.plots": False, "outputs.fields": False}
    bent = run(ROOT / "scenes" / "bent_frame.toml", quiet, out=tmp_path / "bent", quiet=True)
    frame = run(ROOT / "scenes" / "frame.toml", quiet, out=tmp_path / "frame", quiet=True)
    one = np.array([bent.series[f"tip_position_{c}"][-1] for c in "xyz"])
    two = np.array([frame.series[f"beam.tip_position_{c}"][-1] for c in "xyz"])
    deflection = np.linalg.norm(two - [1.5, 0.0, 2.0])
    assert deflection > 1.0
    assert np.linalg.norm(one - two) < 1e-9 * deflection
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for cells, pieces in ((28, "16, 12 cells"), (27, "15, 12 cells")):   # by hand: 27 * 2/3.5
        said = subprocess.run([sys.executable, "-m", "dolfin_rod", "check",   # = 15.4, 11.6
                               str(ROOT / "scenes" / "bent_frame.toml"), "--set",
                               f"geometry.n_cells={cells}"], capture_output=True, text=True,
                              timeout=120, cwd=ROOT, env=env)
        assert f"kinks: the rod is split at its corners (s = 2) into 2 straight pieces joined " \
            f"rigidly, of {pieces}" in said.stdout, said.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text((ROOT / "scenes" / "bent_frame.toml").read_text().replace(
        "[1.5, 0.0, 2.0]", "[1.2, 0.0, 2.0]"))
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(bad)],
                         capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
    assert out.returncode == 2, out.stderr
    assert "[geometry.reference_shape.points]" in out.stderr and "Traceback" not in out.stderr


def kinked_arm_system(split: bool, comm=None) -> dict:
    """A system with a kinked rod: the arm, an L (column 1 along e_3 clamped at the
    origin, beam 0.8 along e_1) as ONE rod of 10 cells whose corner falls between nodes
    (split into 6 + 4 cells), and a hanger (0.5 along -e_3, 5 cells) welded to the arm's
    tip by a rigid joint, a dead force (0.3, 0, -1) at its tip; or (``split`` False) the
    arm given as its two pieces, column and beam, welded by a rigid joint.  Diagnostics
    after the load in 2 steps (hyperelastic, quasi-static)."""
    from mpi4py import MPI

    from dolfin_rod import Rod, RodSystem, loads
    from dolfin_rod.rod.joints import Joint
    comm = comm or MPI.COMM_WORLD
    stiff = dict(A=(2.0, 2.0, 1.5), B=(500.0, 500.0, 1e3))
    tip, top = (0.8, 0.0, 1.0), (0.0, 0.0, 1.0)
    hanger = Rod(RodParameters(length=0.5, **stiff), 5, "free", end="free", name="hanger",
                 position=tip, orientation=(0.0, np.pi, 0.0), end_loads=[
                     EndLoad("force", (0.3, 0.0, -1.0), loads.ramp(1.0, 1.0))])
    hang = Joint("rigid", ("arm", "hanger"), tip, name="arm-hanger")
    if split:
        arm = Rod(RodParameters(length=1.8, **stiff, reference_shape=Polyline(
            ((0.0, 0.0, 0.0), top, tip))), 10, name="arm")
        model = RodSystem([arm, hanger], joints=[replace(hang, name="")],
                          model="hyperelastic", comm=comm)
    else:
        column = Rod(RodParameters(length=1.0, **stiff), 6, name="arm")
        beam = Rod(RodParameters(length=0.8, **stiff), 4, "free", end="free", name="beam",
                   position=top, orientation=(0.0, np.pi / 2, 0.0))
        model = RodSystem([column, beam, hanger], joints=[
            Joint("rigid", ("arm", "beam"), top, name="arm-corner1"),
            replace(hang, rods=("beam", "hanger"))], model="hyperelastic", comm=comm)
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, 1.0, 0.5)
    d = model.diagnostics(1.0)
    for key in [k for k in d if k.startswith("beam.")]:    # the arm's: tip of its last
        own = "arm." + key.removeprefix("beam.")           # piece, energies of both
        d[own] = d[own] + d[key] if "energy" in key else d[key]
        del d[key]
    return d


def test_kinked_rod_in_a_system_is_split():
    """A rod of a system (rod/system.RodSystem) with a corner between nodes is split
    there as a single rod is (kinks.attach: the joint naming it at its tip attaches
    to the piece after the corner, its label kept): the system equals the one with the
    arm given as its two pieces and a rigid joint, to round-off (measured: equal to the
    last digit), every column: the arm's tip (of its last piece) and clamp reactions,
    the hanger's tip, the tip joint's and the corner's reactions; its own free energy
    is the sum over its pieces."""
    one, two = kinked_arm_system(True), kinked_arm_system(False)
    moved = np.linalg.norm([one[f"hanger.tip_position_{c}"] - (0.8, 0.0, 0.5)[i]
                            for i, c in enumerate("xyz")])
    assert moved > 1e-2
    assert set(one) == set(two) and {"joint_arm-corner1_force_z", "arm.free_energy",
                                     "joint_arm-hanger_couple_x"} <= set(one)
    for key, value in one.items():     # vectors: to 1e-11 of the largest component
        scale = (max(abs(v) for k, v in one.items() if k[:-2] == key[:-2])
                 if key[-2:] in ("_x", "_y", "_z") else abs(value))
        assert abs(value - two[key]) <= 1e-11 * scale + 1e-300, (key, value, two[key])


ARM_SCENE = """[time]
t_end = 1.0
dt = 0.5
[material]
model = "hyperelastic"
stiffness = { A = [2.0, 2.0, 1.5], B = [500.0, 500.0, 1000.0] }
[boundary]
end = "free"
[[rods]]
name = "arm"
geometry = { length = 1.8, n_cells = 10, reference_shape = { type = "polyline", points = [[0, 0, 0], [0, 0, 1], [0.8, 0, 1]] } }
[[rods]]
name = "hanger"
position = [0.8, 0.0, 1.0]
orientation = [0.0, 3.141592653589793, 0.0]
geometry = { length = 0.5, n_cells = 5 }
boundary = { start = "free" }
loads = { end_force = { type = "ramp", value = [0.3, 0.0, -1.0], duration = 1.0 } }
[[joints]]
kind = "rigid"
rods = ["arm", "hanger"]
point = [0.8, 0.0, 1.0]
"""


def test_kinked_rod_in_a_system_scene(tmp_path):
    """The system of ``kinked_arm_system`` as a scene ([[rods]], the arm's stress-free
    shape a polyline): `dolfin-rod check` says the arm is split (6 + 4 cells) and places
    the joint on its piece; the run's time series has the arm's tip and the corner's
    reactions, equal to the API's system to round-off (the same model)."""
    from dolfin_rod import run
    path = tmp_path / "arm.toml"
    path.write_text(ARM_SCENE)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    said = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(path)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
    assert said.returncode == 0, said.stderr
    assert "kinks: rod 'arm' is split at its corners (s = 1) into 2 straight pieces joined " \
        "rigidly, of 6, 4 cells" in said.stdout, said.stdout
    quiet = {"outputs.animation": False, "outputs.plots": False, "outputs.fields": False}
    series = run(path, quiet, out=tmp_path / "run", quiet=True).series
    api = kinked_arm_system(True)
    for key in ("arm.tip_position_x", "hanger.tip_position_z", "arm.reaction_couple_start_y",
                "joint_arm-corner1_force_z", "joint_arm-corner1_couple_y"):
        assert series[key][-1] == pytest.approx(api[key], rel=1e-12, abs=1e-14), key


# bent_frame 1e4 times softer (its 1 % stretch: forces of 120 N, whose round-off stays
# below assert_serial_run_equal's absolute 1e-10), at 25 cells, started stretched
STRETCHED_BENT_FRAME = (ROOT / "scenes" / "bent_frame.toml").read_text().replace(
    "A = [4.0e4, 4.0e4, 2.4e4], B = [2.05e7, 2.05e7, 1.2e8]",
    "A = [4.0, 4.0, 2.4], B = [2.05e3, 2.05e3, 1.2e4]").replace(
    "[0.0, 0.0, -1.0e4]", "[0.0, 0.0, -1.0]").replace(
    "n_cells = 28", "n_cells = 25").replace("[time]", """[initial]
shape = { type = "polyline", points = [[0.0, 0.0, 0.0], [0.0, 0.0, 2.02], [1.515, 0.0, 2.02]], rest_arc_length = [0.0, 2.0, 3.5] }

[time]""")


@pytest.mark.mpi
@pytest.mark.parametrize("scene", [ARM_SCENE, STRETCHED_BENT_FRAME], ids=["arm", "stretched"])
def test_kinked_rod_in_a_system_serial_equals_two_ranks(tmp_path, scene):
    """The scene of ``test_kinked_rod_in_a_system_scene``, and bent_frame.toml at 25
    cells (14 + 11: the corner between nodes) started on its L stretched by 1 %, on the
    ranks of the run and serially (a separate process): the same time series, the
    corner's reactions too, to 1e-10 (quick_scenes.assert_serial_run_equal)."""
    from mpi4py import MPI
    from quick_scenes import assert_serial_run_equal, quick_scene

    from dolfin_rod import run_scene
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path), root=0))
    path = folder / "arm.toml"
    if comm.rank == 0:
        path.write_text(scene)
    comm.barrier()
    quiet = dict(outputs__animation=False, outputs__plots=False, outputs__fields=False)
    summary = run_scene(quick_scene(path, 2, **quiet), folder / "run", quiet=True)
    assert summary["status"] == "completed"
    if comm.size > 1 and comm.rank == 0:
        assert_serial_run_equal(path, folder, 2, **quiet)


def test_placed_kinked_rod_of_a_system_starts_placed():
    """A kinked rod of a system, itself placed (position P, orientation Q0) and started
    moved by a StartingState (p, Q in its own frame): its pieces start where the rod
    does (kinks.system_starts, the pieces' poses in the rod's own frame), so the corner
    joints hold at t = 0 (check_joints_at_start passes) and the tip is
    P + Q0 (p + Q (0.8, 0, 1)) to 1e-12."""
    from dolfin_rod import Rod, RodSystem
    from dolfin_rod.theory.quaternions import (np_quaternion_from_rotation_vector,
                                               np_rotation_matrix)
    P, theta0 = np.array([1.0, 2.0, 0.0]), np.array([0.3, 0.0, 0.2])
    p, theta = np.array([0.1, -0.2, 0.3]), np.array([0.0, 0.5, -0.4])
    stiff = dict(A=(2.0, 2.0, 1.5), B=(500.0, 500.0, 1e3))
    arm = Rod(RodParameters(length=1.8, **stiff, reference_shape=Polyline(
        ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.8, 0.0, 1.0)))), 10, name="arm",
        position=tuple(P), orientation=tuple(theta0))
    other = Rod(RodParameters(length=1.0, **stiff), 4, name="other", position=(5.0, 0.0, 0.0))
    model = RodSystem([arm, other], model="hyperelastic")
    model.set_initial_state(start={"arm": StartingState(position=tuple(p),
                                                        orientation=tuple(theta))})
    d = model.diagnostics(0.0)
    turn = [np_rotation_matrix(np_quaternion_from_rotation_vector(v)) for v in (theta0, theta)]
    expected = P + turn[0] @ (p + turn[1] @ np.array([0.8, 0.0, 1.0]))
    assert np.array([d[f"arm.tip_position_{c}"] for c in "xyz"]) == pytest.approx(
        expected, abs=1e-12)


def _start(shape: str) -> tuple[str, str]:
    return "[time]", f"[initial]\nshape = {shape}\n\n[time]"


@pytest.mark.parametrize("change, key, message", [
    (_start('{ type = "polyline", points = [[0.0, 0.0, 0.0], [0.0, 0.0, 2.02], '
            '[1.515, 0.0, 2.02]], rest_arc_length = [0.0, 2.0, 3.5] }'), None, None),
    (_start('{ type = "arc", radius = 2.0 }'), "initial.shape",
     "starts on a polyline with the same corners, not on a smooth arc"),
    (_start('{ type = "polyline", points = [[0.0, 0.0, 0.0], [0.0, 0.0, 2.0], '
            '[1.2, 0.0, 2.9]] }'), "initial.shape",
     "the starting polyline does not keep the rod's rigid corners"),
    (("n_cells = 28", 'n_cells = 28\nrotations = "quaternion"'), "geometry.reference_shape",
     "a polyline with corners is split there into pieces joined rigidly, which needs "
     "rotation-vector unknowns")])
def test_kinked_scene_is_checked(tmp_path, change, key, message):
    """bent_frame.toml started on a curve, or with quaternions: `dolfin-rod check`
    accepts its L stretched by 1 %, and refuses (exit 2, naming the key, before any
    model) an arc, an L whose corner has another angle, and quaternion unknowns (its
    rigid corners are joints)."""
    path = tmp_path / "start.toml"
    path.write_text((ROOT / "scenes" / "bent_frame.toml").read_text().replace(*change))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(path), "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, timeout=120,
                         cwd=ROOT, env=env)
    if message is None:
        assert out.returncode == 0, out.stderr
    else:
        assert out.returncode == 2 and f"[{key}]: " in out.stderr \
            and message in out.stderr and "Traceback" not in out.stderr, out.stderr
