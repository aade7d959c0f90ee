"""The picture of an analysis's modes (``dolfin-rod buckle``, ``modes``: buckle.png,
modes.png beside the .bp file, output/modes.py): one panel per mode, the rod's centre
line (grey) and the centre line displaced by the mode (scaled as in the .bp file),
each projected on the plane of the centre line's axis and the mode's main direction
(view_plane), titled with the mode's load factor or frequency.  A rod system's lines are
drawn rod by rod (``segments``: the cells' nodes; a rod's nodes are a run of them), not
joined from one rod's end to the next one's start."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["view_plane", "mode_figure", "draw_modes", "runs"]


def view_plane(centre: np.ndarray, displacement: np.ndarray) -> np.ndarray:
    """Two orthonormal directions (rows): the centre line's principal axis (pointing from
    its start to its end), then the principal direction of the displacement across it
    (pointing to the largest one)."""
    axis = _principal(centre - centre.mean(axis=0), np.array([0.0, 0.0, 1.0]))
    axis *= 1.0 if axis @ (centre[-1] - centre[0]) >= 0.0 else -1.0
    across = displacement - np.outer(displacement @ axis, axis)
    fallback = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    side = _principal(across, fallback / np.linalg.norm(fallback))
    side -= (side @ axis) * axis
    largest = across[np.argmax(np.linalg.norm(across, axis=1))]
    side *= 1.0 if side @ largest >= 0.0 else -1.0
    return np.array([axis, side / np.linalg.norm(side)])


def _principal(points: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """The unit direction of the points' largest extent (``fallback`` for none)."""
    if np.linalg.norm(points) == 0.0:
        return fallback
    return np.linalg.svd(points, full_matrices=False)[2][0]


def runs(segments: np.ndarray | None, count: int) -> list[np.ndarray]:
    """The nodes of each rod of ``count`` nodes joined by the cells ``segments`` ((N, 2),
    in the order of s; None: one rod), each run a range of node numbers."""
    if segments is None or len(segments) == 0:
        return [np.arange(count)]
    breaks = np.flatnonzero(segments[1:, 0] != segments[:-1, 1]) + 1
    return [np.arange(part[0, 0], part[-1, 1] + 1) for part in np.split(segments, breaks)]


def mode_figure(centre: np.ndarray, displaced: list[np.ndarray], titles: list[str],
                heading: str = "", segments: np.ndarray | None = None):
    """The figure: a panel per mode (the centre line, the line ``displaced``, both
    projected by view_plane; the axes' lines: the centre line's rods, then the displaced
    line's, one line per rod of ``segments`` (runs))."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ncols = min(3, len(displaced))
    nrows = -(-len(displaced) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 3.6 * nrows),
                             squeeze=False)
    rods = runs(segments, len(centre))
    for ax, points, title in zip(axes.flat, displaced, titles):
        plane = view_plane(centre, points - centre)
        for line, style in ((centre, dict(color="0.6", lw=1.5)),
                            (points, dict(color="C0", lw=2.0, marker=".", ms=4))):
            along, across = ((line - centre.mean(axis=0)) @ plane.T).T
            for rod in rods:
                ax.plot(across[rod], along[rod], **style)
        if np.array_equal(points, centre):     # (analysis.stability.mode_shapes)
            ax.text(0.5, 0.1, "a turn alone: no displacement", ha="center",
                    transform=ax.transAxes)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("across (the mode's direction)")
        ax.set_ylabel("along the centre line")
    for ax in list(axes.flat)[len(displaced):]:
        ax.set_visible(False)
    fig.suptitle(heading)
    fig.tight_layout()
    return fig


def draw_modes(path: Path, centre: np.ndarray, displaced: list[np.ndarray],
               titles: list[str], heading: str = "",
               segments: np.ndarray | None = None) -> None:
    """mode_figure saved as ``path`` (PNG)."""
    import matplotlib.pyplot as plt
    fig = mode_figure(centre, displaced, titles, heading, segments)
    fig.set_layout_engine(None)     # laid out: savefig would lay it out again (plots.py)
    fig.savefig(path, dpi=100)
    plt.close(fig)
