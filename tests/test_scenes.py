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
from dolfin_rod.cli import run_scene
from dolfin_rod.scenes import SceneError, build, load_scene, parse_scene, select_model, validate

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
                  "cantilever_creep.toml": "rod", "gravity_cantilever.toml": "rod",
                  "twisted_rod_relaxation.toml": "rod"}


@pytest.mark.parametrize("path", SCENES, ids=[p.name for p in SCENES])
def test_bundled_scenes_are_valid(path):
    scene = load_scene(path)
    assert select_model(scene).model == BUNDLED_MODELS[path.name]


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
    (BASE.replace("mu_d = 0.5", 'mu_d = 0.5\nvariant = "uniform"\nenergy = "kelvin_voigt"'),
     "material.variant", "kelvin_voigt"),
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
    sim = build(scene, model)
    sim.start()
    dt, n = scene["time"]["dt"], round(scene["time"]["t_end"] / scene["time"]["dt"])
    out = [sim.diagnostics(0.0)]
    for k in range(1, n + 1):
        sim.advance((k - 1) * dt, k * dt)
        out.append(sim.diagnostics(k * dt))
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
    with open(path) as f:
        return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]


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
def test_fe_run_writes_everything(tmp_path):
    folder = shared_folder(tmp_path) / "run"
    scene = _case("creep_kelvin_voigt", scene__model="torsion", time__t_end=0.05)
    summary = run_scene(scene, folder, quiet=True)
    assert summary["status"] == "completed" and summary["model"] == "torsion"
    if MPI.COMM_WORLD.rank == 0:
        for name in ("timeseries.csv", "timeseries.json", "summary.json", "timings.json",
                     "histories.png", "fields/twist_angle.bp", "fields/natural_twist.bp"):
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
