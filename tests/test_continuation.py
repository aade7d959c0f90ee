"""Arc-length continuation through limit points (issue 27 item 6,
dolfin_rod/analysis/continuation.py).

A shallow circular arch (radius R = 10, half-angle 0.1 rad: span 2.0, rise 0.05; EI = 1,
EA = GA = 1e4, pinned feet) under a central point load 2 F snaps through.  Half of it
by symmetry: s = 0 the crown, clamped (no turn) and sliding along the load's direction
-e_2, s = L = R 0.1 a pinned foot; 16 cells.  Its load F at the crown against the
crown's deflection d rises to a limit point, falls (the crown snaps: negative F holds
it), and rises again.  Reference, computed here independently of the arc length: the
same half-arch with the crown's deflection prescribed (displacement control, 200 steps
of 5e-4, the crown's reaction), where the curve is single-valued in d; its maximum and
minimum refined by the parabola through the three samples around them.  Measured
(16 cells): upper limit F = 0.404559 at d = 0.0300, lower -0.146969 at d = 0.0794; arc
length (ds = 0.01, psi = 1): 0.404558 and -0.146969 (parabolas through its points).
Tolerance 1e-3 F: the parabolas' error with the arc length's spacing at the limit
points (d steps of ~4e-3: (4e-3)^2 F''/8 ~ 2e-4 F).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from dolfin_rod import TimeStepper
from dolfin_rod.analysis.continuation import ArcLength
from dolfin_rod.fem.fe_model import NodeValues
from dolfin_rod.rod import EndLoad, RodModel, RodParameters

ROOT = Path(__file__).resolve().parents[1]
RADIUS, HALF_ANGLE, CELLS = 10.0, 0.1, 16
ARCH = RodParameters(length=RADIUS * HALF_ANGLE, A=(1.0, 1.0, 1.0), B=(1e4, 1e4, 1e4),
                     reference_curvature=(1.0 / RADIUS, 0.0, 0.0))   # bends towards -e_2
DOWN = np.array([0.0, -1.0, 0.0])          # the load's direction at the crown


def crown_deflection(rod):
    crown = NodeValues(rod.f["displacement"].function_space, [0.0])
    return lambda: float(crown(rod.f["displacement"].x.array)[0] @ DOWN)


def extremum(x, y, k):
    """The vertex of the parabola through the points k - 1, k, k + 1."""
    a, b, _ = np.polyfit(x[k - 1:k + 2], y[k - 1:k + 2], 2)
    return float(np.polyval([a, b, _], -b / (2 * a)))


def turning_points(y) -> tuple[int, int]:
    """The first local maximum of y and the first local minimum after it."""
    rising = np.diff(y) > 0
    top = int(np.argmin(rising))                  # first step down
    return top, top + int(np.argmax(rising[top:]))


def first_maximum(lam) -> tuple[float, int]:
    """The first maximum of the load factors lam along a path (the parabola through the
    steps around it) and its step."""
    lam = np.asarray(lam, dtype=float)
    top, _ = turning_points(lam)
    return extremum(np.arange(len(lam), dtype=float), lam, top), top


@cache
def displacement_controlled(steps: int = 200, d_max: float = 0.1):
    """(d, F) of the half-arch with the crown's deflection prescribed (computed once, the
    reference of the API's and the scene's arc-length paths; callers do not modify it)."""
    rod = RodModel(ARCH, n_cells=CELLS, model="hyperelastic", start="clamped", end="pinned",
                   end_displacement={"start": lambda t: d_max * t * DOWN})
    rod.set_initial_state()
    out = []

    def record(t, _):
        d = rod.diagnostics(t)
        out.append((d_max * t, np.array([d[f"reaction_force_start_{c}"] for c in "xyz"]) @ DOWN))

    TimeStepper(rod.problem).run(0.0, 1.0, 1.0 / steps, record)
    return np.array(out).T


def arc_length(ds: float = 0.01):
    """(lambda, d) of the arc-length path of the half-arch, F = lambda x 1."""
    rod = RodModel(ARCH, n_cells=CELLS, model="hyperelastic", start="clamped", end="pinned",
                   end_slide={"start": (0.0, 1.0, 0.0)},
                   end_loads=[EndLoad("force", tuple(DOWN), lambda t: t, end="start")])
    rod.set_initial_state()
    deflection = crown_deflection(rod)
    path = ArcLength(rod, ds=ds, observe=lambda lam: deflection())
    path.run(0.0, 1.0)
    return np.array(path.points).T


@pytest.mark.mpi
def test_shallow_arch_snaps_through_its_limit_points():
    d_ref, F_ref = displacement_controlled()
    upper, lower = turning_points(F_ref)
    lam, d = arc_length()
    top, bottom = turning_points(lam)
    assert extremum(d, lam, top) == pytest.approx(extremum(d_ref, F_ref, upper), abs=1e-4)
    assert extremum(d, lam, bottom) == pytest.approx(extremum(d_ref, F_ref, lower), abs=1e-4)
    assert np.all(np.diff(d) > 0)              # the crown goes down all along the path
    assert lam[-1] >= 1.0 and d[-1] > 0.11     # past the snap, on the far branch


@pytest.mark.mpi
def test_snap_through_scene(tmp_path):
    """scenes/snap_through_arch.toml ([continuation] method = "arc_length"): the same
    path as the API's above (its limit loads against displacement control; the series'
    time is the load factor; the parabola through the steps around each turning point,
    of equal arc lengths: 0.405589 and -0.149688, 1.2e-5 and 1.8e-5 off; tolerance 1e-3),
    and the tangent's count is 1 on the branch between the limit points and 0 on the
    others (item 1)."""
    import dolfin_rod
    from mpi4py import MPI
    out = MPI.COMM_WORLD.bcast(str(tmp_path / "arch"))
    result = dolfin_rod.run(ROOT / "scenes" / "snap_through_arch.toml",
                            {"outputs.fields": False, "outputs.animation": False,
                             "outputs.plots": False}, out=out, quiet=True)
    assert result.status == "completed"
    lam = np.array(result.series["time"])
    count = np.array(result.series["negative_eigenvalues"])
    top, bottom = turning_points(lam)
    steps = np.arange(len(lam), dtype=float)
    d_ref, F_ref = displacement_controlled()
    upper, lower = turning_points(F_ref)
    assert extremum(steps, lam, top) == pytest.approx(extremum(d_ref, F_ref, upper), abs=1e-3)
    assert extremum(steps, lam, bottom) == pytest.approx(extremum(d_ref, F_ref, lower),
                                                         abs=1e-3)
    assert np.all(count[:top] == 0) and np.all(count[top + 2:bottom] == 1) \
        and np.all(count[bottom + 2:] == 0), count


def deep_arch_limit_load(n_cells: int) -> float:
    """The limit load (x EI/R^2) of the 215-degree clamped-hinged arch, R = 1, EI = 1,
    EA = GA = 1e6, under a crown load towards the centre (a PointLoad at the crown
    node), F = 20 lambda, arc length ds = 0.04; the first maximum of lambda refined by
    the parabola through its neighbours."""
    from dolfin_rod.rod import PointLoad
    length = np.radians(215.0)
    params = RodParameters(length=length, A=(1.0, 1.0, 1.0), B=(1e6, 1e6, 1e6),
                           reference_curvature=(1.0, 0.0, 0.0))
    probe = RodModel(params, n_cells=n_cells, model="hyperelastic")
    crown = probe.stress_free(np.array([length / 2]))[0][0]
    inwards = np.array([0.0, -1.0, 0.0]) - crown
    rod = RodModel(params, n_cells=n_cells, model="hyperelastic", start="clamped",
                   end="pinned",
                   point_loads=[PointLoad("force", 20.0 * inwards, length / 2, lambda t: t)])
    rod.set_initial_state()
    path = ArcLength(rod, ds=0.04, max_steps=1000)
    path.run(0.0, 1.0)
    return 20.0 * first_maximum(np.array(path.points)[:, 0])[0]


@pytest.mark.slow
def test_deep_arch_limit_load():
    """The 215-degree clamped-hinged arch (DaDeppo & Schmidt 1975, as quoted by Simo &
    Vu-Quoc 1986: P_cr = 897 for R = 100, EI = 1e6, i.e. 8.97 EI/R^2; inextensible).
    Measured (the crown load a PointLoad, nodal): 10.5205, 9.3230, 9.0584 EI/R^2 at 16,
    32, 64 cells, observed order 2.18; Richardson's extrapolation 8.9702 (0.003 % off).  Asserted: the order within 0.3 of 2
    (P1 elements), the extrapolation within 0.5 % of 8.97 (the reference's three digits
    and our EA = 1e6 against inextensible)."""
    loads = [deep_arch_limit_load(n) for n in (16, 32, 64)]
    order = np.log2((loads[0] - loads[1]) / (loads[1] - loads[2]))
    assert abs(order - 2.0) < 0.3, loads
    extrapolated = loads[2] + (loads[2] - loads[1]) / 3.0
    assert extrapolated == pytest.approx(8.97, rel=5e-3), (loads, extrapolated)


ARCH_RUNS = {16: 0.1, 32: 0.14, 64: 0.2}   # cells: arc length (~65 steps to the limit)


def deep_arch_scene(n_cells: int, folder: str):
    """scenes/deep_arch.toml at n_cells: the limit load P = 20 t (the parabola through
    the steps around the first maximum of t), its step and the stability counts."""
    import dolfin_rod
    result = dolfin_rod.run(ROOT / "scenes" / "deep_arch.toml", {
        "geometry.n_cells": n_cells, "continuation.arc_length": ARCH_RUNS[n_cells],
        "continuation.max_steps": 100, "outputs.fields": False, "outputs.animation": False,
        "outputs.plots": False}, out=folder, quiet=True)
    assert result.status == "completed"
    limit, top = first_maximum(result.series["time"])
    return 20.0 * limit, top, np.array(result.series["negative_eigenvalues"])


@pytest.mark.mpi
def test_deep_arch_scene(tmp_path):
    """scenes/deep_arch.toml: the 215-degree clamped-pinned arch (R = 1, EI = 1 in its
    plane, EA = GA = 1e6), turned so that its crown is on top, a point_force at the crown
    (loads.point_force, continuation.parameter), at 16 and 32 cells (ds 0.1, 0.14: about
    65 steps to the limit point each).  Measured: limit loads 10.5206, 9.3230 EI/R^2,
    Richardson's extrapolation (order 2) 8.9238, -0.51 % from DaDeppo & Schmidt's 8.97
    (J. Appl. Mech. 42 (1975) 894; Simo & Vu-Quoc 1986: P = 897 for R = 100, EI = 1e6).
    Tolerance 1 %: the extrapolation assumes order 2 where 16/32/64 cells show 2.18 (its
    error ~ 0.2 of the 32-cell error's 3.9 %), plus the reference's 3 digits.  The tangent's count is 0 up to the limit point and 1 on the
    falling branch past it (item 1)."""
    from mpi4py import MPI
    folder = MPI.COMM_WORLD.bcast(str(tmp_path))
    (coarse, top, count), (fine, _, _) = [deep_arch_scene(n, f"{folder}/arch{n}")
                                          for n in (16, 32)]
    assert fine + (fine - coarse) / 3 == pytest.approx(8.97, rel=1e-2), (coarse, fine)
    assert np.all(count[:top] == 0) and np.all(count[top + 2:] == 1), count


@pytest.mark.slow
def test_deep_arch_from_its_scene(tmp_path):
    """scenes/deep_arch.toml at 16, 32, 64 cells: measured 10.520620, 9.323040, 9.058348
    EI/R^2 (order 2.18), Richardson's extrapolation 8.970118 against DaDeppo & Schmidt's
    8.97 (asserted as test_deep_arch_limit_load: order within 0.3 of 2, the
    extrapolation within 0.5 %); the stability count turns 1 at the limit point (within
    one step of it)."""
    loads = []
    for n in (16, 32, 64):
        load, top, count = deep_arch_scene(n, str(tmp_path / f"arch{n}"))
        loads.append(load)
        assert np.all(count[:top] == 0) and count[top + 2] == 1, (n, count[top - 2:top + 3])
    order = np.log2((loads[0] - loads[1]) / (loads[1] - loads[2]))
    assert abs(order - 2.0) < 0.3, loads
    extrapolated = loads[2] + (loads[2] - loads[1]) / 3.0
    assert extrapolated == pytest.approx(8.97, rel=5e-3), (loads, extrapolated)


def lee_frame_limit_load(n_cells: int) -> float:
    """The limit load (x EI/L^2) of Lee's frame: a column (L = 1, pinned at its foot)
    and a beam (L = 1, pinned at its far end) joined rigidly at the knee, a dead point
    force down on the beam 0.2 L from the knee (a node), F = 40 lambda; the pins clamped
    ends turning freely about the normal of the frame's plane (end_turn), out of the
    plane stiff (100 EI, 100 GJ); EA = 43200 EI/L^2 (A = 6, I = 2, L = 120), GA = EA /
    2.6 (nu = 0.3).  Arc length ds = 0.02 on the rod system (the joint's constraint map
    in the bordered Newton); the first maximum of lambda by a parabola."""
    import math

    from dolfin_rod import Rod, RodSystem
    from dolfin_rod.rod.external_forces import PointLoad
    from dolfin_rod.rod.joints import Joint
    params = RodParameters(length=1.0, A=(100.0, 1.0, 100.0), B=(16615.0, 16615.0, 43200.0))
    in_plane = {"start": (0.0, 1.0, 0.0)}, {"end": (0.0, 1.0, 0.0)}
    rods = [Rod(params, n_cells, start="clamped", end="free", end_turn=in_plane[0],
                name="column"),
            Rod(params, n_cells, start="free", end="clamped", end_turn=in_plane[1],
                name="beam", position=(0.0, 0.0, 1.0), orientation=(0.0, math.pi / 2, 0.0),
                point_loads=[PointLoad("force", (0.0, 0.0, -1.0), 0.2, lambda t: 40.0 * t)])]
    frame = RodSystem(rods, joints=[Joint("rigid", ("column", "beam"), (0.0, 0.0, 1.0))],
                      model="hyperelastic")
    frame.set_initial_state()
    path = ArcLength(frame, ds=0.02, max_steps=20 * n_cells + 200)   # past the limit
    path.run(0.0, 1.0)
    return 40.0 * first_maximum(np.array(path.points)[:, 0])[0]


@pytest.mark.slow
def test_lee_frame_limit_load():
    """Lee's frame (Lee, Manuel & Rossow 1968; Schweizerhof & Wriggers 1986: limit load
    about 18.5 EI/L^2): arc-length continuation through the joint.  Measured 18.937692,
    18.643406, 18.570713 EI/L^2 at 10, 20, 40 cells per member (order 2.02), Richardson's
    extrapolation 18.5465 (the point load nodal; with the 2-point rule that smeared it,
    before, 19.097394, 18.681955, 18.580192, 18.5463).  Asserted: the order within 0.3 of 2, the extrapolation within
    0.5 % of 18.5 (the published value's digits)."""
    loads = [lee_frame_limit_load(n) for n in (10, 20, 40)]
    order = np.log2((loads[0] - loads[1]) / (loads[1] - loads[2]))
    assert abs(order - 2.0) < 0.3, loads
    extrapolated = loads[2] + (loads[2] - loads[1]) / 3.0
    assert extrapolated == pytest.approx(18.5, rel=5e-3), (loads, extrapolated)


def test_a_continuation_parameter_that_is_not_a_load_is_refused(tmp_path, capsys):
    from dolfin_rod.cli import main
    scene = tmp_path / "arch.toml"
    scene.write_text((ROOT / "scenes" / "snap_through_arch.toml").read_text().replace(
        'parameter = "loads.start_force"', 'parameter = "material.stiffness"'))
    assert main(["check", str(scene)]) == 2
    err = capsys.readouterr().err
    assert "[continuation.parameter]: 'material.stiffness' is not a load of this scene: " \
           "name one of loads.start_force" in err, err


@pytest.mark.mpi
def test_lee_frame_from_its_scene(tmp_path):
    """scenes/lee_frame.toml (two [[rods]] and a rigid joint; the continuation parameter
    names the beam's point_force, a load of one rod: checked on the system, not per rod):
    the limit load at 10 cells per member is the API's (lee_frame_limit_load: 18.937692
    EI/L^2, the same discrete frame and arc length: to the parabola's 6 digits) and lies
    within its discretisation error of the published 18.5 (2.1 % from the 10/20/40-cell
    extrapolation 18.5465; asserted 3 %).  Cut at 230 steps (the limit: step ~207).
    The stability count on the joint's free dofs (P^T K P) is 0 up to the limit point
    and 1 past it (measured: it turns 1 at t = 0.473437, the first step after the
    maximum 0.4734423 of t)."""
    import dolfin_rod
    from mpi4py import MPI
    result = dolfin_rod.run(ROOT / "scenes" / "lee_frame.toml", {
        "continuation.max_steps": 230, "outputs.fields": False, "outputs.animation": False,
        "outputs.plots": False}, out=MPI.COMM_WORLD.bcast(str(tmp_path / "lee")), quiet=True)
    assert result.status == "completed"
    limit, top = first_maximum(result.series["time"])
    assert 40.0 * limit == pytest.approx(18.937692, rel=1e-6)
    assert 40.0 * limit == pytest.approx(18.5, rel=3e-2)
    count = np.array(result.series["negative_eigenvalues"])
    assert np.all(count[:top + 1] == 0) and np.all(count[top + 1:] == 1), count[top - 2:top + 3]
    # the load's point on the beam (beam.point0_position_*: force_extension's curve)
    # starts at the beam's s = 0.2 and stays in the frame's plane
    point = np.array([result.series[f"beam.point0_position_{c}"] for c in "xyz"])
    assert point[:, 0] == pytest.approx([0.2, 0.0, 1.0], abs=1e-12)
    assert np.max(np.abs(point[1])) < 1e-12


def test_a_systems_continuation_parameter_names_a_load_of_any_rod():
    """A parameter that is no rod's load: exit-2 error naming the key and the rods' loads."""
    from dolfin_rod import SceneError, parse_scene
    text = (ROOT / "scenes" / "lee_frame.toml").read_text()
    with pytest.raises(SceneError, match=r"continuation\.parameter.*'loads\.end_force' is "
                                         r"not a load of this scene: name one of "
                                         r"loads\.point_force"):
        parse_scene(text.replace('parameter = "loads.point_force"',
                                 'parameter = "loads.end_force"'))
