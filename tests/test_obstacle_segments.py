"""Segment contact with thin obstacles (issue 26; rod/obstacle_segments.py,
docs/contact.md "Thin obstacles"): a rod rests on a cylinder thinner than its cells.

References: beam theory (a cantilever propped at a point a inside a cell: the prop's
reaction from the deflection it holds), the closest points of a segment and a point or a
segment by dense sampling, Taylor remainders of the energy's gradient and Hessian
(Newton's quadratic convergence), the run that stopped before (tests/test_thin_obstacle:
a rod thrown at a 6 mm cylinder between its nodes).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod.rod.contact import ContactLaw, Obstacle, check_contact, on_segments
from dolfin_rod.rod.pair_contact import pair_energy
from dolfin_rod.rod.segments import closest_points
from test_contact import DELTA, PROPPED, R, propped_rod
from test_pair_contact import energy_drift

THIN_R = 0.003          # the bar's radius: nodes 1/16 apart cannot hold a rod across it


def test_closest_points_of_a_segment_and_a_point_against_sampling():
    """A second segment of length 0 (a sphere's centre) is a point: the distance is the
    least of 20001 samples of the first segment's distance to it (to the samples'
    spacing, Lipschitz 1: 1e-4 of the segment's length), t = 0."""
    rng = np.random.default_rng(3)
    p0, p1, q = (rng.uniform(-1, 1, (200, 3)) for _ in range(3))
    s, t, d = closest_points(p0, p1, q, q)
    u = np.linspace(0.0, 1.0, 20001)[None, :, None]
    sampled = np.min(np.linalg.norm(p0[:, None] + u * (p1 - p0)[:, None] - q[:, None],
                                    axis=2), axis=1)
    length = np.linalg.norm(p1 - p0, axis=1)
    assert np.all(t == 0.0)
    assert np.all(d <= sampled + 1e-15) and np.all(sampled - d <= 1e-4 * length)
    assert np.all((s >= 0) & (s <= 1)) and 0 < np.sum((s > 0) & (s < 1)) < 200


@pytest.mark.parametrize("shape", ["sphere", "cylinder"])
def test_segment_obstacle_energy_taylor_test(shape):
    """The energy of a segment near a thin obstacle (pair_energy with the obstacle's
    segment fixed; its rows of the segment's two nodes): |E(X + h dX) - E - h G dX| and
    |G(X + h dX) - G - h H dX| fall 4-fold per halving of h (ratios 4 +- 0.2: second
    order, the consistent Hessian Newton converges quadratically with), the segment's
    closest point inside it and (cylinder) inside the bar's axis."""
    q0, q1 = ((0.0, 0.0, 0.0),) * 2 if shape == "sphere" else ((0.0, -0.1, 0.0),
                                                                 (0.0, 0.1, 0.0))
    rho, delta = THIN_R + R, DELTA
    X = np.array([[[rho + 0.4 * delta, 0.01, -0.03], [rho + 0.6 * delta, -0.02, 0.04],
                   q0, q1]])
    rng = np.random.default_rng(2)
    dX = np.zeros_like(X)
    dX[0, :2] = rng.standard_normal((2, 3))

    def terms(Y):
        return pair_energy(Y, 0.5 * rho, delta, 1e3, np.array([0.05]))

    E, G, H = terms(X)
    s, t, _ = closest_points(*X[:, :, None].transpose(1, 2, 0, 3)[:, 0])
    assert 0 < s[0] < 1 and (shape == "sphere" or 0 < t[0] < 1)
    g, h6 = G[0, :6], H[0, :6, :6]
    step = dX[0, :2].ravel()
    rests = []
    for k in range(4):
        h = 1e-5 * delta * 2.0**-k
        E1, G1, _ = terms(X + h * dX)
        rests.append((abs(E1[0] - E[0] - h * g @ step),
                      np.linalg.norm(G1[0, :6] - g - h * h6 @ step)))
    ratios = np.array(rests[:-1]) / np.array(rests[1:])
    assert np.all(np.abs(ratios - 4.0) < 0.2), ratios


def _rod_near(obstacle: Obstacle, curve: str):
    """A free quasi-static rod (L = 1, 8 cells, r = 1 cm) near ``obstacle``, its contact
    on the obstacle's segment with contact.obstacle_curve ``curve`` (kappa = 1e3), and
    its nodes' arc lengths (owned)."""
    from dolfin_rod.rod import RodModel
    from test_contact import ROD
    rod = RodModel(ROD, n_cells=8, model="hyperelastic", start="free", end="free",
                   obstacles=[obstacle],
                   contact=ContactLaw(R, DELTA, 1e3, obstacle_curve=curve))
    rod.set_initial_state()
    seg = rod.obstacle_segments
    x = seg.x
    return seg, x.function_space.tabulate_dof_coordinates()[:seg.line.n_owned, 0]


def _assembled(seg, u: np.ndarray):
    """(E, gradient (nodes, 3), Hessian (3 nodes, 3 nodes)) of the term at the owned
    displacement u, summed over its pairs (the rows the systems get)."""
    terms = seg.evaluate(u)
    n, k = seg.line.n_nodes, terms.nodes.shape[1]
    g = np.zeros((n, 3))
    np.add.at(g, terms.nodes, terms.gradient.reshape(-1, k, 3))
    dofs = (3 * terms.nodes[:, :, None] + np.arange(3)).reshape(len(terms.nodes), -1)
    H = np.zeros((3 * n, 3 * n))
    np.add.at(H, (dofs[:, :, None], dofs[:, None, :]), terms.hessian)
    return terms.energy.sum(), g, H


@pytest.mark.parametrize("shape, a", [("cylinder", 0.5625), ("cylinder", 0.504),
                                      ("sphere", 0.5625)])
def test_curve_obstacle_energy_taylor_test(shape, a):
    """contact.obstacle_curve = "smooth": the energy of a bent rod's C^1 curve near a thin
    bar (in a cell's middle, and 4 mm from a node: the neighbouring cell's curve within
    reach, not counted) or a small sphere, summed as assembled: |E(u + h du) - E - h G du|
    and |G(u + h du) - G - h H du| fall 4-fold per halving of h (ratios 4 +- 0.2: the
    value function's Hessian, consistent with the gradient: Newton converges
    quadratically), over random du of every node."""
    bent = lambda s: np.column_stack([-0.3 * (s - 0.5)**2, 0.02 * np.sin(3 * s), 0 * s])
    centre = bent(np.array([a]))[0] + (-(R + 0.5 * DELTA + THIN_R), 0.0, a)
    ob = Obstacle(shape, centre=tuple(centre), axis=(0.0, 1.0, 0.0), radius=THIN_R,
                  length=0.2)
    seg, s = _rod_near(ob, "smooth")
    u = bent(s).ravel()
    du = np.random.default_rng(5).standard_normal(u.shape)
    E, g, H = _assembled(seg, u)
    assert E > 0 and len(seg.evaluate(u).energy) == 1
    dX = seg.line.gather(du.reshape(-1, 3))
    rests = []
    for k in range(4):
        h = 1e-5 * DELTA * 2.0**-k
        E1, g1, _ = _assembled(seg, u + h * du)
        rests.append((abs(E1 - E - h * np.sum(g * dX)),
                      np.linalg.norm((g1 - g).ravel() - h * H @ dX.ravel())))
    ratios = np.array(rests[:-1]) / np.array(rests[1:])
    assert np.all(np.abs(ratios - 4.0) < 0.2), ratios


def test_a_straight_rods_curve_counts_a_bar_once_wherever_it_lies():
    """A straight rod slid along itself across a bar (from one node to the next, 51
    places, both nodes included): on the C^1 curve (collinear nodes: the line, the curve
    reproduces it) the energy and force are the line's, kappa h b(g) and kappa h b'(g),
    one pair, at every place to 1e-12; on the segments a node on the bar has its two
    cells' energy: twice that of a cell's middle."""
    from dolfin_rod.rod.contact import barrier_derivatives
    g = 0.5 * DELTA
    bar = Obstacle("cylinder", centre=(-(R + g + THIN_R), 0.0, 0.5625), axis=(0.0, 1.0, 0.0),
                   radius=THIN_R, length=0.2)
    b, b1, _ = barrier_derivatives(np.array([g]), DELTA)
    for curve in ("smooth", "segments"):
        seg, s = _rod_near(bar, curve)
        energies, forces = [], []
        for shift in np.linspace(-0.0625, 0.0625, 51):
            u = np.tile((0.0, 0.0, shift), len(s))
            E, grad, _ = _assembled(seg, u)
            assert curve == "segments" or len(seg.evaluate(u).energy) == 1
            energies.append(E)
            forces.append(-grad.sum(axis=0))
        energies, forces = np.array(energies), np.array(forces)
        if curve == "smooth":
            assert np.allclose(energies, 1e3 * b[0] / 8, rtol=1e-12, atol=0)
            force = -1e3 * b1[0] / 8
            assert np.allclose(forces, (force, 0.0, 0.0), rtol=1e-12, atol=1e-12 * force)
        else:
            assert energies[25] == pytest.approx(1e3 * b[0] / 16, rel=1e-12)
            assert energies[0] == pytest.approx(2 * energies[25], rel=1e-12)


def test_auto_chooses_segments_for_thin_obstacles_only():
    """obstacles[k].contact = "auto": segments where nodes h apart cannot hold a rod
    across the obstacle (h^2 >= 4 (r + delta) (2 R + r + delta); a mesh: some convex
    edge has (h / 2) sin(phi / 2) >= r + delta, a cube's edges at h >= 2 sqrt(2)
    (r + delta)), with or without friction; nodes elsewhere and for planes; explicit
    choices kept."""
    reach = R + DELTA
    h_limit = np.sqrt(4 * reach * (2 * THIN_R + reach))
    bar = Obstacle("cylinder", centre=(0, 0, 0), axis=(0, 1, 0), radius=THIN_R, length=0.1)
    assert on_segments(bar, R, DELTA, 1.001 * h_limit)
    assert not on_segments(bar, R, DELTA, 0.999 * h_limit)
    assert on_segments(Obstacle("sphere", centre=(0, 0, 0), radius=THIN_R, friction=0.3),
                       R, DELTA, 1.0)
    for ob in (Obstacle("plane", point=(0, 0, 0), normal=(1, 0, 0)),
               Obstacle("sphere", centre=(0, 0, 0), radius=THIN_R, contact="nodes")):
        assert not on_segments(ob, R, DELTA, 1.0)
    assert on_segments(Obstacle("sphere", centre=(0, 0, 0), radius=1.0, contact="segments"),
                       R, DELTA, 1e-3)
    cube = replace(_diamond(0.5), contact="auto")
    assert on_segments(cube, R, DELTA, 1.001 * 2 * np.sqrt(2) * reach)
    assert not on_segments(cube, R, DELTA, 0.999 * 2 * np.sqrt(2) * reach)
    assert not on_segments(replace(cube, contact="nodes"), R, DELTA, 1.0)


@pytest.mark.mpi
def test_auto_puts_a_cubes_sharp_edges_on_the_segments():
    """The propped cantilever's rod (16 cells: h = 1/16 > 2 sqrt(2) (r + delta) = 0.031)
    over the cube with contact = "auto": its faces on the nodes and its 12 edges on the
    segments, as with "segments"; with a radius 5 times the cell's the edges are held
    by the nodes (h < 2 sqrt(2) (r + delta)): nodes only."""
    from dolfin_rod.rod import RodModel, RodParameters
    for radius, edges in ((R, 12), (5 * R, 0)):
        rod = RodModel(RodParameters(length=1.0, A=(1e-2,) * 3, B=(1e3,) * 3), 16,
                       model="hyperelastic", obstacles=[replace(_diamond(0.78125),
                                                                contact="auto")],
                       contact=ContactLaw(radius, DELTA, 1.0))
        assert rod.contact.nodal == [0]
        assert len(rod.obstacle_segments.index if rod.obstacle_segments else ()) == edges


@pytest.mark.parametrize("ob, key", [
    (Obstacle("plane", point=(0, 0, 0), normal=(1, 0, 0), contact="segments"),
     "obstacles[0].contact"),
    (Obstacle("sphere", centre=(0, 0, 0), radius=0.1, contact="edges"), "obstacles[0].contact")])
def test_bad_segment_contact_is_named(ob, key):
    with pytest.raises(ValueError, match=key.replace("[", r"\[").replace("]", r"\]")):
        check_contact([ob], ContactLaw(R, DELTA, 1.0))


def test_bad_obstacle_curve_is_named():
    """contact.obstacle_curve other than "segments" or "smooth": one error naming the key
    (the law's, and the scene's before anything is built: the CLI's exit 2)."""
    from pathlib import Path

    from dolfin_rod.scenes import SceneError, parse_scene
    with pytest.raises(ValueError, match=r"contact\.obstacle_curve"):
        check_contact([], ContactLaw(R, DELTA, 1.0, obstacle_curve="hermite"))
    text = (Path(__file__).resolve().parents[1] / "scenes/rope_over_thin_bar.toml").read_text()
    text = text.replace("[contact]\n", '[contact]\nobstacle_curve = "hermite"\n')
    with pytest.raises(SceneError, match=r"contact\.obstacle_curve"):
        parse_scene(text)


def _point_at(rod, a: float) -> np.ndarray:
    """The centre line's point at s = a (P1: linear between the nodes), over all ranks."""
    x = rod.unknowns.f["displacement"]
    n = x.function_space.dofmap.index_map.size_local
    s = x.function_space.tabulate_dof_coordinates()[:n, 0]
    gathered = MPI.COMM_WORLD.allgather((s, x.x.array.reshape(-1, 3)[:n]))
    s_all = np.concatenate([g[0] for g in gathered])
    x_all = np.concatenate([g[1] for g in gathered]) + np.outer(s_all, (0.0, 0.0, 1.0))
    order = np.argsort(s_all)
    return np.array([np.interp(a, s_all[order], x_all[order, i]) for i in range(3)])


@pytest.mark.mpi
@pytest.mark.parametrize("curve", ["segments", "smooth"])
def test_cantilever_propped_by_a_thin_bar_between_two_nodes(curve):
    """The quasi-static cantilever of test_contact (L = 1, EI = 1e-2, w = 0.02, 16 cells,
    r = 1 cm) propped by a bar of radius 3 mm across it at a = 0.78125, the middle of a
    cell (nodes 3.1 cm on either side: beyond the barrier's reach, so the nodal law
    would let the cell pass through it; "auto" takes segments).  Beam theory's reaction of
    a prop at a that holds the deflection Delta (the centre line's at a):
    F = 3 EI / a^3 (w a^2 (6 L^2 - 4 L a + a^2) / (24 EI) - Delta), to 1 % (the P1 rod's
    O(h^2) error at 16 cells with the point force spread on the cell's two nodes: 0.12 %
    measured; 0.12 % on the C^1 curve, contact.obstacle_curve = "smooth", Delta its
    contact point's); the gap in (0, delta); the force normal to the centre line where
    it touches the bar (frictionless: to the cell's chord, to the curve's tangent)."""
    w, EI = PROPPED
    a = 0.78125
    bar = Obstacle("cylinder", centre=(-(R + 0.5 * DELTA + THIN_R), 0.0, a),
                   axis=(0.0, 1.0, 0.0), radius=THIN_R, length=0.2)
    rod = propped_rod(bar, curve=curve)
    assert rod.contact.segment_obstacles == [0]
    d = rod.diagnostics(1.0)
    point, tangent = (_contact_point(rod) if curve == "smooth" else
                      (_point_at(rod, a), _point_at(rod, a + 1 / 32) - _point_at(rod, a - 1 / 32)))
    Delta = -point[0]
    reaction = 3 * EI / a**3 * (w * a**2 * (6 - 4 * a + a**2) / (24 * EI) - Delta)
    assert 0.0 < d["min_gap"] < DELTA
    assert Delta < w * a**2 * (6 - 4 * a + a**2) / (24 * EI)       # held
    assert d["contact_force_x"] == pytest.approx(reaction, rel=1e-2)
    # frictionless: the force is normal to the centre line at the contact (not to e_3:
    # the rod slopes)
    force = np.array([d[f"contact_force_{c}"] for c in "xyz"])
    assert abs(force @ tangent) < 1e-9 * np.linalg.norm(force) * np.linalg.norm(tangent)


@pytest.mark.mpi
def test_the_curve_on_a_thin_bar_with_quaternions_and_per_step_schemes():
    """The propped cantilever above on the C^1 curve with quaternion unknowns (BDF2) and
    with rotation vectors stepped by the per-step scheme bdf2 (pair_contact.StepTerm):
    generalized-alpha's bar force to 1e-9 (quasi-static: the same equilibrium equations,
    Newton to 1e-10)."""
    a = 0.78125
    bar = Obstacle("cylinder", centre=(-(R + 0.5 * DELTA + THIN_R), 0.0, a),
                   axis=(0.0, 1.0, 0.0), radius=THIN_R, length=0.2)
    force = propped_rod(bar).diagnostics(1.0)["contact_force_x"]
    for rotations in ("quaternion", "rotation_vector"):
        rod = propped_rod(bar, rotations=rotations, scheme="bdf2")
        assert rod.obstacle_segments.stencils is not None
        assert rod.diagnostics(1.0)["contact_force_x"] == pytest.approx(force, rel=1e-9)


def _contact_point(rod) -> tuple[np.ndarray, np.ndarray]:
    """The point and the tangent (d/du) of the rod's curve where it is closest to its
    one obstacle segment within reach (contact.obstacle_curve = "smooth"; collective)."""
    seg = rod.obstacle_segments
    P = seg.line.positions(seg.owned_displacement())
    cell, _, (s, _, _, _) = seg.curve_contacts(P, seg.law.gap)
    assert len(cell) == 1
    X = P[seg.stencils.nodes[cell]]
    w, w1, _ = seg.stencils.weights(cell, s)
    return np.einsum("mk,mki->i", w, X), np.einsum("mk,mki->i", w1, X)


CUBE_TRIANGLES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                  (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def _diamond(a: float) -> Obstacle:
    """A cube of side 4 cm turned by 45 degrees about e_2, one edge (along e_2) pointing
    at +e_1 below the cantilever at s = a (0.5 delta + r below its centre line), its nodal
    law and ("segments") its sharp edges on the segments."""
    side = 0.02
    vertices = [(x, y, z) for x in (-side, side) for y in (-side, side) for z in (-side, side)]
    return Obstacle("mesh", vertices=vertices, triangles=CUBE_TRIANGLES,
                    centre=(-(R + 0.5 * DELTA) - side * np.sqrt(2), 0.0, a),
                    rotation=(0.0, np.pi / 4, 0.0), contact="segments")


def test_a_cubes_sharp_edges_are_its_segments():
    """A cube's 12 edges are convex with a right angle between their faces' normals; those
    of a cube turned about e_2 lie where the turned cube's are; a flat surface (two
    triangles) has no convex edge."""
    ob = _diamond(0.5)
    ends, turn = ob.surface.convex_edges()
    assert len(turn) == 12 and np.allclose(turn, np.pi / 2, atol=1e-14)
    top = ends[np.argmax(ends[:, :, 0].sum(axis=1))]       # the edge pointing at +e_1
    assert np.allclose(top[:, 0], -(R + 0.5 * DELTA), atol=1e-15)
    assert np.allclose(np.sort(top[:, 1]), [-0.02, 0.02]) and np.allclose(top[:, 2], 0.5)
    flat = Obstacle("mesh", vertices=[(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)],
                    triangles=[(0, 1, 3), (0, 3, 2)])
    assert len(flat.surface.convex_edges()[1]) == 0


@pytest.mark.mpi
def test_cantilever_propped_by_a_sharp_mesh_edge_between_two_nodes():
    """The propped cantilever above on the edge of a cube turned by 45 degrees (a mesh,
    contact = "segments": its nodal law and its sharp edges as segments of radius 0),
    the edge at a = 0.78125, the middle of a cell (the nodes 3.1 cm away: 2.2 cm from the
    faces, beyond the barrier's reach r + delta = 1.1 cm, so the nodal law alone would
    let the cell cut the edge): beam theory's prop reaction with the measured deflection
    at a, to 1 % as for the bar (1.1e-3 measured); the gap in (0, delta).  On the nodes
    only the steps are cut until the run stops (at t = 0.058) as the cell meets the edge."""
    from dolfin_rod.integrators.step_control import IntegrationError
    w, EI = PROPPED
    a = 0.78125
    rod = propped_rod(_diamond(a))
    assert len(rod.obstacle_segments.index) == 12
    d = rod.diagnostics(1.0)
    Delta = -_point_at(rod, a)[0]
    reaction = 3 * EI / a**3 * (w * a**2 * (6 - 4 * a + a**2) / (24 * EI) - Delta)
    assert 0.0 < d["min_gap"] < DELTA
    assert d["contact_force_x"] == pytest.approx(reaction, rel=1e-2)
    with pytest.raises(IntegrationError, match=r"passed through obstacles\[0\]"):
        propped_rod(replace(_diamond(a), contact="nodes"))


@pytest.mark.mpi
@pytest.mark.parametrize("curve", ["segments", "smooth"])
def test_rope_over_a_thin_bar_scene_rests_on_the_bar(curve):
    """scenes/rope_over_thin_bar.toml: the rope (31 cells of 3.2 cm) dropped across a bar
    of radius 4 mm at the middle of its middle cell ("auto": segment contact) folds over
    it and its ends land on the ground.  At rest (t = 2 s) bar and ground carry the weight
    rho_A g L = 0.7848 N to 1e-3 (the rest: the drag of the ends' creep under the smoothed
    friction, < eps = 1e-3 m/s; measured 1.7e-4, 1.1e-4 on the curve); the gap stays in
    (0, delta) at every output; the rope's middle lies on the bar (its centre line
    r + R + g above the bar's axis, not below it: the nodes on either side are 1.6 cm
    away).  With contact.obstacle_curve = "smooth" the C^1 curve's contact point lies
    there (the P1 chord of the middle cell 2.9 mm lower: the rope bends over the bar
    at its nodes, the curve keeps r from the bar, the chords only R)."""
    from pathlib import Path

    from dolfin_rod.scenes import build, parse_scene
    text = (Path(__file__).resolve().parents[1] / "scenes/rope_over_thin_bar.toml").read_text()
    scene = parse_scene(text.replace("[contact]\n", f'[contact]\nobstacle_curve = "{curve}"\n'))
    sim = build(scene, "rod")
    rod = sim.model
    assert rod.contact.segment_obstacles == [0]
    sim.start()
    sim.begin(0.0)
    gaps = []
    for k in range(100):
        sim.advance(0.02 * k, 0.02 * (k + 1))
        gaps.append(sim.diagnostics(0.02 * (k + 1))["min_gap"])
    d = sim.diagnostics(2.0)
    assert 0.0 < min(gaps) and max(gaps[10:]) < 5e-4
    assert d["contact_force_z"] == pytest.approx(0.08 * 9.81, rel=1e-3)
    middle = _contact_point(rod)[0] if curve == "smooth" else _point_at(rod, 0.5)
    assert middle[2] == pytest.approx(-0.01 + 0.004 + 0.005, abs=5e-4)  # bar's top + r


def test_check_says_where_each_obstacles_contact_acts():
    """`dolfin-rod check` names where each obstacle's barrier acts, by the model's rule
    (the rope's bar: segments; the ground: nodes; a mesh with contact = "segments": its
    nodes and its sharp edges, a cube's 12 at these cells, and so with "auto")."""
    from pathlib import Path

    from dolfin_rod.cli import _check_lines
    from dolfin_rod.scenes import load_scene
    path = Path(__file__).resolve().parents[1] / "scenes/rope_over_thin_bar.toml"
    lines = _check_lines(load_scene(path), 1)
    assert any("obstacles[0] (cylinder, contact = 'auto') acts on the segments" in line
               for line in lines), lines
    assert any("obstacles[1] (plane, contact = 'auto') acts on the nodes" in line
               for line in lines), lines
    from dolfin_rod.scenes import parse_scene
    text = path.read_text()
    cube = _diamond(0.5)
    mesh = (f'[[obstacles]]\nshape = "mesh"\ncontact = "segments"\ncentre = [-0.05, 0.0, 0.5]\n'
            f"vertices = {[list(v) for v in cube.vertices]}\n"
            f"triangles = {[list(t) for t in CUBE_TRIANGLES]}\n\n")
    text = text[:text.index("[[obstacles]]")] + mesh + text[text.index("[time]"):]
    for contact in ("segments", "auto"):     # the rope's cells: h = 0.032 > 0.0156
        lines = _check_lines(parse_scene(text.replace('"segments"', f'"{contact}"')), 1)
        assert any(f"contact = '{contact}') acts on the nodes, its 12 sharp edges on the "
                   "segments" in line for line in lines), lines


def _sliding_over_bars(mu, a: float, steps: int, dt: float = 1e-2, EI: float = 10.0,
                       curve: str = "smooth", across: bool = False) -> list:
    """A stiff free rod (L = 1, EI = 10, 1 kg/m, 8 cells, r = 1 cm: it sags 1e-3 of its
    overhangs) lying across two bars of radius 3 mm (axis e_2, at s = 0.3125 and 0.6875:
    the middles of cells; friction mu, or (forward, backward, lateral): directional;
    "auto": segments; contact.obstacle_curve ``curve``; the barrier's stiffness of EI =
    10 at any EI) under gravity tilted by a from -e_1 towards -e_3 (an incline along the
    rod; ``across``: towards -e_2, along the bars); the diagnostics of each step."""
    from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters
    from scipy.optimize import brentq

    from dolfin_rod.rod.contact import barrier_derivatives, default_stiffness
    from test_contact import G, TIGHT, _history
    rod_data = RodParameters(length=1.0, A=(EI,) * 3, B=(1e4,) * 3, density=1.0,
                             section_inertia=1e-5)
    law = ContactLaw(R, DELTA, default_stiffness(1.0, (10.0,) * 3, 1.0, 8, dt),
                     slip_tolerance=1e-4, obstacle_curve=curve)
    # the start at the gap g0 where each bar's barrier carries its half of the normal
    # load: kappa w (-b'(g0)) = rho_A g L cos(a) / 2 (no drop), w the weight of a contact
    # in a cell's middle: h on the curve, h / 2 on the segment
    load, w = 0.5 * G * np.cos(a), (1 / 8 if curve == "smooth" else 1 / 16)
    g0 = brentq(lambda g: -law.stiffness * w * barrier_derivatives(g, DELTA)[1] - load,
                1e-4 * DELTA, DELTA * (1 - 1e-12))
    friction = ({"directional_friction": mu} if isinstance(mu, tuple) else {"friction": mu})
    bars = [Obstacle("cylinder", centre=(-(R + g0 + THIN_R), 0.0, z),
                     axis=(0.0, 1.0, 0.0), radius=THIN_R, length=0.2, **friction)
            for z in (0.3125, 0.6875)]
    down = (0.0, -G * np.sin(a), 0.0) if across else (0.0, 0.0, -G * np.sin(a))
    rod = RodModel(rod_data, n_cells=8, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad(
                       "force", (-G * np.cos(a), down[1], down[2]))],
                   obstacles=bars, contact=law)
    rod.set_initial_state()
    assert rod.contact.segment_obstacles == [0, 1]
    assert rod.contact.V is None        # friction on the segments only, not twice
    assert (rod.obstacle_segments.friction is not None) == (np.max(mu) > 0)
    return _history(rod, dt, steps, {**TIGHT, "snes_linesearch_type": "bt"})


@pytest.mark.mpi
@pytest.mark.parametrize("curve", ["segments", "smooth"])
def test_a_rod_slides_over_thin_bars_with_kinetic_friction(curve):
    """mu = 0.2 < tan 30 deg: the rod slides along itself over two thin bars (each
    between two nodes at the start, its contact handed from segment to segment as the
    rod slides over the nodes), from rest, 0.26 m in 0.4 s: its mean acceleration
    2 (z(T) - z(0)) / T^2 is g (sin a - mu cos a) to 5 % (measured 2.3 % on the segments,
    1.8 % at half the step; 2.3 % on the curve): what limits it is not the contact law
    but the start and the rod (test_the_bars_carry_the_weights_share_as_a_rod_slides and
    test_a_stiff_rod_slides_over_thin_bars_at_coulombs_acceleration below): the first
    steps' acceleration (7 % off in the first, with the frictionless accelerations of the
    start), the rod's lowest bending mode (11 Hz at EI = 10) that the straight start on
    two points excites, swinging the bars' normal force by +-20 % (the lagged friction
    with it), and after 0.34 s the centre of mass beyond the lower bar (the rod tips);
    the friction's dissipation >= 0 at every step, the gaps > 0."""
    from test_contact import G
    a, mu, dt = np.radians(30.0), 0.2, 1e-2
    rows = _sliding_over_bars(mu, a, 40, dt, curve=curve)
    assert min(d["friction_dissipation"] for d in rows) >= 0.0
    assert min(d["min_gap"] for d in rows) > 0.0
    T, z = rows[-1]["time"], rows[-1]["tip_position_z"]
    accel = 2 * (z - 1.0) / T**2                    # the tip starts at rest at z = 1
    assert accel == pytest.approx(-G * (np.sin(a) - mu * np.cos(a)), rel=5e-2)


@pytest.mark.mpi
def test_the_bars_carry_the_weights_share_as_a_rod_slides_over_them():
    """A rigid rod (EI = 1e3: its lowest mode, 113 Hz, is damped within the first steps
    by the integrator, rho_inf = 0, omega dt = 7) sliding frictionless down the incline
    over the two bars: the bars' normal forces add up to the weight's normal part
    rho_A g L cos a at every instant (a rigid body moving along a straight line).  Over
    t = 0.12-0.2 s (the start's transient gone; the bars pass nodes at t = 0.16, the
    upper bar's share still above 1/4) the largest relative deviation: on the segments
    28 % (a node on a bar carries its two cells' barrier: the rod is kicked off the bars
    and falls back), on the C^1 curve 1.6e-3 (asserted 3e-3: the start's transient's tail,
    1e-3 at t = 0.12-0.13, and the rod tilting on its barriers as the bars' shares change,
    their gaps with them: -1.6e-3 at t = 0.2 growing to -3.4e-3 at 0.22)."""
    from test_contact import G
    a = np.radians(30.0)
    deviation = {}
    for curve in ("segments", "smooth"):
        rows = _sliding_over_bars(0.0, a, 20, 1e-2, EI=1e3, curve=curve)
        N = np.array([d["contact_force_x"] for d in rows if d["time"] > 0.12 - 1e-9])
        deviation[curve] = np.abs(N / (G * np.cos(a)) - 1).max()
    assert deviation["smooth"] < 3e-3 and deviation["segments"] > 0.1, deviation


@pytest.mark.mpi
@pytest.mark.parametrize("curve", ["segments", "smooth"])
def test_a_stiff_rod_slides_over_thin_bars_at_coulombs_acceleration(curve):
    """The rigid rod of the test above with mu = 0.2 < tan 30 deg: its tip's path over
    t = 0.1-0.3 s (after the start's transient, before the centre of mass nears the lower
    bar; 0.14 m, the bars passing a node each) is a parabola of acceleration
    g (sin a - mu cos a): the least-squares parabola's to 3e-3 (measured 1.4e-3 on the
    segments, 1.7e-3 on the curve: the acceleration drifts as the bars' shares change,
    +0.13 % at t = 0.15 to +0.5 % at 0.3 in the steps' second differences; the mean
    acceleration from rest 2 (z(T) - z(0)) / T^2 is 1.7 % off for both: the first steps')."""
    from test_contact import G
    a, mu = np.radians(30.0), 0.2
    rows = _sliding_over_bars(mu, a, 30, 1e-2, EI=1e3, curve=curve)
    assert min(d["friction_dissipation"] for d in rows) >= 0.0
    t, z = (np.array([d[k] for d in rows if d["time"] > 0.1 - 1e-9])
            for k in ("time", "tip_position_z"))
    accel = 2 * np.polyfit(t, z, 2)[0]
    assert accel == pytest.approx(-G * (np.sin(a) - mu * np.cos(a)), rel=3e-3)


@pytest.mark.mpi
@pytest.mark.parametrize("curve", ["segments", "smooth"])
def test_a_rod_sticks_on_thin_bars_with_static_friction(curve):
    """mu = 0.8 > tan 30 deg: after it settled (1 s) the rod on the two thin bars creeps
    at the smoothed law's speed y eps with phi(y) = tan a / mu (as on test_contact's
    plane: the bars' normal forces add up to the weight's normal part at rest), over 10 s
    to 1e-3; dissipation >= 0 at every step."""
    from scipy.optimize import brentq
    a, mu, eps = np.radians(30.0), 0.8, 1e-4
    rows = _sliding_over_bars(mu, a, 220, dt=5e-2, curve=curve)
    assert min(d["friction_dissipation"] for d in rows) >= 0.0
    z = {round(d["time"], 6): d["tip_position_z"] for d in rows}
    y = brentq(lambda y: 1.5 * y - 0.5 * y**3 - np.tan(a) / mu, 0.0, 1.0)
    assert abs(z[11.0] - z[1.0]) == pytest.approx(y * eps * 10.0, rel=1e-3)


def test_friction_on_segments_needs_rotation_vectors():
    """Friction on the segments follows generalized-alpha's rates (rotation vectors):
    with quaternion unknowns the model refuses it, naming the obstacle's friction."""
    from dolfin_rod.rod import RodModel
    from test_contact import ROD
    bar = Obstacle("cylinder", centre=(-0.02, 0.0, 0.5), axis=(0.0, 1.0, 0.0),
                   radius=THIN_R, length=0.2, friction=0.3)
    with pytest.raises(ValueError, match=r"obstacles\[0\]\.friction"):
        RodModel(ROD, n_cells=8, model="hyperelastic", start="free", end="free",
                 rotations="quaternion", obstacles=[bar],
                 contact=ContactLaw(R, DELTA, 1e3))


def _bounce_drift(dt: float, t_end: float = 0.4, curve: str = "smooth", slide: float = 0.0):
    """A free rod (L = 0.2, 5 cells, r = 2 mm) sent at 0.02 m/s along -e_1 onto a bar of
    radius 3 mm at its middle (the middle of a cell; delta = 1 mm, kappa = 1e3, the bar
    1.5 delta away), and at ``slide`` along itself (e_3): it presses into the barrier
    and bounces back; frictionless, no drag, generalized-alpha with rho_inf = 1,
    contact.obstacle_curve ``curve``.  (largest |E(t) - E(0)| of E = K + Psi + contact
    energy, E(0), largest contact energy, smallest gap)."""
    from dolfin_rod.rod import RodModel, RodParameters, StartingState
    r, delta = 0.002, 1e-3
    params = RodParameters(length=0.2, A=(1e-2,) * 3, B=(10.0,) * 3, density=1.0,
                           section_inertia=1e-6)
    bar = Obstacle("cylinder", centre=(-(r + 1.5 * delta + THIN_R), 0.0, 0.1),
                   axis=(0.0, 1.0, 0.0), radius=THIN_R, length=0.05)
    rod = RodModel(params, 5, model="hyperelastic", start="free", end="free",
                   obstacles=[bar], contact=ContactLaw(r, delta, 1e3, obstacle_curve=curve))
    rod.set_initial_state(start=StartingState(velocity=(-0.02, 0.0, slide)))
    assert rod.contact.segment_obstacles == [0]
    return energy_drift(rod, dt, t_end, "min_gap")


@pytest.mark.mpi
@pytest.mark.parametrize("curve, slide", [("segments", 0.0), ("smooth", 0.15)])
def test_frictionless_segment_contact_conserves_energy_at_second_order(curve, slide):
    """The bounce on the bar (_bounce_drift; the barrier's energy reaches 46 % of E =
    4e-5 J, the gap 0.22 delta): K + Psi + the segments' barrier energy is conserved to
    the integrator's order (the force is the energy's exact derivative), the largest
    drift falling 4x per halving of dt (measured 1.4e-7, 3.6e-8, 9.0e-9 J at dt = 4, 2,
    1 ms: ratios 3.97, 3.99); asserted: ratios > 3.5.  On the C^1 curve with the rod
    sliding along itself at 0.15 m/s as well (the contact, in touch over t = 0.03-0.18 s,
    passes from cell 2 to cell 1 across their node at t = 0.135 s: the energy is C^1
    there, its Hessian jumps): drifts 1.2e-7, 2.9e-8, 7.3e-9 J (ratios 4.00, 3.99; E =
    2.3e-3 J, the barrier's energy up to 1.4e-5 J, a third of the normal motion's 4e-5
    J).  (The same slide on the segments: ratios 2.3, 6.6, the node's bump in the
    energy resolved by too few steps.)"""
    runs = [_bounce_drift(dt, curve=curve, slide=slide) for dt in (4e-3, 2e-3, 1e-3)]
    drifts = np.array([r[0] for r in runs])
    normal = 0.5 * 0.2 * 0.02**2            # the kinetic energy of the motion onto the bar
    assert all(r[2] > 0.1 * normal and 0 < r[3] < DELTA for r in runs), runs
    assert np.all(drifts[:-1] / drifts[1:] > 3.5), drifts


def _thrown_at_boxes(n_cells: int = 20, count: int = 25):
    """A free rod (L = 0.2, r = 2 mm, delta = 1 mm, h = 1 cm) sent at 0.05 m/s along -e_1
    onto a grid of ``count`` cubes (half-side 1 cm, 3 cm apart, their faces 1.5 delta
    from it; meshes.boxes, contact = "segments": 12 count sharp edges, the rod crossing
    five rows of them)."""
    from dolfin_rod.rod import RodModel, RodParameters, StartingState
    from meshes import boxes, grid
    r, delta, half = 0.002, 1e-3, 0.01
    V, T = boxes(grid(count, 0.03, (-(r + 1.5 * delta + half), 0.0, 0.1)), half)
    grid = Obstacle("mesh", vertices=V.tolist(), triangles=T.tolist(), contact="segments")
    params = RodParameters(length=0.2, A=(1e-2,) * 3, B=(10.0,) * 3, density=1.0,
                           section_inertia=1e-6)
    rod = RodModel(params, n_cells, model="hyperelastic", start="free", end="free",
                   obstacles=[grid], contact=ContactLaw(r, delta, 1e3))
    rod.set_initial_state(start=StartingState(velocity=(-0.05, 0.0, 0.0)))
    return rod


@pytest.mark.mpi
def test_the_broad_phase_finds_the_pairs_every_pair_comparison_finds():
    """The obstacle segments' broad phase (the pieces' cKDTree and its candidate list,
    kept while no node moved beyond the skin) against comparing every (cell, obstacle
    segment) pair: on random centre lines (random walks of 20 cells of 0.2 to 2 h, among
    300 sharp edges of 25 cubes, and 1 m away from them), each moved by 1e-4, 5e-4, 2e-3
    (below and beyond the skin r / 2 = 1e-3: the list kept and searched anew), the same
    pairs within reach in the same order with the same closest points and distances,
    bit for bit, and the same smallest gap and its pair."""
    rod = _thrown_at_boxes()
    contact = rod.obstacle_segments
    assert contact.tree and len(contact.index) == 300
    rng = np.random.default_rng(7)
    n, h = len(contact.line.ends) + 1, contact.line.lengths.max()
    found = 0
    for trial in range(40):
        steps = rng.standard_normal((n, 3))
        steps *= (rng.uniform(0.2, 2.0, n) * h / np.linalg.norm(steps, axis=1))[:, None]
        start = np.array([-0.005 + 1.0 * (trial % 8 == 7), 0.0, 0.1]) + rng.uniform(
            -0.06, 0.06, 3) * (0.2, 1.0, 1.0)
        P = start + np.cumsum(steps, axis=0)
        for amplitude in (0.0, 1e-4, 5e-4, 2e-3):
            Q = P + amplitude * rng.uniform(-1, 1, P.shape) / np.sqrt(3)
            contact.tree = True
            broad = contact.near(Q, contact.law.gap), contact.smallest(Q)
            contact.tree = False
            every = contact.near(Q, contact.law.gap), contact.smallest(Q)
            assert all(np.array_equal(a, b) for a, b in zip(broad[0], every[0]))
            assert broad[1] == every[1]
            found += len(broad[0][0])
    assert found > 200, found       # the configurations meet the edges (measured 811)


@pytest.mark.mpi
def test_a_rod_thrown_at_many_sharp_edges_is_the_same_with_the_broad_phase():
    """The rod of ``_thrown_at_boxes`` pressed onto the cubes' faces and edges and
    bouncing back (24 steps of 5 ms; up to 20 (cell, edge) pairs active, the smallest gap
    1.9e-4): every step's diagnostics (contact energy, force, smallest gap, energies)
    are the same, bit for bit, with the broad phase and comparing every pair."""
    from dolfin_rod import TimeStepper
    rows = []
    for tree in (True, False):
        rod = _thrown_at_boxes()
        rod.obstacle_segments.tree = tree
        stepper = TimeStepper(rod.problem)
        stepper.initial_accelerations(0.0)
        run = []
        for k in range(24):
            stepper.run(5e-3 * k, 5e-3 * (k + 1), 5e-3)
            run.append(rod.diagnostics(5e-3 * (k + 1)))
        rows.append(run)
    assert rows[0] == rows[1]
    assert max(d["contact_energy"] for d in rows[0]) > 0
    assert 0 < min(d["min_gap"] for d in rows[0]) < 1e-3


@pytest.mark.mpi
@pytest.mark.parametrize("mu, across, effective", [
    ((0.2, 0.2, 0.2), False, 0.2), ((0.05, 0.2, 0.04), False, 0.2),
    ((0.2, 0.05, 0.04), False, 0.05), ((0.2, 0.3, 0.04), True, 0.04)],
    ids=["equal", "backward", "forward", "lateral"])
def test_directional_friction_on_thin_bars(mu, across, effective):
    """Directional friction (forward, backward, lateral) on obstacles that act on the
    segments: the rigid rod (EI = 1e3) on the two thin bars slides down a 30-degree
    incline along itself towards s = 0 (its backward direction) or across itself along
    the bars (lateral), 20 steps of 0.01 s: its slide is that of the isotropic law with
    the coefficient of its direction, to 1e-6 (measured 1.1e-7 and 4.8e-8 along: the
    forward/backward blend u_a / sqrt(u_a^2 + eps^2) at slips >> eps; 1.4e-13 across;
    equal coefficients: the isotropic law, 1e-12), and its acceleration (quadratic fit
    over t = 0.1-0.2 s) is g (sin a - mu cos a): along the rod to 3e-3 as
    test_a_stiff_rod_slides_over_thin_bars_at_coulombs_acceleration (measured 1.1e-3,
    8.2e-4), across it to 1e-5 (measured 1.7e-6: the contacts keep their cells); the
    friction's dissipation >= 0."""
    from test_contact import G
    a = np.radians(30.0)
    key, start = ("tip_position_y", 0.0) if across else ("tip_position_z", 1.0)
    rows = _sliding_over_bars(mu, a, 20, 1e-2, EI=1e3, across=across)
    iso = _sliding_over_bars(effective, a, 20, 1e-2, EI=1e3, across=across)
    slide, slide_iso = (np.array([start - d[key] for d in r]) for r in (rows, iso))
    assert slide == pytest.approx(slide_iso, rel=1e-12 if len(set(mu)) == 1 else 1e-6)
    assert min(d["friction_dissipation"] for d in rows) >= 0.0
    t = np.array([d["time"] for d in rows])
    late = t > 0.1 - 1e-9
    accel = 2 * np.polyfit(t[late], slide[late], 2)[0]
    assert accel == pytest.approx(G * (np.sin(a) - effective * np.cos(a)),
                                  rel=1e-5 if across else 3e-3)
