"""The picture of docs/gallery.md's continuum snake: scenes/continuum_snake.toml run for
PyElastica's 11 periods (or a run folder of it given as the argument, such as
benchmarks/snake_peer.py's), drawn from above: the centre line every two periods, its
centre of mass's path, and the centre of mass's forward position against time beside
the straight line of PyElastica's average speed (results/bench/snake_peer*.json, when
one holds PyElastica's run).

    ./rodenv python3 docs/gallery_snake.py [RUN_FOLDER]   # docs/figures/continuum_snake.png
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dolfin_rod import load_scene, read_pvd, run_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PERIOD = 2.0


def centre(points: np.ndarray) -> np.ndarray:
    """The centre of mass of the uniform P1 centre line (the trapezoidal rule)."""
    w = np.ones(len(points))
    w[[0, -1]] = 0.5
    return w @ points / w.sum()


def main() -> None:
    if len(sys.argv) > 1:
        folder = Path(sys.argv[1])
    else:
        folder = ROOT / "results" / "gallery" / "continuum_snake"
        run_scene(load_scene(ROOT / "scenes" / "continuum_snake.toml",
                             {"time.t_end": 11.01 * PERIOD, "outputs.every": 5,
                              "outputs.animation": False, "outputs.progress": False}),
                  folder, quiet=True, overwrite=True)
    steps = read_pvd(folder / "rod.pvd")
    t = np.array([s["time"] for s in steps])
    com = np.array([centre(s["points"]) for s in steps])
    fig, (top, forward) = plt.subplots(1, 2, figsize=(12, 3.4),
                                       gridspec_kw={"width_ratios": [2.6, 1]})
    shown = [int(np.argmin(np.abs(t - k * 2 * PERIOD)))
             for k in range(int(t[-1] / (2 * PERIOD)) + 1)]
    colours = plt.cm.viridis(np.linspace(0, 1, len(shown)))
    for i, c in zip(shown, colours):
        top.plot(steps[i]["points"][:, 2], steps[i]["points"][:, 0], color=c, lw=1.5)
        top.plot(steps[i]["points"][-1, 2], steps[i]["points"][-1, 0], "o", color=c, ms=3)
    top.plot(com[:, 2], com[:, 0], "k--", lw=0.8, label="centre of mass")
    top.set_aspect("equal")
    top.set_xlabel("z [m] (forward)")
    top.set_ylabel("x [m]")
    top.set_title("from above, every 2 T = 4 s (dot: the head, s = L)")
    top.legend(loc="lower right", fontsize=8)
    forward.plot(t, com[:, 2] - com[0, 2], label="dolfin_rod")
    runs = [r for peer in sorted((ROOT / "results" / "bench").glob("snake_peer*.json"))
            for r in json.loads(peer.read_text())["runs"]]
    pyelastica = [r for r in runs if r["code"] == "PyElastica"]
    if pyelastica:
        a = int(np.argmin(np.abs(t - 2 * PERIOD)))
        line = com[a, 2] - com[0, 2] + pyelastica[-1]["forward"] * (t[a:] - t[a])
        forward.plot(t[a:], line, "k--", lw=1,
                     label=f"PyElastica's average speed ({pyelastica[-1]['forward']:.4f} m/s)")
    forward.set_xlabel("t [s]")
    forward.set_ylabel("centre of mass, forward [m]")
    forward.legend(fontsize=8)
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "continuum_snake.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
