"""The README's and the docs' command blocks marked runnable run as documented.

A block is marked by an HTML comment on the line before it (blank lines between are
allowed), invisible in the rendered Markdown:

    <!-- runnable -->         a fast block: in the default test run
    <!-- runnable: slow -->   a long one (demos, 3-D rod fits): @pytest.mark.slow

A fenced block (```sh) runs as one bash script (``set -e``); an indented block is a
transcript: its ``$ `` lines are commands, the lines after each are the output it
documents, and every such line must appear in the actual output (a line with "..." or
a placeholder such as <time>: up to there).  Numbers in those lines are compared to 1e-3 relative: what the docs print
is rounded to 3-6 digits, the runs reproduce it to the solver tolerance (1e-10) apart from
round-off between DOLFINx releases (~1e-12); a changed result (a drifting fit) is not.
Commands run in a fresh folder that links the repository's scenes/, examples/ and
demos/ (results/ stays there) with ``./rodenv`` a pass-through: the test itself runs
inside the environment.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MARK = re.compile(r"<!--\s*runnable(?:\s*:\s*(slow))?\s*-->")
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
REL_TOL = 1e-3
TIMEOUT = 600   # s: the slowest marked block (the DNA demo, ~40 s) with a shared machine


@dataclass
class Block:
    source: str        # file:line of the marker
    text: str
    transcript: bool   # an indented $ block
    slow: bool


def _block_after(lines: list[str], i: int) -> tuple[str, bool]:
    """The block after line i: (its text, whether it is an indented transcript)."""
    j = i + 1
    while j < len(lines) and not lines[j].strip():
        j += 1
    if j < len(lines) and lines[j].startswith("```"):
        end = next(k for k in range(j + 1, len(lines)) if lines[k].startswith("```"))
        return "\n".join(lines[j + 1:end]), False
    body = []
    while j < len(lines) and (lines[j].startswith("    ") or not lines[j].strip()):
        body.append(lines[j][4:])
        j += 1
    if not body:
        raise ValueError(f"line {i + 1}: a runnable marker without a block after it")
    return "\n".join(body).strip("\n"), True


def runnable_blocks() -> list[Block]:
    blocks = []
    for path in DOCS:
        lines = path.read_text().splitlines()
        for i, line in enumerate(lines):
            match = MARK.fullmatch(line.strip())
            if match:
                text, transcript = _block_after(lines, i)
                blocks.append(Block(f"{path.relative_to(ROOT)}:{i + 1}", text, transcript,
                                    match.group(1) == "slow"))
    return blocks


def _workdir(tmp_path: Path) -> Path:
    for name in ("scenes", "examples", "demos"):
        (tmp_path / name).symlink_to(ROOT / name)
    rodenv = tmp_path / "rodenv"
    rodenv.write_text('#!/bin/sh\nexec "$@"\n')
    rodenv.chmod(0o755)
    return tmp_path


def _run(script: str, cwd: Path) -> str:
    done = subprocess.run(["bash", "-c", "set -e\n" + script], cwd=cwd, text=True,
                          capture_output=True, timeout=TIMEOUT,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stdout}\n{done.stderr}"
    return done.stdout + done.stderr


def _same_line(expected: str, actual: str) -> bool:
    """Words equal, numbers to REL_TOL."""
    a, b = expected.split(), actual.split()
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        if NUMBER.fullmatch(x) and NUMBER.fullmatch(y):
            if not math.isclose(float(x), float(y), rel_tol=REL_TOL, abs_tol=1e-12):
                return False
        elif x != y:
            return False
    return True


def _check_transcript(text: str, cwd: Path) -> None:
    for chunk in re.split(r"^\$ ", text, flags=re.M)[1:]:
        command, *expected = chunk.splitlines()
        output = _run(command, cwd).splitlines()
        for line in filter(str.strip, expected):
            if "..." in line or "<" in line:       # elided, or a placeholder (<time>)
                head = " ".join(re.split(r"\.\.\.|<", line)[0].split())
                assert any(" ".join(o.split()).startswith(head) for o in output), \
                    (line, output)
            else:
                assert any(_same_line(line, o) for o in output), (line, output)


def _params():
    return [pytest.param(b, id=b.source, marks=[pytest.mark.slow] if b.slow else [])
            for b in runnable_blocks()]


@pytest.mark.parametrize("block", _params())
def test_runnable_block(block: Block, tmp_path):
    cwd = _workdir(tmp_path)
    if block.transcript:
        _check_transcript(block.text, cwd)
    else:
        _run(block.text, cwd)


def test_markers_found():
    """The markers this test relies on are where the docs say (a renamed marker would
    silently test nothing): at least the fast creep fit transcript and the DNA blocks."""
    sources = {b.source.split(":")[0] for b in runnable_blocks()}
    assert {"README.md", "docs/fitting.md", "docs/dna.md"} <= sources, sources
    assert any(not b.slow for b in runnable_blocks())


def test_the_gallery_names_bundled_scenes_only():
    """Each scene docs/gallery.md names (in its table or as scenes/NAME.toml) is in scenes/,
    so each gallery scene is one that tests/test_scenes.py::test_bundled_scene_runs runs;
    every picture it shows exists."""
    text = (ROOT / "docs" / "gallery.md").read_text()
    table = text[:text.index("Every scene named here is bundled")]
    named = {n for cell in re.findall(r"^\|[^|]*\| ([^|]*) \|", table, flags=re.M)
             for n in re.findall(r"`([a-z_]+)`", cell)}
    named |= set(re.findall(r"scenes/([a-z_]+)\.toml", text))
    bundled = {p.stem for p in (ROOT / "scenes").glob("*.toml")}
    assert len(named) >= 20 and named <= bundled, named - bundled
    for picture in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text):
        assert (ROOT / "docs" / picture).is_file(), picture


def test_links_stay_in_the_repository_and_the_paper_is_cited():
    """Every relative link of the README and the docs (Markdown links and pictures) names
    a file of this repository (a clone has nothing beside it: no ../shared/...), and the
    README cites the paper by its authors and title (the paper's source carries no arXiv
    identifier, so none is given: docs/corrections.md says so)."""
    for page in DOCS:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text()):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue                       # a web address or an anchor of the page
            path = (page.parent / target.split("#")[0]).resolve()
            assert path.is_relative_to(ROOT) and path.exists(), f"{page.name}: {target}"
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert ("K. R. Rajagopal and C. Rodriguez, *Special Cosserat rods with rate-dependent "
            "evolving natural configurations*") in readme
