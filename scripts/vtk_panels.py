"""Shared by the render scripts: renderers side by side in one off-screen window, saved as PNG."""
import vtk


def write_panels_png(renderers, png_path, panel_width, height):
    window = vtk.vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(panel_width * len(renderers), height)
    for k, renderer in enumerate(renderers):
        renderer.SetViewport(k / len(renderers), 0, (k + 1) / len(renderers), 1)
        window.AddRenderer(renderer)
    window.Render()
    image = vtk.vtkWindowToImageFilter()
    image.SetInput(window)
    image.Update()
    writer = vtk.vtkPNGWriter()
    writer.SetFileName(png_path)
    writer.SetInputConnection(image.GetOutputPort())
    writer.Write()
    print(f"wrote {png_path}")
