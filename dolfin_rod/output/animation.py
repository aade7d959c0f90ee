"""Pictures of a run from the gathered line samples (rank 0 only).

3-D rod:  ``animation.gif``  the centre line in 3-D, a short fading trail of the
          previous frames, coloured by |u_d - u_ref| per cell (how far the natural
          curvature has evolved from the reference; |u - u_ref| for models without
          natural strains);
          ``snapshots.png``  selected frames in 3-D and |u_d - u_ref|(s) at those times.
torsion:  ``spacetime.png``  phi(s, t) and u_d(s, t) as space-time images.

Frames are kept thinned (``FrameStore``: at most ``max_frames``, every other frame is
dropped when full), so memory does not grow with the number of steps; the GIF draws at
most ``GIF_FRAMES`` of them (matplotlib.animation with Pillow).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["FrameStore", "rod_animation", "rod_snapshots", "torsion_spacetime",
           "GIF_FRAMES"]

GIF_FRAMES = 24
TRAIL = 3


class FrameStore:
    """(t, LineSample) pairs, thinned to at most ``max_frames`` (the last one is kept)."""

    def __init__(self, max_frames: int = 160):
        self.max_frames, self.stride, self.count = max_frames, 1, 0
        self.frames: list = []
        self.last = None

    def add(self, t: float, sample) -> None:
        frame = (t, sample)
        if self.count % self.stride == 0:
            self.frames.append(frame)
            if len(self.frames) > self.max_frames:
                self.frames = self.frames[::2]
                self.stride *= 2
        self.count += 1
        self.last = frame

    def all(self) -> list:
        """The kept frames and the latest one."""
        if self.last is not None and (not self.frames or self.frames[-1] is not self.last):
            return self.frames + [self.last]
        return list(self.frames)


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _colour_label(frames) -> str:
    """|u_d - u_ref| (how far the natural curvature evolved), or |u - u_ref| (the
    curvature change) for models whose natural strains do not evolve."""
    evolved = max(np.max(np.linalg.norm(s.cell["u_d"] - s.cell["u_ref"], axis=1))
                  for _, s in frames)
    return "|u_d - u_ref|" if evolved > 0 else "|u - u_ref|"


def _colour(sample, label: str) -> np.ndarray:
    key = "u_d" if label == "|u_d - u_ref|" else "u"
    return np.linalg.norm(sample.cell[key] - sample.cell["u_ref"], axis=1)


def _box(frames):
    pts = np.concatenate([s.point["centre_line"] for _, s in frames])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid, half = 0.5 * (lo + hi), 0.5 * max(np.max(hi - lo), 1e-12) * 1.05
    return mid - half, mid + half


def _setup_3d(ax, box, title=""):
    lo, hi = box
    ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
    ax.set_xlabel("x"), ax.set_ylabel("y"), ax.set_zlabel("z")
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=18, azim=-72)
    ax.set_title(title, fontsize=9)


def _segments(sample) -> np.ndarray:
    return sample.point["centre_line"][sample.segments()]


def _plot_lines(ax, sample, **style) -> None:
    """The centre line, one line per rod (the label on the first)."""
    for k, nodes in enumerate(sample.lines()):
        r = sample.point["centre_line"][nodes]
        ax.plot(r[:, 0], r[:, 1], r[:, 2], **(style if k == 0 else
                                               {**style, "label": None}))


def rod_animation(frames: list, path: Path, title: str = "") -> None:
    """The GIF of the 3-D shape (see module docstring)."""
    from matplotlib.animation import FuncAnimation, PillowWriter
    from mpl_toolkits.mplot3d.art3d import Line3DCollection
    plt = _pyplot()
    pick = np.unique(np.linspace(0, len(frames) - 1, min(GIF_FRAMES, len(frames))).astype(int))
    shown = [frames[i] for i in pick]
    label = _colour_label(frames)
    vmax = max(max(np.max(_colour(s, label)) for _, s in frames), 1e-300)
    fig = plt.figure(figsize=(4.8, 4.4))
    ax = fig.add_subplot(projection="3d")
    box = _box(frames)
    current = Line3DCollection([], cmap="viridis", linewidths=3)
    current.set_clim(0.0, vmax)
    trail = [Line3DCollection([], colors="0.5", linewidths=1) for _ in range(TRAIL)]
    for line in trail:
        ax.add_collection(line)
    ax.add_collection(current)
    fig.colorbar(current, ax=ax, shrink=0.6, label=label)
    _setup_3d(ax, box)

    def draw(k):
        t, sample = shown[k]
        current.set_segments(_segments(sample))
        current.set_array(_colour(sample, label))
        for j, line in enumerate(trail):
            line.set_segments(_segments(shown[max(k - j - 1, 0)][1]))
            line.set_alpha(0.5 * (TRAIL - j) / TRAIL if k - j - 1 >= 0 else 0.0)
        ax.set_title(f"{title}  t = {t:.4g}", fontsize=9)
        return [current, *trail]

    anim = FuncAnimation(fig, draw, frames=len(shown), blit=False)
    anim.save(path, writer=PillowWriter(fps=6), dpi=64)
    plt.close(fig)


def rod_snapshots(frames: list, path: Path, title: str = "", n: int = 6) -> None:
    """Selected frames in 3-D (coloured by time) and the evolved curvature along s."""
    plt = _pyplot()
    pick = np.unique(np.linspace(0, len(frames) - 1, min(n, len(frames))).astype(int))
    label = _colour_label(frames)
    fig = plt.figure(figsize=(10, 4.2))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    colours = plt.cm.plasma(np.linspace(0.0, 0.85, len(pick)))
    for c, i in zip(colours, pick):
        t, sample = frames[i]
        _plot_lines(ax, sample, color=c, lw=2, label=f"t = {t:.3g}")
        colour, first_nodes = _colour(sample, label), sample.segments()[:, 0]
        for nodes in sample.lines():      # one rod at a time: no step across a gap
            cells = (first_nodes >= nodes.start) & (first_nodes < nodes.stop)
            ax2.step(sample.s_cells[cells], colour[cells], where="mid", color=c)
    _setup_3d(ax, _box(frames), "centre line r(s, t)")
    ax.legend(fontsize=7, loc="upper left")
    ax2.set_xlabel("s"), ax2.set_ylabel(label)
    ax2.set_title("evolved natural curvature" if label == "|u_d - u_ref|" else
                  "curvature change", fontsize=9)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def torsion_spacetime(frames: list, path: Path, title: str = "") -> None:
    """phi(s, t) and u_d(s, t) as images over (s, t)."""
    plt = _pyplot()
    t = np.array([f[0] for f in frames])
    first = frames[0][1]
    phi = np.array([s.point["phi"] for _, s in frames])
    u_d = np.array([s.cell["u_d"] for _, s in frames])
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for a, values, s, name in ((ax[0], phi, first.s_nodes, "twist angle phi(s, t)"),
                               (ax[1], u_d, first.s_cells, "natural twist u_d(s, t)")):
        im = a.pcolormesh(s, t, values, shading="nearest", cmap="viridis")
        fig.colorbar(im, ax=a)
        a.set_xlabel("s"), a.set_title(name, fontsize=10)
    ax[0].set_ylabel("t")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
