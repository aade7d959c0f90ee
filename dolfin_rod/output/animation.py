"""Pictures of a run from the gathered line samples (rank 0 only).

3-D rod:  ``animation.mp4`` where the system's ffmpeg exists (matplotlib's FFMpegWriter,
          H.264), ``animation.gif`` otherwise (``animation_name``): the centre line in
          3-D, a short fading trail of the
          previous frames, coloured by a field along the rod (``Look.colour``:
          ``outputs.color``; default ``colour_field``: the evolving strain with the largest
          change), the deformation magnified when the motion is small (stated on the
          picture), supports and gravity drawn; 840 x 640 px;
          ``snapshots.png``  selected frames in 3-D and the colour field along s.
torsion:  ``spacetime.png``  phi(s, t) and u_d(s, t) as space-time images.

The GIF is cheap (issue 30): matplotlib draws the axes, colour bar and labels once, and
that image is reduced to the GIF's one palette once; each frame is a copy of it with the
projected centre line drawn on it by Pillow in the palette's colours, and the GIF is
written once (an MP4: the same frames in RGB through FFMpegWriter).

Frames are kept thinned (``FrameStore``: at most ``max_frames``, every other frame is
dropped when full), so memory does not grow with the number of steps; the GIF draws at
most ``GIF_FRAMES`` of them.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..scenes.schema import COLOURS
from .plots import save_laid_out

__all__ = ["FrameStore", "Look", "rod_animation", "rod_snapshots", "torsion_spacetime",
           "colour_field", "magnification", "animation_name", "GIF_FRAMES", "COLOURS"]

GIF_FRAMES = 24
TRAIL = 3
SIZE = (8.4, 6.4)            # inches at 100 dpi: 840 x 640 px
FRAME_MS = 160               # ms a frame is shown (GIF and MP4)
STRAINS = ("u", "v", "u_d", "v_d")
SMALL_MOTION = 0.05          # motion below 5 % of the rod's size is magnified ...
SHOWN_MOTION = 0.2           # ... to about 20 % of it
ROUND_OFF = 1e-9             # a colour field below this is round-off (strains: 1e-11)


@dataclass(frozen=True)
class Look:
    """What the 3-D pictures show: the colour field ("auto" or a key of COLOURS), the
    supports {"start": kind, "end": kind} (clamped, pinned, free; a rod system: a tuple
    of such dicts, one per rod in the order of [[rods]]) and gravity (or None)."""

    colour: str = "auto"
    supports: dict = field(default_factory=dict)
    gravity: tuple | None = None
    obstacles: tuple = ()       # the scene's [[obstacles]] tables (planes, spheres and
    #                             meshes drawn; a mesh's with its triangles' "corners")

    @classmethod
    def of(cls, scene, colour: str | None = None) -> Look:
        """The scene's look: ``colour`` or its outputs.color, its ends' supports, its
        gravity."""
        ends = lambda b: {e: b[e] for e in ("start", "end") if e in b}   # noqa: E731
        supports = tuple(ends(r.scene["boundary"]) for r in scene.rods) if scene.rods \
            else ends(scene["boundary"])
        return cls(colour or scene["outputs"]["color"], supports,
                   scene["loads"].get("gravity"), tuple(map(_drawn(scene),
                                                            scene["obstacles"])))


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


def _arc_length(sample) -> float:
    return float(np.ptp(sample.s_nodes))


def _change(frames, key: str) -> float:
    """Largest |x(s, t) - x(s, 0)| of a strain over the run (curvatures times the rod's
    length, so that they compare with stretches)."""
    first = frames[0][1]
    scale = _arc_length(first) if key.startswith("u") else 1.0
    return scale * max(np.max(np.linalg.norm(s.cell[key] - first.cell[key], axis=1))
                       for _, s in frames)


def colour_field(frames, chosen: str = "auto") -> str:
    """``chosen``, or for "auto" the evolving natural strain (u_d, v_d) with the largest
    change; if none evolves, the strain (u, v) with the largest change."""
    if chosen != "auto":
        return chosen
    for pair in (("u_d", "v_d"), ("u", "v")):
        changes = {k: _change(frames, k) for k in pair}
        best = max(changes, key=changes.get)
        if changes[best] > 1e-12:
            return best
    return "u"


def colour_label(key: str) -> str:
    return f"|{key} - {key}(t=0)|" if key in STRAINS else ("xi" if key == "xi" else f"|{key}|")


def colour_values(sample, first, key: str) -> np.ndarray:
    """Per cell: the change of a strain since t = 0, |n| or |m|, or xi."""
    x = np.asarray(sample.cell[key])
    if key in STRAINS:
        x = x - first.cell[key]
    return np.linalg.norm(x.reshape(len(x), -1), axis=1) if key != "xi" else x.ravel()


def magnification(frames) -> float:
    """1, or when the centre line moves less than SMALL_MOTION of the rod's size, a round
    factor (1, 2 or 5 times a power of ten) bringing the motion to about SHOWN_MOTION."""
    r0 = frames[0][1].point["centre_line"]
    size = max(np.max(np.ptp(r0, axis=0)), _arc_length(frames[0][1]))
    motion = max(np.max(np.linalg.norm(s.point["centre_line"] - r0, axis=1))
                 for _, s in frames)
    if motion == 0.0 or motion >= SMALL_MOTION * size:
        return 1.0
    wanted = SHOWN_MOTION * size / motion
    power = 10.0 ** np.floor(np.log10(wanted))
    return float(max(m for m in (1, 2, 5) if m * power <= wanted) * power)


def _shape(sample, first, factor: float) -> np.ndarray:
    r0 = first.point["centre_line"]
    return r0 + factor * (sample.point["centre_line"] - r0)


def _box(shapes):
    pts = np.concatenate(shapes)
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


def _plot_lines(ax, sample, points, **style) -> None:
    """The centre line, one line per rod (the label on the first)."""
    for k, nodes in enumerate(sample.lines()):
        r = points[nodes]
        ax.plot(r[:, 0], r[:, 1], r[:, 2], **(style if k == 0 else
                                               {**style, "label": None}))


def support_nodes(sample, look: Look) -> list[tuple[int, str]]:
    """(node, kind) of the clamped and pinned ends of each rod (none if the supports
    given do not match the sample's rods)."""
    per_rod = look.supports if isinstance(look.supports, tuple) else (look.supports,)
    lines = sample.lines()
    if len(per_rod) != len(lines):
        return []
    held = []
    for supports, nodes in zip(per_rod, lines):
        s = sample.s_nodes[nodes]
        ends = {"start": nodes.start + int(np.argmin(s)), "end": nodes.start + int(np.argmax(s))}
        held += [(ends[e], k) for e, k in supports.items() if k in ("clamped", "pinned")]
    return held


def colour_scale(values: list[np.ndarray]):
    """The colour map and its normalisation for the frames' values: viridis from 0 for a
    field of one sign; for a signed field (xi of the uniform variant, negative in places)
    a diverging map symmetric about 0, so that the sign reads off the colour; values
    below ROUND_OFF (a rod sliding or spinning rigidly) all in the map's first colour."""
    from matplotlib.colors import Normalize
    lo = min(float(np.min(v)) for v in values)
    hi = max(float(np.max(v)) for v in values)
    if max(-lo, hi) < ROUND_OFF:            # nothing changes: one colour, not noise
        return "viridis", Normalize(0.0, 1.0)
    if lo < 0.0 < hi:
        top = max(-lo, hi)
        return "coolwarm", Normalize(-top, top)
    return "viridis", Normalize(min(lo, 0.0), max(hi, 1e-300))


def _notes(factor: float, supports: list) -> str:
    text = [f"displacement x {factor:g}"] if factor != 1.0 else []
    if supports:
        text.append("square: clamped end, circle: pinned end")
    return "   ".join(text)


class _Projection:
    """3-D points -> pixels of the drawn figure (rows from the top)."""

    def __init__(self, ax, height: int):
        self.matrix, self.ax, self.height = ax.get_proj(), ax, height

    def __call__(self, points: np.ndarray) -> np.ndarray:
        h = np.column_stack([points, np.ones(len(points))]) @ self.matrix.T
        xy = self.ax.transData.transform(h[:, :2] / h[:, 3:4])
        xy[:, 1] = self.height - xy[:, 1]
        return xy


def _gravity_arrow(draw, project, box, gravity) -> None:
    """An arrow 'g' along gravity near the box's upper corner."""
    lo, hi = box
    g = np.asarray(gravity, dtype=float)
    start = hi - 0.15 * (hi - lo)
    tip = start + 0.15 * np.max(hi - lo) * g / np.linalg.norm(g)
    a, b = project(np.array([start, tip]))
    draw.line([tuple(a), tuple(b)], fill=(200, 30, 30), width=3)
    d = (b - a) / max(np.linalg.norm(b - a), 1e-9)
    n = np.array([-d[1], d[0]])
    draw.polygon([tuple(b + 6 * d), tuple(b - 6 * d + 5 * n), tuple(b - 6 * d - 5 * n)],
                 fill=(200, 30, 30))
    draw.text(tuple(a + 8 * n), "g", fill=(200, 30, 30))


def plane_patch(box, point, normal) -> np.ndarray:
    """(2, 2, 3) corners of a square in the plane through ``point`` normal to ``normal``:
    centred at the foot of the box's centre, as wide as the box."""
    lo, hi = box
    centre, half = 0.5 * (lo + hi), 0.5 * np.max(hi - lo)
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    foot = centre - np.dot(centre - np.asarray(point, dtype=float), n) * n
    t1 = np.cross(n, np.eye(3)[np.argmin(np.abs(n))])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    a, b = np.meshgrid([-half, half], [-half, half])
    return foot + a[..., None] * t1 + b[..., None] * t2


def _drawn(scene):
    """An [[obstacles]] table as drawn: a mesh's with the corners (m, 3, 3) of its placed
    triangles."""
    from ..scenes.contact import mesh_surface

    def drawn(ob: dict) -> dict:
        if ob["shape"] != "mesh":
            return ob
        surface = mesh_surface(scene, ob)
        return {**ob, "corners": surface.vertices[surface.triangles]}
    return drawn


def draw_obstacles(ax, box, obstacles) -> None:
    """Planes as a grey square of the box's size about the point nearest the box's
    centre, spheres as a grey wire sphere, cylinders as a grey wire tube, meshes as their
    grey triangles that have a corner in the box (drawn once, in the background)."""
    grey = {"color": (0.5, 0.5, 0.5), "alpha": 0.25}
    for ob in obstacles:
        if ob["shape"] == "mesh":
            from mpl_toolkits.mplot3d.art3d import Poly3DCollection
            lo, hi = (np.asarray(b, float) for b in box)
            inside = np.all((ob["corners"] >= lo) & (ob["corners"] <= hi), axis=2).any(1)
            ax.add_collection3d(Poly3DCollection(
                ob["corners"][inside], facecolor=(0.5, 0.5, 0.5, 0.25),
                edgecolor=(0.4, 0.4, 0.4, 0.4), linewidth=0.3))
        if ob["shape"] == "plane":
            corners = plane_patch(box, ob["point"], ob["normal"])
            ax.plot_surface(*np.moveaxis(corners, -1, 0), linewidth=0, **grey)
        elif ob["shape"] == "sphere":
            u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 13), np.linspace(0, np.pi, 7))
            unit = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)])
            points = np.asarray(ob["centre"])[:, None, None] + ob["radius"] * unit
            ax.plot_wireframe(*points, linewidth=0.5, **grey)
        elif ob["shape"] == "cylinder":
            ax.plot_wireframe(*np.moveaxis(cylinder_wire(ob), -1, 0), linewidth=1.5,
                              color=(0.4, 0.4, 0.4), alpha=0.6)     # a thin bar stays visible


def cylinder_wire(ob) -> np.ndarray:
    """(5, 13, 3) points of a cylinder's wire picture: 13 points on each of 5 circles
    along its axis, lid to lid."""
    axis = np.asarray(ob["axis"], float) / np.linalg.norm(ob["axis"])
    e1 = np.cross(axis, (1.0, 0.0, 0.0) if abs(axis[0]) < 0.9 else (0.0, 1.0, 0.0))
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    phi = np.linspace(0.0, 2 * np.pi, 13)[:, None]
    ring = ob["radius"] * (np.cos(phi) * e1 + np.sin(phi) * e2)
    along = np.linspace(-0.5, 0.5, 5)[:, None, None] * ob["length"] * axis
    return np.asarray(ob["centre"], float) + along + ring[None]


def _gravity_quiver(ax, box, gravity) -> None:
    """snapshots.png: the arrow 'g' along gravity near the box's upper corner (as in the
    GIF, _gravity_arrow)."""
    lo, hi = box
    g = np.asarray(gravity, dtype=float)
    start = hi - 0.15 * (hi - lo)
    arrow = 0.15 * np.max(hi - lo) * g / np.linalg.norm(g)
    ax.quiver(*start, *arrow, color=(0.78, 0.12, 0.12), linewidth=2, arrow_length_ratio=0.3)
    ax.text(*(start - 0.05 * arrow), "g", color=(0.78, 0.12, 0.12))


def _draw_rod(draw, pixels, segments, colours, width) -> None:
    for (i, j), c in zip(segments, colours):
        draw.line([tuple(pixels[i]), tuple(pixels[j])], fill=c, width=width)


def _draw_supports(draw, pixels, supports, black) -> None:
    for node, kind in supports:
        x, y = pixels[node]
        box = [x - 7, y - 7, x + 7, y + 7]
        (draw.rectangle if kind == "clamped" else draw.ellipse)(box, fill=black)


def animation_name() -> str:
    """The animation's file: animation.mp4 when the system's ffmpeg is on the PATH (what
    matplotlib's FFMpegWriter runs), animation.gif otherwise."""
    return "animation.mp4" if shutil.which("ffmpeg") else "animation.gif"


def rod_animation(frames: list, path: Path, title: str = "", look: Look = Look()) -> None:
    """The animation of the 3-D shape (see module docstring): an MP4 if ``path`` ends in
    .mp4 (``animation_name``), else a GIF."""
    from matplotlib.cm import ScalarMappable
    from PIL import Image, ImageDraw, ImageFont
    plt = _pyplot()
    pick = np.unique(np.linspace(0, len(frames) - 1, min(GIF_FRAMES, len(frames))).astype(int))
    shown = [frames[i] for i in pick]
    first = frames[0][1]
    key, factor = colour_field(frames, look.colour), magnification(frames)
    shapes = [_shape(s, first, factor) for _, s in shown]
    values = [colour_values(s, first, key) for _, s in shown]
    cmap_name, norm = colour_scale(values)
    fig = plt.figure(figsize=SIZE, dpi=100)
    ax = fig.add_subplot(projection="3d")
    box = _box(shapes)
    _setup_3d(ax, box, title)
    draw_obstacles(ax, box, look.obstacles)
    fig.colorbar(ScalarMappable(norm, cmap_name), ax=ax, shrink=0.7, pad=0.1,
                 label=colour_label(key))
    supports = support_nodes(first, look)
    fig.text(0.02, 0.02, _notes(factor, supports), fontsize=10)
    fig.canvas.draw()
    background = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
    project = _Projection(ax, background.height)
    plt.close(fig)
    if look.gravity is not None and np.any(look.gravity):
        _gravity_arrow(ImageDraw.Draw(background), project, box, look.gravity)
    font = ImageFont.load_default(size=18)
    cmap = plt.get_cmap(cmap_name)
    pixels = [project(p) for p in shapes]
    palette = _Palette(background)
    black = palette.index((0, 0, 0))
    images = []
    for k, (t, sample) in enumerate(shown):
        image = palette.background.copy()
        palette.write(image, (20, 40), f"t = {t:.4g}", font)
        draw = ImageDraw.Draw(image)
        for j in range(min(TRAIL, k), 0, -1):
            grey = palette.index((int(255 - 90 * (TRAIL + 1 - j) / TRAIL),) * 3)
            _draw_rod(draw, pixels[k - j], shown[k - j][1].segments(), [grey] * len(
                values[k - j]), 2)
        _draw_rod(draw, pixels[k], sample.segments(),
                  palette.indices(cmap(norm(values[k]))[:, :3] * 255), 5)
        _draw_supports(draw, pixels[k], supports, black)
        images.append(image)
    if Path(path).suffix == ".mp4":
        _write_mp4([image.convert("RGB") for image in images], path)
        return
    images[0].save(path, save_all=True, append_images=images[1:], duration=FRAME_MS,
                   loop=0, optimize=False)   # (optimize: 0.7 s of palette work for no gain)


class _Palette:
    """The GIF's one palette (255 colours of the drawn axes) and the axes in it; the
    frames are drawn on copies of that palette image with the palette's colours nearest
    to the rod's (as a frame drawn in RGB and quantized without dithering, at a third of
    the copying and without a quantization per frame)."""

    def __init__(self, background):
        self.rgb, self.palette = background, background.quantize(colors=255)
        self.background = self._reduced(background)
        self.colours = np.asarray(self.palette.getpalette()[:3 * 255], float).reshape(-1, 3)

    def _reduced(self, rgb):
        from PIL import Image
        return rgb.quantize(palette=self.palette, dither=Image.Dither.NONE)

    def write(self, image, at: tuple, text: str, font) -> None:
        """Black text at ``at`` on a palette image, its edges blended as in RGB: drawn on
        the axes' pixels under it and reduced to the palette."""
        from PIL import ImageDraw
        left, top, right, bottom = ImageDraw.Draw(self.rgb).textbbox(at, text, font=font)
        box = (int(left) - 1, int(top) - 1, int(right) + 2, int(bottom) + 2)
        patch = self.rgb.crop(box)
        ImageDraw.Draw(patch).text((at[0] - box[0], at[1] - box[1]), text, fill=(0, 0, 0),
                                   font=font)
        image.paste(self._reduced(patch), box[:2])

    def indices(self, rgb: np.ndarray) -> list[int]:
        """The palette's indices nearest to each colour (rows 0-255)."""
        distance = np.linalg.norm(rgb[:, None, :] - self.colours[None], axis=2)
        return np.argmin(distance, axis=1).tolist()

    def index(self, rgb: tuple) -> int:
        return self.indices(np.asarray([rgb], float))[0]


def _write_mp4(images: list, path: Path) -> None:
    """The frames (Pillow images) as an H.264 MP4 by matplotlib's FFMpegWriter: each
    shown at its own pixel size on a figure without axes."""
    from matplotlib.animation import FFMpegWriter
    plt = _pyplot()
    width, height = images[0].size
    fig = plt.figure(figsize=(width / 100, height / 100), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    shown = ax.imshow(np.asarray(images[0]))
    writer = FFMpegWriter(fps=1000 / FRAME_MS, codec="libx264",
                          extra_args=["-pix_fmt", "yuv420p"])   # plays in every browser
    with writer.saving(fig, str(path), dpi=100):
        for image in images:
            shown.set_data(np.asarray(image))
            writer.grab_frame()
    plt.close(fig)


def rod_snapshots(frames: list, path: Path, title: str = "", n: int = 6,
                  look: Look = Look()) -> None:
    """Selected frames in 3-D (coloured by time) and the colour field along s."""
    plt = _pyplot()
    pick = np.unique(np.linspace(0, len(frames) - 1, min(n, len(frames))).astype(int))
    first = frames[0][1]
    key, factor = colour_field(frames, look.colour), magnification(frames)
    fig = plt.figure(figsize=(10, 4.2))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    colours = plt.cm.plasma(np.linspace(0.0, 0.85, len(pick)))
    for c, i in zip(colours, pick):
        t, sample = frames[i]
        _plot_lines(ax, sample, _shape(sample, first, factor), color=c, lw=2,
                    label=f"t = {t:.3g}")
        colour, first_nodes = colour_values(sample, first, key), sample.segments()[:, 0]
        for nodes in sample.lines():      # one rod at a time: no step across a gap
            cells = (first_nodes >= nodes.start) & (first_nodes < nodes.stop)
            ax2.step(sample.s_cells[cells], colour[cells], where="mid", color=c)
    r0 = first.point["centre_line"]
    for node, kind in support_nodes(first, look):
        ax.scatter(*r0[node], marker="s" if kind == "clamped" else "o", color="k", s=40)
    box = _box([_shape(frames[i][1], first, factor) for i in pick])
    _setup_3d(ax, box,
              "centre line r(s, t)" + (f", displacement x {factor:g}" if factor != 1 else ""))
    draw_obstacles(ax, box, look.obstacles)
    if look.gravity is not None and np.any(look.gravity):
        _gravity_quiver(ax, box, look.gravity)
    ax.legend(fontsize=7, loc="upper left")
    ax2.set_xlabel("s"), ax2.set_ylabel(colour_label(key))
    ax2.set_title(f"{colour_label(key)} along the rod", fontsize=9)
    fig.suptitle(title)
    save_laid_out(fig, path, 90)
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
    save_laid_out(fig, path, 90)
    plt.close(fig)
