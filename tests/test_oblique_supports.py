"""A clamped end that slides along, and turns about, an axis off the coordinate axes
(issue 25 item 3: one-node links, fem/multipoint.NodeLine), against closed forms
re-derived in each test's docstring."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from quick_scenes import ROOT, assert_serial_run_equal, quick_scene
from scipy.optimize import brentq

from dolfin_rod import TimeStepper, loads, run_scene
from dolfin_rod.fem.fe_model import NodeValues
from dolfin_rod.rod import EndLoad, Rod, RodModel, RodParameters, RodSystem
from dolfin_rod.theory.quaternions import CONJ, np_qmul

comm = MPI.COMM_WORLD
TIGHT = {"snes_rtol": 1e-11, "snes_atol": 1e-12}
AXIS = np.ones(3) / np.sqrt(3.0)          # the rod's tangent and the clamp's axis
E3 = np.array([0.0, 0.0, 1.0])
L, EA, GJ, W, C, N = 1.5, 30.0, 2.0, 0.9, 0.3, 4


def along_the_axis() -> np.ndarray:
    """The rotation vector that turns e_3 into AXIS (the rod's orientation)."""
    normal = np.cross(E3, AXIS)
    return normal / np.linalg.norm(normal) * np.arccos(AXIS @ E3)


def inclined_rod(dynamic: bool = False) -> RodSystem:
    """A straight rod along AXIS = (1, 1, 1)/sqrt 3 from the origin, clamped at its top
    s = L; its bottom s = 0 in a clamp that slides along AXIS and turns about it, loaded
    there by a weight W (-W e_z) and a couple C AXIS, both ramped over [0, 1]."""
    ramp = loads.ramp(1.0, 1.0)
    inertia = dict(density=0.5, section_inertia=1e-3, drag=5.0,
                   rotational_drag=(0.05, 0.05, 0.05)) if dynamic else {}
    rod = Rod(RodParameters(length=L, A=(1.0, 1.0, GJ), B=(20.0, 20.0, EA), **inertia),
              n_cells=N, start="clamped", end="clamped", orientation=tuple(along_the_axis()),
              end_slide={"start": tuple(AXIS)}, end_turn={"start": tuple(AXIS)},
              end_loads=[EndLoad("force", (0.0, 0.0, -W), ramp, end="start"),
                         EndLoad("couple", tuple(C * AXIS), ramp, end="start")])
    return RodSystem([rod], model="hyperelastic")


def bottom(model) -> tuple[np.ndarray, np.ndarray]:
    """(displacement, rotation quaternion) of the node s = 0 (stored rotation: theta = 0
    after a step), on every rank."""
    x = model.unknowns.f["displacement"]
    q_n = model.unknowns.chart.q_n
    return (NodeValues(x.function_space, [0.0])(x.x.array)[0],
            NodeValues(q_n.function_space, [0.0])(q_n.x.array)[0])


def run(model, t_end, dt, scheme=None, observe=None):
    model.set_initial_state()
    rows = []

    def observer(t, _):
        rows.append(model.diagnostics(t))
        if observe:
            observe(t)

    TimeStepper(model.problem, scheme, solver_options=TIGHT).run(0.0, t_end, dt, observer)
    return rows


def twist_angle() -> float:
    """The discrete rod's twist under the end couple C (closed_forms.p1_twist, as in
    test_supports): the end turns by 4 N x with C = GJ 4 tan(x)/(h cos^2 x)."""
    h = L / N
    return 4 * N * brentq(lambda x: GJ * 4 * np.tan(x) / h / np.cos(x) ** 2 - C, 0.0, 0.5)


@pytest.mark.mpi
def test_weight_on_an_inclined_sliding_turning_clamp():
    """Quasi-static.  The clamp takes every force across AXIS and every couple across it,
    so the rod carries only the weight's part along it, the tension N = W (e_z . AXIS) =
    W/sqrt 3, and the couple C about it: it stays straight along AXIS, stretched by
    N L/EA (the P1 bar is nodally exact) and twisted as at a free end (p1_twist).  So
    the bottom clamp sits at -(N L/EA) AXIS (it moves along AXIS only: its part across
    is round-off), turned about AXIS by the twist; the top clamp carries N AXIS and the
    couple -C AXIS; the bottom clamp carries the weight's part across AXIS, W e_z - N
    AXIS, and no couple.  Tolerance: Newton's (rtol 1e-11) on quantities ~1."""
    model = inclined_rod()
    assert model.rotations == "rotation_vector"
    d = run(model, 1.0, 0.5, scheme="backward_euler")[-1]
    tension = W * AXIS[2]
    x, q = bottom(model)
    assert np.allclose(x, -tension * L / EA * AXIS, rtol=0, atol=1e-12)
    assert np.linalg.norm(x - (x @ AXIS) * AXIS) < 1e-14       # only along the axis
    turn = np_qmul(q, model.stress_free([0.0])[1][0] * CONJ)     # spatial: q = turn q_sf
    assert np.linalg.norm(np.cross(turn[1:], AXIS)) < 1e-14        # about AXIS only
    assert 2 * np.arctan2(abs(turn[1:] @ AXIS), abs(turn[0])) == pytest.approx(
        twist_angle(), rel=1e-9)

    def vector(key):
        return np.array([d[f"rod.{key}_{c}"] for c in "xyz"])

    assert np.allclose(vector("reaction_force_end"), tension * AXIS, rtol=0, atol=1e-10)
    assert np.allclose(vector("reaction_force_start"), W * E3 - tension * AXIS, rtol=0,
                       atol=1e-10)
    assert np.allclose(vector("reaction_couple_end"), -C * AXIS, rtol=0, atol=1e-10)
    assert np.linalg.norm(vector("reaction_couple_start")) < 1e-10
    assert np.allclose(vector("tip_position"), L * AXIS, rtol=0, atol=1e-14)


@pytest.mark.mpi
def test_dynamic_rod_on_an_inclined_sliding_clamp_settles_and_stays_on_the_axis():
    """Dynamic, the same rod with mass, rotary inertia and damping (drag c = 5, rotational
    drag 0.05 per length), the loads ramped over 1 s: at every step the bottom clamp is
    on its axis (the part of its displacement across AXIS is round-off: the link holds
    it exactly, also through the start's accelerations), and by t = 4 the damped
    motion (axial decay exp(-c t/(2 rho A)) = exp(-5 t)) has settled to the static
    stretch -(N L/EA) AXIS (measured 4.2e-6 relative; the top clamp's force 6.3e-7)."""
    model = inclined_rod(dynamic=True)
    across = []
    rows = run(model, 4.0, 0.05, observe=lambda t: across.append(
        np.linalg.norm(bottom(model)[0] - (bottom(model)[0] @ AXIS) * AXIS)))
    assert max(across) < 1e-14
    stretch = W * AXIS[2] * L / EA
    assert bottom(model)[0] @ AXIS == pytest.approx(-stretch, rel=3e-5)      # 4.2e-6
    assert rows[-1]["rod.reaction_force_end_x"] == pytest.approx(W * AXIS[2] ** 2,
                                                                 rel=1e-5)  # 6.3e-7


@pytest.mark.parametrize("axis, match", [
    ((0.0, 0.0, 0.0), "must be a unit vector"),
    ((0.6, 0.6, 0.6), "must be a unit vector"),
])
def test_a_slide_axis_that_is_not_unit_is_refused_naming_it(axis, match):
    with pytest.raises(ValueError, match=r"end_slide\['end'\] " + match):
        RodModel(RodParameters(), n_cells=2, start="clamped", end="clamped",
                 end_slide={"end": axis})


def test_inclined_turns_need_rotation_vectors_and_slides_no_motion_across():
    """An oblique turn holds a quaternion in a plane (span(q_0, q_0 (0, a))), not on a
    line: refused with quaternion unknowns, naming it; an oblique slide's motion across
    its axis cannot be prescribed."""
    with pytest.raises(ValueError, match=r"end_turn\['end'\]: a turn about an axis off "
                                         "the coordinate axes needs rotation-vector unknowns"):
        RodModel(RodParameters(), n_cells=2, start="clamped", end="clamped",
                 rotations="quaternion", end_turn={"end": (0.6, 0.0, 0.8)})
    with pytest.raises(ValueError, match=r"end_displacement\['end'\]: the end slides"):
        RodModel(RodParameters(), n_cells=2, start="clamped", end="clamped",
                 end_slide={"end": (0.6, 0.0, 0.8)},
                 end_displacement={"end": lambda t: (0.0, t, 0.0)})


GUIDED = dict(L=1.2, EI=2.0, GJ=1.5, kGA=300.0, EA=900.0, W=1e-6, N=6)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["quaternion", "rotation_vector"])
def test_guided_end_on_an_inclined_slide_closed_form(rotations):
    """Quasi-static, small load: a rod along e_3 clamped at s = 0, its end s = L clamped
    on a slide along AXIS = (1, 1, 1)/sqrt 3 (its rotation held, its position free along
    AXIS only), a dead force F = -W e_3 there.  Linear: the end moves by delta AXIS with
    AXIS . K (delta AXIS) = AXIS . F (the slide's reaction is across AXIS), K =
    diag(1/c_t, 1/c_t, EA/L) the guided end's stiffness, c_t = L^3/(12 EI) (1 - 1/N^2)
    + L/(k GA) (the P1 rod's one-point rule: nodal rotations exact, the deflection the
    trapezoid of a quadratic rotation, -L h^2/(12 EI) per unit force; the cantilever's
    1 - 1/(4 N^2) of test_rod for its own moment): delta = -W sqrt 3/(2/c_t + EA/L).
    Quaternion unknowns hold the slide by the same one-node link as rotation vectors.
    Tolerance 1e-6 relative: the load's nonlinear terms ~ W (measured 2e-7), and the
    end's part across AXIS to round-off."""
    g = GUIDED
    model = RodModel(RodParameters(length=g["L"], A=(g["EI"], g["EI"], g["GJ"]),
                                   B=(g["kGA"], g["kGA"], g["EA"])), n_cells=g["N"],
                     model="hyperelastic", rotations=rotations, start="clamped",
                     end="clamped", end_slide={"end": tuple(AXIS)},
                     end_loads=[EndLoad("force", (0.0, 0.0, -g["W"]))])
    assert model.rotations == rotations
    d = run(model, 1.0, 1.0, scheme="backward_euler")[-1]
    c_t = g["L"] ** 3 / (12 * g["EI"]) * (1 - 1 / g["N"] ** 2) + g["L"] / g["kGA"]
    delta = -g["W"] * np.sqrt(3.0) / (2 / c_t + g["EA"] / g["L"])
    end = np.array([d[f"tip_position_{c}"] for c in "xyz"]) - g["L"] * E3
    assert end @ AXIS == pytest.approx(delta, rel=1e-6)
    # across: the round-off of positions ~ L (tip - L e_3 measured 1.6e-17)
    assert np.linalg.norm(end - (end @ AXIS) * AXIS) < 1e-15
    reaction = np.array([d[f"reaction_force_end_{c}"] for c in "xyz"])
    # the slide pushes across only: along AXIS the free dof's residual, below Newton's
    # atol 1e-12 (measured 8e-15 of a reaction ~4e-8)
    assert abs(reaction @ AXIS) < 1e-12


@pytest.mark.mpi
def test_quaternion_rod_slides_down_an_inclined_rail_at_g_sin_alpha():
    """Dynamic, quaternion unknowns: a rod along the rail a = (0.6, 0, -0.8) (down a
    slope of sin alpha = 0.8), its end s = 0 clamped on a slide along a, its other end
    free, under gravity -g e_3 from rest.  Along a only gravity acts (the slide's
    reaction and couple are across a; the internal forces cancel), so the rod's mean
    displacement along a, int rho A x.a ds/(rho A L), is g sin(alpha) t^2/2 whatever
    the rod's bending meanwhile: the consistent mass and load integrate the constant
    test function exactly, and Crank-Nicolson integrates a constant acceleration
    exactly.  Measured 3.3e-16 relative at t = 0.2 (dt 0.02); the end stays on the rail
    (its part across a 3e-17, asserted < 1e-14, at every step)."""
    import dolfinx.fem as fem
    import ufl
    from dolfin_rod import DistributedLoad
    a, g, rho_A, length = np.array([0.6, 0.0, -0.8]), 9.81, 2.0, 1.0
    normal = np.cross(E3, a)
    orientation = normal / np.linalg.norm(normal) * np.arccos(a @ E3)
    model = RodSystem([Rod(RodParameters(length=length, A=(5.0, 5.0, 4.0),
                                         B=(2e3, 2e3, 5e3), density=rho_A,
                                         section_inertia=1e-3),
                           n_cells=8, start="clamped", end="free",
                           orientation=tuple(orientation), end_slide={"start": tuple(a)},
                           distributed_loads=[DistributedLoad("force", (0.0, 0.0, -rho_A * g))])],
                      model="hyperelastic", rotations="quaternion")
    x = model.unknowns.f["displacement"]
    mean = fem.form(ufl.dot(x, ufl.as_vector(a)) / length * ufl.dx(domain=model.mesh))
    across, along, t_end = [], [], 0.2

    def on_rail(t):
        x0 = bottom_displacement(model)
        across.append(np.linalg.norm(x0 - (x0 @ a) * a))
        along.append(comm.allreduce(fem.assemble_scalar(mean), op=MPI.SUM))

    run(model, t_end, 0.02, scheme="crank_nicolson", observe=on_rail)
    assert along[-1] - along[0] == pytest.approx(0.5 * g * 0.8 * t_end ** 2, rel=1e-12)
    assert max(across) < 1e-14


def bottom_displacement(model) -> np.ndarray:
    """The displacement of the node s = 0, on every rank."""
    x = model.unknowns.f["displacement"]
    return NodeValues(x.function_space, [0.0])(x.x.array)[0]


def test_petsc_ts_refuses_an_inclined_slide():
    from dolfin_rod import TSIntegrator
    model = RodModel(RodParameters(density=1.0, section_inertia=0.01), n_cells=2,
                     rotations="quaternion", start="clamped", end="clamped",
                     end_slide={"end": tuple(AXIS)})
    with pytest.raises(ValueError, match="PETSc TS does not hold the one-node links"):
        TSIntegrator(model.problem)


INCLINED = ROOT / "scenes/inclined_clamp.toml"
QUIET = dict(outputs__animation=False, outputs__plots=False, outputs__fields=False)


@pytest.mark.mpi
def test_inclined_clamp_scene_serially_and_on_two_ranks(tmp_path):
    """scenes/inclined_clamp.toml (its 4 steps): the top clamp carries the weight's part
    along the rail, N a with N = W/sqrt 3 (each component W/3), the carriage the rest,
    W e_z - N a, and no couple (test_weight_on_an_inclined_sliding_turning_clamp's
    closed form; Newton's tolerance on ~0.3 N); 2 ranks give the serial time series to
    round-off."""
    folder = Path(comm.bcast(str(tmp_path), root=0))
    final = run_scene(quick_scene(INCLINED, 4, **QUIET), folder / "run", quiet=True)["final"]
    weight = 0.5
    for c in "xyz":
        assert final[f"rod.reaction_force_end_{c}"] == pytest.approx(weight / 3, rel=1e-8)
        assert final[f"rod.reaction_force_start_{c}"] == pytest.approx(
            (weight if c == "z" else 0.0) - weight / 3, rel=1e-8)
        assert abs(final[f"rod.reaction_couple_start_{c}"]) < 1e-10
    if comm.size > 1 and comm.rank == 0:
        assert_serial_run_equal(INCLINED, folder, 4, **QUIET)


@pytest.mark.parametrize("integrator, key, message", [
    ("stepper", "rods[0].boundary.start_turn", "needs rotation-vector unknowns"),
    ("ts", "rods[0].boundary.start_slide", "PETSc TS does not hold"),
])
def test_inclined_clamp_scene_on_quaternions_names_what_it_cannot(tmp_path, integrator, key,
                                                                  message):
    """scenes/inclined_clamp.toml with quaternion unknowns: its slide is allowed, its
    oblique turn refused naming the key; without the turn, with PETSc TS, the slide is
    refused naming it (exit 2, before any work)."""
    text = INCLINED.read_text().replace('n_cells = 8', 'n_cells = 8\nrotations = "quaternion"')
    if integrator == "ts":
        text = text.replace(", start_turn = [0.5773502691896258, 0.5773502691896258, "
                            "0.5773502691896258]", "").replace(
            "dt = 0.25", 'dt = 0.25\nintegrator = "ts"')
    scene = tmp_path / "quaternion.toml"
    scene.write_text(text)
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(scene)],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2, out.stdout + out.stderr
    assert key in out.stderr and message in out.stderr, out.stderr


@pytest.mark.parametrize("axis", [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
def test_inclined_clamp_scene_with_a_bad_axis_exits_2_naming_the_key(tmp_path, axis):
    text = INCLINED.read_text().replace(
        "start_slide = [0.5773502691896258, 0.5773502691896258, 0.5773502691896258]",
        f"start_slide = {axis}")
    scene = tmp_path / "bad.toml"
    scene.write_text(text)
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(scene)],
                         capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "rods[0].boundary.start_slide" in out.stderr and "unit vector" in out.stderr


def column(axis_of_rod: np.ndarray, dynamic: bool):
    """A rod along ``axis_of_rod`` from the origin, clamped at s = 0, its end s = L
    clamped on a slide along the rod's own axis (a coordinate axis: Dirichlet
    conditions; another: a one-node link); quasi-static: pushed along its axis by a
    force growing as t (buckling), dynamic: unloaded (vibration)."""
    normal = np.cross(E3, axis_of_rod)
    turn = (np.zeros(3) if not np.linalg.norm(normal) else
            normal / np.linalg.norm(normal) * np.arccos(axis_of_rod @ E3))
    inertia = dict(density=1.0, section_inertia=1e-3) if dynamic else {}
    load = [] if dynamic else [EndLoad("force", tuple(-axis_of_rod), lambda t: t)]
    return RodSystem([Rod(RodParameters(length=1.0, A=(1.0, 1.0, 0.8), B=(400.0, 400.0, 900.0),
                                        **inertia),
                          n_cells=12, start="clamped", end="clamped", orientation=tuple(turn),
                          end_slide={"end": tuple(axis_of_rod)}, end_loads=load)],
                     model="hyperelastic")


@pytest.mark.mpi
@pytest.mark.parametrize("analysis", ["vibration", "buckling"])
def test_modes_and_buckling_through_an_inclined_slide(analysis):
    """The analyses see an inclined slide through the constrained system (P^T K P,
    P^T M P): the column of ``column`` along AXIS, its slide a one-node link, has the
    frequencies (6) and buckling loads (2) of the same column along e_3, whose slide is
    held by Dirichlet conditions (a rigid rotation of the whole problem): measured 4e-15
    (frequencies) and 1e-9 (buckling loads: the load path's rate from Newton solves to
    rtol 1e-11); asserted 1e-8.  (The first buckling load, 37.82, is the
    clamped-clamped Euler load 4 pi^2 EI/L^2 = 39.48 lowered by shear and the 12 cells.)"""
    from dolfin_rod.analysis.buckling import buckling_modes
    from dolfin_rod.analysis.vibration import vibration_modes
    values = []
    for axis in (E3, AXIS):
        model = column(axis, analysis == "vibration")
        model.set_initial_state()
        if analysis == "vibration":
            modes = vibration_modes(model, 0.0, 6)
            values.append(modes.omega)
        else:
            TimeStepper(model.problem, solver_options=TIGHT).run(0.0, 1.0, 1.0)
            modes = buckling_modes(model, 1.0, count=2)
            values.append(modes.load_factors)
        assert max(modes.residuals) < 1e-8
    assert values[1] == pytest.approx(values[0], rel=1e-8)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_rod_on_an_inclined_slide_rests_on_an_inclined_floor(rotations):
    """Quasi-static contact through an inclined slide: a rod along the rail
    a = (0.6, 0, -0.8) clamped at s = 0 on a slide along a (its rotation held, its
    position free along a only), its free end resting on a floor tilted by 30 deg
    (a frictionless plane, outward normal n = (-1/2, 0, sqrt 3/2), the end starting
    0.1 delta inside the barrier's reach), under its weight q per length (-q e_3).
    Along a only the weight and the floor act (the slide's reaction is across a, the
    internal forces cancel), so the floor's force F n has F (n . a) = q L (e_3 . a):
    F = q L 0.8/(0.3 + 0.4 sqrt 3), whatever the barrier's gap and the rod's bending
    (a constant test function along a: exact in the discrete rod), with rotation vectors
    or quaternions.  Measured 8.4e-14 relative with rotation vectors (a level floor: q L
    to 1.4e-13), asserted 1e-10 (Newton's atol 1e-12 on residuals ~1); 3.7e-10 with
    quaternions, asserted 1e-9: their Newton stops on its step (snes_stol 1e-8) above
    that atol, which their residual's round-off floor does not reach (without stol: 25
    iterations, no convergence).  The slide's reaction along a: Newton's residual
    (measured 3e-13, 2.5e-13), asserted < 1e-10."""
    from dolfin_rod import DistributedLoad
    from dolfin_rod.rod import ContactLaw, Obstacle
    a, q, length, radius, gap = np.array([0.6, 0.0, -0.8]), 1.0, 1.0, 0.02, 0.01
    n = np.array([-0.5, 0.0, np.sqrt(3.0) / 2])
    normal = np.cross(E3, a)
    floor = Obstacle("plane", point=tuple(length * a - (radius + 0.1 * gap) * n), normal=tuple(n))
    model = RodSystem([Rod(RodParameters(length=length, A=(5.0, 5.0, 4.0), B=(2e3, 2e3, 5e3)),
                           n_cells=8, start="clamped", end="free",
                           orientation=tuple(normal / np.linalg.norm(normal) * np.arccos(a @ E3)),
                           end_slide={"start": tuple(a)},
                           distributed_loads=[DistributedLoad("force", (0.0, 0.0, -q))])],
                      model="hyperelastic", rotations=rotations, obstacles=[floor],
                      contact=ContactLaw(radius=radius, gap=gap, stiffness=1e3))
    assert model.rotations == rotations
    d = run(model, 1.0, 1.0)[-1]
    force = np.array([d[f"contact_force_{c}"] for c in "xyz"])
    F = q * length * 0.8 / (0.3 + 0.4 * np.sqrt(3.0))
    tol = 1e-10 if rotations == "rotation_vector" else 1e-9
    assert np.linalg.norm(force - F * n) < tol * F, (force, F * n)
    assert 0.0 < d["min_gap"] < gap                        # resting on the floor
    reaction = np.array([d[f"rod.reaction_force_start_{c}"] for c in "xyz"])
    assert abs(reaction @ a) < 1e-10
