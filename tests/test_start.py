"""Starting states of the 3-D rod (issue 25 item 2, rod/start.py): a starting curve is
frame 0 to round-off, a pre-stretched start under its matching end load does not move,
initial velocities against a rigid rotation's kinetic energy, a start settled in static
equilibrium against the axial closed form, bad input naming the key."""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod import (Arc, Helix, Polyline, RodModel, RodParameters, StartingState,
                        Straight, TimeStepper)
from dolfin_rod.rod import EndLoad
from dolfin_rod.theory.rotations import np_quaternion_from_rotation_vector, np_rotation_matrix
from test_settle_contact import SLOPE
from test_starting_accelerations import FALLING

EA, RHO_A, I11, I22 = 50.0, 2.0, 0.03, 0.02
PLACE = {"position": (0.4, -1.0, 2.5), "orientation": (0.3, -0.7, 1.1)}


def dynamic_rod(rotations="auto", length=2.0, ends=("free", "free"), end_loads=(), n=8):
    params = RodParameters(length=length, A=(0.8, 1.2, 0.6), B=(40.0, 30.0, EA),
                           density=RHO_A, section_inertia=(I11, I22))
    return RodModel(params, n_cells=n, model="hyperelastic", rotations=rotations,
                    start=ends[0], end=ends[1], end_loads=end_loads)


def nodes(model):
    """(s, r, R) at the nodes owned or ghosted here: rest arc length, centre line and
    rotation matrices."""
    x = model.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    r = x.x.array.reshape(-1, 3) + np.outer(s, [0, 0, 1.0])
    chart = model.unknowns.chart
    q = (chart.q_n if chart is not None else model.f["quaternion"]).x.array.reshape(-1, 4)
    return s, r, np.array([np_rotation_matrix(qi) for qi in q])


def largest_change(model, x0) -> float:
    """max |x - x0| over the displacement dofs of all ranks."""
    from mpi4py import MPI
    local = np.max(np.abs(model.f["displacement"].x.array - x0), initial=0.0)
    return model.mesh.comm.allreduce(local, op=MPI.MAX)


def placement():
    Q = np_rotation_matrix(np_quaternion_from_rotation_vector(np.array(PLACE["orientation"])))
    return np.array(PLACE["position"]), Q


def helix_closed_form(s, a, pitch):
    """A helix of radius a, pitch 2 pi c about e_z, by arc length, carried to the start's
    frame (start at 0, tangent e3, principal normal e1): points and (d1, d2, d3)."""
    c = pitch / (2 * np.pi)
    k = np.hypot(a, c)

    def along(phi):
        gamma = np.stack([a * np.cos(phi), a * np.sin(phi), c * phi], axis=-1)
        T = np.stack([-a * np.sin(phi), a * np.cos(phi), c + 0 * phi], axis=-1) / k
        N = np.stack([-np.cos(phi), -np.sin(phi), 0 * phi], axis=-1)
        return gamma, T, N

    gamma, T, N = along(s / k)
    gamma0, T0, N0 = along(0.0)
    start = np.stack([N0, np.cross(T0, N0), T0])             # rows: the start's frame
    frame = np.stack([N, np.cross(T, N), T], axis=-1)        # columns d1, d2, d3
    return (gamma - gamma0) @ start.T, start @ frame


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_helix_start_is_frame_0(rotations):
    """A helix start placed anywhere: the nodes and directors of frame 0 are the closed
    form (an independent parametrisation about the helix axis) to round-off."""
    a, pitch = 0.3, 0.5
    model = dynamic_rod(rotations)
    model.set_initial_state(start=StartingState(shape=Helix(a, pitch), **PLACE))
    s, r, R = nodes(model)
    p, Q = placement()
    r_ref, frames = helix_closed_form(s, a, pitch)
    # round-off of O(1) numbers through a few products: 1e-14
    assert np.max(np.abs(r - (p + r_ref @ Q.T))) < 1e-14 * 4
    assert np.max(np.abs(R - Q @ frames)) < 1e-14 * 4
    assert model.diagnostics(0.0)["kinetic_energy"] == 0.0


def test_arc_and_polyline_starts():
    """An arc: nodes on the circle of its radius, s/radius apart in angle; a polyline
    without rest lengths through the arc's own nodes gives the same nodes, and its
    directors are the mean chord directions (d3) to round-off."""
    radius, L, n = 0.7, 2.0, 8
    model = dynamic_rod(length=L, n=n)
    model.set_initial_state(start=StartingState(shape=Arc(radius)))
    s, r, R = nodes(model)
    angle = s / radius    # bends towards d1 = e1 in the (e1, e3) plane
    circle = np.stack([radius * (1 - np.cos(angle)), 0 * s, radius * np.sin(angle)], axis=1)
    assert np.max(np.abs(r - circle)) < 1e-14 * 4
    order = np.argsort(s)
    chord = 2 * radius * np.sin(L / n / radius / 2)      # the arc's chords sum to L'
    points = circle[order] * (L / (n * chord))           # scaled: the polyline is L long
    line = dynamic_rod(length=L, n=n)
    line.set_initial_state(start=StartingState(shape=Polyline(tuple(map(tuple, points)))))
    s2, r2, R2 = nodes(line)
    assert np.max(np.abs(r2 - circle * L / (n * chord))) < 1e-14 * 4
    interior = (s2 > 0) & (s2 < L)
    # the polyline's nodal tangent of a circle's chords is the circle's tangent
    assert np.max(np.abs(R2[interior, :, 2] - R[interior, :, 2])) < 1e-14 * 4


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_prestretched_start_under_its_load_does_not_move(rotations):
    """A straight start stretched by lam, clamped at s = 0, under the end force
    EA (lam - 1) along it (n = B (v - v_ref) of the quadratic energy) is in equilibrium:
    its first steps do not move it (round-off), and the stored energy is
    EA (lam - 1)^2 L / 2.  With 0.9 of that force it moves (the test can fail)."""
    lam, L = 1.02, 2.0
    _, Q = placement()
    axis = Q[:, 2]

    def first_steps(force_factor):
        load = EndLoad("force", tuple(force_factor * EA * (lam - 1) * axis))
        model = dynamic_rod(rotations, L, ("clamped", "free"), [load])
        model.set_initial_state(start=StartingState(shape=Straight(lam), **PLACE))
        x0 = model.f["displacement"].x.array.copy()
        energy = model.diagnostics(0.0)["free_energy"]
        scheme = None if rotations == "rotation_vector" else "generalized_alpha"
        TimeStepper(model.problem, scheme).run(0.0, 0.02, 0.01)
        return largest_change(model, x0), energy

    still, energy = first_steps(1.0)
    assert energy == pytest.approx(0.5 * EA * (lam - 1) ** 2 * L, rel=1e-12)
    assert still < 1e-12 * L     # Newton's residual tolerance, not the physics
    moved, _ = first_steps(0.9)
    assert moved > 1e-5          # 10 % of the load off: it starts to contract


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_rigid_rotation_kinetic_energy(rotations):
    """Velocities v = w x (r - c), angular velocity w on a straight rod placed at p along
    Q e3: K = rho_A/2 int |w x (a + s t)|^2 ds + L/2 w . Q J Q^T w (a = p - c, t = Q e3,
    J = diag(I22, I11, I11 + I22)), exact for the nodal (P1) fields and the quadrature."""
    L = 2.0
    w, centre = np.array([0.4, -1.3, 0.9]), np.array([0.1, 0.2, -0.3])
    model = dynamic_rod(rotations, L)
    model.set_initial_state(start=StartingState(angular_velocity=tuple(w),
                                                rotation_centre=tuple(centre), **PLACE))
    p, Q = placement()
    a, t = np.cross(w, p - centre), np.cross(w, Q[:, 2])
    translational = 0.5 * RHO_A * (L * a @ a + L**2 * a @ t + L**3 / 3 * t @ t)
    rotational = 0.5 * L * w @ Q @ np.diag([I22, I11, I11 + I22]) @ Q.T @ w
    assert model.diagnostics(0.0)["kinetic_energy"] == pytest.approx(
        translational + rotational, rel=1e-13)


def test_velocity_field_callable_and_held_end():
    """A velocity field given as a callable of s: K = rho_A/2 int |v|^2 ds, exact for a
    field linear in s; a clamped end holds its node still (the support's rate)."""
    L = 2.0
    model = dynamic_rod(length=L, ends=("clamped", "free"))
    model.set_initial_state(start=StartingState(
        velocity=lambda s: np.outer(s, [0.0, 3.0, 0.0])))
    # v = 3 s e2 vanishes at s = 0 anyway: K = rho_A/2 int 9 s^2 ds = 3/2 rho_A L^3
    assert model.diagnostics(0.0)["kinetic_energy"] == pytest.approx(1.5 * RHO_A * L**3,
                                                                     rel=1e-13)
    shifted = dynamic_rod(length=L, ends=("clamped", "free"))
    shifted.set_initial_state(start=StartingState(velocity=(0.0, 3.0, 0.0)))
    # uniform 3 e2 but the clamped node at rest: the P1 field rises over the first cell
    h = L / 8
    exact = 0.5 * RHO_A * 9 * (L - h + h / 3)
    assert shifted.diagnostics(0.0)["kinetic_energy"] == pytest.approx(exact, rel=1e-13)


def test_equilibrium_start_matches_axial_closed_form():
    """A straight, unstretched start of a dynamic rod under an axial end force F,
    settled in equilibrium: the tip moves by F L / EA along the rod (the uniform stretch
    of the quadratic energy, exact for P1), and the first step does not move it."""
    L, F = 2.0, 1.5
    _, Q = placement()
    model = dynamic_rod("auto", L, ("clamped", "free"), [EndLoad("force", tuple(F * Q[:, 2]))])
    model.set_initial_state(start=StartingState(equilibrium=True, **PLACE))
    p, _ = placement()
    d = model.diagnostics(0.0)
    tip = np.array([d[f"tip_position_{c}"] for c in "xyz"])
    assert np.max(np.abs(tip - (p + (L + F * L / EA) * Q[:, 2]))) < 1e-12
    x0 = model.f["displacement"].x.array.copy()
    TimeStepper(model.problem).run(0.0, 0.01, 0.01)
    assert largest_change(model, x0) < 1e-12 * L


@pytest.mark.parametrize("start, key", [
    (StartingState(shape=Polyline(((0, 0, 0), (0, 0, 1.5)))), "start.shape.points"),
    (StartingState(shape=Polyline(((0, 0, 0), (0, 0, 1.0)), rest_arc_length=(0, 1.9))),
     "start.shape.rest_arc_length"),
    (StartingState(shape=Polyline(((0, 0, 0), (0, 0, 2.0)), normal=(0, 0, 1))),
     "start.shape.normal"),
    (StartingState(shape=Arc(-1.0)), "start.shape.radius"),
    (StartingState(shape=Straight(0.0)), "start.shape.stretch"),
    (StartingState(position=(0, 1)), "start.position"),
])
def test_bad_starting_state_names_the_parameter(start, key):
    model = dynamic_rod(length=2.0, n=2)
    with pytest.raises(ValueError, match=key.replace(".", r"\.")):
        model.set_initial_state(start=start)


def test_quasi_static_rod_refuses_velocities():
    params = RodParameters(length=1.0)
    model = RodModel(params, n_cells=2, model="hyperelastic")
    with pytest.raises(ValueError, match=r"start\.velocity"):
        model.set_initial_state(start=StartingState(velocity=(1.0, 0, 0)))


# -- scenes: [initial] position, orientation, shape, velocities, equilibrium ---------------

SCENE = """
[geometry]
length = 2.0
n_cells = 8
[material]
model = "hyperelastic"
stiffness = { A = [0.8, 1.2, 0.6], B = [40.0, 30.0, 50.0] }
density = 2.0
section_inertia = [0.03, 0.02]
[boundary]
start = "free"
[time]
t_end = 0.01
dt = 0.01
[outputs]
animation = false
plots = false
"""


@pytest.mark.mpi
def test_helix_scene_frame_0_is_the_curve(tmp_path):
    """initial.shape = helix, position, orientation: frame 0 of rod.bp (the deformed
    centre line a user opens in ParaView) is the closed-form helix to round-off, and
    the rigid spin's kinetic energy is in the time series' first row."""
    from mpi4py import MPI

    from dolfin_rod import parse_scene, run_scene
    from dolfin_rod.output.vtx import read_vtx
    text = SCENE + (
        "[initial]\nshape = { type = \"helix\", radius = 0.3, pitch = 0.5 }\n"
        f"position = {list(PLACE['position'])}\norientation = {list(PLACE['orientation'])}\n")
    folder = MPI.COMM_WORLD.bcast(str(tmp_path / "run"))
    summary = run_scene(parse_scene(text, "helix.toml"), folder, quiet=True)
    assert summary["status"] == "completed", summary["message"]
    if MPI.COMM_WORLD.rank:
        return
    frame = read_vtx(tmp_path / "run" / "rod.bp")[0]
    s = np.linspace(0.0, 2.0, 9)
    p, Q = placement()
    r_ref, _ = helix_closed_form(s, 0.3, 0.5)
    assert frame["time"] == 0.0
    assert np.max(np.abs(frame["points"] - (p + r_ref @ Q.T))) < 1e-14 * 4


BAD_STARTS = [
    ('shape = { type = "polyline", points = [[0, 0, 0], [0, 0, 1.5]] }',
     "initial.shape.points", "differs from the rod's length"),
    ('shape = { type = "polyline", points = [[0, 0, 0], [0, 0, 1]], rest_arc_length = [0, 1] }',
     "initial.shape.rest_arc_length", "differs from the rod's length"),
    # folding back (by pi): parallel transport divided by 1 + cos(turn) = 0, the run
    # failed at t = 0 with NaN after building the model (the trial of 1205d)
    ('shape = { type = "polyline", points = [[0, 0, 0], [0, 0, 1], [0, 0, 0]] }',
     "initial.shape.points", "turns back on itself at point 1 (0, 0, 1: by 180 degrees"),
    ('shape = { type = "arc" }', "initial.shape.radius", "missing"),
    ('shape = { type = "spiral" }', "initial.shape.type", "one of"),
    ('shape = { type = "helix", radius = 0.1, pitch = 0.2, turns = 3 }', "initial.shape.turns",
     "unknown key"),
    ("rotation_centre = [0, 0, 0]", "initial.rotation_centre", "angular_velocity"),
]


@pytest.mark.parametrize("line, key, reason", BAD_STARTS)
def test_bad_start_in_a_scene_is_one_clear_error(line, key, reason):
    from dolfin_rod import SceneError, parse_scene
    with pytest.raises(SceneError) as info:
        parse_scene(SCENE + "[initial]\n" + line + "\n", "bad.toml")
    assert info.value.key == key and reason in info.value.reason, str(info.value)


def test_quasi_static_scene_refuses_initial_velocity():
    from dolfin_rod import SceneError, parse_scene
    text = SCENE.replace("density = 2.0\nsection_inertia = [0.03, 0.02]\n", "").replace(
        'start = "free"', 'start = "clamped"') + "[initial]\nvelocity = [1.0, 0.0, 0.0]\n"
    with pytest.raises(SceneError) as info:
        parse_scene(text, "bad.toml")
    assert info.value.key == "initial.velocity"


def test_cli_starting_curve_of_wrong_length_exits_2(tmp_path):
    """The command line: exit status 2, one line naming the file and the key."""
    from test_cli import cli
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE + '[initial]\nshape = { type = "polyline", points = [[0, 0, 0], '
                   '[0, 0, 1.5]] }\n')
    out = cli("check", bad)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.startswith(f"error: {bad}: [initial.shape.points]: the polyline's "
                                 "length 1.5 differs from the rod's length 2"), out.stderr


DROOPING = """
[geometry]
length = 1.0
n_cells = 8
[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 1.0], B = [1e4, 1e4, 1e4] }
density = 1.0
section_inertia = 0.001
[boundary]
start = "clamped"
end = "free"
[loads]
gravity = [-60.0, 0.0, 0.0]
[initial]
equilibrium = true
[time]
t_end = 0.01
dt = 0.01
"""


QUASI_STATIC_DROOP = (DROOPING.replace("density = 1.0\nsection_inertia = 0.001\n", "")
                      .replace("gravity = [-60.0, 0.0, 0.0]",
                               "distributed_force = { value = [-60.0, 0.0, 0.0] }")
                      .replace("[initial]\nequilibrium = true\n", ""))


@pytest.mark.parametrize("ranks", [0, 2])
def test_heavy_cantilever_scene_settles_as_its_quasi_static_twin(tmp_path, ranks):
    """A cantilever settled under its weight q L^3 / EI = 60 (its tip turns by 88
    degrees): Newton from the straight start does not converge.  That was refused (exit
    2, [initial.equilibrium]); now the settle's pseudo-time finds it (rod/initial_state.py),
    and the quasi-static rod under the same load constant in time (all of it on the
    start, where one Newton solve fails too) reaches it on the start's load path
    (integrators/lie_alpha.py): both runs complete and end at the same tip (two paths to
    the same static equations: measured 2.6e-13 m, asserted 1e-10 m, Newton's tolerance;
    tests/test_settle.py checks the state against the Reissner rod); the same under
    mpirun -n 2 (``ranks``)."""
    import json

    from test_cli import cli
    tips = []
    for name, text in (("droop", DROOPING), ("twin", QUASI_STATIC_DROOP)):
        scene, out = tmp_path / f"{name}.toml", tmp_path / name
        scene.write_text(text)
        result = cli("run", scene, "--out", out, mpi=ranks)
        assert result.returncode == 0, result.stderr
        final = json.loads((out / "summary.json").read_text())["final"]
        tips.append(np.array([final[f"tip_position_{c}"] for c in "xyz"]))
    assert tips[0][0] < -0.9                # it droops
    assert np.max(np.abs(tips[0] - tips[1])) < 1e-10


def test_polyline_rotations_keep_one_sign_near_a_half_turn():
    """A polyline along e1 with d1 = e3 (a rotation by ~pi from the reference frame, q0 ~ 0:
    cosseratbench's twist rods) with a small bend: the nodal quaternions keep one sign
    along the rod (their P1 interpolant would pass through 0 between q and -q), so the
    first steps run and the rod, held at rest, stays put to round-off."""
    s = np.linspace(0.0, 1.0, 201)
    bump = 1e-4 * (1 - np.cos(2 * np.pi * s)) / 2
    points = np.stack([s, bump, 0 * s], axis=1)
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    line = Polyline(tuple(map(tuple, points)), normal=(0.0, 0.0, 1.0))
    _, q = line.frames(np.linspace(0.0, length, 9), length, 8)
    assert np.all(np.einsum("ij,ij->i", q[:-1], q[1:]) > 0.99)
    assert abs(q[0, 0]) < 1e-3          # a half turn: the case that flipped signs
    model = dynamic_rod(length=length, ends=("clamped", "clamped"))
    model.set_initial_state(start=StartingState(shape=line))
    x0 = model.f["displacement"].x.array.copy()
    TimeStepper(model.problem).run(0.0, 0.02, 0.01)
    # a bent start of a straight rod between clamps is not in equilibrium: it moves,
    # by less than the bump
    assert 0 < largest_change(model, x0) < 1e-4


# Euler's column, clamped-free, EI = 1, L = 1: P_cr = pi^2 EI / (4 L^2) (the drooping
# cantilever's rod under an end force along it)
EULER_COLUMN = DROOPING.replace(
    "gravity = [-60.0, 0.0, 0.0]", 'end_force = { type = "constant", value = [0.0, 0.0, '
    '-LOAD] }') + "[outputs]\nplots = false\nanimation = false\n"


@pytest.mark.parametrize("ranks", [0, 2])
@pytest.mark.parametrize("factor", [0.5, 1.5])
def test_unstable_equilibrium_start_is_said(tmp_path, ranks, factor):
    """A dynamic column settled straight (initial.equilibrium) under 1.5 Euler loads is
    an unstable equilibrium whose perfect run stays straight to round-off: the run said
    nothing ("completed", no warning).  Now a warning, kept in summary.json, with the
    count of negative eigenvalues: 2 (the first mode in each bending plane of the round
    section; the second is at 9 P_cr); at 0.5 P_cr none.  Serial and mpirun -n 2."""
    import json
    from test_cli import cli
    load = factor * np.pi ** 2 / 4
    scene, out = tmp_path / "column.toml", tmp_path / "out"
    scene.write_text(EULER_COLUMN.replace("LOAD", repr(load)))
    result = cli("run", scene, "--out", out, "--quiet", mpi=ranks)
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / "summary.json").read_text())
    unstable = [w for w in summary["warnings"] if w.startswith("initial.equilibrium")]
    if factor < 1:
        assert unstable == []
    else:
        assert len(unstable) == 1 and "(2 negative eigenvalues of the tangent" in unstable[0]


def test_unstable_equilibrium_start_with_contact_is_said_once(tmp_path):
    """scenes/supercoiled_minicircle.toml clamped at its weld and settled planar
    (initial.equilibrium): twisted by Delta Lk = 2 turns, past Michell's sqrt(3) A/C =
    0.87, the planar ring is unstable.  A scene with contact started twice (the first
    start looked for overlaps while the scene was built): the terminal said the warning
    twice (summary.json once); now once (the scene starts once:
    test_a_scene_with_contact_starts_and_settles_once)."""
    import json
    from test_cli import cli
    from quick_scenes import ROOT
    text = (ROOT / "scenes" / "supercoiled_minicircle.toml").read_text()
    scene, out = tmp_path / "minicircle.toml", tmp_path / "out"
    scene.write_text(text.replace('start = "free"', 'start = "clamped"')
                     .replace("n_cells = 48", "n_cells = 24")
                     .replace("t_end = 3.0", "t_end = 0.005")
                     .replace("[boundary]", "[initial]\nequilibrium = true\n[boundary]"))
    result = cli("run", scene, "--out", out)
    assert result.returncode == 0, result.stderr
    said = (result.stdout + result.stderr).count("warning: initial.equilibrium: the settled")
    assert said == 1, result.stdout + result.stderr
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    unstable = [w for w in warnings if w.startswith("initial.equilibrium")]
    assert len(unstable) == 1 and "negative eigenvalues of the tangent" in unstable[0], warnings


@pytest.mark.parametrize("curvature, warned", [([0.0, 1.0, 0.0], False),
                                               ([1.0, 0.0, 0.0], True),
                                               ([0.0, -1.0, 0.0], True)])
def test_a_ring_whose_stress_free_circle_is_not_its_start_is_warned_of(
        tmp_path, curvature, warned):
    """scenes/pinched_ring.toml (R = 1) is stress-free with reference_curvature [0, 1,
    0], the circle it starts as (bending towards d1: about d2).  Given [1, 0, 0] (about
    d1) its stress-free ring is the start turned a quarter turn about the tangents and
    its quasi-static start diverged (DIVERGED_DTOL) with no hint (found by published);
    `check` and `run` now warn, naming geometry.reference_curvature, before any work;
    [0, -1, 0] (inside out) too."""
    from quick_scenes import ROOT
    from test_cli import cli
    text = (ROOT / "scenes" / "pinched_ring.toml").read_text()
    scene = tmp_path / "ring.toml"
    scene.write_text(text.replace("reference_curvature = [0.0, 1.0, 0.0]",
                                  f"reference_curvature = {curvature}"))
    out = cli("check", scene)
    assert out.returncode == 0, out.stderr
    said = f"warning: {scene}: [geometry.reference_curvature]: a closed rod starts as the " \
        "circle bending towards d1, its curvature 1 about d2"
    assert (said in out.stderr) == warned, out.stderr


# a free rod above a plane, its weight towards it, settled onto it (tests/test_settle_contact.py)
RESTING = SLOPE.replace("gravity = [-8.5, 0.0, -4.9]", "gravity = [-9.81, 0.0, 0.0]")


@pytest.mark.mpi
@pytest.mark.parametrize("given, settles", [("crossing_rods.toml", 0), (RESTING, 1)])
def test_a_scene_with_contact_starts_and_settles_once(given, settles, tmp_path, monkeypatch):
    """A scene with contact makes its start while it is built (a rod starting inside an
    obstacle or another rod is refused before the integrator is compiled); the run then
    made it again, and settled again where initial.equilibrium is set (found by a user
    trial).  Counted through the model's set_initial_state and rod/initial_state.settle
    over a whole run: scenes/crossing_rods.toml (two rods, contact between them) starts
    once, a free rod settled on a plane below it (initial.equilibrium) starts and
    settles once.  The run's numbers are the same as with the doubled start (bit for bit:
    docs/contact.md, "A start in contact")."""
    import dolfin_rod
    from dolfin_rod.rod import initial_state
    from dolfin_rod.scenes import parse_scene
    from quick_scenes import ROOT, quick_scene
    calls = {"start": 0, "settle": 0}

    def counted(name, function):
        def count(*args, **kwargs):
            calls[name] += 1
            return function(*args, **kwargs)
        return count

    monkeypatch.setattr(RodModel, "set_initial_state",
                        counted("start", RodModel.set_initial_state))
    monkeypatch.setattr(initial_state, "settle", counted("settle", initial_state.settle))
    scene = quick_scene(ROOT / "scenes" / given, steps=1, outputs__fields=False,
                        outputs__animation=False, outputs__plots=False) if given.endswith(".toml") \
        else parse_scene(given)
    from mpi4py import MPI
    out = MPI.COMM_WORLD.bcast(str(tmp_path / "out"), root=0)
    result = dolfin_rod.run(scene, out=out, quiet=True)
    assert result.status == "completed", result.summary
    assert calls == {"start": 1, "settle": settles}


# a quasi-static cantilever, unloaded, started as a polyline of four right-angle corners
ZIGZAG = (FALLING.replace("density = 1.0\nsection_inertia = 1e-5\n", "")
          .replace("n_cells = 4", "length = 1.25\nn_cells = 16")
          .replace('start = "free"', 'start = "clamped"')
          .replace("[loads]\ngravity = [-9.81, 0.0, 0.0]\n", "")
          + '[initial.shape]\ntype = "polyline"\npoints = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.25], '
            '[0.25, 0.0, 0.25], [0.25, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 0.0, 0.75]]\n')


@pytest.mark.mpi
@pytest.mark.parametrize("settled", [False, True])
def test_a_quasi_static_polyline_start_settles_first(tmp_path, settled):
    """A quasi-static cantilever, stress-free straight and unloaded, started as a polyline
    of four right-angle corners (as a knotted polyline: far from its equilibrium): the
    start's solve from that shape fails (DIVERGED_LINEAR_SOLVE), the message naming the
    remedy, initial.equilibrium = true, which a quasi-static rod was refused ("in
    equilibrium at every step"): with it the start settles in pseudo-time to the
    equilibrium, straight along the clamp's tangent e3, the tip at (0, 0, L).  Measured
    6.3e-11 m (the settle's residual over EI = 10); asserted 1e-9 m."""
    from mpi4py import MPI

    import dolfin_rod
    from dolfin_rod.scenes import parse_scene
    folder = MPI.COMM_WORLD.bcast(str(tmp_path / "run"), root=0)
    text = ZIGZAG + ("[initial]\nequilibrium = true\n" if settled else "")
    result = dolfin_rod.run(parse_scene(text), out=folder, quiet=True)
    if not settled:
        assert result.status == "failed"
        assert "settle the start first (initial.equilibrium = true" in result.summary["message"]
        return
    assert result.status == "completed", result.summary["message"]
    tip = [result.series[f"tip_position_{c}"][-1] for c in "xyz"]
    assert np.max(np.abs(np.array(tip) - (0.0, 0.0, 1.25))) < 1e-9
