"""The picture of docs/gallery.md's deep arch: runs scenes/deep_arch.toml (the
215-degree clamped-pinned arch under a crown load, arc-length continuation) at 16, 32
and 64 cells and draws the load against the crown's displacement, down and sideways,
with DaDeppo & Schmidt's limit load 8.97 EI/R^2, and the arch's shapes up to the limit
point.

    ./rodenv python3 docs/gallery_deep_arch.py    # ~30 s; docs/figures/gallery_deep_arch.png
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dolfin_rod import load_scene, read_vtx, run_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
LIMIT = 8.97           # DaDeppo & Schmidt 1975, P R^2/EI
# cells: (arc length, most steps): about 65 steps to the limit point and 30 past it
RUNS = {16: (0.1, 95), 32: (0.14, 100), 64: (0.2, 110)}


def run(n_cells: int) -> tuple[dict, list]:
    """The scene's time series (columns) and rod.bp steps at n_cells."""
    ds, steps = RUNS[n_cells]
    folder = ROOT / "results" / "gallery" / f"deep_arch_{n_cells}"
    run_scene(load_scene(ROOT / "scenes" / "deep_arch.toml", {
        "geometry.n_cells": n_cells, "continuation.arc_length": ds,
        "continuation.max_steps": steps, "outputs.animation": False, "outputs.plots": False,
        "outputs.progress": False}), folder, quiet=True, overwrite=True)
    rows = np.genfromtxt(folder / "timeseries.csv", delimiter=",", names=True,
                         deletechars="")
    return {k: rows[k] for k in rows.dtype.names}, read_vtx(folder / "rod.bp")


def main() -> None:
    fig, (ax_load, ax_shape) = plt.subplots(1, 2, figsize=(11, 4.6))
    for n_cells, colour in zip(RUNS, ("tab:blue", "tab:orange", "tab:green")):
        s, steps = run(n_cells)
        load = 20.0 * s["time"]
        top = int(np.argmax(load))
        down = s["point0_position_y"][0] - s["point0_position_y"]
        sideways = s["point0_position_z"] - s["point0_position_z"][0]
        ax_load.plot(down, load, "-", color=colour,
                     label=f"crown down, {n_cells} cells (limit {load[top]:.2f})")
        ax_load.plot(sideways, load, "--", color=colour,
                     label=f"crown sideways, {n_cells} cells")
        ax_load.plot(down[top], load[top], "o", color=colour)
        if n_cells == 64:
            colours = plt.cm.plasma(np.linspace(0.0, 0.85, len(range(0, top + 1, 8))))
            for c, step in zip(colours, steps[:top + 1:8]):
                for a, b in step["cells"]:
                    ax_shape.plot(*step["points"][[a, b]][:, [2, 1]].T, color=c, lw=2)
            unstable = steps[-1]
            for a, b in unstable["cells"]:
                ax_shape.plot(*unstable["points"][[a, b]][:, [2, 1]].T, color="0.5", lw=1,
                              ls=":")
    ax_load.axhline(LIMIT, color="k", lw=0.8, ls=":",
                    label="DaDeppo & Schmidt: 8.97 EI/R$^2$")
    ax_load.set(xlabel="crown displacement / R", ylabel="P R$^2$ / EI",
                title="215-degree arch: load against crown displacement")
    ax_load.legend(fontsize=7, loc="lower right")
    ax_shape.set_aspect("equal")
    ax_shape.set(xlabel="z / R", ylabel="y / R",
                 title="64 cells: shapes up to the limit point;\ndotted: the last step on the unstable branch")
    fig.tight_layout()
    FIGURES.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURES / "gallery_deep_arch.png", dpi=110)
    print(FIGURES / "gallery_deep_arch.png")


if __name__ == "__main__":
    main()
