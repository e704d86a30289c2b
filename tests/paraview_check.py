"""Open a run's XDMF with ParaView's own reader and report what ParaView sees (pvpython script).

    xvfb-run -a pvpython tests/paraview_check.py RUN/solution.xdmf OUT.png OUT.json [SCALE]

Loads the file with ``XDMFReader`` (what ParaView's File > Open uses for .xdmf), and writes to
OUT.json: the point arrays and time steps ParaView lists, the mesh points, every point array
at every time step, and the points of "Warp By Vector" with ``displacement`` (scale factor 1)
at the last time step. Then renders the warped rod (scale factor SCALE, default 1, as a tube
coloured by the contact torque |torque_m| when present) at the last time step to OUT.png with
``SaveScreenshot``. Used by tests/test_visualisation.py; runs with Debian's python3-paraview
(no DOLFINx, no project code). There is no screen here: ``pvpython
--force-offscreen-rendering`` crashed, ``xvfb-run -a pvpython`` works.
"""

import json
import sys

from paraview import servermanager
from paraview.simple import (
    ColorBy,
    ExtractSurface,
    GetActiveViewOrCreate,
    GetColorTransferFunction,
    GetScalarBar,
    Render,
    ResetCamera,
    SaveScreenshot,
    Show,
    Tube,
    UpdatePipeline,
    WarpByVector,
    XDMFReader,
)
from paraview.vtk.numpy_interface import dataset_adapter as dsa


def fetch(source, t):
    """(points, {array: values}) of ``source`` at time t, as lists."""
    source.UpdatePipeline(t)
    data = servermanager.Fetch(source)
    if data.IsA("vtkMultiBlockDataSet"):  # a single block for one grid
        data = data.GetBlock(0)
    wrapped = dsa.WrapDataObject(data)
    arrays = {name: wrapped.PointData[name].tolist() for name in wrapped.PointData.keys()}
    return wrapped.Points.tolist(), arrays


def main(xdmf, png, out, scale=1.0):
    reader = XDMFReader(FileNames=[xdmf])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues) if reader.TimestepValues else [0.0]
    names = list(reader.PointData.keys())
    report = {"point_arrays": names, "times": times, "frames": {}}
    for t in times:
        points, arrays = fetch(reader, t)
        report["points"] = points
        report["frames"][repr(t)] = arrays
    last = times[-1]
    warp = WarpByVector(Input=reader)
    warp.Vectors = ["POINTS", "displacement"]
    warp.ScaleFactor = 1.0
    report["warped_points"] = fetch(warp, last)[0]

    warp.ScaleFactor = scale
    UpdatePipeline(last, warp)
    z = [point[2] for point in report["points"]]
    length = max(max(z) - min(z), 1e-12)  # the reference centreline (0, 0, s)
    tube = Tube(Input=ExtractSurface(Input=warp))  # Tube needs polygonal lines
    tube.Radius = 0.02 * length
    tube.NumberofSides = 16
    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = [800, 600]
    view.ViewTime = last
    view.Background = [1.0, 1.0, 1.0]
    try:  # ParaView 5.11 uses a background palette unless told otherwise
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    view.OrientationAxesVisibility = 1
    display = Show(tube, view)
    view.OrientationAxesLabelColor = [0.0, 0.0, 0.0]
    if "torque_m" in names:
        ColorBy(display, ("POINTS", "torque_m", "Magnitude"))
        display.SetScalarBarVisibility(view, True)
        bar = GetScalarBar(GetColorTransferFunction("torque_m"), view)
        bar.Title = "|torque_m| [N m]"
        bar.ComponentTitle = ""
        bar.TitleColor = [0.0, 0.0, 0.0]
        bar.LabelColor = [0.0, 0.0, 0.0]
    else:
        display.DiffuseColor = [0.1, 0.3, 0.8]
    view.CameraPosition = [1.5 * length, -2.5 * length, 0.6 * length]
    view.CameraFocalPoint = [0.0, 0.0, 0.5 * length]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    ResetCamera(view)
    Render(view)
    SaveScreenshot(png, view, ImageResolution=[800, 600])
    with open(out, "w", encoding="utf-8") as stream:
        json.dump(report, stream)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]) if len(sys.argv) > 4 else 1.0)
