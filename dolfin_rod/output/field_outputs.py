"""The fields along the rod written while a run goes: ``rod.bp`` (ParaView >= 5.13,
ADIOS2VTXReader), the same steps as ``rod.pvd`` + ``rod/*.vtu`` (any ParaView,
vtk_xml.py) and the frames of the animation and pictures (animation.py)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from .run_folders import on_root

class FieldOutputs:
    """The fields along the rod of an FE model (RodModel or TorsionModel, anything with
    ``observables()``): ``rod.bp`` and ``rod.pvd`` (ParaView) and the pictures of
    animation.py, from
    LineSampler samples gathered on rank 0.  ``model = None`` (ODE runs): nothing.
    Usable from scripts:

        out = FieldOutputs(folder, model, comm)     # collective
        ... out.write(t) after each step (collective) ...
        out.finish("title")                         # rank 0: close rod.bp, draw
    """

    POINT = ("centre_line", "d1", "d2", "d3", "phi",    # vertex values; others per cell
             "contact_force")

    def __init__(self, folder: Path, model, comm, fields: bool = True, animation: bool = True):
        self.folder, self.comm = Path(folder), comm
        self.outputs = {"fields": fields, "animation": animation}
        self.sampler = None
        if model is not None and hasattr(model, "observables"):
            from .line_fields import LineSampler
            self.sampler = LineSampler(model.mesh, model.observables(), self.POINT)
        self.keep_until: float | None = None     # resume: steps of rod.bp kept up to here
        self.writers: list = []           # rod.bp (vtx.py), rod.pvd (vtk_xml.py)
        self.listing = None               # the rod.pvd writer (LineVTU)
        self.frames = None

    def write(self, t: float) -> None:
        """Collective: one sample; rank 0 writes it to rod.bp and keeps it as a frame."""
        if self.sampler is None:
            return
        sample = self.sampler.sample()
        on_root(self.comm, lambda: self._keep(t, sample),     # a full disk: every rank
                f"cannot write the fields along the rod in {self.folder}")

    def _keep(self, t: float, sample) -> None:
        """Rank 0: the sample to rod.bp, rod.pvd and the frames."""
        if self.frames is None:
            self._start()
        for writer in self.writers:
            writer.write(t, _geometry(sample), *self._data(sample), sample.segments())
        self.frames.add(t, sample)

    def _start(self) -> None:
        from .animation import FrameStore
        from .vtk_xml import LineVTU
        from .vtx import LineVTX
        self.frames = FrameStore()
        if self.outputs["fields"]:
            vtx = LineVTX(self.folder / "rod.bp", keep_until=self.keep_until)
            self.listing = LineVTU(self.folder / "rod.pvd", keep_until=self.keep_until)
            self.writers = [vtx, self.listing]
            for step in vtx.kept:   # resume: earlier frames come back from rod.bp
                self.frames.add(step["time"], sample_from_steps(step))

    @staticmethod
    def _data(sample) -> tuple[dict, dict]:
        """Point data (arc length s first) and cell data; the centre line is the geometry."""
        point = {"s": sample.s_nodes, **{k: v for k, v in sample.point.items()
                                         if k != "centre_line"}}
        return point, dict(sample.cell)

    def finish(self, title: str) -> None:
        """Rank 0: close rod.bp; the animation and pictures (outputs.animation)."""
        self.close()
        for _, draw in self.pictures(title):
            draw()

    def flush(self) -> None:
        """Rank 0: rod.pvd listing every step written (it is rewritten at most every
        vtk_xml.PVD_EVERY seconds otherwise): at a checkpoint, whose resume keeps the
        steps the listing has."""
        if self.comm.rank == 0 and self.listing is not None:
            self.listing.flush()

    def close(self) -> None:
        """Rank 0: close rod.bp and rod.pvd (every sample written is then readable;
        rod.pvd first, whatever rod.bp's close says)."""
        self.flush()
        if self.comm.rank == 0:
            for writer in self.writers:
                writer.close()

    def pictures(self, title: str, look=None) -> list[tuple[str, Callable[[], None]]]:
        """Rank 0: the pictures of outputs.animation, as (file name, draw it); ``look``
        an animation.Look (colour field, supports, gravity)."""
        from . import animation
        look = look or animation.Look()
        frames = self.frames.all() if self.frames is not None else []
        if self.comm.rank != 0 or not (self.outputs["animation"] and len(frames) > 1):
            return []
        path = self.folder.joinpath
        if "centre_line" in frames[0][1].point:       # (partials pickle: drawing.Painter)
            video = animation.animation_name()         # MP4 with ffmpeg, else GIF
            return [(video, partial(animation.rod_animation, frames, path(video), title,
                                    look)),
                    ("snapshots.png", partial(animation.rod_snapshots, frames,
                                              path("snapshots.png"), title, look=look))]
        return [("spacetime.png", partial(animation.torsion_spacetime, frames,
                                          path("spacetime.png"), title))]


def _geometry(sample) -> np.ndarray:
    """The points of rod.bp: the centre line (3-D rod) or s e_3 (torsion, dimensionless)."""
    if "centre_line" in sample.point:
        return sample.point["centre_line"]
    s = sample.s_nodes
    return np.column_stack([np.zeros_like(s), np.zeros_like(s), s])


def sample_from_steps(step: dict):
    """A LineSample from a step of rod.bp or rod.pvd (vtx.read_vtx, vtk_xml.read_pvd;
    resume: the frames before the checkpoint; redraw.py)."""
    from .line_fields import LineSample
    point = dict(step["point"])
    s_nodes = point.pop("s")
    if "phi" not in point:
        point["centre_line"] = step["points"]
    cells = np.asarray(step["cells"], dtype=int)
    return LineSample(s_nodes, s_nodes[cells].mean(axis=1), point, dict(step["cell"]), cells)
