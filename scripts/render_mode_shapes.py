"""Renders calibrated mode shapes from `fullspace_calib calibrate --vtu DIR` to a PNG, headless.

Usage: xvfb-run -a /usr/bin/python3 scripts/render_mode_shapes.py OUT.png DIR/calibrated.vtu MODE [MODE]...

Each MODE (1-based elastic mode index) gets a panel: the undeformed mesh as a grey wireframe, the
mesh deformed by the mode shape and coloured by displacement magnitude, and at the sensors the
measured shape (from DIR/calibrated_sensors.vtu) as black arrows, scaled like the model's shape.
Needs VTK's Python module (Debian python3-vtk9); Debian's VTK renders through X even off screen,
so without a display run it under xvfb-run (Debian xvfb).
"""
import os
import sys

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk, vtk_to_numpy

from vtk_panels import write_panels_png

if len(sys.argv) < 4:
    sys.exit(__doc__)
png_path, grid_path, modes = sys.argv[1], sys.argv[2], [int(m) for m in sys.argv[3:]]


def read(path):
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput()


def strings(array):
    return [array.GetValue(i) for i in range(array.GetNumberOfValues())]


grid = read(grid_path)
sensors = read(grid_path.replace(".vtu", "_sensors.vtu"))
names = strings(grid.GetFieldData().GetAbstractArray("shape_names"))
frequencies = vtk_to_numpy(grid.GetFieldData().GetArray("frequencies_hz"))
measured_names = strings(sensors.GetFieldData().GetAbstractArray("shape_names")) if sensors.GetFieldData().GetAbstractArray("shape_names") else []
bounds = np.array(grid.GetBounds()).reshape(3, 2)
size = float(np.linalg.norm(bounds[:, 1] - bounds[:, 0]))
node_ids = vtk_to_numpy(grid.GetPointData().GetArray("node_id")) if grid.GetPointData().GetArray("node_id") else None
row_of_node = {int(i): r for r, i in enumerate(node_ids)} if node_ids is not None else {}
sensor_ids = vtk_to_numpy(sensors.GetPointData().GetArray("node_id"))


def panel(mode):
    name = names[mode - 1]
    shape = vtk_to_numpy(grid.GetPointData().GetArray(name))
    scale = 0.08 * size / np.abs(shape).max()
    renderer = vtk.vtkRenderer()
    renderer.SetBackground(1, 1, 1)

    outline = vtk.vtkDataSetSurfaceFilter()
    outline.SetInputData(grid)
    wire = vtk.vtkDataSetMapper()
    wire.SetInputConnection(outline.GetOutputPort())
    wire.ScalarVisibilityOff()
    wire_actor = vtk.vtkActor()
    wire_actor.SetMapper(wire)
    wire_actor.GetProperty().SetRepresentationToWireframe()
    wire_actor.GetProperty().SetColor(0.75, 0.75, 0.75)
    renderer.AddActor(wire_actor)

    warped = vtk.vtkUnstructuredGrid()
    warped.DeepCopy(grid)
    warped.GetPointData().SetActiveVectors(name)
    magnitude_array = numpy_to_vtk(np.ascontiguousarray(np.linalg.norm(shape, axis=1)), deep=True)
    magnitude_array.SetName("magnitude")
    warped.GetPointData().AddArray(magnitude_array)
    warp = vtk.vtkWarpVector()
    warp.SetInputData(warped)
    warp.SetScaleFactor(scale)
    magnitude = vtk.vtkDataSetSurfaceFilter()
    magnitude.SetInputConnection(warp.GetOutputPort())
    lookup = vtk.vtkLookupTable()
    lookup.SetHueRange(0.667, 0.0)
    lookup.SetRange(0, float(np.linalg.norm(shape, axis=1).max()))
    lookup.Build()
    mapper = vtk.vtkDataSetMapper()
    mapper.SetInputConnection(magnitude.GetOutputPort())
    mapper.SetScalarModeToUsePointFieldData()
    mapper.SelectColorArray("magnitude")
    mapper.SetLookupTable(lookup)
    mapper.UseLookupTableScalarRangeOn()
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    renderer.AddActor(actor)

    title = f"mode {mode}: {frequencies[mode - 1]:.2f} Hz"
    # The measured shape whose name carries this mode's pairing, if any, as arrows at the sensors.
    if mode - 1 < len(measured_names) and sensor_ids.size:
        measured = vtk_to_numpy(sensors.GetPointData().GetArray(measured_names[mode - 1]))
        model_at_sensors = shape[[row_of_node[int(i)] for i in sensor_ids]] if row_of_node else None
        factor = scale
        if model_at_sensors is not None and np.abs(measured).sum() > 0:
            factor = scale * float((measured * model_at_sensors).sum() / (measured * measured).sum())
        points = vtk.vtkPolyData()
        points.SetPoints(sensors.GetPoints())
        vectors = numpy_to_vtk(np.ascontiguousarray(measured * factor), deep=True)
        vectors.SetName("measured")
        points.GetPointData().SetVectors(vectors)
        arrow = vtk.vtkArrowSource()
        glyph = vtk.vtkGlyph3D()
        glyph.SetInputData(points)
        glyph.SetSourceConnection(arrow.GetOutputPort())
        glyph.SetVectorModeToUseVector()
        glyph.SetScaleModeToScaleByVector()
        glyph.SetScaleFactor(1.0)
        glyph_mapper = vtk.vtkPolyDataMapper()
        glyph_mapper.SetInputConnection(glyph.GetOutputPort())
        glyph_actor = vtk.vtkActor()
        glyph_actor.SetMapper(glyph_mapper)
        glyph_actor.GetProperty().SetColor(0, 0, 0)
        renderer.AddActor(glyph_actor)
        title += f"  (arrows: measured {measured_names[mode - 1]})"
    text = vtk.vtkTextActor()
    text.SetInput(title)
    text.GetTextProperty().SetColor(0, 0, 0)
    text.GetTextProperty().SetFontSize(16)
    text.SetPosition(10, 10)
    renderer.AddActor2D(text)
    # z is up in the bundled problems: look from the front-right, slightly above.
    camera = renderer.GetActiveCamera()
    center = bounds.mean(axis=1)
    camera.SetFocalPoint(*center)
    camera.SetPosition(*(center + size * np.array([0.9, -1.6, 0.7])))
    camera.SetViewUp(0, 0, 1)
    renderer.ResetCamera()
    camera.Zoom(1.15)
    renderer.ResetCameraClippingRange()
    return renderer


write_panels_png([panel(mode) for mode in modes], png_path, 520, 480)
