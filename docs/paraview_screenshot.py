"""Render a run's rod.bp or rod.pvd with ParaView (pvpython), as in
docs/figures/paraview_rod.png.

    xvfb-run pvpython docs/paraview_screenshot.py RUN_FOLDER/rod.bp OUT.png [FIELD]
    xvfb-run pvpython docs/paraview_screenshot.py RUN_FOLDER/rod.pvd OUT.png [FIELD]

rod.bp is a VTX file (ADIOS2): open it with the ADIOS2VTXReader of ParaView >= 5.13
(ParaView's default reader for .bp, the ADIOS2 image reader, fails on VTX files).
rod.pvd (+ rod/*.vtu) holds the same steps and fields for any ParaView (PVDReader).  The
points are the deformed centre line, so no "Warp By Vector" is needed.  FIELD (default
xi) colours the rod; cell fields: u, v, u_d, v_d, u_ref, v_ref, n, m, n_spatial,
m_spatial, xi; point fields: s, d1, d2, d3.

The picture is framed from the rod's own size (a 1 m cantilever and a 100 nm DNA
molecule alike; a fixed tube radius and camera rendered the DNA run blank): ``framing``
takes the bounds of the centre line at the last step and the range of s, and gives the
tube radius and the director arrows as fractions of the rod's size (its length or its
extent, whichever is larger) and a camera that looks at the centre across the thinnest
side of the bounds (the rod's plane faces the camera), the longest side horizontal, from
the distance at which the rod fills 60 % of the picture (ParaView's 30 degree view angle).  ``framing`` needs no ParaView (tests/test_redraw.py imports it).
"""

import math
import sys

TUBE, START_TUBE, ARROWS = 0.02, 0.01, 0.06     # fractions of the rod's size
VIEW, VIEW_ANGLE, FILL = (900, 700), 30.0, 0.6  # px, degrees (ParaView's), picture filled


def framing(bounds, s_range) -> dict:
    """The tube radii, arrow length and camera of a rod whose centre line lies in
    ``bounds`` (xmin, xmax, ymin, ymax, zmin, zmax) with arc lengths ``s_range`` (min,
    max): "size" max(length, largest extent); "tube", "start_tube", "arrows"; camera
    "focal_point" (the centre), "position" (along the thinnest axis, at the distance
    where the bounds fill FILL of the picture: at least a tenth of the size across),
    "view_up" (the remaining shorter axis, so the longest lies across the picture)."""
    extents = [bounds[2 * i + 1] - bounds[2 * i] for i in range(3)]
    size = max(max(extents), s_range[1] - s_range[0])
    if not size > 0:
        raise ValueError(f"the rod has no size: bounds {bounds}, s {s_range}")
    centre = [0.5 * (bounds[2 * i] + bounds[2 * i + 1]) for i in range(3)]
    thinnest, up, across = sorted(range(3), key=lambda i: extents[i])
    span = max(extents[up], extents[across] * VIEW[1] / VIEW[0], 0.1 * size)
    position = list(centre)
    position[thinnest] += span / (FILL * 2 * math.tan(math.radians(VIEW_ANGLE / 2)))
    return {"size": size, "tube": TUBE * size, "start_tube": START_TUBE * size,
            "arrows": ARROWS * size, "focal_point": centre, "position": position,
            "view_up": [1.0 if i == up else 0.0 for i in range(3)]}


def main(path: str, out: str, field: str = "xi") -> None:
    from paraview.simple import (ADIOS2VTXReader, ColorBy, ExtractSurface, ForceTime,
                                 GetActiveViewOrCreate, GetAnimationScene,
                                 GetColorTransferFunction, Glyph, PVDReader, ResetCamera,
                                 SaveScreenshot, Show, Tube)
    reader = (PVDReader if path.endswith(".pvd") else ADIOS2VTXReader)(FileName=path)
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues) or [0.0]
    reader.UpdatePipeline(times[-1])
    frame = framing(reader.GetDataInformation().GetBounds(),
                    reader.PointData["s"].GetRange())
    scene = GetAnimationScene()
    scene.UpdateAnimationUsingDataTimeSteps()
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = list(VIEW)
    view.ViewTime = times[-1]                       # the last step: the deformed rod
    line = ExtractSurface(Input=reader)             # polylines for the Tube filter
    last = Tube(Input=line, Radius=frame["tube"])
    start = ForceTime(Input=line, ForcedTime=times[0], IgnorePipelineTime=1)
    shown_start = Show(Tube(Input=start, Radius=frame["start_tube"]), view)   # t = 0
    shown_start.DiffuseColor = [0.55, 0.55, 0.55]
    shown_start.AmbientColor = [0.55, 0.55, 0.55]
    shown_start.ColorArrayName = ["POINTS", ""]
    shown = Show(last, view)
    association = "CELLS" if field not in ("s", "d1", "d2", "d3") else "POINTS"
    ColorBy(shown, (association, field, "Magnitude"))
    shown.SetScalarBarVisibility(view, True)
    GetColorTransferFunction(field).ApplyPreset("Viridis (matplotlib)", True)
    shown.RescaleTransferFunctionToDataRange(True, False)
    directors = Glyph(Input=reader, GlyphType="Arrow", OrientationArray=["POINTS", "d1"],
                      ScaleArray=["POINTS", "No scale array"], ScaleFactor=frame["arrows"])
    Show(directors, view).DiffuseColor = [0.8, 0.2, 0.2]
    view.CameraPosition = frame["position"]
    view.CameraFocalPoint = frame["focal_point"]
    view.CameraViewUp = frame["view_up"]
    view.OrientationAxesVisibility = 1
    ResetCamera()                                   # keeps the direction, fits the rod
    SaveScreenshot(out, view, ImageResolution=list(VIEW))
    print(f"{path}: {len(times)} steps, t = {times[0]:g} .. {times[-1]:g}; wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
