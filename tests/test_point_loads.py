"""Concentrated forces and couples inside a rod (rod/external_forces.PointLoad; scene keys
loads.point_force, loads.point_couple; issue 27).

A point load at s_0 enters as its consistent load vector: the P1 hat functions' values
N_i(s_0) times the load on the nodes around s_0 (all of it on the node when s_0 is one),
evaluated at the nodes (vertex rule plus the end points).  References: Euler-Bernoulli
beam formulas plus the shear term (Timoshenko), for small loads (rotations ~1e-5, so the
geometric nonlinearity is ~1e-10 relative).
"""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod import TimeStepper
from dolfin_rod.fem.fe_model import NodeValues
from dolfin_rod.rod import PointLoad, RodModel, RodParameters
from dolfin_rod.rod.diagnostics import tip_rotation_angle

EI, GA, P = 1.0, 1e4, 1e-4
BEAM = RodParameters(length=1.0, A=(EI, EI, 1.0), B=(GA, GA, GA))


def solve(rod):
    rod.set_initial_state()
    TimeStepper(rod.problem).run(0.0, 1.0, 1.0)
    return rod.diagnostics(1.0)


def midspan_deflection(n_cells: int) -> float:
    """The clamped-clamped beam (L = 1) under P e_1 at s = L/2: its deflection there."""
    rod = RodModel(BEAM, n_cells=n_cells, model="hyperelastic", start="clamped", end="clamped",
                   point_loads=[PointLoad("force", (P, 0.0, 0.0), 0.5)])
    solve(rod)
    mid = NodeValues(rod.f["displacement"].function_space, [0.5])
    return float(mid(rod.f["displacement"].x.array)[0][0])


@pytest.mark.mpi
def test_central_force_on_a_clamped_beam():
    """w(L/2) = P L^3/(192 EI) + P L/(4 GA) (bending: Roark; shear: the shear force P/2 over
    each half; the clamps' moment does not depend on the shear compliance, by symmetry).
    Measured (P1, one-point strains): relative errors -1.555e-2, -3.888e-3 at 16, 32
    cells (observed order 2.0000; -6.22e-2 at 8), Richardson's extrapolation of the two
    -2.3e-10: the discrete beam's error is c h^2 alone.  Asserted: the order within 0.05
    of 2, the 32-cell value within 1e-2 (its O(h^2) error) and the extrapolation within
    1e-6 (the geometric nonlinearity, (P/EI)^2 ~ 1e-8, and Newton's tolerance)."""
    reference = P / (192 * EI) + P / (4 * GA)
    w16, w32 = midspan_deflection(16), midspan_deflection(32)
    order = np.log2((w16 - reference) / (w32 - reference))
    assert abs(order - 2.0) < 0.05, (w16, w32, reference)
    assert w32 == pytest.approx(reference, rel=1e-2)
    assert w32 + (w32 - w16) / 3 == pytest.approx(reference, rel=1e-6)


@pytest.mark.mpi
@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
def test_couple_between_nodes_of_a_cantilever(rotations):
    """A couple C e_2 at s_0 = 0.3 (between the nodes 0.25 and 0.375 of 8 cells) of a
    clamped-free cantilever: the rod beyond s_0 carries no moment, so the tip turns by
    C s_0/EI, and the clamp takes -C.  The consistent load (C N_i(s_0) on the two nodes)
    gives the discrete rod exactly this turn (each cell's curvature is its moment/EI;
    the cells before s_0 carry C, the cell across s_0 C N_{i+1}(s_0) = C (s_0 - s_i)/h),
    up to the geometric nonlinearity, of the order of the rotations (3e-5 rad: the two
    nodes' shares act on sections turned by ~1e-5 rad from each other; measured -2.1e-6
    relative), so the tolerance 1e-5 relative."""
    C, s0 = 1e-4, 0.3
    rod = RodModel(BEAM, n_cells=8, model="hyperelastic", rotations=rotations,
                   point_loads=[PointLoad("couple", (0.0, C, 0.0), s0)])
    d = solve(rod)
    assert tip_rotation_angle(d) == pytest.approx(C * s0 / EI, rel=1e-5)
    assert d["reaction_couple_start_y"] == pytest.approx(-C, rel=1e-5)


@pytest.mark.parametrize("rotations", ["rotation_vector", "quaternion"])
@pytest.mark.parametrize("kind", ["force", "couple"])
def test_a_follower_point_load_at_the_tip_is_the_end_load(kind, rotations):
    """A large follower force or couple (tip rotation ~1 rad) as a PointLoad at s = L
    equals the EndLoad at the right end: the same virtual work (the hat's value 1 at the
    tip node, h/2 from its cell's vertex rule and h/2 at the end point), so the same
    equilibrium to Newton's tolerance (1e-10) over two load steps (both rotation unknowns'
    forms evaluate the point load at the nodes: measured equal to round-off)."""
    from dolfin_rod import loads
    from dolfin_rod.rod import EndLoad
    value, ramp = (1.0, 0.0, 0.0) if kind == "force" else (0.0, 1.0, 0.0), loads.ramp(1.0, 1.0)
    tips = []
    for load in ({"point_loads": [PointLoad(kind, value, 1.0, ramp, follower=True)]},
                 {"end_loads": [EndLoad(kind, value, ramp, follower=True)]}):
        rod = RodModel(BEAM, n_cells=8, model="hyperelastic", rotations=rotations, **load)
        rod.set_initial_state()
        TimeStepper(rod.problem).run(0.0, 1.0, 0.5)
        d = rod.diagnostics(1.0)
        tips.append([d[f"tip_position_{c}"] for c in "xyz"] + [tip_rotation_angle(d)])
    assert tips[1][3] > 0.4                  # large: the follower part matters
    assert np.allclose(tips[0], tips[1], rtol=0.0, atol=1e-9), tips


def test_a_point_load_off_the_rod_is_refused():
    with pytest.raises(ValueError, match=r"PointLoad s must be on the rod, 0 <= s <= L = 1"):
        RodModel(BEAM, n_cells=4, point_loads=[PointLoad("force", (P, 0.0, 0.0), 1.5)])


SCENE = """
[scene]
name = "clamped_beam"
[geometry]
length = 1.0
n_cells = 16
[material]
model = "hyperelastic"
stiffness = { A = [1.0, 1.0, 1.0], B = [1e4, 1e4, 1e4] }
[boundary]
start = "clamped"
end = "clamped"
[loads]
point_force = { s = 0.5, type = "ramp", value = [1e-4, 0.0, 0.0], duration = 1.0 }
[time]
t_end = 1.0
dt = 0.5
[outputs]
fields = false
animation = false
plots = false
"""


@pytest.mark.mpi
def test_central_force_from_a_scene(tmp_path):
    """loads.point_force: the same beam (16 cells) as above from a scene: each clamp takes
    -P/2 (equilibrium and symmetry: the load enters whole, at the middle), the
    position of the load's point (column point0_position_x) is the API's, and the
    clamped beam's end moment P L/8 (Roark; independent of the shear compliance; measured
    -5.2e-3 off, the O(h^2) error, h^2 = 3.9e-3: tolerance 1e-2)."""
    import dolfin_rod
    from mpi4py import MPI
    scene = tmp_path / "beam.toml"
    if MPI.COMM_WORLD.rank == 0:
        scene.write_text(SCENE)
    scene = MPI.COMM_WORLD.bcast(str(scene))
    result = dolfin_rod.run(scene, out=MPI.COMM_WORLD.bcast(str(tmp_path / "out")),
                            quiet=True)
    assert result.status == "completed"
    for end in ("start", "end"):
        assert result.series[f"reaction_force_{end}_x"][-1] == pytest.approx(-P / 2, rel=1e-6)
    # the column at the load's point: the API's deflection (same model and kernels)
    assert result.series["point0_position_x"][-1] == pytest.approx(midspan_deflection(16),
                                                                     rel=1e-9)
    for end, sign in (("start", -1), ("end", 1)):      # measured 1.2435e-5: O(h^2)
        assert sign * result.series[f"reaction_couple_{end}_y"][-1] == pytest.approx(
            P / 8, rel=1e-2)


def test_a_point_load_off_the_rod_is_refused_by_the_scene(tmp_path, capsys):
    from dolfin_rod.cli import main
    scene = tmp_path / "beam.toml"
    scene.write_text(SCENE.replace("s = 0.5", "s = 1.5"))
    assert main(["check", str(scene)]) == 2
    assert "[loads.point_force.s]: 1.5 is not on the rod: 0 <= s <= geometry.length = 1" \
        in capsys.readouterr().err
