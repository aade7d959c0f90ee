"""Newton's absolute tolerance follows the rod's forces (rod/force_scale.py): one scene
written in SI, in mm-N-ms and in pN-nm-ns gives one answer after the conversion of units;
a scene with tiny forces does not stop at its first guess; a given snes_atol is used as
it is.

The scenes: a micro-rod (L = 100 nm, bending stiffness 200 pN nm^2, a DNA molecule's
order) under a tip force of 0.02 pN (F* = A/L^2 = 0.02 pN: a large deflection),
quasi-static and creeping (its natural curvature evolving); a hair (L = 1 cm, 1e-5 kg/m)
swinging from a pin in gravity; the micro-rod bent by a prescribed end rotation
(Python API).  Before: in SI and mm-N-ms the micro-rod's forces (2e-14 N) were far
below the fixed absolute tolerance 1e-10, which passed the straight first guess
unchanged (a tip at rest); in SI its LU called every couple row's pivot (6e-18) zero
(PETSc's absolute 2.2e-14: solvers.zero_pivot); in pN-nm-ns the creep's first Newton
iterate was called divergent (its couples in pN nm 4e4 times the 4e-3 pN load).

Agreement: every run stops with a residual below 1e-10 of its force scale, which scales
with the units like the residual's largest rows (rod/force_scale.py), or at the step
test |dy| < 1e-10 (|y| + L); either leaves the converged state's relative error near
1e-10 in each system (the solve's error K^-1 R over its size: the force scale over a
stiffness's response to it), and Newton's last quadratic iteration usually lands far
below.  The runs take the same Newton path up to the round-off of the converted data
(1e-16 relative, amplified by the condition of the steps), so the dimensionless results
agree to TOL = 1e-8: 100x above the tolerance-level error (measured <= 3e-10), far
below a first guess left unchanged (an O(1) error) or a step's truncation error (1e-3
.. 1e-5 here).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import RodModel, RodParameters, TimeStepper
from dolfin_rod.checks import NEWTON_ATOL, NEWTON_FORCE_TOL
from dolfin_rod.scenes import build, parse_scene

# (force, length, time) units in SI
UNITS = {"SI": (1.0, 1.0, 1.0), "mm-N-ms": (1.0, 1e-3, 1e-3),
         "pN-nm-ns": (1e-12, 1e-9, 1e-9)}
TOL = 1e-8          # module docstring (measured: <= 3e-10)
TOL_SWING = 1e-7    # the pendulum: 20 steps of a swing amplify (measured: <= 9e-9)
# A dynamic rod's default linear solver on several ranks, GMRES on block-Jacobi LUs to
# ksp_rtol 1e-12 (integrators/lie_alpha.py), breaks down in pN-nm-ns (after 60-90
# iterations: its couple rows are 1e9 times its force rows): a limit of that solver's
# units, not of Newton's tests; MUMPS solves every system here
MUMPS = '[solver]\noptions = { ksp_type = "preonly", pc_type = "lu", ' \
    'pc_factor_mat_solver_type = "mumps" }\n'


def convert(value, units: str, force: int = 0, length: int = 0, time: int = 0):
    """An SI value of dimension F^force L^length T^time in ``units``."""
    phi, ell, tau = UNITS[units]
    return np.asarray(value, float) / (phi**force * ell**length * tau**time)


def toml(value) -> str:
    return "[" + ", ".join(repr(float(v)) for v in value) + "]" if np.ndim(value) \
        else repr(float(value))


def micro_rod(units: str, creep: bool = False) -> str:
    """The micro-rod's scene in ``units``: a tip force (a step) on a clamped rod,
    quasi-static; ``creep``: its natural curvature and stretch evolve with relaxation
    time 1 us (M_d = tau (A + A_d))."""
    def c(value, **dims):
        return toml(convert(value, units, **dims))
    A, B = np.array([2e-28, 2e-28, 4e-28]), np.array([5e-10, 5e-10, 1.5e-9])
    tau = 1e-6
    material = (f"model = \"hyperelastic\"\nstiffness = {{ A = {c(A, force=1, length=2)}, "
                f"B = {c(B, force=1)} }}\n") if not creep else (
        f"stiffness = {{ A = {c(A, force=1, length=2)}, B = {c(B, force=1)}, "
        f"A_d = {c(A, force=1, length=2)}, B_d = {c(B, force=1)} }}\n"
        f"viscosity = {{ M_d = {c(2 * tau * A, force=1, length=2, time=1)}, "
        f"N_d = {c(2 * tau * B, force=1, time=1)} }}\n")
    t_end, dt = (2e-6, 2.5e-7) if creep else (1.0, 0.25)
    force = 4e-15 if creep else 2e-14     # P L^2 / A = 0.2 (a step at t = 0), 1
    history = "" if creep else f'type = "ramp", duration = {c(1.0, time=1)}, '
    return f"""
[geometry]
length = {c(1e-7, length=1)}
n_cells = 8
[material]
{material}[boundary]
start = "clamped"
end = "free"
[loads]
end_force = {{ {history}value = {c([force, 0.0, 0.0], force=1)} }}
[time]
t_end = {c(t_end, time=1)}
dt = {c(dt, time=1)}
"""


def hair(units: str) -> str:
    """A hair (L = 1 cm, E I = 2e-8 N m^2, 1e-5 kg/m) pinned at s = 0, released
    horizontal (along e_3) in gravity along -e_1: a dynamic rod (generalized-alpha on
    the rotation group, the default)."""
    def c(value, **dims):
        return toml(convert(value, units, **dims))
    return f"""
[geometry]
length = {c(0.01, length=1)}
n_cells = 8
[material]
model = "hyperelastic"
stiffness = {{ A = {c([2e-8, 2e-8, 1.5e-8], force=1, length=2)}, B = {c([10.0, 10.0, 30.0], force=1)} }}
density = {c(1e-5, force=1, length=-2, time=2)}
section_inertia = {c(6.4e-15, force=1, time=2)}
[boundary]
start = "pinned"
end = "free"
[loads]
gravity = {c([-9.81, 0.0, 0.0], length=1, time=-2)}
[time]
t_end = {c(0.04, time=1)}
dt = {c(0.002, time=1)}
rtol = 1e-14
""" + (MUMPS if MPI.COMM_WORLD.size > 1 else "")


def run_scene(text: str, t_end: float, dt: float) -> dict:
    sim = build(parse_scene(text), "rod")
    sim.start()
    steps = round(t_end / dt)
    for k in range(steps):
        sim.advance(k * dt, (k + 1) * dt)
    return sim.diagnostics(t_end)


def tip(units: str, d: dict, length: float) -> np.ndarray:
    """The tip's position over the rod's length (dimensionless)."""
    return np.array([d[f"tip_position_{c}"] for c in "xyz"]) / convert(length, units,
                                                                        length=1)


def agree(results: dict, tol: float = TOL) -> None:
    """Every system's dimensionless result equals SI's to ``tol`` (relative to its
    size)."""
    reference = results["SI"]
    for units, value in results.items():
        assert np.abs(value - reference).max() <= tol * np.abs(reference).max(), units


@pytest.mark.mpi
def test_a_cantilever_under_a_tip_force_in_three_systems_of_units():
    """The micro-rod bends under P L^2 / A = 1, ramped in 4 load steps (a large
    deflection): the same tip in every system; the fixed atol of before left SI and
    mm-N-ms straight."""
    results = {}
    for units in UNITS:
        d = run_scene(micro_rod(units), *convert([1.0, 0.25], units, time=1))
        results[units] = tip(units, d, 1e-7)
    assert results["SI"][0] > 0.3                   # bent, not the straight first guess
    agree(results)


@pytest.mark.mpi
def test_a_creeping_micro_rod_in_three_systems_of_units():
    """The evolving model's creep under a step tip force over two relaxation times (its
    natural curvature follows the bend): the same tip after the first step and at the
    end in every system, and the tip moved on (it creeps).  Before, SI and mm-N-ms
    stayed straight and pN-nm-ns stopped at t = 0 with DIVERGED_DTOL (the first
    iterate's residual, of couples in pN nm, 4e4 times the load's 4e-3 pN)."""
    results, first = {}, {}
    for units in UNITS:
        t_end, dt = convert([2e-6, 2.5e-7], units, time=1)
        sim = build(parse_scene(micro_rod(units, creep=True)), "rod")
        sim.start()
        for k in range(8):
            sim.advance(k * dt, (k + 1) * dt)
            if k == 0:
                first[units] = tip(units, sim.diagnostics(dt), 1e-7)
        results[units] = tip(units, sim.diagnostics(t_end), 1e-7)
    # crept on from the first step's bend (measured 0.074 -> 0.107 of L)
    assert results["SI"][0] > 1.3 * first["SI"][0] > 0.05
    agree(first)
    agree(results)


@pytest.mark.mpi
def test_a_pendulum_swinging_in_gravity_in_three_systems_of_units():
    """The hair falls through 64 degrees in t = 0.04 s (its period ~0.16 s): the same
    tip in every system, to TOL_SWING (20 steps of the swing amplify the differences
    of Newton's stops).  The scene gives time.rtol = 1e-14, so that each step stops by
    the tests under scrutiny, the absolute test (unit-free now) and the step test: the
    dynamic integrator's default rtol 1e-4 compares with a residual that weighs force
    rows against couple rows as the units do, and stopped this stiff pendulum early in
    every system (tip x/L -0.52, -0.75, -0.62 against -0.90) until the relative test was
    capped by the force scale (the next test; docs/rod.md)."""
    results = {}
    for units in UNITS:
        d = run_scene(hair(units), *convert([0.04, 0.002], units, time=1))
        results[units] = tip(units, d, 0.01)
    assert results["SI"][0] < -0.5                      # fell (measured -0.90)
    agree(results, TOL_SWING)


def bend(units: str, options: dict | None = None):
    """The micro-rod (Python API), clamped at s = 0, bent quasi-statically by a
    prescribed rotation of its free end about e_2, ramped to a quarter turn in 4 load
    steps; (model, stepper) after the run."""
    A = convert([2e-28, 2e-28, 4e-28], units, force=1, length=2)
    B = convert([5e-10, 5e-10, 1.5e-9], units, force=1)
    L = float(convert(1e-7, units, length=1))
    model = RodModel(RodParameters(length=L, A=A, B=B), n_cells=8, model="hyperelastic",
                     end_rotation={"end": lambda t: np.array([0.0, 0.5 * np.pi * t, 0.0])})
    model.set_initial_state()
    stepper = TimeStepper(model.problem, solver_options=options)
    stepper.run(0.0, 1.0, 0.25)
    return model, stepper


@pytest.mark.mpi
def test_a_quasi_static_bend_in_three_systems_of_units_through_the_api():
    """RodModel and TimeStepper: a couple at the end bends the micro-rod into a quarter
    circle (n = 0, m = A theta/L uniform): the same tip and clamp couple, over their
    scales L and A/L, in every system (the reaction is the rod's internal couple: the
    part of the answer a first guess left unchanged misses entirely); the couple theta
    and the tip (L/theta)(1 - cos theta, 0, sin theta) to the discretisation error
    (measured 3e-3 at 8 cells; tolerance 1e-2)."""
    results, theta = {}, 0.5 * np.pi
    for units in UNITS:
        model, _ = bend(units)
        d = model.diagnostics(1.0)
        L = float(convert(1e-7, units, length=1))
        A = float(convert(2e-28, units, force=1, length=2))
        couple = np.array([d[f"reaction_couple_start_{c}"] for c in "xyz"]) * L / A
        results[units] = np.concatenate([tip(units, d, 1e-7), couple])
    assert np.abs(results["SI"][3:]) == pytest.approx([0.0, theta, 0.0], abs=1e-2)
    assert results["SI"][:3] == pytest.approx(
        [(1 - np.cos(theta)) / theta, 0.0, np.sin(theta) / theta], abs=1e-2)
    agree(results)


@pytest.mark.mpi
def test_a_given_snes_atol_is_used_exactly_and_the_default_follows_the_forces():
    """A given snes_atol is SNES's, exactly; without one, snes_atol is NEWTON_FORCE_TOL
    times the rod's force scale at the step's time (at most NEWTON_ATOL): at t = 1 the turn's couple
    F* L pi/2 (F* = max |A| / L^2) in SI and mm-N-ms (L < 1: the scale of the couple rows, the
    smaller ones, in N m and N mm), over L in pN-nm-ns (L = 100 > 1: of the force rows,
    in pN)."""
    A, L = 4e-28, 1e-7          # A's largest entry (torsion), the length in SI
    for units, scale in (("SI", A / L), ("mm-N-ms", A / L * 1e3),
                         ("pN-nm-ns", A / L**2 / 1e-12)):
        model, stepper = bend(units)
        atol = stepper.integrator.solver.snes.getTolerances()[1]
        assert atol == min(NEWTON_FORCE_TOL * model.force_scale_now(), NEWTON_ATOL)
        assert model.force_scale_now() == pytest.approx(scale * np.pi / 2, rel=1e-12)
    _, stepper = bend("SI", {"snes_atol": 1e-30})
    assert stepper.integrator.solver.snes.getTolerances()[1] == 1e-30


@pytest.mark.mpi
def test_a_hook_pushed_onto_its_column_in_large_load_steps_reaches_its_equilibrium(tmp_path):
    """Quasi-static self-contact (tests/test_kinked_contact.py's hook, pushed by 0.4 N) in
    load steps of 0.05: the step on which the arm reaches the column starts (linear
    predictor) with a segment pair deep in its barrier, a first residual of 4.8e8, and
    the relative test, snes_rtol 1e-8 of it, accepted 0.76 N before, more than the load:
    the arm was left 4 mm off the column (no pair), the run "completed".  A static step's
    relative test is now against at most the force scale (solvers.relative_reference,
    196 N here).  References: (1) the run in load steps of 0.025, which meets no barrier
    at its predictor (the same equations at the same load: the same state to Newton's
    tolerance, measured 3e-12 of the arm's travel, asserted 1e-8); (2) statics, which
    no run enters: the clamp's reaction balances the push, force and moment about the
    clamp (the pairs' forces are internal).  Newton's accepted residual is at most
    snes_rtol 1e-8 x 196 N = 2e-6 N, moments of it at most that times the hook's size
    (< 1.2 m): asserted 1e-5 N and N m (measured 1.2e-11 N, 1.5e-14 N m); the wrong state
    was off by 7.4e-4 N and 0.21 N m."""
    from test_kinked_contact import KINKED, POINTS, QUIET

    from dolfin_rod import run
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path), root=0))
    if comm.rank == 0:
        (folder / "hook.toml").write_text(KINKED)
    comm.barrier()
    push = np.array([0.0, -0.4, 0.0])           # the ramp's value at t = 0.4
    tips = []
    for dt in (0.05, 0.025):
        result = run(folder / "hook.toml", {**QUIET, "time.dt": dt, "time.t_end": 0.4},
                     out=folder / f"dt{dt}", quiet=True)
        series = result.series
        assert result.status == "completed"
        assert series["contact_pairs"][-1] >= 1            # the arm rests on the column
        tip = np.array([series[f"tip_position_{c}"][-1] for c in "xyz"])
        force = np.array([series[f"reaction_force_start_{c}"][-1] for c in "xyz"])
        couple = np.array([series[f"reaction_couple_start_{c}"][-1] for c in "xyz"])
        assert np.linalg.norm(force + push) < 1e-5
        assert np.linalg.norm(couple + np.cross(tip, push)) < 1e-5   # clamp at the origin
        tips.append(tip)
    travel = np.linalg.norm(tips[1] - POINTS[4])
    assert np.linalg.norm(tips[0] - tips[1]) <= 1e-8 * travel


@pytest.mark.mpi
def test_a_stiff_pendulum_at_the_default_rtol_is_the_converged_swing():
    """The hair of the test above at the dynamic integrator's default snes_rtol 1e-4
    (time.rtol not given): the first residual of a step is dominated by its stiff axial
    rows (E A / E I ~ 1e9), and rtol 1e-4 of it accepted residuals of 3.2 times the
    force scale, 6 times the hair's weight: the swing ended at tip x/L -0.52 (SI), -0.75
    (mm-N-ms), -0.62 (pN-nm-ns) against -0.90.  The relative test now accepts no
    residual above checks.NEWTON_FORCE_CAP = 1e-3 of the force scale
    (solvers.relative_tolerance).  Reference: the run at rtol 1e-14 (SI).  Tolerance
    1e-3 L, the steps' own error (the run at dt / 4 ends 1.1e-3 L away): Newton's part
    of the error stays below it (measured 8.6e-5, 5.1e-4, 2e-8 L)."""
    t_end, dt = 0.04, 0.002
    tight = tip("SI", run_scene(hair("SI"), t_end, dt), 0.01)
    for units in UNITS:
        text = hair(units).replace("rtol = 1e-14\n", "")
        d = run_scene(text, *convert([t_end, dt], units, time=1))
        assert np.abs(tip(units, d, 0.01) - tight).max() < 1e-3, units
