"""Reads the VTU files fullspace_calib writes back with VTK's own reader (python3-vtk9) and checks
what ParaView would show: cell types and node order, block properties, volumes and mass, mode
shapes against the measured shapes at the sensors, and the error indicator of `localize`.

Usage: vtu_readback.py FULLSPACE_CALIB SOURCE_DIR WORK_DIR
Fails (exit 1, with what to install) when `import vtk` fails: a test that cannot run is a failure.
"""
import json
import math
import os
import shutil
import subprocess
import sys
from xml.etree import ElementTree

try:
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
except ImportError as error:
    print(f"FAILED: cannot import VTK's Python module ({error}); install python3-vtk9 and "
          "python3-numpy (scripts/install-deps.sh) to read the VTU files back")
    sys.exit(1)

cli, source, work = sys.argv[1:4]
problem = os.path.join(source, "problems/portal-frame/synthetic.yaml")
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
        print("FAIL:", message)


def run(*args):
    done = subprocess.run([cli, *args], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(args)} exited with {done.returncode}:\n{done.stdout}{done.stderr}")
    return done.stdout


def read(path):
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    grid = reader.GetOutput()
    if grid.GetNumberOfPoints() == 0:
        sys.exit(f"VTK read no points from {path}")
    return grid


def strings(array):
    return [array.GetValue(i) for i in range(array.GetNumberOfValues())]


def close(a, b, tol):
    return abs(a - b) <= tol * max(abs(a), abs(b), 1e-300)


# --- modes: the truth model of the portal frame (tet10), its modes and the sensors.
out = os.path.join(work, "modes")
run("modes", problem, "--params", "truth", "--vtu", out, "--json", os.path.join(work, "modes.json"))
report = json.load(open(os.path.join(work, "modes.json")))
# VTK has no .pvd reader (ParaView's vtkPVDReader is not in python3-vtk9): parse it as XML.
collection = ElementTree.parse(os.path.join(out, "modes.pvd")).getroot()
parts = [d.get("file") for d in collection.iter("DataSet")]
check(collection.get("type") == "Collection" and parts == ["modes.vtu", "modes_sensors.vtu"],
      f"modes.pvd lists {parts}")

model = read(os.path.join(out, "modes.vtu"))
check(model.GetNumberOfCells() == report["elements"], f"{model.GetNumberOfCells()} cells, {report['elements']} elements")
types = {model.GetCellType(c) for c in range(model.GetNumberOfCells())}
check(types == {vtk.VTK_QUADRATIC_TETRA}, f"cell types {types}, expected only VTK_QUADRATIC_TETRA (24)")

# VTK's own edge definition of the quadratic tetra: (end, end, mid-node). Our Exodus mid-node
# order must put every mid-node halfway along the edge VTK thinks it is on.
worst = 0.0
for c in range(model.GetNumberOfCells()):
    cell = model.GetCell(c)
    for e in range(cell.GetNumberOfEdges()):
        ids = cell.GetEdge(e).GetPointIds()
        a, b, m = (model.GetPoint(ids.GetId(k)) for k in range(3))
        worst = max(worst, max(abs(m[k] - 0.5 * (a[k] + b[k])) for k in range(3)))
check(worst < 1e-12, f"tet10 mid-nodes off their VTK edges by up to {worst} m")

cell_data = model.GetCellData()
for name in ["block_id", "E", "nu", "K", "G", "density", "stiffness_scale", "mass_scale"]:
    check(cell_data.GetArray(name) is not None, f"cell array {name} missing")
E = vtk_to_numpy(cell_data.GetArray("E"))
nu = vtk_to_numpy(cell_data.GetArray("nu"))
K = vtk_to_numpy(cell_data.GetArray("K"))
check(abs(E - 6.9e10).max() < 1e-3, "E should be the truth 6.9e10 in every element")
check(abs(K - 6.9e10 / (3 * (1 - 2 * 0.33))).max() < 1e-3 * 6.9e10, "K should follow from E and nu")
check(abs(nu - 0.33).max() < 1e-15, "nu should be 0.33")
field = model.GetFieldData()
check(strings(field.GetAbstractArray("block_names")) == ["column_1", "column_2", "beam"],
      f"block names {strings(field.GetAbstractArray('block_names'))}")
check(close(field.GetArray("parameter_E").GetValue(0), 6.9e10, 1e-15), "parameter_E field")

# Volume and mass by VTK's cell sizes: 2 columns 20x20x500 mm + beam 20x20x400 mm, aluminium.
sizes = vtk.vtkCellSizeFilter()
sizes.SetInputData(model)
sizes.Update()
volume = vtk_to_numpy(sizes.GetOutput().GetCellData().GetArray("Volume"))
density = vtk_to_numpy(cell_data.GetArray("density"))
check(close(volume.sum(), 5.6e-4, 1e-9), f"total volume {volume.sum()} m^3, expected 5.6e-4")
check(close((volume * density).sum(), 1.512, 1e-9), f"mass {(volume * density).sum()} kg, expected 1.512")
check(volume.min() > 0, "a cell has non-positive volume (node order)")

frequencies = vtk_to_numpy(field.GetArray("frequencies_hz"))
expected = [m["frequency_hz"] for m in report["modes"]]
check(len(frequencies) == len(expected) and all(close(a, b, 1e-12) for a, b in zip(frequencies, expected)),
      f"frequencies {frequencies} against the JSON report {expected}")
names = strings(field.GetAbstractArray("shape_names"))
check(names == ["mode_%d_%.2fHz" % (k + 1, f) for k, f in enumerate(expected)], f"shape names {names}")
point_data = model.GetPointData()
node_ids = vtk_to_numpy(point_data.GetArray("node_id"))
mode1 = vtk_to_numpy(point_data.GetArray(names[0]))
check(mode1.shape == (model.GetNumberOfPoints(), 3), f"mode shape array of shape {mode1.shape}")
points = vtk_to_numpy(model.GetPoints().GetData())
base = abs(points[:, 2]) < 1e-12
check(base.sum() > 0 and abs(mode1[base]).max() == 0, "the clamped column feet must not move")

# The synthetic measurements are the truth model's modes 1-6 at the sensors (scaled to a largest
# value of 1, as synthesized data are): the sensor file's measured shapes must be multiples of
# the model file's mode shapes at the same nodes.
sensors = read(os.path.join(out, "modes_sensors.vtu"))
check(sensors.GetNumberOfPoints() == 12 and sensors.GetNumberOfCells() == 12, "12 sensor points and vertex cells")
check({sensors.GetCellType(c) for c in range(12)} == {vtk.VTK_VERTEX}, "sensor cells should be VTK_VERTEX")
row_of_node = {int(i): r for r, i in enumerate(node_ids)}
sensor_ids = vtk_to_numpy(sensors.GetPointData().GetArray("node_id"))
measured_names = strings(sensors.GetFieldData().GetAbstractArray("shape_names"))
check(len(measured_names) == 6, f"6 measured shapes expected, got {measured_names}")
largest = 0.0
for k, name in enumerate(measured_names):
    measured = vtk_to_numpy(sensors.GetPointData().GetArray(name))
    model_shape = vtk_to_numpy(point_data.GetArray(names[k]))[[row_of_node[int(i)] for i in sensor_ids]]
    scale = float((measured * model_shape).sum() / (model_shape * model_shape).sum())
    largest = max(largest, abs(measured - scale * model_shape).max() / abs(measured).max())
check(largest < 1e-12, f"measured shapes differ from the model's modes at the sensors by {largest} (relative)")

# --- localize: the model's column 1 is 30 % heavier than the test article's.
out = os.path.join(work, "localize")
text = run("localize", problem, "--params", "truth", "--set", "column_1.density=3510", "--vtu", out,
           "--json", os.path.join(work, "localize.json"))
print(text)
report = json.load(open(os.path.join(work, "localize.json")))
grid = read(os.path.join(out, "localize.vtu"))
indicator = vtk_to_numpy(grid.GetCellData().GetArray("error_indicator"))
check(indicator.min() >= 0 and 0.5 < indicator.sum() <= 1 + 1e-12, f"indicator shares sum to {indicator.sum()}")
blocks = vtk_to_numpy(grid.GetCellData().GetArray("block_id"))
block_names = strings(grid.GetFieldData().GetAbstractArray("block_names"))
for region in report["ranking"]:
    if region["kind"] == "block":
        share = indicator[blocks == block_names.index(region["region"])].sum()
        check(close(share, region["share"], 1e-9), f"block {region['region']}: VTU share {share}, JSON {region['share']}")
check(report["ranking"][0]["region"] == "column_1", f"top region {report['ranking'][0]['region']}, expected column_1")
names = strings(grid.GetFieldData().GetAbstractArray("shape_names"))
expanded = [n for n in names if n.startswith("expanded_")]
check(len(expanded) == 6, f"6 expanded measured shapes expected, got {expanded}")
check(grid.GetPointData().GetArray("residual_energy_share") is not None, "point array residual_energy_share missing")

if failures:
    sys.exit(f"{len(failures)} check(s) failed")
print("all VTU checks passed")
