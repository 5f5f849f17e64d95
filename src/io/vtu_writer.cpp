// VTK XML documents (UnstructuredGrid, Collection) in ASCII, from the layout described in VTK's
// "VTK File Formats" (XML formats section): per piece, PointData, CellData, Points and Cells
// (connectivity, offsets, types); field data ahead of the piece.

#include <algorithm>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "modalcal/vtu.hpp"

namespace modalcal {

namespace {

std::string escape_xml(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

// max_digits10 (17) significant digits read back as the same double, so that a reader recovers
// the mode shapes exactly.
void write_values(std::ostringstream& out, const std::vector<double>& values, bool integer) {
  out.precision(std::numeric_limits<double>::max_digits10);
  for (size_t i = 0; i < values.size(); ++i) {
    out << (i % 9 == 0 ? "\n          " : " ");
    if (integer)
      out << static_cast<long long>(values[i]);
    else
      out << values[i];
  }
  out << "\n";
}

// Field arrays state their tuple count; point and cell arrays take it from the piece.
void write_array(std::ostringstream& out, const VtkArray& array, size_t tuples, const std::string& where,
                 bool state_tuples = false) {
  if (array.components < 1 || array.values.size() != tuples * array.components)
    throw std::invalid_argument("VTU array '" + array.name + "' (" + where + "): " +
                                std::to_string(array.values.size()) + " values for " + std::to_string(tuples) +
                                " tuples of " + std::to_string(array.components) + " components");
  out << "        <DataArray type=\"" << (array.integer ? "Int64" : "Float64") << "\" Name=\""
      << escape_xml(array.name) << "\" NumberOfComponents=\"" << array.components << "\"";
  if (state_tuples) out << " NumberOfTuples=\"" << tuples << "\"";
  out << " format=\"ascii\">";
  write_values(out, array.values, array.integer);
  out << "        </DataArray>\n";
}

void write_field_data(std::ostringstream& out, const VtkGrid& grid) {
  if (grid.field_data.empty() && grid.field_strings.empty()) return;
  out << "    <FieldData>\n";
  for (const VtkArray& array : grid.field_data)
    write_array(out, array, array.values.size() / std::max(array.components, 1), "field data", true);
  for (const VtkStringArray& strings : grid.field_strings) {
    out << "        <Array type=\"String\" Name=\"" << escape_xml(strings.name) << "\" NumberOfTuples=\""
        << strings.values.size() << "\" format=\"ascii\">\n         ";
    for (const std::string& s : strings.values) {
      for (unsigned char c : s) out << ' ' << static_cast<int>(c);
      out << " 0";
    }
    out << "\n        </Array>\n";
  }
  out << "    </FieldData>\n";
}

}  // namespace

std::string vtu_document(const VtkGrid& grid) {
  const size_t num_points = grid.points.cols(), num_cells = grid.types.size();
  if (grid.cell_sizes.size() != num_cells)
    throw std::invalid_argument("VTU grid: " + std::to_string(grid.cell_sizes.size()) + " cell sizes for " +
                                std::to_string(num_cells) + " cells");
  std::vector<double> offsets, types;
  size_t end = 0;
  for (size_t c = 0; c < num_cells; ++c) {
    end += grid.cell_sizes[c];
    offsets.push_back(static_cast<double>(end));
    types.push_back(static_cast<int>(grid.types[c]));
  }
  if (end != grid.connectivity.size())
    throw std::invalid_argument("VTU grid: the cells list " + std::to_string(end) + " points, the connectivity has " +
                                std::to_string(grid.connectivity.size()));
  for (long point : grid.connectivity)
    if (point < 0 || static_cast<size_t>(point) >= num_points)
      throw std::invalid_argument("VTU grid: connectivity refers to point " + std::to_string(point) + " of " +
                                  std::to_string(num_points));

  std::ostringstream out;
  out << "<?xml version=\"1.0\"?>\n"
         "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
         "  <UnstructuredGrid>\n";
  write_field_data(out, grid);
  out << "    <Piece NumberOfPoints=\"" << num_points << "\" NumberOfCells=\"" << num_cells << "\">\n";
  out << "      <PointData>\n";
  for (const VtkArray& array : grid.point_data) write_array(out, array, num_points, "point data");
  out << "      </PointData>\n      <CellData>\n";
  for (const VtkArray& array : grid.cell_data) write_array(out, array, num_cells, "cell data");
  out << "      </CellData>\n      <Points>\n";
  write_array(out, {"Points", 3, std::vector<double>(grid.points.data(), grid.points.data() + 3 * num_points)},
              num_points, "points");
  out << "      </Points>\n      <Cells>\n";
  write_array(out, {"connectivity", 1, std::vector<double>(grid.connectivity.begin(), grid.connectivity.end()), true},
              grid.connectivity.size(), "cells");
  write_array(out, {"offsets", 1, offsets, true}, num_cells, "cells");
  out << "        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">";
  write_values(out, types, true);
  out << "        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
  return out.str();
}

std::string pvd_document(const std::vector<std::string>& files) {
  std::ostringstream out;
  out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n";
  for (size_t part = 0; part < files.size(); ++part)
    out << "    <DataSet timestep=\"0\" part=\"" << part << "\" file=\"" << escape_xml(files[part]) << "\"/>\n";
  out << "  </Collection>\n</VTKFile>\n";
  return out.str();
}

}  // namespace modalcal
