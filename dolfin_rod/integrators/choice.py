"""The one place that picks the integrator of a problem.

    TimeStepper(model.problem).run(0.0, 1.0, 0.01, observer)     # the one-liner
    integrator = choose_integrator(model.problem, "bdf2")          # the same, explicitly

``choose_integrator`` picks, in this order:

* ``ts_type`` given (a scene's ``integrator = "ts"``): PETSc TS (ts.py, ``TSIntegrator``)
  on the same residual;
* a SecondOrderProblem (a rod with rotation-vector unknowns, rod/model.py):
  generalized-alpha on the rotation group (lie_alpha.py), unless it has no second-order
  block and a per-step scheme is named (a quasi-static rod: its rotation increments are
  algebraic, ``per_step_schemes``);
* otherwise the per-step scheme (stepper.py, ``SchemeStepper``; default BDF2, the scene's
  ``time.scheme``).

``tolerance`` (e.g. 1e-3) switches the error-controlled steps of the rotation-group
integrator on; None keeps run's fixed dt.  ``TimeStepper`` is the user-facing one-liner:
it holds the chosen integrator (``.integrator``) and every attribute is that
integrator's (run, step, stats, description, checkpoint_state, ...).
"""

from __future__ import annotations

from ..checks import MAX_STEP_CUTS, PREDICTOR, old_keywords
from ..fem.problem import SecondOrderProblem, SemiDiscreteProblem
from .lie_alpha import LieGeneralizedAlpha
from .schemes import get_scheme
from .stepper import SchemeStepper
from .ts import TSIntegrator

__all__ = ["TimeStepper", "choose_integrator", "on_rotation_group"]


def on_rotation_group(problem: SemiDiscreteProblem, scheme: str | None) -> bool:
    """Whether generalized-alpha on the rotation group advances ``problem`` (see the
    module's docstring)."""
    return isinstance(problem, SecondOrderProblem) and not (
        problem.per_step_schemes and scheme is not None
        and not scheme.startswith("generalized_alpha"))


OLD_CUTS = {"max_cuts": "max_step_cuts"}     # deprecated keyword (docs/rod.md)


def _step_cuts(old: dict) -> dict:
    """max_step_cuts of the deprecated max_cuts."""
    return {"max_step_cuts": old["max_cuts"]}


@old_keywords("choose_integrator", OLD_CUTS, _step_cuts)
def choose_integrator(problem: SemiDiscreteProblem, scheme: str | None = None,
                      solver_options: dict | None = None,
                      max_step_cuts: int = MAX_STEP_CUTS,
                      predictor: str = PREDICTOR, tolerance: float | None = None,
                      ts_type: str | None = None, **ts_options):
    """The integrator of ``problem`` (the module's docstring); ``ts_options`` are
    TSIntegrator's keywords (adaptive, rtol, atol, ...).  An unknown scheme name is
    refused first (ValueError), before the problem is looked at."""
    if scheme is not None:
        get_scheme(scheme)
    if problem.terms and ts_type is not None:
        raise ValueError("terms assembled outside the forms (a rod's segment contact, "
                         "contact.self / contact.between_rods, or an obstacle's on the "
                         "segments, obstacles[k].contact) are not solved by PETSc TS "
                         "(ts_type): its residual and Jacobian callbacks see the forms "
                         "only; a per-step scheme (time.scheme) or generalized-alpha")
    if ts_type is not None:
        return TSIntegrator(problem, ts_type, solver_options=solver_options, **ts_options)
    if on_rotation_group(problem, scheme):
        return LieGeneralizedAlpha.for_scheme(problem, scheme, solver_options,
                                              max_step_cuts, tolerance)
    return SchemeStepper(problem, scheme, solver_options, max_step_cuts, predictor,
                         tolerance)


class TimeStepper:
    """``TimeStepper(problem, scheme=None, solver_options=None, max_step_cuts=6,
    predictor="linear", tolerance=None)``: the integrator that ``choose_integrator``
    picks for the problem, held as ``.integrator``; its attributes are read and set
    through this object."""

    PREDICTORS = SchemeStepper.PREDICTORS

    @old_keywords("TimeStepper", OLD_CUTS, _step_cuts)
    def __init__(self, problem: SemiDiscreteProblem, scheme: str | None = None,
                 solver_options: dict | None = None, max_step_cuts: int = MAX_STEP_CUTS,
                 predictor: str = PREDICTOR, tolerance: float | None = None):
        object.__setattr__(self, "integrator", choose_integrator(
            problem, scheme, solver_options, max_step_cuts, predictor, tolerance))

    def __getattr__(self, name: str):
        if name == "integrator":            # (not built: its constructor raised)
            raise AttributeError(name)
        return getattr(self.integrator, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self.integrator, name, value)
