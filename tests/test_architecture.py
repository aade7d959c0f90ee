"""The package's layout rules (docs/architecture.md) and the one-room run.

References: the import graph read from the source (every import, also inside functions),
the modules a fresh interpreter has loaded after the cheap commands, the schema's
defaults, the files a run writes and Section 5's creep closed form.
"""

from __future__ import annotations

import ast
import inspect
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import dolfin_rod
from dolfin_rod import closed_forms, loads

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "dolfin_rod"
# a layer imports only its own and later ones (docs/architecture.md)
LAYERS = [("cli", "__main__", "adapters"), ("fit",), ("run",), ("output",), ("scenes",), ("analysis",),
          ("rod", "torsion"), ("integrators",), ("theory",), ("fem",),
          ("loads", "dna", "checks", "mpi")]
HEAVY = ("dolfinx", "petsc4py", "ufl", "basix", "ffcx")


def _module(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return (path / "__init__.py").exists() or path.with_suffix(".py").exists()


def _imports(path: Path) -> set[str]:
    """The dolfin_rod modules ``path`` imports anywhere in it (a name imported from a
    package counts as the package unless it is a module; the package version is an
    attribute of the package, which Python imports before any of its modules)."""
    me = _module(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("dolfin_rod")}
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[:len(package.split(".")) - node.level + 1] \
                if node.level else []
            source = ".".join(base + ([node.module] if node.module else []))
            if not source.startswith("dolfin_rod"):
                continue
            for alias in node.names:
                if _is_module(f"{source}.{alias.name}"):
                    found.add(f"{source}.{alias.name}")
                elif not (source == "dolfin_rod" and alias.name == "__version__"):
                    found.add(source)
    return found


GRAPH = {_module(p): _imports(p) for p in PACKAGE.rglob("*.py")}


def _layer(name: str) -> int:
    short = name.removeprefix("dolfin_rod.").split(".")[0]
    return next(i for i, layer in enumerate(LAYERS) if short in layer)


def test_no_import_cycle():
    """No module reaches itself through the imports of others (function-level ones
    included): a depth-first search for a back edge."""
    state: dict[str, int] = {}

    def visit(name: str, path: list[str]) -> None:
        state[name] = 1
        for other in sorted(GRAPH.get(name, ())):
            assert state.get(other) != 1, " -> ".join([*path, name, other])
            if other in GRAPH and other not in state:
                visit(other, [*path, name])
        state[name] = 2

    for name in sorted(GRAPH):
        if name not in state:
            visit(name, [])
    assert len(GRAPH) > 50                      # the walk saw the package


def test_layers_import_downwards_only():
    """Nothing below scenes/ imports scenes, run, cli, output or fit; cli is imported by
    __main__ only; every import goes to the same or a lower layer."""
    upward = [(a, b) for a, targets in GRAPH.items() if a != "dolfin_rod"
              for b in targets if b != "dolfin_rod" and _layer(b) < _layer(a)]
    assert upward == []
    assert [a for a, targets in GRAPH.items() if "dolfin_rod.cli" in targets] == \
        ["dolfin_rod.__main__"]


def test_top_level_and_private_attributes():
    """At most 8 modules directly in dolfin_rod/ (the public face, run and shared
    helpers); DOLFINx's C++ objects only in fem/compat.py."""
    assert len(list(PACKAGE.glob("*.py"))) <= 8, sorted(p.name for p in PACKAGE.glob("*.py"))
    users = sorted(str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                   if "_cpp_object" in p.read_text())
    assert users == ["fem/compat.py"]


# a dolfin_rod import written in text: Markdown code, a command string of a benchmark
TEXT_IMPORT = re.compile(r"(?:from\s+(dolfin_rod[\w.]*)\s+import\s+([\w ,]+|\([\w ,\n]+\)))"
                         r"|^\s*import\s+(dolfin_rod[\w.]*)", re.M)


def test_demos_benchmarks_and_docs_use_the_public_api():
    """Every dolfin_rod import of demos/, benchmarks/, docs/ and examples/ (Python, also
    inside strings, and the Markdown of docs/ and README.md) names dolfin_rod itself and
    only names in its __all__."""
    public = set(dolfin_rod.__all__)
    files = [p for d in ("demos", "benchmarks", "docs", "examples") for p in (ROOT / d).rglob("*.py")]
    assert len(files) > 10
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("dolfin_rod"):
                assert node.module == "dolfin_rod", f"{path}: from {node.module} import"
                assert {a.name for a in node.names} <= public, path
            if isinstance(node, ast.Import):
                assert all(not a.name.startswith("dolfin_rod.") for a in node.names), path
    texts = files + [*(ROOT / "docs").rglob("*.md"), ROOT / "README.md"]
    for path in texts:
        for module, names, plain in TEXT_IMPORT.findall(path.read_text()):
            assert (module or "dolfin_rod") == "dolfin_rod" and plain in ("", "dolfin_rod"), \
                (path, module or plain)
            assert {n.split(" as ")[0].strip() for n in names.strip("()").split(",")} - {""} \
                <= public, (path, names)


def _loaded_after(argv_lists: list[list[str]], tmp_path) -> tuple[list, list[str], str]:
    """Exit statuses, heavy packages loaded and output of ``main(argv)`` for each argv in
    a fresh interpreter (--help's SystemExit counts as its status)."""
    code = (
        "import contextlib, io, json, sys\n"
        "from dolfin_rod.cli import main\n"
        "codes, out = [], io.StringIO()\n"
        "with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):\n"
        "    for argv in json.loads(sys.argv[1]):\n"
        "        try:\n"
        "            codes.append(main(argv))\n"
        "        except SystemExit as done:\n"
        "            codes.append(done.code)\n"
        f"heavy = sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r}))\n"
        "print(json.dumps([codes, heavy, out.getvalue()]))\n")
    done = subprocess.run([sys.executable, "-c", code, json.dumps(argv_lists)], cwd=ROOT,
                          capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_cheap_commands_load_no_dolfinx_petsc_or_ufl(tmp_path):
    """``dolfin-rod check`` of every bundled scene, ``schema`` and ``--help`` in a fresh
    interpreter work and never import DOLFINx, PETSc, UFL, Basix or FFCx (the DNA scenes'
    energy is checked by its derivatives in numpy, dna.py; a rod system's joints are
    placed and checked in numpy, rod/joint_points.py; solver options that only this
    package reads, such as tests/test_helices.py's full Newton, are not probed on PETSc:
    checks.probed_options)."""
    scenes = sorted((ROOT / "scenes").glob("*.toml"))
    assert any("\nenergy = " in s.read_text() for s in scenes)    # the DNA scenes are in
    assert sum("[[rods]]" in s.read_text() for s in scenes) >= 5   # and the rod systems
    own_options = tmp_path / "own_solver_options.toml"
    own_options.write_text((ROOT / "scenes/helix_wrench.toml").read_text() + "\n[solver]\n"
                           "options = { jacobian_reuse_ratio = 0, linesearch_fallback = 'bt' }\n")
    scenes.append(own_options)
    out = str(tmp_path / "out")
    argv = [["check", str(s), "--out", out] for s in scenes] + \
        [["schema"], ["--help"], ["run", "--help"], ["fit", "--help"]]
    codes, heavy, text = _loaded_after(argv, tmp_path)
    assert codes == [0] * len(argv) and heavy == [], (codes, heavy)
    assert text.count(": OK") == len(scenes) >= 19


PAIR = """[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 1.0], B = [100.0, 100.0, 100.0] }
density = 1.0
section_inertia = [0.01, 0.01]
[[rods]]
name = "a"
geometry = { length = 1.0, n_cells = 4 }
[[rods]]
name = "b"
position = [0.0, 0.0, 1.0]
geometry = { length = 1.0, n_cells = 4 }
boundary = { start = "free" }
[[joints]]
kind = "ball"
rods = ["a", "b"]
point = [0.0, 0.0, 1.0]
[time]
t_end = 0.1
dt = 0.05
"""
# a third rod "c" at b's place, hinged to a where b is joined to it
THIRD = PAIR[PAIR.index("[[rods]]\nname = \"b\""):PAIR.index("[time]")].replace(
    "\"b\"", "\"c\"").replace("ball", "hinge") + "axis = [1.0, 0.0, 0.0]\n"
SPIN = "initial = { angular_velocity = [0.0, 1.0, 0.0], rotation_centre = [0.0, 0.0, 0.0] }\n"


@pytest.mark.parametrize("change, message", [
    (("point = [0.0, 0.0, 1.0]", "point = [0.0, 0.0, 0.5]"),
     "[joints[0].point]: [0.0, 0.0, 0.5] is not on rod 'b'"),
    (("boundary = { start = \"free\" }", "boundary = { start = \"clamped\" }"),
     "[joints[0]]: rod 'b' is supported at its start"),
    (("kind = \"ball\"", "kind = \"hinge\""), "[joints[0].axis]: is missing"),
    (("kind = \"ball\"", "kind = \"hinge\"\naxis = [0.0, 2.0, 0.0]"),
     "[joints[0].axis]: must be a unit vector"),
    (("kind = \"ball\"", "kind = \"rigid\"\naxis = [0.0, 1.0, 0.0]"),
     "[joints[0].axis]: is a hinge's"),
    (("kind = \"ball\"", "kind = \"rigid\""), None),
    (("point = [0.0, 0.0, 1.0]\n", "point = [0.0, 0.0, 1.0]\n" + THIRD),
     "[joints[1]]: a hinge joins two nodes"),
    (("boundary = { start = \"free\" }", "boundary = { start = \"free\" }\n" + SPIN),
     "start: joints[0] (a-b): the starting states give its two rods a different velocity"),
    (("name = \"a\"", "name = \"a\"\ninitial = { orientation = [0.0, 0.2, 0.0] }"),
     "start: joints[0] (a-b): the starting states give its two rods a different position"),
])
def test_cheap_check_refuses_the_joints_the_api_refuses(tmp_path, change, message):
    """The bad joints of tests/test_joints.py, test_hinge.py and test_system_start.py as
    scenes: ``dolfin-rod check`` refuses each with exit 2 and the API's message
    (rod/joint_points.py on the scene's placement.PlacedRods), loading no DOLFINx; the
    good ones (``None``) pass."""
    path = tmp_path / "pair.toml"
    path.write_text(PAIR.replace(*change))
    codes, heavy, text = _loaded_after([["check", str(path), "--out", str(tmp_path)]],
                                       tmp_path)
    assert heavy == [] and codes == [2 if message else 0], (codes, heavy, text)
    assert message in text if message else ": OK" in text, text


def test_one_default_per_scene_key():
    """Every API argument for a scene key's quantity has the schema's default (one value,
    checks.py): the models, the integrators, the ODE's time, the solver's tolerances."""
    from dolfin_rod import (RodModel, RodSystem, TimeStepper, TorsionModel, TorsionParameters,
                            TSIntegrator)
    from dolfin_rod import FieldOutputs, choose_integrator
    from dolfin_rod.analysis.stability import StabilityMonitor
    from dolfin_rod.checks import NEWTON_ATOL
    from dolfin_rod.fem.solvers import DEFAULT_OPTIONS
    from dolfin_rod.integrators.lie_alpha import LieGeneralizedAlpha
    from dolfin_rod.integrators.stepper import SchemeStepper
    from dolfin_rod.rod import Rod, RodParameters, StartingState
    from dolfin_rod.rod.contact import Obstacle
    from dolfin_rod.scenes import SCHEMA
    from dolfin_rod.torsion.ode import OdeTime

    def default(func, name):
        return inspect.signature(func).parameters[name].default

    pairs = [(RodModel.__init__, "n_cells", "geometry.n_cells"),
             (Rod.__init__, "n_cells", "geometry.n_cells"),
             (TorsionModel.__init__, "n_cells", "geometry.n_cells"),
             (TorsionModel.__init__, "degree", "geometry.degree"),
             (RodParameters, "length", "geometry.length"),
             (RodParameters, "reference_curvature", "geometry.reference_curvature"),
             (RodParameters, "reference_stretch", "geometry.reference_stretch"),
             (StartingState, "equilibrium", "initial.equilibrium"),
             (Obstacle, "friction", "obstacles.friction"),
             *[(cls.__init__, arg, key) for cls in (RodModel, RodSystem)
               for arg, key in (("rotations", "geometry.rotations"),
                                ("variant", "material.variant"), ("model", "material.model"))],
             (TorsionModel.__init__, "variant", "material.variant"),
             *[(func, "max_step_cuts", "time.max_step_cuts") for func in (
                 TimeStepper.__init__, choose_integrator)],
             *[(func, "max_cuts", "time.max_step_cuts") for func in (
                 SchemeStepper.__init__, LieGeneralizedAlpha.__init__)],
             *[(func, "predictor", "time.predictor") for func in (
                 TimeStepper.__init__, choose_integrator, SchemeStepper.__init__)],
             (TSIntegrator.__init__, "adaptive", "time.adaptive"),
             (TSIntegrator.__init__, "rtol", "time.ts_rtol"),
             (TSIntegrator.__init__, "atol", "time.ts_atol"),
             (OdeTime, "solution", "time.ode_solution"),
             (OdeTime, "scheme", "time.scheme"),
             (StabilityMonitor.__init__, "lowest", "stability.lowest_eigenvalue"),
             (FieldOutputs.__init__, "fields", "outputs.fields"),
             (FieldOutputs.__init__, "animation", "outputs.animation")]
    for func, arg, key in pairs:
        table, name = key.split(".")
        want = SCHEMA[table][name].default
        assert default(func, arg) == (tuple(want) if isinstance(want, list) else want), \
            (func, arg, key)
    # the ends; the scene's "none" constraint is the API's None
    for func in (RodModel.__init__, Rod.__init__):
        assert (default(func, "start"), default(func, "end")) == \
            (SCHEMA["boundary"]["start"].default, SCHEMA["boundary"]["end"].default)
    assert SCHEMA["material"]["constraints"].default == "none" and \
        default(RodModel.__init__, "constraints") is None
    # the Newton tolerances: time.rtol; time.atol not given is the API's default too,
    # scaled by the problem's forces (solvers.ForceScale), absolute without a scale;
    # the scheme of a first-order form
    assert DEFAULT_OPTIONS["snes_rtol"] == SCHEMA["time"]["rtol"].default
    assert SCHEMA["time"]["atol"].default is None and DEFAULT_OPTIONS["snes_atol"] == NEWTON_ATOL
    torsion = TorsionModel(TorsionParameters(), n_cells=4, end_torsion=loads.step(1.0))
    assert TimeStepper(torsion.problem).integrator.scheme.name == SCHEMA["time"]["scheme"].default


def _rod(rotations: str, dynamic: bool):
    from dolfin_rod import EndLoad, RodModel, RodParameters
    inertia = dict(density=1.0, section_inertia=0.01) if dynamic else {}
    model = RodModel(RodParameters(**inertia), n_cells=4, model="hyperelastic",
                     end_loads=[EndLoad("force", (0.1, 0.0, 0.0), loads.ramp(1.0, 1.0))],
                     rotations=rotations)
    model.set_initial_state()
    return model


def test_time_stepper_delegates_to_the_chosen_integrator():
    """TimeStepper(problem) holds what choose_integrator picks (rotation group for a
    dynamic rod on rotation vectors, per-step schemes otherwise) and runs it bit for bit
    as the integrator built directly."""
    from dolfin_rod import TimeStepper, choose_integrator
    from dolfin_rod.integrators.lie_alpha import LieGeneralizedAlpha
    from dolfin_rod.integrators.stepper import SchemeStepper
    cases = [("rotation_vector", True, None, LieGeneralizedAlpha),
             ("rotation_vector", False, "bdf2", SchemeStepper),
             ("quaternion", True, "bdf2", SchemeStepper)]
    for rotations, dynamic, scheme, kind in cases:
        a, b = _rod(rotations, dynamic), _rod(rotations, dynamic)
        stepper = TimeStepper(a.problem, scheme)
        assert type(stepper.integrator) is kind
        stepper.run(0.0, 0.2, 0.05)
        choose_integrator(b.problem, scheme).run(0.0, 0.2, 0.05)
        assert stepper.stats.steps == 4
        assert np.array_equal(a.f["displacement"].x.array, b.f["displacement"].x.array)
        assert np.abs(a.f["displacement"].x.array).max() > 1e-3        # the rod moved
    stepper.max_cuts = 2                         # attributes are the integrator's
    assert stepper.integrator.max_cuts == 2


@pytest.mark.mpi
def test_run_returns_what_it_writes(tmp_path):
    """dolfin_rod.run(file, overrides) = run(Scene, overrides): the summary and the time
    series of the run folder, the same on every rank; the ODE's creep is Section 5's
    closed form (eq. creepform, errata 2) to round-off."""
    comm = MPI.COMM_WORLD
    out = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    changes = {"scene.model": "ode", "time.t_end": 0.5, "outputs.fields": False,
               "outputs.plots": False, "outputs.animation": False}
    first = dolfin_rod.run(ROOT / "scenes" / "torsion_creep.toml", changes, out=out / "a",
                           quiet=True)
    scene = dolfin_rod.load_scene(ROOT / "scenes" / "torsion_creep.toml")
    second = dolfin_rod.run(scene, changes, out=out / "b", quiet=True)
    assert first.status == second.status == "completed"
    assert first.series == second.series
    assert first.summary["t_end_reached"] == 0.5 and first.folder == out / "a"
    if comm.rank == 0:
        assert json.loads((out / "a" / "timeseries.json").read_text()) == first.series
    assert comm.allgather(first.series["end_rotation"][-1]) == \
        [first.series["end_rotation"][-1]] * comm.size
    mat = scene["material"]
    t = np.array(first.series["time"])
    m0 = scene["loads"]["end_torsion"].value
    u, _ = closed_forms.creep(t, m0, *(mat[k].constant for k in ("alpha", "alpha_d", "mu",
                                                                  "mu_d")))
    assert np.allclose(first.series["end_rotation"], u, rtol=0, atol=1e-12)


def test_architecture_doc_names_every_module():
    """docs/architecture.md, regrouped by folder, has a row for every module of the
    package (a new module is placed in its layer's table when it is added)."""
    doc = (ROOT / "docs" / "architecture.md").read_text()
    modules = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
               if p.name != "__init__.py"]
    assert len(modules) > 80
    assert [m for m in modules if f"`{m}`" not in doc] == []
    assert "## Where to add X" in doc
