"""A VTX file (ADIOS2 .bp, the format of dolfinx.io.VTXWriter) of a polyline in 3-D.

Each step stores the time, the current point coordinates (the deformed centre line
r(s, t), so ParaView draws the rod as it is: no "Warp By Vector"), and point and cell
data.  Open it in ParaView with the **ADIOS2VTXReader** (File > Open, choose
"ADIOS2VTXReader" when asked; pvpython: ``ADIOS2VTXReader(FileName="rod.bp")``).

The data are gathered on rank 0 (line_fields.py), which alone writes, with the adios2
Python bindings; the file is written serially with the BP4 engine, readable by
ParaView 5.13 (ADIOS2 2.10).  ``keep_until`` (resume): the steps of an existing file
up to that time are kept and the new steps appended after them.

    w = LineVTX(path); w.write(t, points, {"d1": ...}, {"u": ...}); w.close()
    steps = read_vtx(path)     # [{"time", "points", "cells", "point", "cell"}, ...]

A failed write (a full disk: ADIOS2 raises RuntimeError "couldn't write to file ...
errno = 28") is raised as OSError with that errno; the stream is then broken and
``close`` closes what it can, quietly.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
from pathlib import Path

import numpy as np

__all__ = ["LineVTX", "read_vtx", "adios2_module"]

VTK_LINE = 3
_MESH_VARIABLES = ("NumberOfNodes", "NumberOfCells", "connectivity", "types", "geometry",
                   "step")


def adios2_module():
    """adios2 with the MPI bindings, as adios4dolfinx needs them (it refuses to load
    after the serial bindings were imported); a serial Adios() works with them too."""
    os.environ.setdefault("ADIOS2_ALWAYS_USE_MPI", "1")
    import adios2
    return adios2


def _schema(point_names, cell_names) -> str:
    arrays = lambda names: "".join(f'        <DataArray Name="{n}" />\n'  # noqa: E731
                                   for n in names)
    return ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1">\n'
            '  <UnstructuredGrid>\n'
            '    <Piece NumberOfPoints="NumberOfNodes" NumberOfCells="NumberOfCells">\n'
            '      <Points>\n        <DataArray Name="geometry" />\n      </Points>\n'
            '      <Cells>\n        <DataArray Name="connectivity" />\n'
            '        <DataArray Name="types" />\n      </Cells>\n'
            '      <PointData>\n        <DataArray Name="TIME">step</DataArray>\n'
            f'{arrays(point_names)}      </PointData>\n'
            f'      <CellData>\n{arrays(cell_names)}      </CellData>\n'
            '    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n')


class LineVTX:
    """Writes steps of a polyline with point and cell data (rank 0 only, see module)."""

    def __init__(self, path: Path, keep_until: float | None = None):
        adios2 = adios2_module()
        self.path = Path(path)
        kept = []
        if keep_until is not None and self.path.exists():
            kept = [s for s in read_vtx(self.path) if s["time"] <= keep_until * (1 + 1e-12)]
        shutil.rmtree(self.path, ignore_errors=True)
        self._adios = adios2.Adios()
        io = self._adios.declare_io(f"vtx:{self.path}")
        io.set_engine("BP4")
        self._stream = adios2.Stream(io, str(self.path), "w")
        self._schema_written = False
        self.broken = False            # a write failed: close quietly
        for s in kept:
            self.write(s["time"], s["points"], s["point"], s["cell"], s["cells"])
        self.kept = kept

    def write(self, t: float, points: np.ndarray, point_data: dict, cell_data: dict,
              cells: np.ndarray | None = None) -> None:
        """One step; ``cells``: the two point indices of each line (None: the points in
        order, one line through all).  OSError if ADIOS2 cannot write it."""
        try:
            self._write(t, points, point_data, cell_data, cells)
        except RuntimeError as err:
            self.broken = True
            raise adios2_os_error(err, self.path) from None

    def _write(self, t, points, point_data, cell_data, cells) -> None:
        n = len(points)
        if cells is None:
            cells = np.column_stack([np.arange(n - 1), np.arange(1, n)])
        st = self._stream
        st.begin_step()
        if not self._schema_written:
            st.write_attribute("vtk.xml", _schema(list(point_data), list(cell_data)))
            self._schema_written = True
        st.write("NumberOfNodes", np.array(n, dtype=np.uint32))
        st.write("NumberOfCells", np.array(len(cells), dtype=np.uint32))
        st.write("types", np.array(VTK_LINE, dtype=np.uint32))
        conn = np.column_stack([np.full(len(cells), 2), cells])
        _local(st, "connectivity", conn.astype(np.int64))
        _local(st, "geometry", np.ascontiguousarray(points, dtype=np.float64))
        st.write("step", np.array(t, dtype=np.float64))
        for name, values in {**point_data, **cell_data}.items():
            _local(st, name, np.ascontiguousarray(values, dtype=np.float64))
        st.end_step()

    def close(self) -> None:
        """Close the file (OSError if its last data cannot be written); after a failed
        write, close what can be closed and say nothing (the write raised)."""
        try:
            self._stream.close()
        except RuntimeError as err:
            if not self.broken:
                self.broken = True
                raise adios2_os_error(err, self.path) from None
        finally:
            if self.broken:
                self._forget()

    def _forget(self) -> None:
        """Drop the broken stream (quietly: ADIOS2's destructor of an engine whose close
        failed prints "Destroyed without a prior Close()"; the write's error was raised
        already)."""
        def drop():
            self._stream = self._adios = None
        quietly(drop)


def quietly(action) -> None:
    """``action()`` with file descriptor 2 on /dev/null (C++ destructors' messages),
    then a garbage collection there too."""
    import gc
    import sys
    sys.stderr.flush()
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        action()
        gc.collect()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def adios2_os_error(err: RuntimeError, path: Path) -> OSError:
    """ADIOS2's RuntimeError of a failed file operation as an OSError: its errno and
    strerror when the message names them ("errno = 28: No space left on device"), else
    EIO with the message's first line."""
    found = re.search(r"errno = (\d+): ([^\x1b\n]+)", str(err))
    if found:
        return OSError(int(found.group(1)), found.group(2).strip(), str(path))
    first = re.sub(r"\x1b\[[0-9;]*m", "", str(err)).strip().split("\n")[0]
    return OSError(errno.EIO, first, str(path))


def _local(stream, name: str, array: np.ndarray) -> None:
    """A local (per-writer block) array, as dolfinx.io.VTXWriter writes them."""
    stream.write(name, array, [], [], list(array.shape))


def read_vtx(path: Path) -> list[dict]:
    """Every step of a LineVTX (or dolfinx VTX) file: time, points, point and cell data."""
    import xml.etree.ElementTree as ET
    adios2 = adios2_module()
    steps = []
    with adios2.FileReader(str(path)) as f:
        xml = f.read_attribute_string("vtk.xml")
        root = ET.fromstring(xml if isinstance(xml, str) else xml[0])
        names = {kind: [a.get("Name") for e in root.iter(kind) for a in e
                        if a.get("Name") != "TIME"] for kind in ("PointData", "CellData")}
        n_steps = int(f.available_variables()["step"]["AvailableStepsCount"])
        for k in range(n_steps):
            read = lambda v: f.read(v, step_selection=[k, 1])   # noqa: E731
            steps.append({"time": float(np.ravel(read("step"))[0]),
                          "points": read("geometry"),
                          "cells": np.asarray(read("connectivity")).reshape(-1, 3)[:, 1:],
                          "point": {n: read(n) for n in names["PointData"]},
                          "cell": {n: read(n) for n in names["CellData"]}})
    return steps
