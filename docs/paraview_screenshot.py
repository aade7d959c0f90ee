"""Render a run's rod.bp with ParaView (pvpython), as in docs/figures/paraview_rod.png.

    xvfb-run pvpython docs/paraview_screenshot.py RUN_FOLDER/rod.bp OUT.png [FIELD]

rod.bp is a VTX file (ADIOS2): open it with the ADIOS2VTXReader (ParaView's default
reader for .bp, the ADIOS2 image reader, fails on VTX files).  Its points are the
deformed centre line, so no "Warp By Vector" is needed.  FIELD (default xi) colours the
rod; cell fields: u, v, u_d, v_d, u_ref, v_ref, n, m, n_spatial, m_spatial, xi; point
fields: s, d1, d2, d3.
"""

import sys

from paraview.simple import (ADIOS2VTXReader, ColorBy, ExtractSurface, ForceTime, GetActiveViewOrCreate,
                             GetAnimationScene, GetColorTransferFunction, Glyph, Hide,
                             ResetCamera, SaveScreenshot, Show, Tube)

path, out = sys.argv[1], sys.argv[2]
field = sys.argv[3] if len(sys.argv) > 3 else "xi"
reader = ADIOS2VTXReader(FileName=path)
reader.UpdatePipelineInformation()
times = list(reader.TimestepValues) or [0.0]
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
view = GetActiveViewOrCreate("RenderView")
view.ViewSize = [900, 700]
view.ViewTime = times[-1]                       # the last step: the deformed rod
line = ExtractSurface(Input=reader)             # polylines for the Tube filter
last = Tube(Input=line, Radius=0.02)
start = ForceTime(Input=line, ForcedTime=times[0], IgnorePipelineTime=1)
shown_start = Show(Tube(Input=start, Radius=0.01), view)   # the reference line, t = 0
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
                  ScaleArray=["POINTS", "No scale array"], ScaleFactor=0.06)
Show(directors, view).DiffuseColor = [0.8, 0.2, 0.2]
view.CameraPosition = [-0.3, 4.5, 0.4]         # looking along -y; x (against gravity
view.CameraFocalPoint = [-0.3, 0.0, 0.4]        # in gravity_cantilever.toml) points up
view.CameraViewUp = [1.0, 0.0, 0.0]
view.OrientationAxesVisibility = 1
ResetCamera()
SaveScreenshot(out, view, ImageResolution=[900, 700])
print(f"{path}: {len(times)} steps, t = {times[0]:g} .. {times[-1]:g}; wrote {out}")
