"""dolfin_rod as a cosseratbench solver (issue 25 item 7, dolfin_rod/adapters/cosseratbench.py): the
four validation experiments run through cosseratbench's own ``experiment.run`` (its
warm-up, timing and metrics) at small resolution, each metric within what its reference
allows; what the adapter cannot map is reported as unsupported, naming it."""

from __future__ import annotations

import tomllib
from importlib import import_module
from pathlib import Path

import pytest
from cosseratbench import registry
from cosseratbench.experiment import COMPLETED, UNSUPPORTED, run

from dolfin_rod.adapters.cosseratbench import DolfinRodSolver

ROOT = Path(__file__).resolve().parents[1]

# (experiment, cells, {metric: bound}) with the bounds the references allow:
# cantilever: Euler-Bernoulli, geometric nonlinearity and shear each < 0.1 % (its
#   docstring): 1e-3 (dolfin_rod: 2.1e-4 at 20 cells, 2.1e-3 at 10); settled: < 1e-4 L/s;
# catenary: the elastic catenary without bending, which moves the 0.8 m span's shape by
#   a few 1e-4 (the slack 0.6 m span's by up to 1 %): 1e-3 of L for the shape, 2e-3
#   for the sag depth (dolfin_rod at 20 cells: 5.2e-4, 8.6e-4);
# pendulum: the linear first mode, whose period is off by 2e-5 at this amplitude: the
#   solver's own errors below 1e-3 (12 cells: 1.7e-4 period, 1.2e-4 amplitude);
# twist: the growth-rate fit, its own uncertainty ~0.5 % (its docstring): 2 % (20 cells:
#   0.98 %, 12 cells: 2.2 %).
CASES = [
    ("cantilever", 20, {"tip_deflection_error": 1e-3, "settling_residual": 1e-4}),
    ("catenary", 20, {"shape_error": 1e-3, "sag_error": 2e-3, "settling_residual": 1e-4}),
    ("pendulum", 12, {"period_error": 1e-3, "amplitude_change": 1e-3}),
    ("twist", 20, {"critical_twist_error": 2e-2}),
]


@pytest.mark.parametrize("name, cells, bounds", CASES, ids=[c[0] for c in CASES])
def test_validation_experiment_within_its_reference(name, cells, bounds):
    result = run(registry.load_experiment(name), DolfinRodSolver(), n_elements=cells)
    assert result.outcome == COMPLETED, result.failure or result.missing
    for metric, bound in bounds.items():
        assert abs(result.metrics[metric]) < bound, (metric, result.metrics)


def test_obstacles_are_reported_unsupported_by_name():
    """A scenario with obstacles (the capstan's cylinder): cosseratbench does not run it
    (the adapter claims no contact capability), and the adapter itself, called
    directly, raises NotImplementedError naming them."""
    experiment = registry.load_experiment("capstan")
    result = run(experiment, DolfinRodSolver(), n_elements=4, n_frames=2)
    assert result.outcome == UNSUPPORTED and "cylinder_contact" in result.missing
    with pytest.raises(NotImplementedError, match="obstacles \\(cylinder\\)"):
        DolfinRodSolver().run(experiment.scenario, n_elements=4, n_frames=2)


def test_entry_point_names_the_adapter():
    """pyproject.toml registers the adapter for cosseratbench (group
    cosseratbench.solvers) and the optional dependency [bench]."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    target = project["entry-points"]["cosseratbench.solvers"]["dolfin_rod"]
    module, name = target.split(":")
    assert getattr(import_module(module), name) is DolfinRodSolver
    assert any(dep.startswith("cosseratbench") for dep in project["optional-dependencies"]
               ["bench"])
