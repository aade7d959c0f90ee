"""The rod's segments (rod/segments.py): closest points of segment pairs against a brute
force search, the broad phase against all pairs, and the warning when a rod passes
through itself between two output times (serial and mpirun -n 2)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod.rod import RodModel, RodParameters
from dolfin_rod.rod.segments import PassThroughWarning, closest_points, near_pairs
from dolfin_rod.scenes import build, parse_scene


def _brute(p0, p1, q0, q1, n=801):
    """min over a fine grid of both parameters (the reference distance)."""
    u = np.linspace(0.0, 1.0, n)
    P = p0 + u[:, None] * (p1 - p0)
    Q = q0 + u[:, None] * (q1 - q0)
    return np.min(np.linalg.norm(P[:, None, :] - Q[None, :, :], axis=-1))


CASES = {   # crossing at right angles, parallel overlapping, parallel apart, collinear,
            # skew with a clamped end, touching ends
    "crossing": ([0, -1, 0], [0, 1, 0], [-1, 0, 0.5], [1, 0, 0.5], 0.5),
    "parallel": ([0, 0, 0], [2, 0, 0], [1, 0.3, 0], [3, 0.3, 0], 0.3),
    "parallel_apart": ([0, 0, 0], [1, 0, 0], [2, 0.4, 0], [3, 0.4, 0], np.hypot(1.0, 0.4)),
    "collinear": ([0, 0, 0], [1, 0, 0], [1.5, 0, 0], [2.5, 0, 0], 0.5),
    "skew_clamped": ([0, 0, 0], [1, 0, 0], [2, -1, 1], [2, 1, 1], np.sqrt(2.0)),
    "ends": ([0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 1, 0], 0.0),
}


@pytest.mark.parametrize("name", CASES)
def test_closest_points_of_two_segments(name):
    """Distances of the closed-form cases and the grid search agree (to the grid's
    resolution 1e-6 relative of the segments' length squared); random pairs too."""
    p0, p1, q0, q1, exact = (np.asarray(v, float) for v in CASES[name])
    _, _, d = closest_points(p0[None], p1[None], q0[None], q1[None])
    assert d[0] == pytest.approx(exact, abs=1e-12)
    assert d[0] == pytest.approx(_brute(p0, p1, q0, q1), abs=1e-5)


def test_closest_points_of_random_segments():
    rng = np.random.default_rng(3)
    P0, P1, Q0, Q1 = (rng.standard_normal((40, 3)) for _ in range(4))
    _, _, d = closest_points(P0, P1, Q0, Q1)
    brute = [_brute(*v, n=401) for v in zip(P0, P1, Q0, Q1)]
    assert np.allclose(d, brute, atol=1e-4)
    assert np.all(d <= np.array(brute) + 1e-12)      # the exact minimum is below the grid's


@pytest.mark.parametrize("tree", [True, False])
def test_broad_phase_finds_every_near_pair(tree):
    """A random walk of 400 segments: the pairs found with the tree, or by comparing the
    midpoints of every pair, are those of the O(N^2) search of closest points."""
    rng = np.random.default_rng(7)
    nodes = np.cumsum(0.1 * rng.standard_normal((401, 3)), axis=0)
    p0, p1 = nodes[:-1], nodes[1:]
    s = np.arange(400) + 0.5
    found = {tuple(p) for p in near_pairs(p0, p1, s, 0.05, 3.0, tree=tree)}
    i, j = np.triu_indices(400, 1)
    keep = np.abs(s[i] - s[j]) >= 3.0
    i, j = i[keep], j[keep]
    d = closest_points(p0[i], p1[i], p0[j], p1[j])[2]
    assert found == {(a, b) for a, b in zip(i[d < 0.05], j[d < 0.05])}
    assert len(found) > 0


def _figure_eight(rod, height: float) -> None:
    """The centre line a figure eight in the x-y plane, crossing itself at the origin
    (s = 1/7 and 6/7) with the branch s = 6/7 passing 'height' above the other."""
    x = rod.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    u = np.pi * (1.4 * s - 0.2)
    r = np.stack([np.sin(u), 0.5 * np.sin(2 * u), height * (2 * s - 1)], axis=1)
    x.x.array[:] = (r - np.outer(s, (0.0, 0.0, 1.0))).ravel()


@pytest.mark.mpi
def test_a_rod_passing_through_itself_is_reported_once():
    """Between two output times the rod's branches swap sides at the crossing: one
    warning naming the time and the two places (s = 1/7, 6/7 within a cell); nothing
    while the branches keep their sides."""
    rod = RodModel(RodParameters(), n_cells=28, model="hyperelastic", start="free", end="free",
                   rotations="quaternion")
    rod.set_initial_state()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for t, height in ((0.0, 0.01), (0.1, 0.012), (0.2, -0.01), (0.3, 0.01)):
            _figure_eight(rod, height)
            rod.diagnostics(t)
    found = [w for w in caught if issubclass(w.category, PassThroughWarning)]
    if MPI.COMM_WORLD.rank == 0:
        assert len(found) == 1
        text = str(found[0].message)
        assert "t = 0.2 " in text and "self-contact" in text
        places = sorted(float(v) for v in text.split("s = ")[1:3] for v in [v.split()[0]])
        assert places[0] == pytest.approx(1 / 7, abs=1 / 28)
        assert places[1] == pytest.approx(6 / 7, abs=1 / 28)
    else:
        assert not found


TWO_RODS = """
[material]
model = "hyperelastic"
stiffness = { A = [1e-2, 1e-2, 1e-2], B = [10.0, 10.0, 10.0] }
density = 1.0
section_inertia = 1e-5
[[rods]]
name = "a"
geometry = { length = 0.5, n_cells = 11 }
boundary = { start = "free", end = "free" }
[[rods]]
name = "b"
position = [1.0, 0.0, 0.0]
geometry = { length = 0.5, n_cells = 11 }
boundary = { start = "free", end = "free" }
[time]
t_end = 1.0
dt = 0.1
"""


def _two_rods(text: str):
    """(model, its displacement Function, s at its dofs, where rod b's s begins) of a
    started two-rod scene."""
    sim = build(parse_scene(text), "rod")
    sim.start()
    x = sim.model.f["displacement"]
    return sim.model, x, x.function_space.tabulate_dof_coordinates()[:, 0], \
        sim.model.layout.starts[1]


@pytest.mark.mpi
def test_two_rods_passing_through_each_other_are_reported_once():
    """[[rods]] without contact.between_rods: rod a along x, rod b along y crossing it
    at both midpoints (s = 0.25 on each), b moved
    from 1 cm above a to 1 cm below between two output times: one warning naming both
    rods and s on each (each tangent 45 degrees from the mean: the one-rod shortcut,
    no pass-through within 60 degrees of a mean direction, must not hide it); nothing
    while b stays above."""
    rod, x, s, b_start = _two_rods(TWO_RODS)
    local = np.where(s < b_start, s, s - b_start)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for t, height in ((0.0, 0.01), (0.1, 0.012), (0.2, -0.01), (0.3, 0.01)):
            r = np.where((s < b_start)[:, None],
                         np.stack([local - 0.25, 0 * s, 0 * s], axis=1),
                         np.stack([0 * s, local - 0.25, height + 0 * s], axis=1))
            x.x.array[:] = (r - np.outer(s, (0.0, 0.0, 1.0))).ravel()
            rod.diagnostics(t)
    found = [w for w in caught if issubclass(w.category, PassThroughWarning)]
    if MPI.COMM_WORLD.rank == 0:
        assert len(found) == 1
        text = str(found[0].message)
        words = re.fullmatch(r"at t = 0\.2 rod a near s = ([0-9.]+) and rod b near "
                             r"s = ([0-9.]+) passed through each other \(.*\)", text)
        assert words, text
        # the crossing's cell (midpoint 0.25) or a neighbour's may flip first: within a
        # cell h = 0.5 / 11, plus 1e-4 for the 4 digits printed
        assert [float(v) for v in words.groups()] == pytest.approx([0.25, 0.25],
                                                                   abs=0.5 / 11 + 1e-4)
        assert "contact.between_rods" in text
    else:
        assert not found


HINGED = TWO_RODS.replace('position = [1.0, 0.0, 0.0]', 'position = [0.0, 0.0, 0.5]\n'
                          'orientation = [0.0, 1.5707963267948966, 0.0]') + """
[[joints]]
kind = "ball"
rods = ["a", "b"]
point = [0.0, 0.0, 0.5]
"""


@pytest.mark.mpi
def test_rods_meeting_at_a_joint_are_neighbours_there():
    """A gate b (along x) on a ball joint at the top of a post a (along z), as in
    scenes/hinged_door.toml, turned about the post between outputs and shifted across
    it by +-1e-9 m (the joint's own wobble): the segments beside the joint are nearer
    than a cell, their crossing side is the sign of that wobble (the gap between their
    closest points lies along the post, normal to t_a x t_b), which flipped and warned
    in the bundled hinged_door and tripod scenes.  Segments within the exclusion 3h of the joint
    along both rods are neighbours (as along one rod): no warning."""
    rod, x, s, b_start = _two_rods(HINGED)
    on_a = (s < b_start)[:, None]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for t, angle, side in ((0.0, 0.0, 1e-9), (0.1, 0.1, -1e-9), (0.2, 0.2, 1e-9)):
            local = s - b_start
            gate = np.stack([local * np.cos(angle) - side * np.sin(angle),
                             local * np.sin(angle) + side * np.cos(angle),
                             0.5 + 0 * s], axis=1)
            r = np.where(on_a, np.stack([0 * s, 0 * s, s], axis=1), gate)
            x.x.array[:] = (r - np.outer(s, (0.0, 0.0, 1.0))).ravel()
            rod.diagnostics(t)
    assert not [w for w in caught if issubclass(w.category, PassThroughWarning)]
