"""Branch switching at bifurcations of quasi-static paths (issue 27 item 2,
dolfin_rod/analysis/branches.py), from scenes.

* The clamped-free elastica (EI = 1, L = 1, GA = EA = 1e5, a compressive dead load P at
  the free end ramped from 0): past Euler's load P_cr = pi^2/4 the straight column is
  unstable and the run switches to the buckled branch.  Reference (Timoshenko & Gere,
  Theory of Elastic Stability, sec. 2.7), computed here with scipy's complete elliptic
  integrals: lambda = sqrt(P/EI), k = sin(alpha/2) from L lambda = K(k), tip deflection
  2k/lambda, axial tip position (2E(k) - K(k))/lambda.  Measured at 16 cells (deflection,
  axial position, errors): 1.5 P_cr 0.787809 (-0.10 %), 0.368179 (+4.6e-3 L); 3 P_cr
  0.709506 (+0.30 %), -0.198491 (+5.6e-3 L); at 8 and 32 cells the axial errors are
  1.83e-2 and 1.39e-3 L: second order in h (ratios 3.98, 4.05).  Tolerance 1e-2 L on
  both: twice the 16-cell error (extensibility and shear, P/EA <= 7.4e-5, are far below).
  Reached with no imperfection (the branch switch decides the side) and with a lateral
  load of 1e-4 P ramped with P, which decides the side: the deflection must be on its
  side (the issue's runs ended on the other, straight and unstable).
* The rod of the issue's first bullet: clamped at both ends, twisted 2.5 turns
  quasi-statically (Greenhill's critical twist 2.861 pi = 8.99 rad, passed at t = 0.58
  of 50 steps): it switches there and ends buckled and stable, with less energy than
  the straight (unstable) rod at the same twist (measured 128.485 against 128.499 EI/L)
  and a bending couple of 0.189 EI/L at the clamps (0 on the straight rod).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

import dolfin_rod
from test_buckling import jointed_column_scene
from test_stability import COLUMN_SCENE

TWISTED = """
[geometry]
length = 1.0
n_cells = 16
[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 1.0], B = [1e5, 1e5, 1e5] }
[boundary]
start = "clamped"
end = "clamped"
end_rotation = { type = "ramp", value = [0.0, 0.0, 15.707963267948966], duration = 1.0 }
[time]
t_end = 1.0
dt = 0.02
[stability]
follow_unstable = true
[outputs]
fields = false
animation = false
plots = false
progress = false
"""


def elastica(p: float) -> tuple[float, float]:
    """(tip deflection, axial tip position) of the clamped-free elastica, EI = L = 1."""
    lam = math.sqrt(p)
    k = brentq(lambda k: ellipk(k * k) - lam, 1e-12, 1 - 1e-15)
    return 2 * k / lam, (2 * ellipe(k * k) - ellipk(k * k)) / lam


def rank() -> int:
    from mpi4py import MPI
    return MPI.COMM_WORLD.rank


def run_scene(tmp_path, text: str, name: str, overrides=None):
    from mpi4py import MPI
    path = tmp_path / f"{name}.toml"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(text)
    path = MPI.COMM_WORLD.bcast(str(path))
    return dolfin_rod.run(path, overrides, out=MPI.COMM_WORLD.bcast(str(tmp_path / name)),
                          quiet=True)


@pytest.mark.mpi
@pytest.mark.parametrize("imperfection", [0.0, 1e-4])
@pytest.mark.parametrize("factor, steps", [(1.5, 20), (3.0, 40)])
def test_post_buckled_elastica_by_branch_switching(tmp_path, capfd, factor, steps,
                                                   imperfection):
    """Ramped to 1.5 P_cr in 20 steps or 3 P_cr in 40 (steps of 7.5 % P_cr): one switch,
    in the first step past P_cr, to the elastica."""
    p = factor * math.pi ** 2 / 4
    text = COLUMN_SCENE.format(load=-p, follow="false")     # item 1's column, 8 cells
    result = run_scene(tmp_path, text, "column", {
        "geometry.n_cells": 16, "time.dt": 1.0 / steps, "stability.at_bifurcation": "switch",
        "loads.end_force": {"type": "ramp", "value": [0.0, imperfection * p, -p],
                            "duration": 1.0}})
    assert result.status == "completed"
    err = capfd.readouterr().err
    t_switch = math.ceil(steps / factor) / steps          # the first step past P_cr
    if rank() == 0:                                        # (rank 0 warns)
        assert err.count("switched to a stable branch") == 1, err
        assert f"t = {t_switch:g}: a bifurcation" in err, err
    # and summary.json keeps the warning (it was only printed)
    switches = [w for w in result.summary["warnings"] if "switched to a stable branch" in w]
    assert len(switches) == 1 and switches[0].startswith(f"t = {t_switch:g}: a bifurcation")
    series = result.series
    assert series["negative_eigenvalues"][-1] == 0
    deflection, axial = elastica(p)
    lateral = series["tip_position_y"][-1] if imperfection else math.hypot(
        series["tip_position_x"][-1], series["tip_position_y"][-1])
    assert lateral == pytest.approx(deflection, abs=1e-2)      # on the imperfection's side
    assert series["tip_position_z"][-1] == pytest.approx(axial, abs=1e-2)


@pytest.mark.mpi
def test_twisted_rod_ends_buckled_not_straight(tmp_path, capfd):
    """2.5 turns in 50 steps: without switching the rod stays straight (sideways 0,
    unstable: 4 negative eigenvalues at the end); with it, it switches at t = 0.58 (the
    first step past 2.861 pi) and ends stable, bent (a bending couple at the clamps:
    none on the straight rod) and with less free energy than the straight rod at the
    same twist (a stable state the descent reached from it)."""
    straight = run_scene(tmp_path, TWISTED, "straight", {"stability.at_bifurcation": "stay"})
    buckled = run_scene(tmp_path, TWISTED, "buckled")
    err = capfd.readouterr().err
    if rank() == 0:
        assert "t = 0.58: a bifurcation" in err and "switched to a stable branch" in err, err
    assert straight.series["negative_eigenvalues"][-1] == 4
    assert buckled.series["negative_eigenvalues"][-1] == 0
    assert buckled.series["free_energy"][-1] < straight.series["free_energy"][-1]
    lateral = [math.hypot(run.series["reaction_couple_start_x"][-1],
                          run.series["reaction_couple_start_y"][-1])
               for run in (straight, buckled)]
    assert lateral[0] < 1e-8 and lateral[1] > 1e-2, lateral


@pytest.mark.mpi
@pytest.mark.parametrize("imperfection", [0.0, 1e-4])
def test_quaternion_form_switches_to_the_same_elastica(tmp_path, capfd, imperfection):
    """The column of test_post_buckled_elastica_by_branch_switching at 1.5 P_cr (20
    steps, 16 cells) on quaternions (K bordered by the gauge multiplier, G on the
    material rotations of quaternion directions: analysis/stability.LowestEigenvalues):
    one switch at t = 0.7 and the rotation vectors' elastica, tip deflection 0.787809
    (no imperfection; its side is the descent's) or 0.787818 (1e-4 P) and axial position
    0.368179 / 0.368152 (elliptic integrals: 0.788576, 0.363588; the 16-cell error).
    Measured against the rotation vectors' run: 3e-10 and 1e-11."""
    p = 1.5 * math.pi ** 2 / 4
    text = COLUMN_SCENE.format(load=-p, follow="false").replace(
        "[geometry]\n", '[geometry]\nrotations = "quaternion"\n')
    result = run_scene(tmp_path, text, "column", {
        "geometry.n_cells": 16, "time.dt": 1.0 / 20, "stability.at_bifurcation": "switch",
        "loads.end_force": {"type": "ramp", "value": [0.0, imperfection * p, -p],
                            "duration": 1.0}})
    assert result.status == "completed"
    err = capfd.readouterr().err
    if rank() == 0:
        assert err.count("switched to a stable branch") == 1, err
        assert "t = 0.7: a bifurcation" in err, err
    series = result.series
    assert series["negative_eigenvalues"][-1] == 0
    lateral = series["tip_position_y"][-1] if imperfection else math.hypot(
        series["tip_position_x"][-1], series["tip_position_y"][-1])
    vectors = (0.7878178412, 0.3681522831) if imperfection else (0.7878093531, 0.3681786030)
    assert lateral == pytest.approx(vectors[0], abs=1e-8)
    assert series["tip_position_z"][-1] == pytest.approx(vectors[1], abs=1e-8)
    deflection, axial = elastica(p)
    assert lateral == pytest.approx(deflection, abs=1e-2)


@pytest.mark.mpi
def test_quaternion_form_twisted_rod_ends_buckled_as_rotation_vectors(tmp_path, capfd):
    """TWISTED on quaternions: the switch at t = 0.58 and the end state of the rotation
    vectors' run (test_twisted_rod_ends_buckled_not_straight: free energy 128.484832 EI/L,
    bending couple 0.188531 EI/L at the clamps; measured equal to 1e-11).  Newton needs
    the backtracking line search after the switch on quaternions (without it: DIVERGED_DTOL
    at t = 0.88, at any step size)."""
    text = TWISTED.replace("[geometry]\n", '[geometry]\nrotations = "quaternion"\n')
    result = run_scene(tmp_path, text, "twisted",
                       {"solver.options": {"snes_linesearch_type": "bt"}})
    assert result.status == "completed"
    if rank() == 0:
        err = capfd.readouterr().err
        assert "t = 0.58: a bifurcation" in err and "switched to a stable branch" in err, err
    series = result.series
    assert series["negative_eigenvalues"][-1] == 0
    assert series["free_energy"][-1] == pytest.approx(128.484832, abs=1e-5)
    couple = math.hypot(series["reaction_couple_start_x"][-1],
                        series["reaction_couple_start_y"][-1])
    assert couple == pytest.approx(0.188531, abs=1e-5)


JOINTED_COLUMN = jointed_column_scene(8, -3.7011016504085092, 0.05) + """[outputs]
fields = false
animation = false
plots = false
progress = false
"""


@pytest.mark.mpi
def test_jointed_column_ends_unstable_or_buckled(tmp_path, capfd):
    """The column of test_post_buckled_elastica_by_branch_switching (1.5 P_cr in 20
    steps, 16 cells, no imperfection) as two rods of 8 cells joined rigidly ([[rods]],
    [[joints]]; the count and the descent on the joint's free dofs, P^T K P).  With
    stability.at_bifurcation = "stay" it stays straight and ends "completed (unstable
    equilibrium)", 2 negative eigenvalues from t = 0.7 (1.05 P_cr; 0.65 is 0.975);
    switching, it switches at t = 0.7 and ends on the one 16-cell column's elastica:
    tip deflection 0.787809, axial position 0.368179 (measured equal to 1e-9; asserted
    1e-6, the descent's and Newton's tolerances), within the 16-cell error of the
    elliptic integrals' 0.788576, 0.363588 (1e-2 L as there)."""
    straight = run_scene(tmp_path, JOINTED_COLUMN, "straight",
                         {"stability.at_bifurcation": "stay"})
    assert straight.status == "completed (unstable equilibrium)"
    assert list(straight.series["negative_eigenvalues"]) == [0] * 14 + [2] * 7
    assert abs(straight.series["upper.tip_position_y"][-1]) < 1e-8
    capfd.readouterr()
    buckled = run_scene(tmp_path, JOINTED_COLUMN, "buckled")
    assert buckled.status == "completed"
    if rank() == 0:
        err = capfd.readouterr().err
        assert err.count("switched to a stable branch") == 1, err
        assert "t = 0.7: a bifurcation" in err, err
    series = buckled.series
    assert series["negative_eigenvalues"][-1] == 0
    lateral = math.hypot(series["upper.tip_position_x"][-1], series["upper.tip_position_y"][-1])
    assert lateral == pytest.approx(0.787809, abs=1e-6)
    assert series["upper.tip_position_z"][-1] == pytest.approx(0.368179, abs=1e-6)
    deflection, axial = elastica(1.5 * math.pi ** 2 / 4)
    assert lateral == pytest.approx(deflection, abs=1e-2)
    assert series["upper.tip_position_z"][-1] == pytest.approx(axial, abs=1e-2)


def viscous_column_amplitude(times, tau: float, factor: float, imperfection: float):
    """The tip deflection of the clamped-free Kelvin-Voigt column (bending A, viscosity M
    = tau A) under a dead tip load P = factor P_cr t and a lateral one imperfection P,
    in one mode, the buckling mode w(s) = a (1 - cos(pi s / 2L)): its bending stiffness
    K = pi^4 EI / 32 L^3 (tip units), the load's geometric stiffness -K P / P_cr, the
    viscosity's tau K, so tau K a' + K (1 - P / P_cr) a = imperfection P (EI = L = 1)."""
    from scipy.integrate import solve_ivp
    stiffness = math.pi ** 4 / 32
    p_cr = math.pi ** 2 / 4

    def rate(t, a):
        return [(imperfection * factor * p_cr * t / stiffness
                 - (1 - factor * t) * a[0]) / tau]
    solution = solve_ivp(rate, (0.0, max(times)), [0.0], rtol=1e-10, atol=1e-14,
                         dense_output=True)
    return [float(solution.sol(t)[0]) for t in times]


@pytest.mark.mpi
def test_viscous_column_creeps_past_its_bifurcation_it_does_not_jump(tmp_path, capfd):
    """A Kelvin-Voigt column (M = N = 1: the bending creep time M/A = 1, 20 times the
    step) ramped to 1.5 P_cr with the lateral imperfection 1e-4 P: past P_cr (t = 0.7)
    the straight path is unstable, but a viscous rod's positions move at the viscous
    rate: its deflection grows from 2.9e-5 to 6.4e-5 by t = 1.  The default switch
    jumped it to the elastica's 0.374 at t = 0.7 (and warned of a new bifurcation at
    every later step): now the path stays, reported unstable.  Reference: the one-mode
    Galerkin creep (viscous_column_amplitude); measured 2.5, 1.8, 1.4 % above it at
    t = 0.5, 0.7, 1 (16 cells; the mode's truncation): asserted within 5 %."""
    text = (Path(__file__).parents[1] / "scenes" / "buckled_column.toml").read_text()
    written = 'at_bifurcation = "switch"       # the default, written out\n'
    assert written in text
    text = text.replace(written, "")
    text = text.replace('model = "hyperelastic"\n', 'model = "kelvin_voigt"\n'
                        'viscosity = { M = [1.0, 1.0, 1.0], N = [1.0, 1.0, 1.0] }\n')
    result = run_scene(tmp_path, text, "viscous", {
        "outputs.fields": False, "outputs.animation": False, "outputs.plots": False})
    err = capfd.readouterr().err
    if rank() == 0:
        assert "switched" not in err, err
        assert "t = 0.7: the equilibrium is unstable" in err, err
    assert result.status == "completed (unstable equilibrium)"
    series = result.series
    times = [0.5, 0.7, 1.0]
    rows = [series["time"].index(pytest.approx(t)) for t in times]
    reference = viscous_column_amplitude(times, 1.0, 1.5, 1e-4)
    assert [series["tip_position_y"][k] for k in rows] == pytest.approx(reference, rel=5e-2)
    # asked for explicitly, the switch is refused before any work, naming the key
    from dolfin_rod.scenes import SceneError, parse_scene
    with pytest.raises(SceneError, match=r"\[stability.at_bifurcation\]: \"switch\" jumps"):
        parse_scene(text.replace("[stability]\n", '[stability]\nat_bifurcation = "switch"\n'))
