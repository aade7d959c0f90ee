"""Triangle-mesh obstacles (issue 26; rod/triangle_mesh.py, rod/contact.py MeshPose,
docs/contact.md): reading STL and OBJ, the signed distance, the contact law on a mesh,
and its errors.

References: the box's signed distance in closed form, the sphere's for icospheres;
the analytic plane and cylinder obstacles (a rod on a mesh plane of two triangles is
the rod on the plane; on a prism inscribed in a cylinder it differs from the rod on the
cylinder by at most the faceting's sagitta, which falls 4-fold per doubling of the
sides); Taylor remainders for the Jacobian."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from dolfin_rod.rod import DistributedLoad, RodModel, RodParameters
from dolfin_rod.rod.contact import ContactLaw, Obstacle, default_stiffness
from dolfin_rod.rod.triangle_mesh import MeshError, Surface, read_mesh
from dolfin_rod.scenes import SceneError, build

sys.path.insert(0, str(Path(__file__).parent))
from meshes import (box, icosphere, prism, sagitta, write_obj,  # noqa: E402
                    write_stl_ascii, write_stl_binary)
from test_contact import SCENE as CONTACT_SCENE  # noqa: E402
from test_contact import (DELTA, G, R, ROD, TIGHT, _error, _history,  # noqa: E402
                          _lying_rod, _propped)


def _box_distance(p, half):
    """The box's signed distance in closed form (inside: minus the depth)."""
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def test_signed_distance_of_a_box_and_a_sphere():
    """A box of 12 triangles: d equals the closed form at 20000 random points inside and
    out (faces, edges, corners) to round-off; an icosphere: |d - (|p| - R)| is at most
    the sagitta and falls 4-fold per subdivision (3.71, 3.92 from 80 to 320 to 1280
    triangles; 3.1 from the icosahedron's 20)."""
    rng = np.random.default_rng(0)
    P = rng.uniform(-4, 4, (20000, 3))
    half = np.array([1.0, 2.0, 3.0])
    assert Surface(*box(half)).signed_distance(P) == pytest.approx(_box_distance(P, half),
                                                                   abs=1e-12)
    errors = []
    for level in range(4):
        V, T = icosphere(level, 0.5)
        error = np.abs(Surface(V, T).signed_distance(P) - (np.linalg.norm(P, axis=1) - 0.5))
        assert error.max() <= sagitta(V, T, 0.5) * (1 + 1e-12)
        errors.append(error.max())
    assert all(3.6 < a / b < 4.1 for a, b in zip(errors[1:], errors[2:]))


def test_stl_and_obj_files_read_the_same_surface(tmp_path):
    """ASCII STL, binary STL (float32 corners) and OBJ of one icosphere: the same
    vertices (to float32's round-off) and triangles after merging the STL's repeated
    corners."""
    V, T = icosphere(1, 0.3)
    for name, write, tol in (("a.stl", write_stl_ascii, 1e-15), ("b.stl", write_stl_binary,
                                                                  1e-7), ("c.obj", write_obj, 0)):
        write(tmp_path / name, V, T)
        V2, T2 = read_mesh(tmp_path / name)
        assert len(V2) == len(V) and len(T2) == len(T)
        assert np.allclose(V2[T2], V[T], atol=tol)


@pytest.mark.parametrize("vertices, triangles, key, words", [
    ([(0, 0, 0), (1, 0, 0), (2, 0, 0)], [(0, 1, 2)], "triangles", "degenerate"),
    ([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 0, -1)],
     [(0, 1, 2), (1, 0, 3), (0, 1, 4)], "triangles", "belongs to 3"),
    ([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [(0, 1, 2), (1, 2, 3)], "triangles",
     "oriented oppositely"),
    ([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 5)], "triangles", "vertex indices"),
])
def test_bad_surfaces_name_the_key(vertices, triangles, key, words):
    with pytest.raises(MeshError) as err:
        Surface(vertices, triangles)
    assert err.value.key == key and words in str(err.value)


def test_a_closed_surface_oriented_inwards_is_refused():
    V, T = box((1.0, 1.0, 1.0))
    with pytest.raises(MeshError, match="oriented inwards"):
        Surface(V, T[:, ::-1])


def _mesh_plane_rod(dt, gravity, friction=0.0, drag=0.0, gap0=1.5 * DELTA, n_cells=8,
                    eps=1e-4):
    """_lying_rod with its plane x = -(r + gap0) as two triangles (normal +x)."""
    params = RodParameters(**{**ROD.__dict__, "drag": drag})
    law = ContactLaw(R, DELTA, default_stiffness(params.density, params.A, 1.0, n_cells, dt),
                     slip_tolerance=eps)
    x0 = -(R + gap0)
    plane = Obstacle("mesh", vertices=[(x0, -1, -1), (x0, 1, -1), (x0, 1, 2), (x0, -1, 2)],
                     triangles=[(0, 1, 2), (0, 2, 3)], friction=friction)
    rod = RodModel(params, n_cells=n_cells, model="hyperelastic", start="free", end="free",
                   distributed_loads=[DistributedLoad("force", tuple(gravity))],
                   obstacles=[plane], contact=law)
    rod.set_initial_state()
    return rod


# Under mpirun: the frictionless drop (the mesh's face distances on two ranks); friction
# on an obstacle on two ranks is test_contact.py's incline tests (the same law).
@pytest.mark.parametrize("friction", [pytest.param(0.0, marks=pytest.mark.mpi), 0.2])
def test_rod_on_a_mesh_plane_is_the_rod_on_the_plane(friction):
    """A rod dropped onto a 2-triangle mesh plane (with drag, frictionless), and sliding
    down a 30-degree incline on it (mu = 0.2): every row of the time series equals the
    analytic plane's to 1e-9 of its scale (measured 1e-11: the same law, the face's
    distance n . (p - a) instead of n . (p - p0), round-off)."""
    a, dt = np.radians(30.0), 1e-2
    gravity = (-G, 0.0, 0.0) if friction == 0 else (-G * np.cos(a), 0.0, -G * np.sin(a))
    kw = dict(drag=200.0) if friction == 0 else dict(friction=friction, gap0=0.9 * DELTA)
    options = TIGHT if friction == 0 else {**TIGHT, "snes_linesearch_type": "bt"}
    plane = _history(_lying_rod(dt, gravity, **kw), dt, 30, options)
    mesh = _history(_mesh_plane_rod(dt, gravity, **kw), dt, 30, options)
    for key in ("min_gap", "contact_force_x", "contact_force_z", "tip_position_x",
                "tip_position_z", "contact_energy", "friction_dissipation"):
        scale = max(abs(d[key]) for d in plane) or 1.0
        assert [d[key] for d in mesh] == pytest.approx([d[key] for d in plane],
                                                       abs=1e-9 * scale), key


def _prop(obstacle):
    """(tip x, contact force x, smallest gap) of tests/test_contact.py's propped
    cantilever on ``obstacle``."""
    d = _propped(obstacle)
    return d["tip_position_x"], d["contact_force_x"], d["min_gap"]


@pytest.mark.slow
@pytest.mark.mpi
def test_cantilever_propped_on_a_prism_converges_to_the_cylinder():
    """The propped cantilever of tests/test_contact.py with its tip on a cylinder across
    it (radius 5 cm, axis e_2) and on the prisms of 8, 16, 32 sides inscribed in it
    (turned by 0.3 of a side's angle: the tip rests on a tilted face):
    the tip's settlement differs by at most the sagitta s = R (1 - cos(pi / n)) (the
    faces' largest depth below the cylinder), which falls 4-fold per doubling of n; the
    prop's force by at most 3 EI s / L^3 (beam theory's change for a prop lowered by s)
    plus 1e-6 of it.  Measured: the tip 3.06e-3, 7.54e-4, 1.83e-4 lower (0.80, 0.79,
    0.76 s; ratios 4.05, 4.13), the force 8.7e-5, 1.8e-5, 2.9e-6 smaller."""
    Ro = 0.05
    centre = (-(R + 0.5 * DELTA + Ro), 0.0, 1.0)
    x, F, _ = _prop(Obstacle("cylinder", centre=centre, axis=(0.0, 1.0, 0.0), radius=Ro,
                                length=0.2))
    for n in (8, 16, 32):
        V, T = prism(n, Ro, 0.2, 0.3 * 2 * np.pi / n)
        s = Ro * (1 - np.cos(np.pi / n))
        # the nodal law on facets ("nodes": "auto" puts the prisms' lids' edges and, at
        # 8 sides, their 45-degree edges on the segments, which the cylinder lacks)
        xm, Fm, gap = _prop(Obstacle("mesh", vertices=V, triangles=T, centre=centre,
                                     contact="nodes"))
        assert 0.0 < gap < DELTA
        assert abs(xm - x) <= s
        assert abs(Fm - F) <= 3 * 1e-2 * s + 1e-6 * F


def test_mesh_contact_jacobian_is_the_residuals_derivative():
    """Taylor test of the assembled contact terms of a rod whose middle node is at the
    gap delta / 2 from a vertex of an icosphere, an edge of a box (turned by 45 degrees),
    a box's face, the features located anew at every state: the remainder of the
    residual falls 4-fold per halving (the Jacobian is the Hessian of the features'
    distances, in the vertex, edge and face regions alike)."""
    import dolfinx.fem as fem
    import dolfinx.fem.petsc as fem_petsc
    import ufl
    law = ContactLaw(R, DELTA, 1e3)
    near = R + 0.5 * DELTA          # the node s = 0.5 at the gap delta / 2
    V, T = icosphere(2, 0.05)
    tip = V[0] / np.linalg.norm(V[0])          # turned to e_1: a vertex under the node
    axis = np.cross(tip, (1.0, 0.0, 0.0))
    vertex = Obstacle("mesh", vertices=V, triangles=T, centre=(-near - 0.05, 0.0, 0.5),
                      rotation=tuple(axis / np.linalg.norm(axis) * np.arccos(tip[0])))
    Vb, Tb = box((0.05, 1.0, 0.05))
    edge = Obstacle("mesh", vertices=Vb, triangles=Tb, rotation=(0.0, np.pi / 4, 0.0),
                    centre=(-near - 0.05 * np.sqrt(2), 0.0, 0.5))
    Vb, Tb = box((0.05, 1.0, 0.3))
    face = Obstacle("mesh", vertices=Vb, triangles=Tb, centre=(-near - 0.05, 0.0, 0.5))
    for obstacle in (vertex, edge, face):
        rod = RodModel(ROD, n_cells=4, model="hyperelastic", start="free", end="free",
                       obstacles=[obstacle], contact=law)
        rod.set_initial_state()
        x, contact = rod.f["displacement"], rod.contact
        rng = np.random.default_rng(1)
        x.x.array[:] += 1e-3 * DELTA * rng.standard_normal(x.x.array.size)
        dx = fem.Function(x.function_space)
        dx.x.array[:] = 0.1 * DELTA * rng.standard_normal(x.x.array.size)
        R_form = ufl.derivative(contact.energy(), x, ufl.TestFunction(x.function_space))
        J_form = ufl.derivative(R_form, x, ufl.TrialFunction(x.function_space))
        Rf, J = fem.form(R_form), fem.form(J_form)
        x0 = x.x.array.copy()
        contact.locate()
        assert contact.closest()[0] == pytest.approx(0.5 * DELTA, abs=1e-2 * DELTA)
        r0 = fem_petsc.assemble_vector(Rf).array.copy()
        A = fem_petsc.assemble_matrix(J)
        A.assemble()
        Jdx = A.createVecLeft()
        A.mult(dx.x.petsc_vec, Jdx)
        remainders = []
        for h in (1e-1, 5e-2, 2.5e-2):
            x.x.array[:] = x0 + h * dx.x.array
            contact.locate()
            remainders.append(np.linalg.norm(fem_petsc.assemble_vector(Rf).array - r0
                                             - h * Jdx.array))
        for coarse, fine in zip(remainders, remainders[1:]):
            assert coarse / fine == pytest.approx(4.0, rel=0.1)


# -- scenes ----------------------------------------------------------------------------------

PLANE = """[[obstacles]]
shape = "plane"
point = [-0.0105, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
"""
SCENE = CONTACT_SCENE.replace(PLANE, """[[obstacles]]
shape = "mesh"
vertices = [[-0.0105, -1.0, -1.0], [-0.0105, 1.0, -1.0], [-0.0105, 1.0, 2.0], [-0.0105, -1.0, 2.0]]
triangles = [[0, 1, 2], [0, 2, 3]]
""")


@pytest.mark.parametrize("change, key, words", [
    (("triangles = [[0, 1, 2], [0, 2, 3]]", "triangles = [[0, 1, 2], [0, 1, 3]]"),
     "obstacles[0].triangles", "oriented oppositely"),
    (("triangles = [[0, 1, 2], [0, 2, 3]]", "triangles = [[0, 1, 2], [0, 2, 0]]"),
     "obstacles[0].triangles", "degenerate"),
    (("triangles = [[0, 1, 2], [0, 2, 3]]\n", ""), "obstacles[0].file", "vertices and"),
    (("triangles = [[0, 1, 2], [0, 2, 3]]", 'triangles = [[0, 1, 2], [0, 2, 3]]\n'
      'file = "plane.stl"'), "obstacles[0].file", "not both"),
    (("[-0.0105, -1.0, -1.0]", "[-0.005, -1.0, -1.0]"), "obstacles[0]", "t = 0"),
    (("friction = 0.3", "friction = 0.3\nnormal = [1.0, 0.0, 0.0]"), "obstacles[0].normal",
     "does not apply"),
    (("dt = 0.01", 'dt = 0.01\nscheme = "bdf2"'), "time.scheme", "generalized-alpha"),
])
def test_bad_mesh_input_names_the_key(change, key, words):
    """Each mistake: one SceneError naming the key before any solve (the CLI's exit 2)."""
    old, new = change
    assert old in SCENE
    err = _error(SCENE.replace(old, new, 1))
    assert err.key == key and words in str(err), str(err)


def test_a_missing_or_unreadable_mesh_file_names_the_key(tmp_path):
    vertices = SCENE.split("vertices = ")[1].split("\n")[0]
    text = SCENE.replace(f"vertices = {vertices}\ntriangles = [[0, 1, 2], [0, 2, 3]]",
                         'file = "nowhere.stl"')
    scene_file = tmp_path / "scene.toml"
    scene_file.write_text(text)
    from dolfin_rod.scenes import load_scene
    with pytest.raises(SceneError) as err:
        build(load_scene(scene_file), "rod")
    assert err.value.key == "obstacles[0].file" and "cannot read" in str(err.value)
    (tmp_path / "nowhere.stl").write_text("solid x\nfacet normal 0 0 1\nvertex 0 0\n")
    with pytest.raises(SceneError) as err:
        build(load_scene(scene_file), "rod")
    assert err.value.key == "obstacles[0].file" and "not a valid STL" in str(err.value)


def test_the_bundled_mesh_scene_reads_its_file_and_draws_its_triangles():
    """scenes/rope_over_boulder.toml: its STL (relative to the scene's folder) is the
    320-triangle icosphere of radius 0.15 at the offset centre (every vertex 0.15 from
    it, to float32's round-off), and the pictures get its placed triangles."""
    from dolfin_rod.output.animation import Look
    from dolfin_rod.scenes import load_scene
    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes/rope_over_boulder.toml")
    corners = Look.of(scene).obstacles[0]["corners"]
    assert corners.shape == (320, 3, 3)
    radii = np.linalg.norm(corners - np.array([-0.16, 0.0, 0.45]), axis=2)
    assert radii == pytest.approx(0.15, abs=1e-7)


def test_an_open_surface_is_one_sided_within_its_border():
    """The square [0, 1]^2 at z = 0 as two triangles (normal +e_3): above it d = z;
    behind it, within its border, d = z < 0 (inside); beside it, closest to its border,
    d = +distance to the border (outside), also behind the plane."""
    square = Surface([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)])
    assert not square.closed
    P = np.array([[0.5, 0.5, 0.2], [0.5, 0.5, -0.2], [1.3, 0.5, -0.4], [1.3, 1.4, 0.0],
                  [-0.3, 0.5, 0.4]])
    assert square.signed_distance(P) == pytest.approx([0.2, -0.2, 0.5, 0.5, 0.5])
