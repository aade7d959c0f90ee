"""Segment contact with quaternion rods and per-step schemes (issue 26;
rod/pair_contact.StepTerm: stage k of a scheme adds w_k dE/dX(Y_k) and w_k a0_k H(Y_k);
docs/contact.md), and its refusal with PETSc TS.

Reference: the same scene on rotation vectors advanced by generalized-alpha on the
rotation group (tests/test_pair_contact.py checks it against superposition).
Quasi-static, the equilibria are the same discrete equations: equal to Newton's
tolerance; dynamic (quaternions with BDF2), the two integrators' results approach each
other as dt falls.
"""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod import TimeStepper
from dolfin_rod.integrators.choice import choose_integrator
from dolfin_rod.rod import EndLoad, RodParameters
from dolfin_rod.rod.contact import ContactLaw
from dolfin_rod.rod.rods import Rod
from dolfin_rod.rod.system import RodSystem

R, DELTA, P, L = 0.01, 2e-3, 0.05, 1.0
TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-14, "snes_stol": 1e-15}


def _propped(rotations: str, dynamic: bool, drop: float, kappa: float) -> RodSystem:
    """Cantilever A (EI = 1, 8 cells) along e_1 under the tip load -P e_3 (ramped over t
    in [0, 1] if quasi-static, at once if dynamic) over the stiff clamped-clamped rod B
    along e_2 near A's tip, B's centre line 2 r + drop below A's."""
    mass = dict(density=1.0, section_inertia=1e-4) if dynamic else {}
    beam = RodParameters(length=L, A=(1.0,) * 3, B=(1e4,) * 3, **mass)
    prop = RodParameters(length=0.5, A=(1e3,) * 3, B=(1e6,) * 3, **mass)
    load = EndLoad("force", (0, 0, -P), (lambda t: 1.0) if dynamic else (lambda t: t))
    x_prop = 1.0 if dynamic else 0.75 + 1 / 24       # quasi-static: inside A's segment
    rods = [Rod(beam, 8, "clamped", [load], orientation=(0, np.pi / 2, 0),
                name="A"),
            Rod(prop, 5, "clamped", end="clamped", position=(x_prop, -0.25, -(2 * R + drop)),
                orientation=(-np.pi / 2, 0, 0), name="B")]
    system = RodSystem(rods, model="hyperelastic", rotations=rotations,
                       contact=ContactLaw(R, DELTA, kappa, between_rods=True))
    system.set_initial_state()
    return system


def _quasi_static(rotations: str, scheme: str | None):
    system = _propped(rotations, False, 1.5 * DELTA, 1e4)
    stepper = TimeStepper(system.problem, scheme, TIGHT)
    for k in range(4):
        stepper.run(k / 4, (k + 1) / 4, 1 / 4)
    d = system.diagnostics(1.0)
    return type(stepper.integrator).__name__, d["pair_contact_force"], d["A.tip_position_z"]


@pytest.mark.mpi
def test_quaternions_and_per_step_schemes_rest_where_rotation_vectors_do():
    """The propped cantilever, quasi-static: quaternion unknowns (BDF2, SchemeStepper)
    and rotation vectors with the per-step scheme bdf2 give generalized-alpha's contact
    force (0.06270) and tip deflection to 1e-9 relative (Newton to 1e-12: the same
    equilibrium equations; measured 4e-14 and 1e-13 for the quaternions, bit-identical
    for bdf2)."""
    kind, force, tip = _quasi_static("rotation_vector", None)
    assert kind == "LieGeneralizedAlpha" and 0.05 < force < 0.075
    for rotations, scheme in (("quaternion", "bdf2"), ("rotation_vector", "bdf2")):
        other, f, z = _quasi_static(rotations, scheme)
        assert other == "SchemeStepper"
        assert f == pytest.approx(force, rel=1e-9) and z == pytest.approx(tip, rel=1e-9)


def _dropped(rotations: str, scheme: str, dt: float, t_end: float = 0.35):
    """The dynamic cantilever, B 5 mm below, kappa = 300: A falls under the sudden tip
    load and lands on B near t = 0.22; tip height at t_end and the smallest gap."""
    system = _propped(rotations, True, 5e-3, 300.0)
    stepper = TimeStepper(system.problem, scheme, {"snes_rtol": 1e-10, "snes_atol": 1e-12})
    gaps = []
    stepper.run(0.0, t_end, dt, lambda t, _: gaps.append(system.diagnostics(t)["min_pair_gap"]))
    return system.diagnostics(t_end)["A.tip_position_z"], min(gaps)


def test_dynamic_quaternion_rod_lands_where_rotation_vectors_do():
    """The dropped cantilever at dt = 0.01, 0.005: quaternions with BDF2 against rotation
    vectors with generalized-alpha (rho_inf = 0), tip height at t = 0.35 (in contact:
    smallest gap 0.34-0.37 delta): differences 1.66e-5, 6.73e-6 (3.9e-3, 1.6e-3 of the
    tip's 4.3e-3; at 0.0025: 2.8e-6): they fall with dt (ratio 2.5, then 2.4, not the
    schemes' 4: the two spatial forms' dynamics differ as well; each integrator alone
    converges at ratios 4.5-6.4).  Asserted: relative difference < 5e-3 and falling by
    more than 2 per halving.  Serial only: under mpirun -n 2 the four runs took 4.7 min
    on the shared machine."""
    differences = []
    for dt in (0.01, 0.005):
        reference, gap = _dropped("rotation_vector", "generalized_alpha:0.0", dt)
        assert gap < 0.5 * DELTA
        tip, _ = _dropped("quaternion", "bdf2", dt)
        differences.append(abs(tip - reference) / abs(reference))
    assert differences[0] < 5e-3 and differences[0] / differences[1] > 2, differences


def test_petsc_ts_is_refused_with_segment_contact():
    """PETSc TS would assemble the forms only: a clear error naming ts_type."""
    system = _propped("quaternion", False, 1.5 * DELTA, 1e4)
    with pytest.raises(ValueError, match="ts_type"):
        choose_integrator(system.problem, ts_type="bdf")
