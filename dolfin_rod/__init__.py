"""dolfin_rod: special Cosserat rods with evolving natural configurations in FEniCSx.

The public API (what a user imports); names load on first use, so ``import dolfin_rod``
stays cheap (e.g. for ``dolfin-rod check``):

    from dolfin_rod import RodModel, RodParameters, EndLoad, TimeStepper, loads
    model = RodModel(RodParameters(density=1.0, section_inertia=0.01),
                     start="clamped", end="free", end_loads=[EndLoad("force", (1, 0, 0))])
    model.set_initial_state()
    TimeStepper(model.problem).run(0.0, 1.0, 0.01, observer)   # the defaults: fast
"""

from importlib import import_module

__version__ = "0.1.0"

# a run of a scene: dolfin_rod.run("scene.toml", overrides) (run.py; bound here, as the
# package attribute ``run`` would otherwise be the module once it is imported)
from .run import RunResult, analyse, run, run_scene  # noqa: E402

_WHERE = {
    # models and their data
    "RodModel": "rod", "RodParameters": "rod", "EndLoad": "rod", "DistributedLoad": "rod",
    "PointLoad": "rod", "TravellingWave": "rod",    # a muscle's active moment
    "StartingState": "rod", "Straight": "rod", "Arc": "rod", "Helix": "rod", "Polyline": "rod",
    "EndSpring": "rod",
    "RodSystem": "rod", "Rod": "rod", "Joint": "rod",   # rod systems (docs/systems.md)
    "sections": "rod",      # cross-sections and materials -> RodParameters (rod/sections.py)
    "Obstacle": "rod", "ContactLaw": "rod",    # contact with obstacles (docs/contact.md)
    "TorsionModel": "torsion.model", "TorsionParameters": "torsion.model",
    "SemiDiscreteProblem": "fem.problem", "SecondOrderProblem": "fem.problem",
    # equilibria: buckling and vibration modes (docs/stability.md)
    "buckling_modes": "analysis.buckling", "BucklingModes": "analysis.buckling",
    "vibration_modes": "analysis.vibration", "VibrationModes": "analysis.vibration",
    # integrators and solvers
    "TimeStepper": "integrators.choice", "choose_integrator": "integrators.choice",
    "TSIntegrator": "integrators.ts", "parse_ts_type": "integrators.ts",
    "get_scheme": "integrators.schemes",
    "IntegrationError": "integrators.step_control", "SolverError": "fem.solvers",
    "JACOBIAN_REUSE": "fem.solvers", "NATIVE_LU": "fem.solvers",
    # scenes: load, choose the model, build, run
    "load_scene": "scenes", "parse_scene": "scenes", "select_model": "scenes",
    "build": "scenes", "SceneError": "scenes",
    # what a run writes: fields along the rod (ParaView, animation), versions
    "FieldOutputs": "output.field_outputs", "read_vtx": "output.vtx", "versions": "output.writer",
    "read_pvd": "output.vtk_xml", "redraw": "output.redraw",
    "load_state": "output.from_run",    # a model put in a run's saved state (docs/scenes.md)
    # fitting parameters to measured time series (docs/fitting.md)
    "fit_scene": "fit.least_squares", "FitResult": "fit.least_squares",
    "prepare_fit": "fit.least_squares", "run_fit": "fit.least_squares",
    "FitError": "fit.least_squares",
    "read_series": "fit.inputs",
}
# modules users import as a whole: name -> where it lives
_MODULES = {"loads": "loads", "closed_forms": "torsion.closed_forms",
            "rotations": "theory.rotations", "dna": "dna",
            "form_cache": "fem.form_cache",   # form_cache.clear(): time a fresh process
            "cosseratbench": "adapters.cosseratbench",   # the cosseratbench solver (extra [bench])
            "pair_contact": "rod.pair_contact",   # segment contact: pairs, pair_energy (docs/contact.md)
            "linking": "rod.linking",   # writhe, twist, linking number of polygons (docs/contact.md)
            "triangle_mesh": "rod.triangle_mesh"}   # mesh obstacles' surfaces (docs/contact.md)

__all__ = sorted([*_WHERE, "run", "run_scene", "analyse", "RunResult"]) + list(_MODULES)


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(import_module(f".{_WHERE[name]}", __name__), name)
    if name in _MODULES:
        return import_module(f".{_MODULES[name]}", __name__)
    raise AttributeError(f"module 'dolfin_rod' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
