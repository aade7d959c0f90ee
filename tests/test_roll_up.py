"""The cantilever rolled up by an end couple (Simo & Vu-Quoc 1986: M = 2 pi EI/L closes
it into a circle of radius EI/M) under a DEAD couple, and what decides its stability
(issue 27, docs/stability.md "Couples: the roll-up").

A couple of fixed spatial direction does path-dependent work on finite 3-D rotations:
it is not conservative (Ziegler; Argyris 1982), its load stiffness is skew and K is not
symmetric.  In the plane the roll-up is the follower couple's (tests/test_rod.py), so
its discrete solution is known in closed form; out of the plane the rolled-up rod
flutters: two out-of-plane modes form a complex pair of omega^2 (no real eigenvalue of
K crosses 0 on the way: no divergence).  References: the discrete closed form, and the
growth rate and frequency of a small out-of-plane perturbation integrated in time by the
nonlinear dynamic rod (a code path without eigen-solves) against the vibration modes'.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import run
from dolfin_rod.run import analyse
from test_rod import rollup_discrete_angle

M = 2 * math.pi     # EI = L = 1: the full circle

SCENE = """
[scene]
name = "roll_up"
[geometry]
n_cells = 8
[material]
stiffness = {{ A = [1.0, 1.0, 1.0], B = [100.0, 100.0, 100.0] }}
model = "hyperelastic"
{material}
[boundary]
start = "clamped"
end = "free"
[loads]
end_couple = {couple}
{initial}
[time]
t_end = {t_end}
dt = {dt}
[outputs]
plots = false
fields = false
animation = false
progress = false
"""


def scene_file(tmp_path, name: str, **keys) -> str:
    comm = MPI.COMM_WORLD
    path = tmp_path / f"{name}.toml"
    if comm.rank == 0:
        path.write_text(SCENE.format(**keys))
    return comm.bcast(str(path))


def out_dir(tmp_path) -> str:
    return MPI.COMM_WORLD.bcast(str(tmp_path / "out"))


@pytest.mark.mpi
def test_quasi_static_roll_up_closes_the_circle_and_is_unstable(tmp_path):
    """`dolfin-rod run` of the benchmark (8 cells, the dead couple ramped to 2 pi EI/L in
    one step, default settings): the tip angle is the discrete closed form's
    (tests/test_rod.rollup_discrete_angle, 2 pi - 0.289 at 8 cells; Newton's default
    tolerance: 1e-7), the tip back at the clamp to the 8-cell gap (measured 4.92e-2; the
    gap is O(h^2), 3.2e-3 at 32 cells), in the plane (y = 0), and the end state is
    reported unstable (exit status 4), which it is: it flutters
    (test_rolled_up_rod_flutters_under_a_dead_couple); the message says that the count
    is the energy criterion's (a dead couple is not conservative)."""
    path = scene_file(tmp_path, "roll_up", material="", initial="",
                      couple=f'{{ type = "ramp", value = [0.0, {M!r}, 0.0], duration = 1.0 }}',
                      t_end=1.0, dt=1.0)
    result = run(path, out=out_dir(tmp_path), quiet=True)
    s = result.series
    tip = np.array([s[f"tip_position_{c}"][-1] for c in "xyz"])
    # the tip's turn about e_y (q and -q the same rotation: modulo 2 pi)
    angle = (2 * math.atan2(s["tip_quaternion_2"][-1], s["tip_quaternion_0"][-1])) % (2 * math.pi)
    assert result.status == "completed (unstable equilibrium)"
    # the count is the energy criterion's, and the run says so (no "bifurcation")
    assert "the loads are not conservative" in result.summary["message"]
    assert not any("bifurcation" in w for w in result.summary["warnings"])
    assert angle == pytest.approx(rollup_discrete_angle(8), abs=1e-7)
    assert abs(tip[1]) < 1e-12
    assert np.linalg.norm(tip) == pytest.approx(4.92e-2, rel=1e-2)


@pytest.mark.mpi
def test_rolled_up_rod_flutters_under_a_dead_couple(tmp_path):
    """The rolled-up rod with mass (rho A = 1, rho J = diag(0.01, 0.01, 0.02): that of a
    section with I/A = EI/EA = 0.01; 8 cells), started in equilibrium on the circle:
    `dolfin-rod modes --count 3` finds its lowest out-of-plane pair complex, both
    members (the count is not allowed to cut a pair), flutter (before the
    dead couple was recognised as non-conservative it reported the symmetric part's two
    negative omega^2, divergence).  Reference: the same rod pushed out of its plane
    (velocity 1e-8 along y) and integrated in time (generalized-alpha, dt = 0.005): the
    tip's sideways swing grows between its successive extremes at 8.255, 8.270, 8.270
    per unit time, half a period 0.455 apart (omega 6.905); the modes: growth 8.2591,
    omega 6.8922.  Tolerances: 1 % for the growth, 0.5 % for omega (the time step's
    error, O(dt^2), and extremes picked on the time grid, dt / half-period = 1.1 %
    for omega, made smaller by the three-extreme average)."""
    keys = dict(material="density = 1.0\nsection_inertia = 0.01",
                couple=f'{{ type = "constant", value = [0.0, {M!r}, 0.0] }}')
    start = f'[initial]\nshape = {{ type = "arc", radius = {1 / M!r} }}\nequilibrium = true'
    modes = analyse(scene_file(tmp_path, "modes", initial=start, t_end=0.005, dt=0.005,
                               **keys), "modes", count=3, out=out_dir(tmp_path) + "_modes",
                    quiet=True).summary["modes"]["modes"]
    pair = [row for row in modes if row.get("growth_rate", 0.0) > 0]
    # three asked for: two real modes and the pair, not cut in two (analysis/eigen.py)
    assert len(modes) == 4 and len(pair) == 2
    assert pair[0]["omega"] == pytest.approx(pair[1]["omega"], rel=1e-12)
    perturbed = start + "\nvelocity = [0.0, 1e-8, 0.0]"
    s = run(scene_file(tmp_path, "swing", initial=perturbed, t_end=2.0, dt=0.005, **keys),
            out=out_dir(tmp_path), quiet=True).series
    t, y = np.array(s["time"]), np.abs(np.array(s["tip_position_y"]))
    extremes = [i for i in range(1, len(y) - 1) if y[i] >= max(y[i - 1], y[i + 1])]
    assert len(extremes) == 4 and y[extremes[-1]] < 1e-2       # linear: tip y << L
    growth = np.diff(np.log(y[extremes])) / np.diff(t[extremes])
    half_period = np.mean(np.diff(t[extremes]))
    assert np.all(np.abs(growth / pair[0]["growth_rate"] - 1) < 1e-2), growth
    assert math.pi / half_period == pytest.approx(pair[0]["omega"], rel=5e-3)
