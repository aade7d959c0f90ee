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
molecule alike): the tube radius and the director arrows are fractions of the rod's
length (the range of s) or of its extent at the last step, whichever is larger, and the
camera looks along -y at the rod's centre.
"""

import sys

from paraview.simple import (ADIOS2VTXReader, ColorBy, ExtractSurface, ForceTime,
                             GetActiveViewOrCreate, GetAnimationScene,
                             GetColorTransferFunction, Glyph, PVDReader, ResetCamera,
                             SaveScreenshot, Show, Tube)

TUBE, START_TUBE, ARROWS = 0.02, 0.01, 0.06     # fractions of the rod's size

path, out = sys.argv[1], sys.argv[2]
field = sys.argv[3] if len(sys.argv) > 3 else "xi"
reader = (PVDReader if path.endswith(".pvd") else ADIOS2VTXReader)(FileName=path)
reader.UpdatePipelineInformation()
times = list(reader.TimestepValues) or [0.0]
reader.UpdatePipeline(times[-1])
lo_hi = reader.GetDataInformation().GetBounds()           # xmin, xmax, ymin, ...
extent = max(lo_hi[1] - lo_hi[0], lo_hi[3] - lo_hi[2], lo_hi[5] - lo_hi[4])
s_range = reader.PointData["s"].GetRange()
size = max(extent, s_range[1] - s_range[0])
centre = [0.5 * (lo_hi[2 * i] + lo_hi[2 * i + 1]) for i in range(3)]
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [900, 700]
view.ViewTime = times[-1]                       # the last step: the deformed rod
line = ExtractSurface(Input=reader)             # polylines for the Tube filter
last = Tube(Input=line, Radius=TUBE * size)
start = ForceTime(Input=line, ForcedTime=times[0], IgnorePipelineTime=1)
shown_start = Show(Tube(Input=start, Radius=START_TUBE * size), view)   # the reference line, t = 0
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
                  ScaleArray=["POINTS", "No scale array"], ScaleFactor=ARROWS * size)
Show(directors, view).DiffuseColor = [0.8, 0.2, 0.2]
view.CameraPosition = [centre[0], centre[1] + 4.5 * size, centre[2]]   # along -y; x
view.CameraFocalPoint = centre          # (against gravity in gravity_cantilever.toml) up
view.CameraViewUp = [1.0, 0.0, 0.0]
view.OrientationAxesVisibility = 1
ResetCamera()
SaveScreenshot(out, view, ImageResolution=[900, 700])
print(f"{path}: {len(times)} steps, t = {times[0]:g} .. {times[-1]:g}; wrote {out}")
