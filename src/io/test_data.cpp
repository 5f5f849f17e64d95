// Test data: lookups, the reader chosen by file name, complex shapes made real, and lengths
// converted between the file's units and the model's.
#include "modalcal/test_data.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>
#include <stdexcept>

#include "io/input_file.hpp"
#include "io/measured_test_data.hpp"
#include "support/text_util.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

namespace {

using detail::number_text;

/// The first comma- or blank-separated item of free-text units: "in" of "in, lbf, s".
std::string first_unit(const std::string& units) {
  const size_t start = units.find_first_not_of(" \t");
  if (start == std::string::npos) return "";
  const size_t end = units.find_first_of(", \t;", start);
  return units.substr(start, end == std::string::npos ? std::string::npos : end - start);
}

}  // namespace

std::optional<double> TestMode::value(long node, int component) const {
  const auto it = std::lower_bound(values.begin(), values.end(), std::make_pair(node, component),
                                   [](const TestShapeValue& v, const std::pair<long, int>& key) {
                                     return std::make_pair(v.node, v.component) < key;
                                   });
  if (it == values.end() || it->node != node || it->component != component) return std::nullopt;
  return it->value;
}

const TestNode* TestData::find_node(long id) const {
  for (const TestNode& n : nodes)
    if (n.id == id) return &n;
  return nullptr;
}

std::vector<long> TestData::shape_node_ids() const {
  std::vector<long> ids;
  std::set<long> seen;
  for (const TestMode& m : modes)
    for (const TestShapeValue& v : m.values)
      if (seen.insert(v.node).second) ids.push_back(v.node);
  return ids;
}

std::vector<long> TestData::node_ids() const {
  std::vector<long> ids;
  std::set<long> seen;
  for (const TestNode& n : nodes)
    if (seen.insert(n.id).second) ids.push_back(n.id);
  for (long id : shape_node_ids())
    if (seen.insert(id).second) ids.push_back(id);
  return ids;
}

namespace {

// A listing (import-test-data) shows what the file holds; a problem that selects such a mode is
// refused at its line. The warning says so before a problem is written around it.
void warn_of_unusable_frequencies(TestData* data) {
  for (const TestMode& m : data->modes)
    if (const std::string reason = detail::unusable_frequency(m.frequency_hz); !reason.empty())
      data->warnings.push_back("mode " + std::to_string(m.number) + " (line " + std::to_string(m.line) + "): " +
                               format_round_trip(m.frequency_hz) + " Hz: " + reason +
                               "; a problem cannot select it");
}

}  // namespace

TestData read_test_data(const std::string& path) {
  if (const std::string reason = detail::unreadable_reason(path, "test-data file"); !reason.empty())
    throw ProblemError(path, 0, reason);
  std::string extension = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  TestData data = extension == ".csv" ? read_test_csv(path) : read_uff(path);
  warn_of_unusable_frequencies(&data);
  return data;
}

RealShape best_real_shape(const Eigen::VectorXcd& shape) {
  const Vector a = shape.real(), b = shape.imag();
  const double aa = a.squaredNorm(), bb = b.squaredNorm(), ab = a.dot(b);
  RealShape out;
  if (aa + bb == 0) {
    out.values = Vector::Zero(shape.size());
    return out;
  }
  // |Re(e^{iθ}φ)|² = (aa + bb)/2 + (aa - bb)/2 cos 2θ - ab sin 2θ, largest at this θ.
  out.rotation_rad = 0.5 * std::atan2(-2 * ab, aa - bb);
  out.values = a * std::cos(out.rotation_rad) - b * std::sin(out.rotation_rad);
  out.collinearity = ((aa - bb) * (aa - bb) + 4 * ab * ab) / ((aa + bb) * (aa + bb));
  return out;
}

std::optional<double> metres_per_length_unit(const std::string& unit) {
  if (unit == "m") return 1.0;
  if (unit == "cm") return 0.01;
  if (unit == "mm") return 0.001;
  if (unit == "in") return 0.0254;
  if (unit == "ft") return 0.3048;
  return std::nullopt;
}

double length_factor_to(const TestData& data, const std::string& unit, std::string* assumption) {
  const std::optional<double> metres = metres_per_length_unit(unit);
  if (!metres) throw std::invalid_argument("unknown length unit '" + unit + "'; known: m, cm, mm, in, ft");
  if (!data.units && assumption)
    *assumption = data.path + " has no units dataset (164); its lengths are taken as metres";
  const double file_units_per_metre = data.units ? data.units->length_factor : 1.0;
  return 1.0 / (file_units_per_metre * *metres);
}

void scale_lengths(TestData* data, double factor) {
  for (TestNode& n : data->nodes) n.coordinates *= factor;
  for (CoordinateSystem& s : data->coordinate_systems) s.origin *= factor;
  for (TestMode& m : data->modes)
    for (TestShapeValue& v : m.values)
      if (v.component < 3) v.value *= factor;
  data->length_scale *= factor;
}

std::string convert_lengths(TestData* data, const LengthConversion& conversion, const std::string& problem_units) {
  if (conversion.scale > 0) {
    scale_lengths(data, conversion.scale);
    return "lengths multiplied by " + number_text(conversion.scale);
  }
  std::string unit = conversion.unit;
  if (unit.empty()) {
    const std::string named = first_unit(problem_units);
    // Only a file that states its units can be converted without being told.
    if (!data->units || !metres_per_length_unit(named)) {
      if (data->units && data->units->length_factor != 1 && !data->nodes.empty())
        return "the file's length unit is 1/" + number_text(data->units->length_factor) +
               " m (dataset 164) but no model length unit is known (m, cm, mm, in or ft first in the "
               "problem's units): coordinates are used as they are";
      return "";
    }
    unit = named;
  }
  std::string assumption;
  const double factor = length_factor_to(*data, unit, &assumption);
  scale_lengths(data, factor);
  return "lengths converted to " + unit + " (× " + number_text(factor) + ")" +
         (assumption.empty() ? "" : "; " + assumption);
}

}  // namespace modalcal
