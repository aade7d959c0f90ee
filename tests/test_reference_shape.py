"""A stress-free shape given as a curve (RodParameters.reference_shape, rod/start.py
curves): an arc equals the reference curvature of its circle bit for bit; an L-frame as
one rod with a corner in its stress-free shape is the frame of two rods and a rigid
joint to first order in h; bad shapes named."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rod_systems import FRAME, kinked_frame

from dolfin_rod import EndLoad, RodModel, RodParameters, TimeStepper
from dolfin_rod.rod.start import Arc, Polyline

ROOT = Path(__file__).resolve().parents[1]


def tip(d: dict) -> np.ndarray:
    return np.array([d[f"tip_position_{c}"] for c in "xyz"])


def test_arc_shape_is_the_reference_curvature():
    """reference_shape = Arc(R) and reference_curvature = (0, 1/R, 0) give the same
    stress-free configuration (the same helix), so the same dynamic run bit for bit."""
    results = []
    for shape in ({"reference_shape": Arc(0.7)}, {"reference_curvature": (0.0, 1 / 0.7, 0.0)}):
        p = RodParameters(length=1.0, density=1.0, section_inertia=0.01, **shape)
        model = RodModel(p, 8, model="hyperelastic", end_loads=[EndLoad("force", (0, 1, 0))])
        model.set_initial_state()
        TimeStepper(model.problem).run(0.0, 0.05, 0.01)
        results.append(model.diagnostics(0.05))
    assert results[0] == results[1]
    assert abs(results[0]["tip_position_y"]) > 1e-4


@pytest.mark.parametrize("force", [1e-6, 1.5])
def test_kinked_rod_is_the_joined_frame_to_first_order(force):
    """The L-frame (tests/rod_systems.FRAME, cells of h = 0.2, 0.1, 0.05: 5 and 4 per
    0.2 of column and beam) as one rod with a corner in its stress-free shape against
    the two rods joined rigidly: the same frame in the limit, the difference first
    order in h, as the corner is spread over its node's two cells (each turned by 45 deg
    in the stress-free shape) where the joint ties two nodes.  Measured tip differences
    relative to the tip's displacement: small load 1.9e-2, 9.9e-3, 5.1e-3 (rates 0.92,
    0.96); tip force 1.5 (tip lowered by 0.6 L1): 1.3e-2, 6.4e-3, 3.1e-3 (rates 1.04,
    1.02).  Asserted: rates in [0.8, 1.2], the finest difference below 1 %."""
    steps = 1 if force < 1 else 4
    differences = []
    for k in (1, 2, 4):
        one, two = (kinked_frame(5 * k, 4 * k, force, steps, joined) for joined in (False, True))
        moved = tip(two) - np.array([FRAME["L2"], 0.0, FRAME["L1"]])
        differences.append(np.linalg.norm(tip(one) - tip(two)) / np.linalg.norm(moved))
    rates = np.log2(np.array(differences[:-1]) / differences[1:])
    assert np.all((rates > 0.8) & (rates < 1.2)), (differences, rates)
    assert differences[-1] < 0.01, differences


@pytest.mark.parametrize("params, message", [
    (dict(length=1.5, reference_shape=Polyline(((0, 0, 0), (0, 0, 1), (1, 0, 1)))),
     "reference_shape.points: the polyline's length 2 differs"),
    (dict(reference_shape=Arc(-1.0)), "reference_shape.radius: must be > 0"),
    (dict(reference_shape=Arc(1.0), reference_curvature=(0, 1, 0)),
     "reference_shape: the stress-free shape is a curve or"),
    (dict(reference_shape=((0, 0, 0), (0, 0, 1))), "reference_shape: must be a Straight"),
])
def test_bad_reference_shapes_are_named(params, message):
    with pytest.raises(ValueError, match=message):
        RodModel(RodParameters(**params), 4)


def test_bent_frame_scene_is_the_frame_scene_to_first_order(tmp_path):
    """scenes/bent_frame.toml (one rod, a corner in its stress-free polyline) against
    scenes/frame.toml (two rods welded), the same steel frame and load, 16 + 12 cells:
    the tips after the load ramp agree to 0.4 % of the 1.3 m deflection (measured 4.7
    mm: the first-order difference of the corner above).  A polyline of the wrong
    length: `dolfin-rod check` exit 2 naming geometry.reference_shape.points."""
    from dolfin_rod import run
    quiet = {"outputs.animation": False, "outputs.plots": False, "outputs.fields": False}
    bent = run(ROOT / "scenes" / "bent_frame.toml", quiet, out=tmp_path / "bent", quiet=True)
    frame = run(ROOT / "scenes" / "frame.toml", quiet, out=tmp_path / "frame", quiet=True)
    one = np.array([bent.series[f"tip_position_{c}"][-1] for c in "xyz"])
    two = np.array([frame.series[f"beam.tip_position_{c}"][-1] for c in "xyz"])
    deflection = np.linalg.norm(two - [1.5, 0.0, 2.0])
    assert deflection > 1.0
    assert np.linalg.norm(one - two) < 4e-3 * deflection
    bad = tmp_path / "bad.toml"
    bad.write_text((ROOT / "scenes" / "bent_frame.toml").read_text().replace(
        "[1.5, 0.0, 2.0]", "[1.2, 0.0, 2.0]"))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "dolfin_rod", "check", str(bad)],
                         capture_output=True, text=True, timeout=120, cwd=ROOT, env=env)
    assert out.returncode == 2, out.stderr
    assert "[geometry.reference_shape.points]" in out.stderr and "Traceback" not in out.stderr
