"""What the terminal says (issue 29 item 3): `check` names the rotation unknowns and why,
in plain words, for every reason rod/rotation_choice.py knows."""

from __future__ import annotations

import pytest

from dolfin_rod.cli import main
from dolfin_rod.rod.rotation_choice import choose_rotations, rotations_reason
from quick_scenes import ROOT

SCENES = ROOT / "scenes"


@pytest.mark.parametrize("args, start, why", [
    (("auto", None), "rotation vectors", "nothing here needs quaternions"),
    (("auto", "the uniform variant (use the local one)"), "quaternions",
     "do not fit here: the uniform variant"),
    (("auto", None, True, True), "quaternions", "a prescribed end rotation jumps"),
    (("auto", None, False), "quaternions", "the integrator does not step rotation vectors"),
    (("quaternion", None), "quaternions", "geometry.rotations = 'quaternion' in the scene"),
])
def test_rotation_reason_follows_the_choice(args, start, why):
    """The sentence names the unknowns choose_rotations picks and the rule that picked
    them."""
    text = rotations_reason(*args)
    chosen = choose_rotations(*args)
    assert text.startswith(start) and why in text
    assert (chosen == "rotation_vector") == text.startswith("rotation vectors")


@pytest.mark.parametrize("scene, line", [
    ("gravity_cantilever", "rotations: rotation vectors (a rotation increment of 3 unknowns"),
    ("dna_twist_relaxation", "a prescribed end rotation jumps"),   # a step of end_rotation
])
def test_check_says_why(scene, line, capsys):
    assert main(["check", str(SCENES / f"{scene}.toml")]) == 0
    assert line in capsys.readouterr().out
