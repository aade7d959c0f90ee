"""Scenes: schema validation (one SceneError, fuzzed), model selection, ODE = PDE where the
reduction is exact, incremental outputs and checkpoint/resume.

Tolerances
* ODE with ``ode_solution = "scheme"`` vs the torsion PDE: the same linear equations
  (homogeneous fields are exact in P_k x DG_{k-1}, the reduction is exact) solved by
  Newton/LU with snes_rtol = 1e-10 relative to the initial residual, so they agree to
  ~1e-10 of the load scale; we test 1e-8 (absolute, loads O(1)).
* ODE "exact" vs closed_forms: the same closed form (exact) or solve_ivp at rtol 1e-10:
  1e-8.
* resume vs uninterrupted run: the same floating-point operations on the same data
  (checkpoints store the doubles exactly), so 1e-12 absolute on O(1) values.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mpi4py import MPI

from dolfin_rod import closed_forms
from dolfin_rod import run_scene
from dolfin_rod.scenes import SceneError, build, load_scene, parse_scene, select_model, validate
from dolfin_rod.scenes.schema import UNITS
from quick_scenes import resume_bound

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted((ROOT / "scenes").glob("*.toml"))

BASE = """
[material]
alpha = 2.0
alpha_d = 1.0
mu_d = 0.5
[boundary]
end = "rotation"
end_rotation = { type = "step", value = 0.5 }
[time]
t_end = 0.1
dt = 0.01
"""


def scene_from(text: str = BASE, **changes):
    """A validated scene; ``changes`` as table__key=value edit the parsed dict first."""
    import tomllib
    raw = tomllib.loads(text)
    for path, value in changes.items():
        table, key = path.split("__")
        raw.setdefault(table, {})[key] = value
    return validate(raw, "test.toml")


def shared_folder(tmp_path) -> Path:
    """One folder for all ranks (rank 0's tmp_path)."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))


# --- validation ---------------------------------------------------------------------------


# the least model of each bundled scene, by reading it: homogeneous quasi-static torsion
# with an end load or rotation -> ode; a 3-D material -> rod (a new scene needs its entry)
BUNDLED_MODELS = {"torsion_relaxation.toml": "ode", "torsion_creep.toml": "ode",
                  "torsion_creep_loaded.toml": "torsion",         # scene.model: its state
                  "torsion_creep_recovery.toml": "torsion",       # is saved, then read

                  "cantilever_creep.toml": "rod", "gravity_cantilever.toml": "rod",
                  "twisted_rod_relaxation.toml": "rod", "flexible_pendulum.toml": "rod",
                  "dna_overstretching.toml": "rod", "dna_twist_relaxation.toml": "rod",
                  "hanging_twist.toml": "rod", "inclined_clamp.toml": "rod",
                  "curling_pair.toml": "rod",
                  "helical_spring.toml": "rod", "helix_wrench.toml": "rod",
                  "flying_beam.toml": "rod", "pinched_ring.toml": "rod",
                  "spin_up.toml": "rod",
                  "sprung_cantilever.toml": "rod", "rod_on_incline.toml": "rod",
                  "rod_rolling_on_incline.toml": "rod",
                  "rope_on_floor.toml": "rod", "frame.toml": "rod",
                  "crossing_rods.toml": "rod", "plectoneme.toml": "rod",
                  "ropes_pulled_over_each_other.toml": "rod",
                  "double_pendulum.toml": "rod", "tripod.toml": "rod",
                  "sagging_cable.toml": "rod", "hanging_pendulum.toml": "rod",
                  "hinged_door.toml": "rod", "bent_frame.toml": "rod",
                  "column_buckling_modes.toml": "rod", "string_modes.toml": "rod",
                  "buckled_column.toml": "rod", "snap_through_arch.toml": "rod",
                  "beck_column.toml": "rod", "deep_arch.toml": "rod",
                  "lee_frame.toml": "rod", "plectoneme_setting.toml": "rod",
                  "rope_over_boulder.toml": "rod", "rope_over_thin_bar.toml": "rod",
                  "continuum_snake.toml": "rod", "supercoiled_minicircle.toml": "rod",
                  "sedimenting_fibre.toml": "rod", "continuum_flagella.toml": "rod",
                  "overhand_knot_tie.toml": "rod", "overhand_knot.toml": "rod",
                  "axial_stretching.toml": "rod", "butterfly.toml": "rod",
                  "vibrating_cantilever.toml": "rod", "hanging_ring.toml": "rod"}


@pytest.mark.parametrize("path", SCENES, ids=[p.name for p in SCENES])
def test_bundled_scenes_are_valid(path):
    scene = load_scene(path)
    assert select_model(scene).model == BUNDLED_MODELS[path.name]
    # every bundled scene names its unit system, so no plot axis reads "[scene units]"
    assert scene["scene"]["units"] in UNITS, f"{path.name}: no scene.units"


def relaxation_rederived(t, u0, alpha, alpha_d, mu_d):
    """Stress relaxation re-derived here (not closed_forms): with u = u0 held from t = 0,
    eq. nattwist mu_d u_d' = alpha u0 - (alpha + alpha_d) u_d, u_d(0) = 0 gives
    u_d = alpha u0/(alpha + alpha_d) (1 - exp(-(alpha + alpha_d) t/mu_d)), and eq. twist
    (mu u' = 0 for t > 0) the end torsion m = alpha (u0 - u_d)."""
    u_d = alpha * u0 / (alpha + alpha_d) * (1.0 - np.exp(-(alpha + alpha_d) * t / mu_d))
    return u_d, alpha * (u0 - u_d)


def test_defaults_a_user_expects():
    s = parse_scene("[time]\nt_end = 1.0\ndt = 0.1\n", default_name="x")
    assert s.name == "x" and s["scene"]["model"] == "auto"
    assert s["time"]["scheme"] == "bdf2" and s["geometry"]["n_cells"] == 32
    assert [s["material"][k].constant for k in ("alpha", "alpha_d", "mu", "mu_d", "nu")] == \
        [1.0, 1.0, 0.0, 1.0, 0.0]
    assert s["boundary"]["end"] == "free" and s["material"]["variant"] == "local"


BAD = [
    ("[time]\nt_end = 1\n", "time.dt", "missing required key"),
    ("[tme]\n", "tme", "unknown table"),
    (BASE + "[outputs]\nevry = 2\n", "outputs.evry", "unknown key"),
    (BASE.replace("alpha = 2.0", "alpha = -2.0"), "material.alpha", "must be > 0"),
    (BASE.replace("alpha = 2.0", "alpha = nan"), "material.alpha", "finite"),
    (BASE.replace("alpha = 2.0", 'alpha = "2"'), "material.alpha", "must be a number"),
    (BASE.replace("alpha = 2.0", "alpha = true"), "material.alpha", "must be a number"),
    (BASE.replace("alpha = 2.0", "alpha = {polynomial = [1.0, -2.0]}"), "material.alpha",
     "> 0 on [0, 1]"),
    (BASE.replace("dt = 0.01", "dt = 1.0"), "time.dt", "<= t_end"),
    (BASE.replace("t_end = 0.1", "t_end = 0"), "time.t_end", "> 0"),
    (BASE + '[scene]\nmodel = "fem"\n', "scene.model", "must be one of"),
    (BASE.replace('"step"', '"jump"'), "boundary.end_rotation.type", "must be one of"),
    (BASE.replace('value = 0.5', 'val = 0.5'), "boundary.end_rotation.val", "unknown key"),
    (BASE.replace('{ type = "step", value = 0.5 }',
                  '{ type = "table", times = [0.0, 0.0], values = [0.0, 1.0] }'),
     "boundary.end_rotation.times", "strictly increasing"),
    (BASE.replace('end = "rotation"', 'end = "free"'), "boundary.end_rotation", "is \"free\""),
    (BASE + "[loads]\nend_torsion = { type = \"step\", value = 1.0 }\n", "loads.end_torsion",
     "cannot be applied"),
    (BASE.replace("mu_d = 0.5", "mu_d = 0.5\nnu = 0.01"), "boundary.end_rotation", "inertia"),
    (BASE + '[scene]\nmodel = "ode"\n' + "", None, None),   # valid: ode is enough
    (BASE.replace("mu_d = 0.5", "mu_d = 0.5\nnu = 0.01").replace('"step", value = 0.5',
     '"ramp", value = 0.5, duration = 0.05') + '[scene]\nmodel = "ode"\n',
     "scene.model", "cannot run this scene"),
    (BASE.replace("mu_d = 0.5", 'mu_d = 0.5\nenergy = "kelvin_voigt"'),
     "material.energy", "entry point"),
    (BASE + '[geometry]\nreference_twist = 0.1\n', "geometry.reference_twist",
     "initial.natural_twist"),
    (BASE + '[loads]\ngravity = [0.0, 0.0, -9.81]\n', "loads.gravity", "3-D rod only"),
    (BASE.replace("[boundary]", '[boundary]\nstart = "free"'), "boundary.start",
     "clamped at s = 0"),
    (BASE.replace("[time]", "[time]\nadaptive = true"), "time.adaptive", "integrator = \"ts\""),
    (BASE.replace("[time]", '[time]\nintegrator = "ts"\nts_type = "rk4"'), "time.ts_type",
     "rk4"),
    (BASE.replace("[time]", '[time]\nintegrator = "ts"\nts_rtol = 1e-6'), "time.ts_rtol",
     "adaptive = true"),
    (BASE + '[solver]\noptions = { "-snes_max_it" = 3 }\n', "solver.options.-snes_max_it",
     "without the leading"),
    (BASE.replace("mu_d = 0.5", 'mu_d = {polynomial = [1.0, 1.0]}\nvariant = "uniform"'),
     "material.mu_d", "uniform variant"),
    (BASE + '[geometry]\nlength = 2.0\n', "geometry.length", "dimensionless"),
    (BASE.replace("[time]", '[time]\nscheme = "explicit_euler"'), "time.scheme", "explicit"),
    (BASE.replace("[time]", '[time]\nscheme = "rk4"'), "time.scheme", "unknown time scheme"),
    (BASE + "[geometry]\nn_cells = 0\n", "geometry.n_cells", "integer in"),
    ("[time\n", "", "invalid TOML"),
]


@pytest.mark.parametrize("text, key, reason", BAD)
def test_one_clear_error(text, key, reason):
    if key is None:
        select_model(parse_scene(text, "bad.toml"))
        return
    with pytest.raises(SceneError) as info:
        select_model(parse_scene(text, "bad.toml"))
    err = info.value
    assert err.source == "bad.toml" and err.key == key and reason in err.reason, str(err)
    assert str(err).startswith("bad.toml: ")


def test_unreadable_file_is_a_scene_error(tmp_path):
    with pytest.raises(SceneError, match="cannot read"):
        load_scene(tmp_path / "missing.toml")
    (tmp_path / "latin.toml").write_bytes(b"name = '\xe9'\n")
    with pytest.raises(SceneError, match="UTF-8"):
        load_scene(tmp_path / "latin.toml")


# --- fuzzing: nothing but SceneError ------------------------------------------------------

_scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                     st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
_values = st.recursive(_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=8)
_known_keys = st.sampled_from([
    "alpha", "alpha_d", "mu", "mu_d", "nu", "variant", "energy", "stiffness", "viscosity",
    "density", "end", "end_rotation", "end_torsion", "distributed_couple", "end_force",
    "t_end", "dt", "scheme", "model", "n_cells", "degree", "reference_twist",
    "reference_curvature", "length", "every", "fields", "type", "value", "times"])
_tables = st.sampled_from(["scene", "geometry", "material", "boundary", "loads", "time",
                           "outputs", "extra"])


def _must_be_scene_error(call):
    try:
        scene = call()
        select_model(scene)
    except SceneError:
        pass


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200))
def test_fuzz_text(text):
    _must_be_scene_error(lambda: parse_scene(text, "fuzz.toml"))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(_tables, _known_keys, _values), max_size=5))
def test_fuzz_mutated_scene(edits):
    import tomllib
    raw = tomllib.loads(BASE)
    for table, key, value in edits:
        section = raw.setdefault(table, {})
        if isinstance(section, dict):
            section[key] = value
    _must_be_scene_error(lambda: validate(raw, "fuzz.toml"))


@settings(max_examples=100, deadline=None)
@given(_values)
def test_fuzz_whole_document(raw):
    _must_be_scene_error(lambda: validate(raw, "fuzz.toml"))


# --- model selection -----------------------------------------------------------------------


def test_selection_picks_the_least_model():
    assert select_model(scene_from()).model == "ode"
    c = select_model(scene_from(material__nu=0.01, boundary__end_rotation={
        "type": "ramp", "value": 0.5, "duration": 0.05}))
    assert c.model == "torsion" and "nu > 0" in c.reason
    c = select_model(scene_from(material__alpha={"polynomial": [1.0, 1.0]}))
    assert c.model == "torsion" and "alpha varies" in c.reason
    c = select_model(scene_from(scene__model="torsion"))
    assert c.model == "torsion" and c.forced and "'ode'" in c.reason


# --- ODE vs PDE where the reduction is exact ------------------------------------------------


def _run(scene, model):
    """Diagnostics at the output times min(k dt, t_end) (the last step clipped)."""
    sim = build(scene, model)
    sim.start()
    dt, t_end = scene["time"]["dt"], scene["time"]["t_end"]
    times = [min(k * dt, t_end) for k in range(math.ceil(t_end / dt - 1e-9) + 1)]
    out = [sim.diagnostics(0.0)]
    for t, t_next in zip(times[:-1], times[1:]):
        sim.advance(t, t_next)
        out.append(sim.diagnostics(t_next))
    return out


KEYS = ("end_torsion", "end_rotation", "mean_natural_twist", "free_energy", "dissipation_rate")
CASES = {
    "relaxation": {},
    "relaxation_kelvin_voigt_uniform": {"material__mu": 0.3, "material__variant": "uniform"},
    "relaxation_ramp_cn": {"boundary__end_rotation": {"type": "ramp", "value": 0.5,
                                                      "duration": 0.03},
                           "time__scheme": "crank_nicolson"},
    "creep_kelvin_voigt": {"boundary__end": "free", "boundary__end_rotation": None,
                           "loads__end_torsion": {"type": "step", "value": 1.0},
                           "material__mu": 0.2},
    "creep_clipped_last_step": {"boundary__end": "free", "boundary__end_rotation": None,
                                "loads__end_torsion": {"type": "step", "value": 1.0},
                                "material__mu": 0.2, "time__t_end": 0.1033},
    "creep_inviscid_table": {"boundary__end": "free", "boundary__end_rotation": None,
                             "loads__end_torsion": {"type": "table", "times": [0.0, 0.05, 0.1],
                                                    "values": [0.0, 1.0, 0.5]},
                             "time__scheme": "backward_euler", "geometry__degree": 2},
}


def _case(name, **more):
    changes = {**CASES[name], **more}
    import tomllib
    raw = tomllib.loads(BASE)
    for path, value in changes.items():
        table, key = path.split("__")
        if value is None:
            raw[table].pop(key)
        else:
            raw.setdefault(table, {})[key] = value
    raw.setdefault("geometry", {})["n_cells"] = 4
    return validate(raw, name)


@pytest.mark.mpi
@pytest.mark.parametrize("name", list(CASES))
def test_ode_equals_torsion_pde_to_solver_tolerance(name):
    scene = _case(name, time__ode_solution="scheme")
    ode, pde = _run(scene, "ode"), _run(scene, "torsion")
    for a, b in zip(ode, pde):
        for k in KEYS:
            assert abs(a[k] - b[k]) < 1e-8, (k, a["time"], a[k], b[k])


def test_ode_exact_is_the_closed_form():
    scene = _case("relaxation")
    d = _run(scene, "ode")
    t = np.array([x["time"] for x in d])
    ud, m = relaxation_rederived(t, 0.5, 2.0, 1.0, 0.5)
    # the same exponential evaluated in two ways: round-off, 1e-13 on O(1) values
    assert np.allclose([x["end_torsion"] for x in d], m, atol=1e-13)
    assert np.allclose([x["mean_natural_twist"] for x in d], ud, atol=1e-13)
    scene = _case("creep_inviscid_table")          # solve_ivp (Radau) path, mu = 0
    d = _run(scene, "ode")
    t = np.array([x["time"] for x in d])
    hist = scene["loads"]["end_torsion"].build()
    u, ud = closed_forms.creep_response(t, hist, 2.0, 1.0, 0.5)
    assert np.allclose([x["end_rotation"] for x in d], u, atol=1e-8)
    assert np.allclose([x["mean_natural_twist"] for x in d], ud, atol=1e-8)


# --- outputs, checkpoints ---------------------------------------------------------------------


def _read_csv(path):
    """Rows of timeseries.csv; an empty field (no value, e.g. row 0's residual) is NaN."""
    with open(path) as f:
        return [{k: float(v) if v else math.nan for k, v in r.items()}
                for r in csv.DictReader(f)]


@pytest.mark.mpi
def test_resume_continues_to_the_same_result(tmp_path):
    """An interrupted FE run resumed from its checkpoint = the uninterrupted run."""
    folder = shared_folder(tmp_path)
    for variant in ("local", "uniform"):
        scene = _case("relaxation_kelvin_voigt_uniform", material__variant=variant,
                      scene__model="torsion", outputs__checkpoint_every=3,
                      outputs__plots=False, time__t_end=0.08)
        full = run_scene(scene, folder / f"full-{variant}", quiet=True)
        part = run_scene(scene, folder / f"part-{variant}", stop_after=5, quiet=True)
        assert part["status"] == "stopped"
        resumed = run_scene(scene, folder / f"part-{variant}", resume=True, quiet=True)
        assert full["status"] == resumed["status"] == "completed"
        if MPI.COMM_WORLD.rank == 0:
            a = _read_csv(folder / f"full-{variant}" / "timeseries.csv")
            b = _read_csv(folder / f"part-{variant}" / "timeseries.csv")
            assert len(a) == len(b) == 9
            for x, y in zip(a, b):
                for k in x:
                    if not (math.isnan(x[k]) and math.isnan(y[k])):
                        assert abs(x[k] - y[k]) <= 1e-12, (variant, k, x, y)


@pytest.mark.mpi
def test_dynamic_rod_scene_runs_the_default_api_and_resumes_exactly(tmp_path):
    """The bundled gravity cantilever (dynamic, local variant, no scheme given) runs
    RodModel's default rotation vectors with TimeStepper's default integrator: the
    scene's tip equals the Python API's (same model, same steps: round-off), and a run
    stopped after 5 steps and resumed from its checkpoint (stored rotations, rates,
    accelerations) equals the uninterrupted one (round-off)."""
    from dolfin_rod import TimeStepper
    from dolfin_rod.rod import RodModel
    from dolfin_rod.scenes.builders import rod_loads, rod_parameters
    folder = shared_folder(tmp_path)
    scene = load_scene(ROOT / "scenes" / "gravity_cantilever.toml", {
        "geometry.n_cells": 8, "time.t_end": 0.08, "outputs.checkpoint_every": 3,
        "outputs.plots": False, "outputs.animation": False})
    full = run_scene(scene, folder / "full", quiet=True)
    assert full["status"] == "completed" and "rotation group" in full["method"]
    end_loads, distributed = rod_loads(scene)
    model = RodModel(rod_parameters(scene), n_cells=8, end_loads=end_loads,
                     distributed_loads=distributed)
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, 0.08, 0.01)
    d = model.diagnostics(0.08)
    for c in "xyz":    # same kernels, same data, same steps
        assert full["final"][f"tip_position_{c}"] == pytest.approx(
            d[f"tip_position_{c}"], abs=1e-13)
    assert abs(d["tip_position_x"]) > 1e-3                   # it moved
    _assert_resumed_run_is_the_full_run(scene, folder, 9)


def _assert_resumed_run_is_the_full_run(scene, folder: Path, rows: int) -> list[dict]:
    """Run ``scene`` stopped after 5 steps and resumed from its checkpoint, in
    folder/part, against the uninterrupted run in folder/full: the same ``rows`` rows,
    equal to round-off (resume_bound: the restart re-reads the state exactly).  Returns
    the full run's rows (on rank 0; [] elsewhere)."""
    part = run_scene(scene, folder / "part", stop_after=5, quiet=True)
    assert part["status"] == "stopped"
    resumed = run_scene(scene, folder / "part", resume=True, quiet=True)
    assert resumed["status"] == "completed"
    if MPI.COMM_WORLD.rank != 0:
        return []
    a = _read_csv(folder / "full" / "timeseries.csv")
    b = _read_csv(folder / "part" / "timeseries.csv")
    assert len(a) == len(b) == rows
    for i, (x, y) in enumerate(zip(a, b)):
        for k in x:
            if not (math.isnan(x[k]) and math.isnan(y[k])):
                assert abs(x[k] - y[k]) <= resume_bound(x, a[i - 1] if i else None, k), \
                    (k, x, y)
    return a


@pytest.mark.mpi
@pytest.mark.parametrize("scheme, method", [("generalized_alpha", "rotation group"),
                                            ("bdf2", "bdf2")])
def test_quasi_static_rod_scene_resumes_exactly(tmp_path, scheme, method):
    """The bundled quasi-static cantilever creep on its default rotation vectors, by the
    rotation-group integrator (algebraic positions and rotations) and by a named BDF2:
    a run stopped after 5 steps and resumed from its checkpoint (stored rotations, the
    integrator's history) equals the uninterrupted one (round-off, resume_bound), and
    the tip creeps (the natural curvature follows the bent shape)."""
    folder = shared_folder(tmp_path) / scheme
    scene = load_scene(ROOT / "scenes" / "cantilever_creep.toml", {
        "time.t_end": 0.4, "time.scheme": scheme, "outputs.checkpoint_every": 3,
        "outputs.plots": False, "outputs.animation": False})
    full = run_scene(scene, folder / "full", quiet=True)
    assert full["status"] == "completed" and method in full["method"], full["method"]
    rows = _assert_resumed_run_is_the_full_run(scene, folder, 9)
    if rows:
        assert rows[-1]["tip_position_x"] > 1.05 * rows[1]["tip_position_x"] > 0   # creeps


@pytest.mark.mpi
def test_fe_run_writes_everything(tmp_path):
    folder = shared_folder(tmp_path) / "run"
    scene = _case("creep_kelvin_voigt", scene__model="torsion", time__t_end=0.05)
    summary = run_scene(scene, folder, quiet=True)
    assert summary["status"] == "completed" and summary["model"] == "torsion"
    if MPI.COMM_WORLD.rank == 0:
        for name in ("timeseries.csv", "timeseries.json", "summary.json", "timings.json",
                     "histories.png", "rod.bp", "spacetime.png"):
            assert (folder / name).exists(), name
        data = json.loads((folder / "summary.json").read_text())
        assert {"dolfin_rod", "dolfinx", "petsc"} <= set(data["versions"])
        rows = _read_csv(folder / "timeseries.csv")
        t = np.array([r["time"] for r in rows])
        u, ud = closed_forms.creep(t, 1.0, 2.0, 1.0, 0.2, 0.5)
        # BDF2 with dt = 0.01 on rates ~10: O(dt^2) error, well below 5e-3
        assert np.allclose([r["end_rotation"] for r in rows], u, atol=5e-3)
        # power balance: quasi-static creep, smooth after t = 0: O(dt) residual (BE start)
        assert max(abs(r["power_residual"]) for r in rows[2:]) < 5e-2


def test_petsc_ts_integrator_runs_a_scene(tmp_path):
    scene = _case("creep_kelvin_voigt", scene__model="torsion", time__integrator="ts",
                  time__t_end=0.05, outputs__plots=False, outputs__fields=False)
    summary = run_scene(scene, shared_folder(tmp_path) / "ts", quiet=True)
    assert summary["status"] == "completed" and "PETSc TS" in summary["method"]
    u, _ = closed_forms.creep(0.05, 1.0, 2.0, 1.0, 0.2, 0.5)
    assert abs(summary["final"]["end_rotation"] - u) < 5e-3


# --- 3-D rod scenes: every RodModel capability has a key ----------------------------------
#
# Statics used below (quasi-static rods, P1 positions, 1-point Gauss rule): testing the
# displacement equations with the hat function of node i gives
# (R n)_{cell left of i} - (R n)_{cell right of i} = F_i (the consistent nodal load), so the
# spatial contact force of a cell is the sum of the loads on its right (a load at the
# free end s = L) or minus the sum on its left (free start).  Exact up to Newton's
# residual (atol 1e-10 on O(0.1) loads): 1e-8.

ROD_BASE = """
[geometry]
n_cells = 4
[material]
stiffness = { A = [1.0, 1.0, 1.0], B = [100.0, 100.0, 100.0], A_d = [1.0, 1.0, 1.0], B_d = [100.0, 100.0, 100.0] }
viscosity = { M_d = [1.0, 1.0, 1.0], N_d = [1.0, 1.0, 1.0] }
[time]
t_end = 0.02
dt = 0.01
[outputs]
animation = false
plots = false
"""

ROD_BAD = [
    (ROD_BASE.replace("[material]", '[material]\nconstraints = "unshearable"\ndensity = 1.0\n'
                      'section_inertia = 0.01'), "material.constraints", "index-3 DAE"),
    (ROD_BASE + "[loads]\nend_torsion = { type = \"step\", value = 1.0 }\n", "loads.end_torsion",
     "torsion model only"),
    (ROD_BASE.replace("[material]", '[material]\nmodel = "hyperelastic"'),
     "material.stiffness.A_d", "hyperelastic model has none"),
    (ROD_BASE.replace("[material]", '[material]\nmodel = "kelvin_voigt"\nvariant = "local"')
     .replace(", A_d = [1.0, 1.0, 1.0], B_d = [100.0, 100.0, 100.0]", "")
     .replace("M_d = [1.0, 1.0, 1.0], N_d = [1.0, 1.0, 1.0]", "M = [0.1, 0.1, 0.1]"),
     "material.variant", "do not evolve"),
    (ROD_BASE.replace("A = [1.0, 1.0, 1.0]", "A = [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], "
                      "[0.0, 0.0, 1.0]]"), "material.stiffness.A", "positive definite"),
    (ROD_BASE.replace("A = [1.0, 1.0, 1.0]", "A = [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], "
                      "[0.0, 0.0, 1.0]]"), "material.stiffness.A", "symmetric"),
    (ROD_BASE + "[loads]\ngravity = [0.0, 0.0, -9.81]\n", "loads.gravity", "density > 0"),
    (ROD_BASE.replace("[material]", "[material]\ndensity = 1.0"), "material.section_inertia",
     "all > 0"),
    (ROD_BASE + "[loads]\nstart_force = { type = \"step\", value = [1.0, 0.0, 0.0] }\n",
     "loads.start_force", "support takes it"),
    (ROD_BASE + '[boundary]\nstart = "free"\n', "boundary.start", "rigid motions"),
    (ROD_BASE + '[boundary]\nend = "rotation"\n', "boundary.end", "end_rotation"),
    (ROD_BASE + "[loads]\ndistributed_force = { profile = 2.0 }\n",
     "loads.distributed_force.value", "missing"),
    (ROD_BASE + '[geometry]\ndegree = 2\n', None, None),    # duplicate table: invalid TOML
    (ROD_BASE.replace("n_cells = 4", "n_cells = 4\ndegree = 2"), "geometry.degree",
     "torsion model only"),
    (ROD_BASE.replace("[material]", '[material]\nenergy = "no_such_module:psi"'),
     "material.energy", "cannot import"),
    (ROD_BASE.replace('[time]', '[time]\nscheme = "explicit_euler"'), "time.scheme",
     "explicit"),
    (ROD_BASE + "[initial]\nnatural_twist = 0.1\n", "initial.natural_twist",
     "torsion model only"),
    # rotation vectors: not with Kelvin-Voigt viscosity in a quasi-static rod, not with
    # the uniform variant, and for a dynamic rod by the rotation-group integrator only
    (ROD_BASE.replace("n_cells = 4", 'n_cells = 4\nrotations = "rotation_vector"')
     .replace("M_d = [1.0", "M = [0.1, 0.1, 0.1], M_d = [1.0"), "geometry.rotations",
     "Kelvin-Voigt"),
    (ROD_BASE.replace("n_cells = 4", 'n_cells = 4\nrotations = "rotation_vector"')
     .replace("[material]", '[material]\nvariant = "uniform"'), "geometry.rotations",
     "uniform variant"),
    (ROD_BASE.replace("n_cells = 4", 'n_cells = 4\nrotations = "euler_angles"'),
     "geometry.rotations", "one of"),
    (ROD_BASE.replace("n_cells = 4", 'n_cells = 4\nrotations = "rotation_vector"')
     .replace("[material]", "[material]\ndensity = 1.0\nsection_inertia = 0.01")
     .replace("[time]", '[time]\nscheme = "bdf2"'), "time.scheme", "generalized_alpha"),
]


@pytest.mark.parametrize("text, key, reason", ROD_BAD)
def test_rod_scene_one_clear_error(text, key, reason):
    with pytest.raises(SceneError) as info:
        select_model(parse_scene(text, "bad.toml"))
    if key is not None:
        assert info.value.key == key and reason in info.value.reason, str(info.value)


def _rod(extra: str = "", **changes):
    import tomllib
    raw = tomllib.loads(ROD_BASE + extra)
    for path, value in changes.items():
        table, key = path.split("__")
        raw.setdefault(table, {})[key] = value
    return validate(raw, "rod.toml")


def _final_fields(scene, tmp_path):
    from dolfin_rod.output.vtx import read_vtx
    folder = shared_folder(tmp_path) / "run"
    summary = run_scene(scene, folder, quiet=True)
    assert summary["status"] == "completed", summary["message"]
    return read_vtx(folder / "rod.bp")[-1] if MPI.COMM_WORLD.rank == 0 else None


@pytest.mark.mpi
def test_distributed_force_profile_statics(tmp_path):
    """distributed_force = {value, profile = 1 - s (the polynomial issue 13 item 14 found
    rejected)}: R n of cell [a, b] = int_a^b p(s) (s - a)/h ds + int_b^L p ds, p = q (1 - s)."""
    q = 0.2
    scene = _rod("[loads]\ndistributed_force = { type = \"step\", value = [0.2, 0.0, 0.0], "
                 "profile = { polynomial = [1.0, -1.0] } }\n")
    last = _final_fields(scene, tmp_path)
    if last is None:
        return
    a = np.linspace(0.0, 0.75, 4)
    b, h = a + 0.25, 0.25
    P = lambda s: q * (s - s**2 / 2)                        # noqa: E731 antiderivative
    Q = lambda s: q * (s**2 / 2 - s**3 / 3)                 # noqa: E731 of q (1 - s) s
    own = (Q(b) - Q(a) - a * (P(b) - P(a))) / h
    expected = own + P(1.0) - P(b)
    assert np.allclose(last["cell"]["n_spatial"][:, 0], expected, atol=1e-8)
    assert np.allclose(last["cell"]["n_spatial"][:, 1:], 0.0, atol=1e-8)


@pytest.mark.mpi
def test_start_force_on_a_rod_clamped_at_its_end(tmp_path):
    """start = free, end = clamped, start_force P: R n = -P in every cell."""
    scene = _rod('[boundary]\nstart = "free"\nend = "clamped"\n[loads]\n'
                 'start_force = { type = "ramp", value = [0.0, 0.1, 0.0], duration = 0.01 }\n')
    last = _final_fields(scene, tmp_path)
    if last is not None:
        assert np.allclose(last["cell"]["n_spatial"], [0.0, -0.1, 0.0], atol=1e-8)
        assert np.allclose(last["points"][-1], [0.0, 0.0, 1.0], atol=1e-14)   # clamped end


def test_follower_end_force_turns_with_the_end(tmp_path):
    """end_force with follower = true: P = 0.1 along the end's director d1, so every
    cell's R n is 0.1 d1(L) (and not along e_1 once the rod bends)."""
    scene = _rod("[loads]\nend_force = { type = \"step\", value = [0.1, 0.0, 0.0], "
                 "follower = true }\nend_couple = { type = \"step\", value = [0.0, 0.5, 0.0] }\n")
    last = _final_fields(scene, tmp_path)
    d1 = last["point"]["d1"][-1]
    assert abs(d1[2]) > 0.05                                  # the end has turned
    assert np.allclose(last["cell"]["n_spatial"], 0.1 * d1, atol=1e-8)


@pytest.mark.mpi
def test_prescribed_end_motion(tmp_path):
    """end_displacement and end_rotation histories: the end is where they put it."""
    scene = _rod('[boundary]\nend = "clamped"\nend_displacement = { type = "ramp", value = '
                 '[0.0, 0.0, -0.05], duration = 0.02 }\nend_rotation = { type = "table", '
                 'times = [0.0, 0.02], values = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.3]] }\n')
    last = _final_fields(scene, tmp_path)
    if last is not None:
        assert np.allclose(last["points"][-1], [0.0, 0.0, 0.95], atol=1e-12)
        assert np.allclose(last["point"]["d1"][-1], [np.cos(0.3), np.sin(0.3), 0.0],
                           atol=1e-12)


def test_rod_keys_reach_the_model():
    """Full and s-dependent tensors, I11 != I22, drag, density polynomial, models,
    constraints, supports, follower flags and initial natural strains: RodModel sees them."""
    scene = _rod(
        "[boundary]\nstart = \"pinned\"\nstart_rotation = { type = \"constant\", value = "
        "[0.0, 0.0, 0.0] }\n[loads]\ngravity = [0.0, -9.81, 0.0]\n"
        "distributed_couple = { value = [0.0, 0.0, 1.0], follower = true }\n"
        "[initial]\nnatural_curvature = [0.1, 0.0, 0.0]\n[solver]\npreset = \"jacobian_reuse\"\n"
        "options = { snes_max_it = 40 }\n",
        material__section_inertia=[0.01, 0.02], material__density={"polynomial": [1.0, 1.0]},
        material__drag=0.3, geometry__reference_stretch=[0.0, 0.0, 1.1])
    scene["material"]["stiffness"]["A"] = validate(  # a full, s-dependent tensor
        {"time": {"t_end": 1.0, "dt": 0.5}, "material": {"stiffness": {"A": {"polynomial": [
            [[2.0, 0.5, 0.0], [0.5, 2.0, 0.0], [0.0, 0.0, 1.0]], [1.0, 1.0, 1.0]]}, "B": [
            1.0, 1.0, 1.0]}, "model": "hyperelastic"}}, "t").data["material"]["stiffness"]["A"]
    sim = build(scene, "rod")
    model, p = sim.model, sim.model.params
    assert model.supports.ends == ("pinned", "free") and model.constraint is None
    quasi_static = build(_rod(material__constraints="unshearable"), "rod").model
    assert quasi_static.constraint == "unshearable"
    assert (p.section_inertia, p.drag) == ((0.01, 0.02), 0.3) and p.density(0.5) == 1.5
    assert np.allclose(np.asarray(p.A(0.5), float), [[2.5, 0.5, 0], [0.5, 2.5, 0], [0, 0, 1.5]])
    assert p.reference_stretch == (0.0, 0.0, 1.1)
    kinds = [(d.kind, d.follower) for d in model.distributed_loads]
    assert kinds == [("couple", True), ("force", False)]             # couple, then gravity
    assert np.allclose(np.asarray(model.distributed_loads[1].value(0.5), float),
                       [0.0, -9.81 * 1.5, 0.0])                       # rho_A(s) g
    assert set(model.supports.rotation) == {"start"}
    assert sim.stepper.options["snes_lag_jacobian"] == 10 and \
        sim.stepper.options["snes_max_it"] == 40
    sim.start()
    u_d = model.f["natural_curvature"].x.array.reshape(-1, 3)
    assert np.allclose(u_d, [0.1, 0.0, 0.0])


def test_user_energy_entry_point(tmp_path):
    """energy = "module:function" from the scene's folder is the psi the model uses; a
    bad one is a SceneError naming material.energy."""
    (tmp_path / "my_energy.py").write_text(
        "import ufl\n\ndef psi(u_d, v_d, u, v):\n"
        "    return 0.5 * ufl.dot(u - u_d, u - u_d) + 50.0 * ufl.dot(v - v_d, v - v_d)"
        " + 0.5 * ufl.dot(u_d, u_d)\n\ndef bad(u_d, v_d, u, v):\n    return u\n")
    text = ROD_BASE.replace("[material]", '[material]\nenergy = "my_energy:psi"')
    path = tmp_path / "rod.toml"
    path.write_text(text)
    sim = build(load_scene(path), "rod")
    import my_energy
    assert sim.model.params.energy is my_energy.psi
    path.write_text(text.replace("my_energy:psi", "my_energy:bad"))
    with pytest.raises(SceneError, match=r"\[material.energy\].*scalar"):
        build(load_scene(path), "rod")


def test_solver_options_reach_newton(tmp_path):
    """solver.options: one Newton iteration cannot solve a large-deflection step."""
    scene = _rod('[loads]\nend_force = { type = "step", value = [0.5, 0.0, 0.0] }\n'
                 '[solver]\noptions = { snes_max_it = 1 }\n', time__max_step_cuts=0)
    summary = run_scene(scene, shared_folder(tmp_path) / "run", quiet=True)
    assert summary["status"] == "failed" and "DIVERGED_MAX_IT after 1 iter" in summary["message"]


def test_adaptive_ts_scene(tmp_path):
    """integrator = "ts", ts_type = "arkimex:4", adaptive: torsion creep within the local
    error tolerance (ts_rtol = ts_atol = 1e-6; the global error after a few dozen steps
    of a contracting system stays below 1e-4)."""
    scene = _case("creep_kelvin_voigt", scene__model="torsion", time__integrator="ts",
                  time__ts_type="arkimex:4", time__adaptive=True, time__ts_rtol=1e-6,
                  time__ts_atol=1e-6, time__t_end=0.5, time__dt=0.05, outputs__plots=False,
                  outputs__fields=False, outputs__animation=False)
    summary = run_scene(scene, shared_folder(tmp_path) / "ts", quiet=True)
    assert summary["status"] == "completed" and "arkimex" in summary["method"]
    u, _ = closed_forms.creep(0.5, 1.0, 2.0, 1.0, 0.2, 0.5)
    assert abs(summary["final"]["end_rotation"] - u) < 1e-4


# --- every bundled scene runs --------------------------------------------------------------


# Bundled scenes that a test of their own runs on two ranks (against the serial run or
# the same reference): test_bundled_scene_runs runs them serially only (make test-mpi
# takes 3-6 s a scene); every other scene also runs here under mpirun.
ON_TWO_RANKS_ELSEWHERE = {
    "axial_stretching.toml":
        "test_peer_examples::test_axial_stretching_settles_at_the_closed_form",
    "butterfly.toml":
        "test_peer_examples::test_butterfly_keeps_its_centre_of_mass_and_energy",
    "vibrating_cantilever.toml":
        "test_peer_examples::test_the_cantilever_vibrates_at_timoshenko_s_frequency",
    "hanging_ring.toml":
        "test_peer_examples::test_a_ring_hanging_from_a_point_sags_by_the_closed_form",
    "beck_column.toml": "test_vibration::test_modes_command_reports_flutter",
    "bent_frame.toml": "test_rod_system_scenes::test_system_scenes_serial_equals_two_ranks",
    "cantilever_creep.toml": "test_scenes::test_quasi_static_rod_scene_resumes_exactly",
    "column_buckling_modes.toml": "test_buckling::test_buckle_command",
    "deep_arch.toml": "test_continuation::test_deep_arch_scene",
    "dna_overstretching.toml": "test_dna::test_pull_scene_under_mpirun_matches_serial",
    "double_pendulum.toml": "test_rod_system_scenes::test_system_scenes_serial_equals_two_ranks",
    "flying_beam.toml": "test_flying_beam::test_free_flying_beam_conserves_momentum_and_energy",
    "frame.toml": "test_rod_system_scenes::test_system_scenes_serial_equals_two_ranks",
    "gravity_cantilever.toml":
        "test_scenes::test_dynamic_rod_scene_runs_the_default_api_and_resumes_exactly",
    "hanging_twist.toml":
        "test_supports::test_hanging_twist_scene_carries_the_weight_serially_and_on_two_ranks",
    "helical_spring.toml":
        "test_helices::test_coil_spring_stiffness_is_the_open_coiled_closed_form",
    "helix_wrench.toml": "test_helices::test_helix_held_by_an_end_wrench",
    "hinged_door.toml": "test_rod_system_scenes::test_system_scenes_serial_equals_two_ranks",
    "inclined_clamp.toml":
        "test_oblique_supports::test_inclined_clamp_scene_serially_and_on_two_ranks",
    "lee_frame.toml": "test_continuation::test_lee_frame_from_its_scene",
    "pinched_ring.toml": "test_pinched_ring::test_pinched_ring_shortens_by_the_closed_form",
    "rope_over_thin_bar.toml":
        "test_obstacle_segments::test_rope_over_a_thin_bar_scene_rests_on_the_bar",
    "ropes_pulled_over_each_other.toml":   # its friction between rods and self-friction
        "test_pair_friction::test_static_friction_between_rods_holds (and self-friction)",
    "snap_through_arch.toml": "test_continuation::test_snap_through_scene",
    "spin_up.toml": "test_damping::test_spin_up_scene_on_two_ranks_equals_the_serial_run",
    "sprung_cantilever.toml":
        "test_supports::test_sprung_cantilever_scene_serially_and_on_two_ranks",
    "string_modes.toml": "test_vibration::test_modes_command",
    "torsion_creep.toml": "test_architecture::test_run_returns_what_it_writes (ODE), "
                          "test_cli::test_run_under_mpirun_rank0_writes (torsion PDE)",
    "torsion_relaxation.toml": "test_torsion::test_parallel_run_reproduces_serial",
    "tripod.toml": "test_rod_system_scenes::test_system_scenes_serial_equals_two_ranks",
}


# Bundled coils whose few cells would turn by more than the 2 rad a cell represents
# (the start stops naming n_cells), or, the held helix, whose start from its Kirchhoff
# helix converges at its scene's 64 cells (not at 32 or fewer with the default Jacobian
# reuse: docs/verification.md, "Helices"); a knot, whose polyline start on 8 cells is no
# knot (its chords turn by more than 2 rad between nodes and cross).
QUICK_CELLS = {"helical_spring.toml": 20, "helix_wrench.toml": 64,
               "overhand_knot_tie.toml": 100, "overhand_knot.toml": 100}


@pytest.mark.parametrize("path", [
    pytest.param(p, id=p.name, marks=() if p.name in ON_TWO_RANKS_ELSEWHERE else pytest.mark.mpi)
    for p in SCENES])
def test_bundled_scene_runs(path, tmp_path):
    """Each scenes/*.toml, a few steps on at most 8 cells (coils: QUICK_CELLS;
    tests/quick_scenes.py), writes its outputs; the physics of each is checked by the
    tests above and the demos.  Under mpirun: the scenes that no other test runs on two
    ranks (ON_TWO_RANKS_ELSEWHERE)."""
    from quick_scenes import quick_scene
    import tomllib
    data = tomllib.loads(path.read_text())
    n = min(data.get("geometry", {}).get("n_cells", 32), QUICK_CELLS.get(path.name, 8))
    # rods of [[rods]] that give their own n_cells keep them (an override would not
    # reach them: refused, tests/test_faults.py)
    cells = {} if any("n_cells" in rod.get("geometry", {}) for rod in data.get("rods", [])) \
        else {"geometry__n_cells": n}
    folder = shared_folder(tmp_path) / "run"
    first = data.get("initial", {}).get("from_run")
    starts = {}
    if first:      # a second stage: first its first stage, the scene its run folder names
        stage = quick_scene(ROOT / "scenes" / f"{Path(first).name}.toml", 3, **cells)
        assert run_scene(stage, folder.with_name("first"), quiet=True)["status"] == "completed"
        starts["initial__from_run"] = str(folder.with_name("first"))
    scene = quick_scene(path, 3, **cells, **starts)
    summary = run_scene(scene, folder, quiet=True)
    assert summary["status"] == "completed", summary["message"]
    if MPI.COMM_WORLD.rank == 0:
        files = set(json.loads((folder / "summary.json").read_text())["files"])
        assert {"timeseries.csv", "summary.json", "histories.png"} <= files
        if summary["model"] == "rod":
            assert {"rod.bp", "animation.gif", "snapshots.png"} <= files
        elif summary["model"] == "torsion":
            assert {"rod.bp", "spacetime.png"} <= files


# --- one load syntax (issue 25 item 6) ------------------------------------------------------


@pytest.mark.parametrize("old, new", [
    ("{ value = [0.0, 0.0, 2.0], history = { type = \"ramp\", value = 0.5, duration = 1.0 } }",
     "{ type = \"ramp\", value = [0.0, 0.0, 1.0], duration = 1.0 }"),
    ("{ value = [1.0, 0.0, 0.0], profile = 2.0, follower = true }",
     None),      # no history: already the new syntax (type "constant")
    ("{ value = [1.0, 0.0, 0.0], profile = 2.0, history = { type = \"table\", times = [0.0, "
     "1.0], values = [0.0, 3.0] } }",
     "{ type = \"table\", times = [0.0, 1.0], values = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], "
     "profile = 2.0 }"),
])
def test_old_distributed_load_form_is_an_error_showing_the_new_one(old, new):
    """The error's suggestion is itself a valid load with the same value(s) history(t)."""
    text = ROD_BASE + f"[loads]\ndistributed_force = {old}\n"
    if new is None:
        assert parse_scene(text)["loads"]["distributed_force"].value == (1.0, 0.0, 0.0)
        return
    with pytest.raises(SceneError) as info:
        parse_scene(text)
    assert info.value.key == "loads.distributed_force.history"
    assert info.value.reason.endswith(f"write {new}"), info.value.reason
    spec = parse_scene(ROD_BASE + f"[loads]\ndistributed_force = {new}\n")[
        "loads"]["distributed_force"]
    assert spec.vector()(0.5) == pytest.approx([0.0, 0.0, 0.5] if "ramp" in new
                                               else [1.5, 0.0, 0.0], rel=1e-15)


def test_one_load_syntax_for_end_and_distributed_loads_with_ramp_t0():
    """The same table {type, value, t0, duration, follower} at an end and along the rod
    (with profile); ramp from t0: value (t - t0)/duration."""
    load = "{ type = \"ramp\", value = [0.0, 0.0, 2.0], t0 = 1.0, duration = 0.5, follower = true"
    scene = parse_scene(ROD_BASE + f"[loads]\nend_force = {load} }}\n"
                        f"distributed_couple = {load}, profile = {{ polynomial = [1.0, 1.0] }} }}\n")
    end, distributed = scene["loads"]["end_force"], scene["loads"]["distributed_couple"]
    for spec in (end, distributed):
        assert spec.follower and spec.vector()(1.25) == pytest.approx([0.0, 0.0, 1.0])
        assert spec.vector()(1.0) == pytest.approx([0.0, 0.0, 0.0])
        assert spec.breakpoints() == (1.0, 1.5)
    assert distributed.profile(0.5) == 1.5 and end.profile is None
    with pytest.raises(SceneError, match=r"\[loads.end_force.profile\]: a profile along s"):
        parse_scene(ROD_BASE + f"[loads]\nend_force = {load}, profile = 2.0 }}\n")


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="one process of its own")
def test_a_run_without_checkpoints_does_not_import_adios4dolfinx(tmp_path):
    """run.import_finite_elements: adios4dolfinx (0.1 s of a run's start) only for runs
    that write or read checkpoints; the summary still names its version (its metadata)."""
    import subprocess
    import sys
    from importlib.metadata import version

    scene = Path(__file__).resolve().parents[1] / "scenes" / "gravity_cantilever.toml"
    code = ("import sys; sys.path.insert(0, %r); from quick_scenes import quick_scene; "
            "from dolfin_rod import run_scene; run_scene(quick_scene(%r, 2, "
            "outputs__animation=False, outputs__plots=False), %r, quiet=True); "
            "print('adios4dolfinx' in sys.modules)"
            % (str(Path(__file__).resolve().parent), str(scene), str(tmp_path / "run")))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600, check=True)
    assert done.stdout.strip().splitlines()[-1] == "False"
    data = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert data["versions"]["adios4dolfinx"] == version("adios4dolfinx")


@pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="one process of its own")
def test_a_run_imports_dolfinx_without_numba_and_leaves_numba_importable():
    """run.import_finite_elements (fem/compat.py's table: numba): DOLFINx 0.9's optional
    numba helpers are skipped while a run imports the stack, and numba imports as usual
    after it (user code, PyElastica)."""
    import subprocess
    import sys

    code = ("import sys; from dolfin_rod.run import import_finite_elements; "
            "import_finite_elements(False); skipped = 'numba' not in sys.modules; "
            "import numba; print(skipped, numba.__name__)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600, check=True)
    assert done.stdout.split() == ["True", "numba"], done.stdout + done.stderr
