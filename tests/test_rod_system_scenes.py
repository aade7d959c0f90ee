"""Scenes of several rods ([[rods]], [[joints]]; dolfin_rod/scenes/systems.py): the
example scenes build the systems the Python API builds, bad keys are named, and a
joint off the rods is refused by `dolfin-rod check` with exit 2 before any model."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dolfin_rod import EndLoad, Joint, Rod, RodParameters, RodSystem, TimeStepper, loads
from dolfin_rod.scenes import SceneError, build, load_scene, parse_scene

ROOT = Path(__file__).resolve().parents[1]
FRAME = (ROOT / "scenes" / "frame.toml").read_text()


def run_to_one(name: str, steps: int, t_end: float = 1.0) -> dict:
    """A bundled scene built and advanced to t_end in ``steps`` steps: diagnostics."""
    sim = build(load_scene(ROOT / "scenes" / name), "rod")
    sim.start()
    sim.begin(0.0)
    for k in range(steps):
        sim.advance(k * t_end / steps, (k + 1) * t_end / steps)
    return sim.diagnostics(t_end)


def assert_same_tip(here: dict, api: RodSystem, rod: str, t_end: float, dt: float,
                    tolerance: float) -> None:
    """The API system ``api`` run to t_end in steps dt has the scene's (``here``) tip
    of ``rod`` to ``tolerance``."""
    api.set_initial_state()
    TimeStepper(api.problem).run(0.0, t_end, dt)
    there = api.diagnostics(t_end)
    for c in "xyz":
        assert here[f"{rod}.tip_position_{c}"] == pytest.approx(
            there[f"{rod}.tip_position_{c}"], rel=0, abs=tolerance)


def test_frame_scene_is_the_api_frame():
    """scenes/frame.toml and the same frame through the Python API: the same beam tip
    after the load ramp (the same model, stepped alike: to round-off, 1e-12 of ~2 m),
    the knee's vertical force the load, 1e4 N (Newton's tolerance: 1e-6 relative)."""
    here = run_to_one("frame.toml", 10)
    A, B = (4.0e4, 4.0e4, 2.4e4), (2.05e7, 2.05e7, 1.2e8)
    top = (0.0, 0.0, 2.0)
    api = RodSystem([
        Rod(RodParameters(length=2.0, A=A, B=B), 16, name="column"),
        Rod(RodParameters(length=1.5, A=A, B=B), 12, "free", end="free", name="beam",
            position=top, orientation=(0.0, np.pi / 2, 0.0),
            end_loads=[EndLoad("force", (0.0, 0.0, -1.0e4), loads.ramp(1.0, 1.0))])],
        joints=[Joint("rigid", ("column", "beam"), top, name="knee")], model="hyperelastic")
    assert_same_tip(here, api, "beam", 1.0, 0.1, 1e-12)
    assert here["joint_knee_force_z"] == pytest.approx(1.0e4, rel=1e-6)
    assert here["beam.tip_position_z"] < 1.0          # a large deflection (from 2 m)


@pytest.mark.parametrize("change, key", [
    (("[[joints]]\nkind = \"rigid\"", "[[joints]]\nkind = \"weld\""), "joints[0].kind"),
    (("rods = [\"column\", \"beam\"]", "rods = [\"column\", \"roof\"]"), "joints[0].rods"),
    (("geometry = { length = 1.5,", "geometry = { length = -1.5,"), "rods[1].geometry.length"),
    (("name = \"beam\"\n", "name = \"beam\"\ncolour = \"red\"\n"), "rods[1].colour"),
    (("boundary = { start = \"free\" }", "boundary = { start = \"free\" }\n"
      "material = { model = \"evolving\" }"), "rods[1].material.model"),
    (("name = \"beam\"", "name = \"column\""), "rods[1].name"),
    # the column pinned at the floor: no rotation held anywhere (check said OK, run
    # refused it naming scene.model: "joints need rotation-vector unknowns ...")
    (("boundary = { start = \"clamped\" }", "boundary = { start = \"pinned\" }"),
     "rods[0].boundary.start"),
    # drag on a quasi-static frame: no rotation-vector unknowns, which joints need (the
    # same: check said OK, run refused it naming scene.model)
    (("model = \"hyperelastic\"", "model = \"hyperelastic\"\ndrag = 0.5"), "material.drag"),
])
def test_bad_system_keys_are_named(change, key):
    with pytest.raises(SceneError) as err:
        parse_scene(FRAME.replace(*change), source="frame.toml")
    assert err.value.key == key, err.value


def test_joint_off_the_rods_exits_2(tmp_path):
    """A joint at a point that is on the column but not on the beam: `dolfin-rod check`
    names joints[0].point and the rod, exit 2, no traceback."""
    bad = tmp_path / "frame.toml"
    bad.write_text(FRAME.replace("point = [0.0, 0.0, 2.0]", "point = [0.0, 0.0, 1.0]"))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(bad)],
                         capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr
    assert "[joints[0].point]" in out.stderr and "is not on rod 'beam'" in out.stderr


DOOR_SCENE = (ROOT / "scenes" / "hinged_door.toml").read_text()


@pytest.mark.parametrize("change, reason", [
    (("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 2.0]"), "must be a unit vector"),
    (("axis = [0.0, 0.0, 1.0]", ""), "is missing"),
    (("kind = \"hinge\"", "kind = \"ball\""), "is a hinge's; a ball joint has none"),
    (("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 1.0]"), "array of 3 numbers"),
])
def test_bad_hinge_axis_is_named(change, reason):
    with pytest.raises(SceneError) as err:
        parse_scene(DOOR_SCENE.replace(*change), source="hinged_door.toml")
    assert err.value.key == "joints[0].axis" and reason in err.value.reason, err.value


def test_hinged_door_scene_is_the_api_door():
    """scenes/hinged_door.toml and the same gate through the Python API (steel, the
    derived tensors of rod/sections.py): the same gate tip after 4 steps of the scene's
    5 ms (the same model: round-off, 1e-13 m), and the hinge's couple about its axis is
    0 (free) to Newton's tolerance (the dynamic rod's rtol 1e-4, integrators/lie_alpha.py:
    measured 1.3e-5 of the weight's moment, ~17 N m; tolerance 1e-4 of it)."""
    from dolfin_rod import DistributedLoad, sections
    here = run_to_one("hinged_door.toml", 4, 0.02)
    steel = sections.Material(youngs_modulus=210e9, shear_modulus=81e9, density=7850.0)
    rods = []
    for name, length, radius, extra in (
            ("post", 1.0, 0.02, dict(start="clamped", end="free")),
            ("gate", 1.2, 0.01, dict(start="free", end="free", position=(0.0, 0.0, 1.0),
                                     orientation=(0.0, np.pi / 2, 0.0),
                                     end_loads=[EndLoad("force", (0.0, 2.0, 0.0))]))):
        p = RodParameters(length=length, **sections.section_parameters(
            sections.circle(radius), steel))
        gravity = DistributedLoad("force", (0.0, 0.0, -9.81 * p.density))
        rods.append(Rod(p, 8, name=name, distributed_loads=[gravity], **extra))
    api = RodSystem(rods, joints=[Joint("hinge", ("post", "gate"), (0.0, 0.0, 1.0),
                                        name="hinge", axis=(0.0, 0.0, 1.0))],
                    model="hyperelastic")
    assert_same_tip(here, api, "gate", 0.02, 0.005, 1e-13)
    assert abs(here["joint_hinge_couple_z"]) < 1e-4 * 9.81 * 2.47 * 1.2 ** 2 / 2
    assert here["gate.tip_position_y"] > 1e-5          # it turned


PENDULUM_SCENE = (ROOT / "scenes" / "double_pendulum.toml").read_text()


def test_system_scene_starting_states(tmp_path):
    """[initial] start keys in a scene of several rods: the scene's for every rod, or a
    rod's own (rods[k].initial), each in its rod's placed frame (rod/start.RodStarts).
    double_pendulum.toml spun about its pin, OMEGA e_2, both ways: the kinetic energy at
    t = 0 the same (round-off, 1e-14) and the rigid rotation's (upper rod 1/2 OMEGA^2
    (rho_A l^3/3 + rho I_22 l), 1e-12); only the lower rod spun: exit 2 naming
    `start: joints[0]`; a rod's own initial.natural_curvature on a hyperelastic rod:
    refused (no natural strains)."""
    from dolfin_rod import run
    spin = "angular_velocity = [0.0, 1.5, 0.0], rotation_centre = [0.0, 0.0, 0.0]"
    shared = PENDULUM_SCENE.replace("[[rods]]\nname = \"upper\"",
                                    f"[initial]\n{spin.replace(', r', chr(10) + 'r')}\n\n"
                                    "[[rods]]\nname = \"upper\"", 1)
    own = PENDULUM_SCENE.replace("boundary = { start = \"pinned\" }",
                                 f"boundary = {{ start = \"pinned\" }}\ninitial = {{ {spin} }}"
                                 ).replace("boundary = { start = \"free\" }\n",
                                           f"boundary = {{ start = \"free\" }}\n"
                                           f"initial = {{ {spin} }}\n")
    quiet = {"time.t_end": 0.002, "outputs.animation": False, "outputs.plots": False,
             "outputs.fields": False}
    energies = []
    for k, text in enumerate((shared, own)):
        path = tmp_path / f"spun{k}.toml"
        path.write_text(text)
        series = run(path, quiet, out=tmp_path / f"run{k}", quiet=True).series
        energies.append((series["kinetic_energy"][0], series["upper.kinetic_energy"][0]))
    assert energies[1] == pytest.approx(energies[0], rel=1e-14)
    rho_A, rho_I = 7850.0 * np.pi * 0.005 ** 2, 7850.0 * np.pi * 0.005 ** 4 / 4
    assert energies[0][1] == pytest.approx(0.5 * 1.5 ** 2 * (rho_A / 3 + rho_I), rel=1e-12)
    half = PENDULUM_SCENE.replace("boundary = { start = \"free\" }\n",
                                  f"boundary = {{ start = \"free\" }}\ninitial = {{ {spin} }}\n")
    bad = tmp_path / "half.toml"
    bad.write_text(half)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "run", str(bad), "--out",
                          str(tmp_path / "half"), "--quiet"], capture_output=True, text=True,
                         timeout=300, cwd=ROOT, env=env)
    assert out.returncode == 2, out.stderr
    assert "start: joints[0] (elbow)" in out.stderr and "Traceback" not in out.stderr
    with pytest.raises(SceneError) as err:
        parse_scene(PENDULUM_SCENE.replace("boundary = { start = \"pinned\" }",
                                           "boundary = { start = \"pinned\" }\n"
                                           "initial = { natural_curvature = [0, 1, 0] }"),
                    source="double_pendulum.toml")
    assert err.value.key == "rods[0].initial.natural_curvature"


def test_tripod_scene_carries_its_load():
    """scenes/tripod.toml (three legs welded at the head, a load F on the head through
    leg3's tip): the three clamps' reactions balance F (reaction = -F summed, measured
    to 1e-9 relative: Newton's tolerance) and the joints pass on what leg2 and leg3
    carry; every leg's tip stays at the head (the joints hold to round-off)."""
    d = run_to_one("tripod.toml", 4)
    force = np.array([200.0, 0.0, -2000.0])
    reactions = sum(np.array([d[f"leg{i}.reaction_force_start_{c}"] for c in "xyz"])
                    for i in (1, 2, 3))
    assert reactions == pytest.approx(-force, rel=1e-8, abs=1e-6)
    tips = [np.array([d[f"leg{i}.tip_position_{c}"] for c in "xyz"]) for i in (1, 2, 3)]
    assert np.allclose(tips[1], tips[0], rtol=0, atol=1e-14)
    assert np.allclose(tips[2], tips[0], rtol=0, atol=1e-14)
    assert np.linalg.norm(tips[0] - [0.0, 0.0, 1.0]) > 1e-5        # the head moved


@pytest.mark.parametrize("name", ["double_pendulum.toml", "tripod.toml", "frame.toml",
                                  "hinged_door.toml"])
def test_example_scenes_are_valid(name):
    scene = load_scene(ROOT / "scenes" / name)
    assert len(scene.rods) >= 2 and scene.joints


@pytest.mark.mpi
@pytest.mark.parametrize("name, cells", [
    ("frame.toml", None), ("double_pendulum.toml", None), ("tripod.toml", None),
    ("hinged_door.toml", None), ("bent_frame.toml", None), ("bent_frame.toml", 27)])
def test_system_scenes_serial_equals_two_ranks(tmp_path, name, cells):
    """Each example scene, a few steps (bent_frame also at 27 cells: its corner between
    nodes, split into pieces of 15 and 12 cells, whose 2-rank partition by graph
    partitioning left the clamped cell alone on a rank, which fem/assembly.py refuses;
    compat.contiguous_parts cuts at the pieces' ends), on the ranks of the run and
    serially (a separate process): the same time series, every rod's and joint's column,
    to 1e-8 of the largest value of its kind (``kind``: a force component that is 0 in theory is
    round-off of the others, measured 2.6e-8 N in a knee force of 1e4 N).  The dynamic pendulum's Newton stops at rtol 1e-4 of a tiny residual, on
    another iterate under another partition (block-Jacobi GMRES): measured 2.6e-9
    relative on a clamp force."""
    from mpi4py import MPI
    from quick_scenes import quick_scene, run_serially

    from dolfin_rod import run_scene
    comm = MPI.COMM_WORLD
    quiet = dict(outputs__animation=False, outputs__plots=False, outputs__fields=False)
    folder = Path(comm.bcast(str(tmp_path), root=0))
    path = ROOT / "scenes" / name
    if cells:
        quiet["geometry__n_cells"] = cells
    summary = run_scene(quick_scene(path, 4, **quiet), folder / "run", quiet=True)
    assert summary["status"] == "completed"
    if comm.size == 1 or comm.rank != 0:
        return
    assert run_serially(path, folder / "serial", 4, **quiet) == "completed"
    parallel, serial = (np.genfromtxt(folder / part / "timeseries.csv", delimiter=",",
                                      names=True) for part in ("run", "serial"))
    def kind(key: str) -> str:
        """Forces and couples of every rod and joint together (a ball joint's couple is
        0 in theory: round-off of the forces), energies and powers together, else the
        components of one vector."""
        for words, family in ((("force", "couple"), "loads"),
                              (("energy", "power", "dissipation"), "energies")):
            if any(w in key for w in words):
                return family
        return key.rstrip("xyz0123") if key[-2:-1] == "_" else key

    scale = {}
    for key in serial.dtype.names:
        scale[kind(key)] = max(scale.get(kind(key), 0.0), np.nanmax(np.abs(serial[key])))
    for key in parallel.dtype.names:
        np.testing.assert_allclose(parallel[key], serial[key], rtol=1e-8,
                                   atol=1e-8 * scale[kind(key)] + 1e-14, err_msg=key)


@pytest.mark.mpi
def test_double_pendulum_scene_resumes_exactly(tmp_path):
    """scenes/double_pendulum.toml stopped after 5 steps and resumed from its checkpoint
    (both rods' stored rotations, rates and accelerations on the one mesh) equals the
    uninterrupted run, every rod's and joint's column to round-off (resume_bound)."""
    import csv
    import math

    from mpi4py import MPI
    from quick_scenes import resume_bound

    from dolfin_rod import run_scene
    folder = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))
    scene = load_scene(ROOT / "scenes" / "double_pendulum.toml", {
        "time.t_end": 0.016, "outputs.checkpoint_every": 3, "outputs.every": 1,
        "outputs.plots": False, "outputs.animation": False, "outputs.progress": False})
    assert run_scene(scene, folder / "full", quiet=True)["status"] == "completed"
    assert run_scene(scene, folder / "part", stop_after=5, quiet=True)["status"] == "stopped"
    assert run_scene(scene, folder / "part", resume=True, quiet=True)["status"] == "completed"
    if MPI.COMM_WORLD.rank != 0:
        return
    full, part = ([{k: float(v) if v else math.nan for k, v in row.items()}
                   for row in csv.DictReader(open(folder / name / "timeseries.csv"))]
                  for name in ("full", "part"))
    assert len(full) == len(part) == 9
    for i, (x, y) in enumerate(zip(full, part)):
        for k in x:
            if not (math.isnan(x[k]) and math.isnan(y[k])):
                assert abs(x[k] - y[k]) <= resume_bound(x, full[i - 1] if i else None, k), k


TWO_EVOLVING_RODS = """
[scene]
name = "two_rods"
[material]
model = "evolving"
stiffness = { A = [1.0, 1.0, 1.0], B = [1.0, 1.0, 1.0], A_d = [1.0, 1.0, 1.0], B_d = [1.0, 1.0, 1.0] }
viscosity = { M = [0.0, 0.0, 0.0], N = [0.0, 0.0, 0.0], M_d = [5.0, 5.0, 5.0], N_d = [5.0, 5.0, 5.0] }
[time]
t_end = 0.1
dt = 0.1
[[rods]]
name = "a"
boundary = { start = "clamped" }
initial = { natural_curvature = [0.0, 0.4, 0.0], natural_stretch = [0.0, 0.0, 1.1] }
[[rods]]
name = "b"
position = [1.0, 2.0, 3.0]
geometry = { length = 0.7, n_cells = 5, reference_curvature = [0.3, 0.0, 0.0] }
boundary = { start = "clamped" }
initial = { natural_curvature = [0.1, 0.0, 0.2] }
"""


def test_each_rod_of_a_scene_has_its_own_initial_natural_strains():
    """[[rods]] with their own initial.natural_curvature / natural_stretch (rod b's
    stretch left at its discrete reference strains): the built system starts with each rod's
    values on its cells, exactly as the API's set_initial_state(natural_curvature=
    {rod: value}) writes them (the same field, bit for bit)."""
    sim = build(parse_scene(TWO_EVOLVING_RODS, source="two_rods.toml"), "rod")
    sim.start()
    model = sim.model
    api = RodSystem(model.rods, model="evolving")
    api.set_initial_state(natural_curvature={"a": (0.0, 0.4, 0.0), "b": (0.1, 0.0, 0.2)},
                          natural_stretch={"a": (0.0, 0.0, 1.1)})
    for name in ("natural_curvature", "natural_stretch"):
        assert np.array_equal(model.unknowns.f[name].x.array, api.unknowns.f[name].x.array)
    field = model.unknowns.f["natural_curvature"]
    rod_of = model.layout.rod_of(field.function_space.tabulate_dof_coordinates()[:, 0])
    values = field.x.array.reshape(-1, 3)
    assert np.array_equal(values[rod_of == 0], np.tile([0.0, 0.4, 0.0], ((rod_of == 0).sum(), 1)))
    assert np.array_equal(values[rod_of == 1], np.tile([0.1, 0.0, 0.2], ((rod_of == 1).sum(), 1)))
    stretch = model.unknowns.f["natural_stretch"].x.array.reshape(-1, 3)[rod_of == 1]
    reference = model.reference[1].x.array.reshape(-1, 3)[rod_of == 1]   # b's discrete v_ref
    assert np.array_equal(stretch, reference) and abs(reference[0, 2] - 1.0) > 1e-5


def test_curling_pair_scene_each_rod_curls_onto_its_own_natural_curvature(tmp_path):
    """scenes/curling_pair.toml: a free end carries no couple, so each cantilever's
    discrete strain equals its natural curvature u_d on every cell: at t = 0 the tip
    turns by the discrete arc's angle N 4 atan(u_d h/4) (nodal turns dphi with
    4 tan(dphi/4)/h = u_d, closed_forms.p1_twist's relation) for its own u_d(0), 1.2 and
    0.6 (round-off: 1e-12); then u_d relaxes as M_d u_d' = -A_d u_d, so at t = 1 the
    angle is that of u_d(0) exp(-t/tau), tau = 0.5 s (measured 0.7 % off: the time
    scheme's error at dt = tau/5; tolerance 1 %)."""
    from dolfin_rod import run
    series = run(ROOT / "scenes" / "curling_pair.toml",
                 {"outputs.animation": False, "outputs.plots": False, "outputs.fields": False},
                 out=tmp_path / "run", quiet=True).series
    N, h, tau = 8, 1.0 / 8, 0.5

    def arc(u_d):
        return N * 4 * np.arctan(u_d * h / 4)

    for rod, u0 in (("a", 1.2), ("b", 0.6)):
        angle = np.asarray(series[f"{rod}.tip_rotation_angle"])
        assert angle[0] == pytest.approx(arc(u0), abs=1e-12)
        assert angle[-1] == pytest.approx(arc(u0 * np.exp(-1.0 / tau)), rel=1e-2)


@pytest.mark.parametrize("cells, parts, expected", [
    # two rods of 15 and 12 cells on 2 ranks: the even cut (14) would leave the
    # first rod's last cell alone on rank 1: moved to the rods' boundary
    ((15, 12), 2, [15]),
    # 16 + 12 on 2: the even cut at 14 leaves 2 cells of rod 1 on rank 1: kept
    ((16, 12), 2, [14]),
    # one rod of 9 cells on 3 ranks: no boundary inside, even cuts
    ((9,), 3, [3, 6]),
    # 3 rods of 4 cells on 2 ranks: the cut at 6 leaves 2 and 2 cells of rod 2: kept
    ((4, 4, 4), 2, [6]),
    # 10 + 1 + 10 on 3 ranks: cuts at 7 and 14 (rod 3's 3rd cell): kept
    ((10, 1, 10), 3, [7, 14])])
def test_contiguous_parts_cut_components_only_where_two_cells_stay(cells, parts, expected):
    """compat.contiguous_parts: each part a run of consecutive cells, the cuts at
    round(k m / parts) unless a component keeps fewer than 2 cells on a side (then at
    its nearer end); the expected cuts worked out by hand above."""
    from dolfin_rod.fem.compat import contiguous_parts
    first = np.concatenate([[0], np.cumsum(np.asarray(cells) + 1)[:-1]])
    mesh_cells = np.vstack([f + np.column_stack([np.arange(n), np.arange(1, n + 1)])
                            for f, n in zip(first, cells)])
    owners = contiguous_parts(mesh_cells, parts)
    cuts = [int(i) for i in np.flatnonzero(np.diff(owners)) + 1]
    assert cuts == expected
    assert list(np.unique(owners)) == list(range(parts))
