"""rod/placement.py: the rods of a scene with [[rods]] placed without DOLFINx
(scenes/builders.placed_rods: placement.PlacedRod, what ``dolfin-rod check`` places the
joints on) are where the model's rods (rods.Rod with its RodParameters) are."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dolfin_rod.rod.joint_points import locate
from dolfin_rod.rod.placement import placed_shape
from dolfin_rod.scenes import load_scene, parse_scene
from dolfin_rod.scenes.builders import placed_rods, rods_and_joints

ROOT = Path(__file__).resolve().parents[1]
SYSTEMS = sorted(p.name for p in (ROOT / "scenes").glob("*.toml") if "[[rods]]" in p.read_text())
# a curved rod (reference strains, turned) joined at its start to an interior node of a
# rod whose stress-free shape is a polyline, held at an end by a prescribed rotation
CURVED = """[time]
t_end = 0.1
dt = 0.05
[boundary]
start = "free"
[material]
stiffness = { B = [100.0, 100.0, 100.0], A = [1.0, 1.0, 1.0] }
model = "hyperelastic"
[[rods]]
name = "arc"
position = [0.0, 0.0, 1.0]
orientation = [0.3, 0.0, 0.0]
geometry = { length = 1.0, n_cells = 6, reference_curvature = [0.0, 1.5, 0.2] }
[[rods]]
name = "kinked"
geometry = { length = 2.0, n_cells = 4, reference_shape = { type = "polyline", points = [[0, 0, 0], [0, 0, 1], [1, 0, 1]] } }
boundary = { start_rotation = { type = "step", value = [0.0, 0.0, 0.0] } }
[[joints]]
kind = "ball"
rods = ["kinked", "arc"]
point = [0.0, 0.0, 1.0]
"""


@pytest.mark.parametrize("name", [*SYSTEMS, "curved"])
def test_scene_rods_are_placed_as_the_model_rods(name):
    """Every node of every rod (positions and quaternions) is the model's rod's exactly
    (the same numbers go in: bit for bit), the joints are at the same nodes, and each
    joint's point is its two nodes' position (1e-9 of the longest rod: locate's
    tolerance)."""
    scene = (parse_scene(CURVED, "curved.toml") if name == "curved"
             else load_scene(ROOT / "scenes" / name))
    light = placed_rods(scene)
    rods, joints = rods_and_joints(scene)
    assert [rod.name for rod in light] == [rod.name for rod in rods]
    for here, model in zip(light, rods):
        s = np.linspace(0.0, model.params.length, model.n_cells + 1)
        for a, b in zip(placed_shape(here, s), placed_shape(model, s)):
            np.testing.assert_array_equal(a, b)
    nodes = locate(light, joints)
    assert nodes == locate(rods, joints)
    scale = max(rod.params.length for rod in rods)
    for joint, (i, m, j, n) in zip(joints, nodes):
        for k, node in ((i, m), (j, n)):
            h = light[k].params.length / light[k].n_cells
            r = placed_shape(light[k], [node * h])[0][0]
            assert np.linalg.norm(r - joint.point) < 1e-9 * scale, (joint, r)


@pytest.mark.parametrize("v0", [(0.0, 0.0, 1.0), (-0.1, 0.0, 1.2)])
def test_a_straight_helix_is_the_line_s_v0(v0):
    """Zero reference curvature: r(s) = s v0 and q = 1, exactly (placement.helix's
    straight case, which skips the series of the curved one), with +0.0 where s v0 is 0
    (what the curved case's matrix product gives: its sums start at +0.0)."""
    from dolfin_rod.rod.placement import helix
    s = np.linspace(0.0, 2.0, 9)
    r, q = helix(s, (0.0, 0.0, 0.0), v0)
    assert np.array_equal(r, np.outer(s, v0))
    assert not np.signbit(r[r == 0.0]).any()
    assert np.array_equal(q, np.tile([1.0, 0.0, 0.0, 0.0], (len(s), 1)))
