"""A contact solve that finally fails, as a user runs it (issue 26): ``dolfin-rod run``
ends with exit 3, keeps the rows computed so far, and its error names the segment pair
(rods, arc lengths s on each rod) and where in space (step_control.step_failure,
SegmentContact.nearest_pair)."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest

from test_cli import cli

CROSSING = Path(__file__).resolve().parents[1] / "scenes" / "crossing_rods.toml"
# scenes/crossing_rods.toml: the beam (8 cells) rests at its node s = 0.75 on the prop
# (4 cells) at the prop's node s = 0.25: the pair of segments around them
PAIR = re.compile(r"segments of rod beam at s = 0\.\d+ and rod prop at s = 0\.\d+, near "
                  r"\(0\.75\d*, [-0-9.e]+, [-0-9.e]+\)")


def _run(tmp_path, changes: dict[str, str]):
    text = CROSSING.read_text().replace("dt = 0.25", "dt = 0.125\nmax_step_cuts = 2")
    for old, new in changes.items():
        assert old in text
        text = text.replace(old, new, 1)
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    proc = cli("run", scene, "--out", tmp_path / "run")
    with open(tmp_path / "run" / "timeseries.csv") as f:
        rows = list(csv.DictReader(f))
    return proc, rows


def test_a_barrier_overcome_names_the_pair_and_keeps_the_rows(tmp_path):
    """contact.stiffness = 10: the barrier's force below its exact range (1e-4 delta) is
    bounded, ~0.6 kappa = 6 N per pair, and the prop must take more as the tip load
    grows: at t = 0.34 s every cut still overlaps.  Exit 3; the rows at t = 0, 0.125,
    0.25 kept; the error names the pair, the point (x = 0.75) and the reason."""
    proc, rows = _run(tmp_path, {"gap = 0.0005 ": "stiffness = 10.0\ngap = 0.0005 "})
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert [float(r["time"]) for r in rows] == pytest.approx([0.0, 0.125, 0.25])
    message = proc.stdout + proc.stderr
    assert "time step failed at t = 0.34375" in message
    assert PAIR.search(message) and "the barrier was overcome" in message


def test_a_newton_failure_in_contact_names_the_pair(tmp_path):
    """Newton limited to 4 iterations (solver.options), which a contact step needs more
    than: the final IntegrationError adds where it failed, the pair nearest to touching
    at Newton's last iterate (rods, s, point, gap), exit 3, the first row kept."""
    proc, rows = _run(tmp_path, {"gap = 0.0005 ": "stiffness = 1e4\ngap = 0.0005 ",
                                 "[time]": "[solver]\noptions = { snes_max_it = 4 }\n[time]"})
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert len(rows) == 1
    message = proc.stdout + proc.stderr
    assert "DIVERGED_MAX_IT" in message and "; where: " in message
    assert PAIR.search(message) and "at Newton's last iterate" in message
