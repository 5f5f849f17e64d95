// The model, its sensors and its mode shapes as VTU grids for ParaView (see vtu.hpp).

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>

#include "modalcal/output.hpp"
#include "modalcal/vtu.hpp"

namespace modalcal {

namespace {

VtkCellType cell_type(SolidType type) {
  switch (type) {
    case SolidType::Hex8: return VtkCellType::Hexahedron;
    case SolidType::Tet4: return VtkCellType::Tetra;
    case SolidType::Tet10: return VtkCellType::QuadraticTetra;
  }
  return VtkCellType::Hexahedron;
}

// (E, nu, K, G) of a block from whichever pair it gives:
// K = E / (3(1 - 2 nu)), G = E / (2(1 + nu)); E = 9KG / (3K + G), nu = (3K - 2G) / (2(3K + G)).
std::array<double, 4> elastic_constants(const ElementBlock& block, const Vector& theta) {
  const double a = theta[block.modulus_a], b = theta[block.modulus_b];
  if (block.form == ElasticForm::YoungPoisson) return {a, b, a / (3 * (1 - 2 * b)), a / (2 * (1 + b))};
  return {9 * a * b / (3 * a + b), (3 * a - 2 * b) / (2 * (3 * a + b)), a, b};
}

double optional_property(PropertyId id, const Vector& theta) { return id == kNoProperty ? 1.0 : theta[id]; }

// Translations of every node for a free-DOF vector (coupled nodes follow their reference).
std::vector<double> nodal_translations(const DofMap& dofs, int num_nodes, const Vector& u) {
  std::vector<double> values(3 * num_nodes);
  for (int node = 0; node < num_nodes; ++node)
    for (int c = 0; c < 3; ++c) values[3 * node + c] = dofs.value(u, node, c);
  return values;
}

VtkArray node_ids(const Model& model, const std::vector<int>& nodes) {
  VtkArray ids{"node_id", 1, {}, true};
  for (int node : nodes) ids.values.push_back(static_cast<double>(model.node_ids[node]));
  return ids;
}

}  // namespace

std::string shape_field_name(const std::string& prefix, int index, double frequency_hz) {
  char text[64];
  std::snprintf(text, sizeof text, "_%d_%.2fHz", index, frequency_hz);
  return prefix + text;
}

void add_mode_fields(const ModalResult& modal, int count, VtuFields* fields) {
  const int available = static_cast<int>(modal.modes.cols());
  for (int k = 0; k < (count < 0 ? available : std::min(count, available)); ++k) {
    const double hz = frequency_hz(modal.eigenvalues[k]);
    fields->shapes.push_back({shape_field_name("mode", k + 1, hz), hz, modal.modes.col(k)});
  }
}

VtkGrid model_grid(const Problem& problem, const ParametricSystem& system, const Vector& p, const VtuFields& fields) {
  const Model& model = system.model();
  const int num_nodes = model.num_nodes();
  VtkGrid grid;
  grid.points.resize(3, num_nodes);
  for (int node = 0; node < num_nodes; ++node) grid.points.col(node) = model.coordinates[node];

  const Vector theta = system.property_values(p);
  const char* property_names[] = {"E", "nu", "K", "G", "density", "stiffness_scale", "mass_scale"};
  std::vector<VtkArray> properties;
  for (const char* name : property_names) properties.push_back({name, 1, {}, false});
  VtkArray block_id{"block_id", 1, {}, true};
  VtkStringArray block_names{"block_names", {}};
  for (size_t b = 0; b < model.blocks.size(); ++b) {
    const ElementBlock& block = model.blocks[b];
    block_names.values.push_back(block.name);
    const std::array<double, 4> elastic = elastic_constants(block, theta);
    const double values[] = {elastic[0], elastic[1], elastic[2], elastic[3], theta[block.density],
                             optional_property(block.stiffness_scale, theta), optional_property(block.mass_scale, theta)};
    const int nodes = nodes_per_element(block.type);
    for (int e = 0; e < block.num_elements(); ++e) {
      grid.types.push_back(cell_type(block.type));
      grid.cell_sizes.push_back(nodes);
      grid.connectivity.insert(grid.connectivity.end(), block.connectivity.begin() + e * nodes,
                               block.connectivity.begin() + (e + 1) * nodes);
      block_id.values.push_back(static_cast<double>(b));
      for (size_t k = 0; k < properties.size(); ++k) properties[k].values.push_back(values[k]);
    }
  }
  grid.cell_data.push_back(block_id);
  grid.cell_data.insert(grid.cell_data.end(), properties.begin(), properties.end());
  for (const VtkArray& array : fields.element_data) {
    if (array.values.size() != static_cast<size_t>(model.num_elements()) * array.components)
      throw std::invalid_argument("element field '" + array.name + "' has " + std::to_string(array.values.size()) +
                                  " values for " + std::to_string(model.num_elements()) + " elements");
    grid.cell_data.push_back(array);
  }
  grid.field_strings.push_back(block_names);

  std::vector<int> all_nodes(num_nodes);
  for (int node = 0; node < num_nodes; ++node) all_nodes[node] = node;
  grid.point_data.push_back(node_ids(model, all_nodes));
  VtkArray frequencies{"frequencies_hz", 1, {}, false};
  VtkStringArray shape_names{"shape_names", {}};
  for (const ShapeField& field : fields.shapes) {
    if (field.shape.size() != system.num_dofs())
      throw std::invalid_argument("shape field '" + field.name + "' has " + std::to_string(field.shape.size()) +
                                  " values for " + std::to_string(system.num_dofs()) + " free DOFs");
    grid.point_data.push_back({field.name, 3, nodal_translations(system.dof_map(), num_nodes, field.shape), false});
    frequencies.values.push_back(field.frequency_hz);
    shape_names.values.push_back(field.name);
  }
  for (const VtkArray& array : fields.node_data) {
    if (array.values.size() != static_cast<size_t>(num_nodes) * array.components)
      throw std::invalid_argument("node field '" + array.name + "' has " + std::to_string(array.values.size()) +
                                  " values for " + std::to_string(num_nodes) + " nodes");
    grid.point_data.push_back(array);
  }
  if (!fields.shapes.empty()) {
    grid.field_data.push_back(frequencies);
    grid.field_strings.push_back(shape_names);
  }
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    grid.field_data.push_back({"parameter_" + problem.parameters[j].name, 1, {p[j]}, false});
  return grid;
}

VtkGrid sensor_grid(const Problem& problem) {
  const Model& model = problem.model;
  std::map<int, int> point_of_node;  // sensed node -> point index, in order of first appearance
  std::vector<int> nodes;
  for (const Sensor& sensor : problem.sensors)
    if (point_of_node.emplace(sensor.node, static_cast<int>(nodes.size())).second) nodes.push_back(sensor.node);
  const int num_points = static_cast<int>(nodes.size());
  VtkGrid grid;
  grid.points.resize(3, num_points);
  for (int k = 0; k < num_points; ++k) {
    grid.points.col(k) = model.coordinates[nodes[k]];
    grid.connectivity.push_back(k);
    grid.types.push_back(VtkCellType::Vertex);
    grid.cell_sizes.push_back(1);
  }
  grid.point_data.push_back(node_ids(model, nodes));
  VtkArray directions{"measured_directions", 1, std::vector<double>(num_points, 0.0), true};
  for (const Sensor& sensor : problem.sensors) directions.values[point_of_node[sensor.node]] += 1;
  grid.point_data.push_back(directions);
  VtkArray frequencies{"frequencies_hz", 1, {}, false};
  VtkStringArray shape_names{"shape_names", {}};
  for (size_t i = 0; i < problem.measured.size(); ++i) {
    const MeasuredMode& measured = problem.measured[i];
    if (measured.shape.size() == 0) continue;
    VtkArray shape{shape_field_name("measured", static_cast<int>(i) + 1, measured.frequency_hz), 3,
                   std::vector<double>(3 * num_points, 0.0), false};
    for (size_t s = 0; s < problem.sensors.size(); ++s)
      shape.values[3 * point_of_node[problem.sensors[s].node] + problem.sensors[s].component] = measured.shape[s];
    grid.point_data.push_back(shape);
    frequencies.values.push_back(measured.frequency_hz);
    shape_names.values.push_back(shape.name);
  }
  if (!frequencies.values.empty()) {
    grid.field_data.push_back(frequencies);
    grid.field_strings.push_back(shape_names);
  }
  return grid;
}

std::vector<std::string> write_vtu_set(const std::string& directory, const std::string& stem, const Problem& problem,
                                       const ParametricSystem& system, const Vector& p, const VtuFields& fields) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) throw std::runtime_error("cannot create the VTU directory '" + directory + "': " + ec.message());
  // Build every document before writing any, so that bad input leaves no file behind.
  std::vector<std::pair<std::string, std::string>> documents;  // file name, content
  documents.emplace_back(stem + ".vtu", vtu_document(model_grid(problem, system, p, fields)));
  if (!problem.sensors.empty()) documents.emplace_back(stem + "_sensors.vtu", vtu_document(sensor_grid(problem)));
  std::vector<std::string> parts;
  for (const auto& document : documents) parts.push_back(document.first);
  documents.emplace_back(stem + ".pvd", pvd_document(parts));
  std::vector<std::string> paths;
  for (const auto& document : documents) {
    paths.push_back((fs::path(directory) / document.first).string());
    check_not_input(paths.back(), problem.source_files);
  }
  for (size_t k = 0; k < documents.size(); ++k)
    write_file_atomically(paths[k], documents[k].second, problem.source_files);
  return paths;
}

}  // namespace modalcal
