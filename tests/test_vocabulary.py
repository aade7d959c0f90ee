"""One vocabulary (issue 29 item 1, docs/rod.md): the API's keywords are the scene's keys;
each old keyword still works for one release, with a DeprecationWarning naming the new
one, and gives the same model: the reference is the same model built with the new
names, whose runs must agree to the bit (the same numbers reach the same forms)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dolfin_rod import (EndLoad, Rod, RodModel, RodParameters, RodSystem, TimeStepper,
                        choose_integrator, loads, sections)

STIFF = dict(A=(1.0, 1.0, 1.0), B=(100.0, 100.0, 100.0))


def _old(call, new_name: str):
    """call() under a DeprecationWarning that names ``new_name``; its result."""
    with pytest.warns(DeprecationWarning, match=new_name) as seen:
        result = call()
    assert all(w.filename == __file__ for w in seen if w.category is DeprecationWarning), \
        "the warning must point at the caller's line"
    return result


def _new(call):
    """call() without any DeprecationWarning; its result."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        return call()


def test_rod_parameters_take_the_scene_names():
    """density = rho_A; section_inertia = (I11, I22) (one number: both); the old fields
    read back the new ones."""
    assert _old(lambda: RodParameters(rho_A=2.5), "density") == \
        _new(lambda: RodParameters(density=2.5))
    assert _old(lambda: RodParameters(I11=0.01, I22=0.02), "section_inertia") == \
        _new(lambda: RodParameters(section_inertia=(0.01, 0.02)))
    assert _old(lambda: RodParameters(I11=0.03), "section_inertia").section_inertia == \
        (0.03, 0.0)
    assert _new(lambda: RodParameters(section_inertia=0.04)).section_inertia == (0.04, 0.04)
    params = RodParameters(density=3.0, section_inertia=(0.1, 0.2))
    assert (_old(lambda: params.rho_A, "density"), _old(lambda: params.I11, "section_inertia"),
            _old(lambda: params.I22, "section_inertia")) == (3.0, 0.1, 0.2)
    steel = sections.Material(youngs_modulus=2e11, poisson_ratio=0.3, density=7850.0)
    keys = _new(lambda: sections.section_parameters(sections.circle(0.01), steel))
    area, I = np.pi * 1e-4, np.pi * 1e-8 / 4          # a circle of radius 1 cm
    assert keys["density"] == pytest.approx(7850.0 * area, rel=1e-14)
    assert keys["section_inertia"] == pytest.approx((7850.0 * I, 7850.0 * I), rel=1e-14)


def test_old_and_new_names_together_or_unknown_are_refused():
    with pytest.raises(TypeError, match="density or the deprecated rho_A"):
        with pytest.warns(DeprecationWarning):
            RodParameters(rho_A=1.0, density=1.0)
    with pytest.raises(TypeError, match="start or the deprecated ends"):
        with pytest.warns(DeprecationWarning):
            RodModel(RodParameters(), 4, ends=("clamped", "free"), start="pinned")
    with pytest.raises(TypeError, match="unexpected keyword argument 'rho'"):
        RodParameters(rho=1.0)
    with pytest.raises(ValueError, match="section_inertia must be one value"):
        RodParameters(section_inertia=(1.0, 2.0, 3.0))


def test_rod_and_system_take_start_end_and_constraints():
    params = RodParameters(**STIFF)
    assert _old(lambda: Rod(params, 4, ends=("pinned", "clamped")), "start=") == \
        _new(lambda: Rod(params, 4, start="pinned", end="clamped"))
    assert _old(lambda: Rod(params, 4, ("pinned", "clamped")), "start=") == \
        _new(lambda: Rod(params, 4, "pinned", end="clamped"))      # ends by its position
    rod = Rod(params, 4, start="pinned", end="free")
    assert rod.ends == ("pinned", "free")
    by_position = _old(lambda: RodModel(params, 4, "hyperelastic", "local", None,
                                        ("clamped", "pinned")), "start=")
    assert by_position.rods[0] == Rod(params, 4, start="clamped", end="pinned")
    old = _old(lambda: RodSystem([Rod(params, 4)], constraint="unshearable"), "constraints")
    new = _new(lambda: RodSystem([Rod(params, 4)], constraints="unshearable"))
    assert old.problem.structure == new.problem.structure is not None


def _quasi_static(**names):
    model = RodModel(RodParameters(**STIFF), n_cells=4, model="hyperelastic",
                     end_loads=[EndLoad("couple", (0.0, 0.3, 0.0), loads.ramp(1.0, 1.0))],
                     **names)
    model.set_initial_state()
    return model


def _dynamic(**inertia):
    model = RodModel(RodParameters(**STIFF, **inertia), n_cells=4, model="hyperelastic",
                     end_loads=[EndLoad("force", (0.1, 0.0, 0.0), loads.ramp(1.0, 1.0))])
    model.set_initial_state()
    return model


def _same_state(a, b) -> None:
    """Every field of the two models equal to the bit, and the rod moved."""
    for name in a.f:
        assert np.array_equal(a.f[name].x.array, b.f[name].x.array), name
    assert np.abs(a.f["displacement"].x.array).max() > 1e-4     # well above round-off


def test_old_names_give_the_same_runs_to_the_bit():
    """A quasi-static clamped-pinned rod, unshearable (ends, constraint), stepped by
    TimeStepper(max_cuts); a dynamic one with rho_A, I11, I22 by choose_integrator
    (max_cuts): the same states as with the new names after 4 steps."""
    old = _old(lambda: _quasi_static(ends=("clamped", "pinned"), constraint="unshearable"),
               "start=|constraints")
    new = _new(lambda: _quasi_static(start="clamped", end="pinned",
                                     constraints="unshearable"))
    _old(lambda: TimeStepper(old.problem, "bdf2", max_cuts=3), "max_step_cuts").run(
        0.0, 0.2, 0.05)
    stepper = _new(lambda: TimeStepper(new.problem, "bdf2", max_step_cuts=3))
    stepper.run(0.0, 0.2, 0.05)
    assert stepper.max_cuts == 3
    _same_state(old, new)
    old = _old(lambda: _dynamic(rho_A=1.0, I11=0.01, I22=0.02), "density|section_inertia")
    new = _new(lambda: _dynamic(density=1.0, section_inertia=(0.01, 0.02)))
    _old(lambda: choose_integrator(old.problem, max_cuts=2), "max_step_cuts").run(
        0.0, 0.2, 0.05)
    _new(lambda: choose_integrator(new.problem, max_step_cuts=2)).run(0.0, 0.2, 0.05)
    _same_state(old, new)
