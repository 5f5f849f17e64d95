"""Renders the error indicator of `fullspace_calib localize --vtu DIR` to a PNG, headless.

Usage: xvfb-run -a python3 scripts/render_error_indicator.py OUT.png DIR/localize.vtu TITLE [VTU TITLE]...
(several VTU files are drawn side by side, each with its own colour scale)

Needs VTK's Python module (Debian python3-vtk9). Debian's VTK renders through X even off
screen, so without a display run it under xvfb-run (Debian xvfb).
"""
import sys

import vtk

from vtk_panels import write_panels_png

png_path = sys.argv[1]
views = list(zip(sys.argv[2::2], sys.argv[3::2]))
if not views:
    sys.exit(__doc__)


def view(grid_path, title):
    """A renderer with the mesh surface coloured by the per-element error indicator."""
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(grid_path)
    reader.Update()
    grid = reader.GetOutput()
    indicator = grid.GetCellData().GetArray("error_indicator")
    if indicator is None:
        sys.exit(f"{grid_path} has no cell array error_indicator; write it with `fullspace_calib localize --vtu`")
    surface = vtk.vtkDataSetSurfaceFilter()
    surface.SetInputData(grid)
    lookup = vtk.vtkLookupTable()
    lookup.SetHueRange(0.667, 0.0)  # blue (no residual) to red (largest)
    lookup.SetRange(0.0, indicator.GetRange()[1])
    lookup.Build()
    mapper = vtk.vtkDataSetMapper()
    mapper.SetInputConnection(surface.GetOutputPort())
    mapper.SetScalarModeToUseCellFieldData()
    mapper.SelectColorArray("error_indicator")
    mapper.SetLookupTable(lookup)
    mapper.UseLookupTableScalarRangeOn()
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    edges = vtk.vtkActor()  # element edges, faint, so that the mesh shows
    edges_mapper = vtk.vtkDataSetMapper()
    edges_mapper.SetInputConnection(surface.GetOutputPort())
    edges_mapper.ScalarVisibilityOff()
    edges.SetMapper(edges_mapper)
    edges.GetProperty().SetRepresentationToWireframe()
    edges.GetProperty().SetColor(0.2, 0.2, 0.2)
    edges.GetProperty().SetOpacity(0.25)
    bar = vtk.vtkScalarBarActor()
    bar.SetLookupTable(lookup)
    bar.SetTitle("share")
    bar.SetNumberOfLabels(5)
    bar.SetWidth(0.1)
    bar.SetHeight(0.6)
    bar.SetPosition(0.88, 0.2)
    bar.GetTitleTextProperty().SetColor(0, 0, 0)
    bar.GetLabelTextProperty().SetColor(0, 0, 0)
    text = vtk.vtkTextActor()
    text.SetInput(title)
    text.GetTextProperty().SetFontSize(16)
    text.GetTextProperty().SetColor(0, 0, 0)
    text.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
    text.SetPosition(0.02, 0.02)
    renderer = vtk.vtkRenderer()
    renderer.SetBackground(1, 1, 1)
    for item in (actor, edges, bar, text):
        renderer.AddActor(item)
    camera = renderer.GetActiveCamera()
    camera.SetViewUp(0, 0, 1)
    camera.SetPosition(1, -2, 0.8)
    camera.SetFocalPoint(0, 0, 0)
    renderer.ResetCamera()
    camera.Zoom(1.05)
    return renderer


write_panels_png([view(path, title) for path, title in views], png_path, 600, 650)
