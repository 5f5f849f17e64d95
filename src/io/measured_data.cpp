// Writes measured-modes data files (format in docs/problem-format.md; read by the problem loader).
#include "modalcal/problem_file.hpp"
#include "modalcal/measured_data.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <sstream>

#include "modalcal/output.hpp"

namespace modalcal {

namespace {

// A JSON string is a valid YAML double-quoted scalar: labels and descriptions may hold anything
// (bytes that are not UTF-8 become U+FFFD).
std::string quoted(const std::string& s) {
  return nlohmann::json(s).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string number(double v) { return format_round_trip(v); }

std::string point(const Vec3& x) { return "[" + number(x[0]) + ", " + number(x[1]) + ", " + number(x[2]) + "]"; }

void write_truth(std::ostream& out, const SyntheticTruth& truth) {
  out << "truth:   # what the data were made from; calibration reports show it as hidden_effect\n";
  out << "  source: " << quoted(truth.source) << "\n";
  if (!truth.changes.empty()) {
    out << "  changes:\n";
    for (const std::string& c : truth.changes) out << "    - " << quoted(c) << "\n";
  }
  const char* none = truth.other_differences.empty() ? " []   # none: the nominal model form is right"
                                                     : " []   # none among the properties";
  out << "  hidden_effects:" << (truth.hidden_effects.empty() ? none : "") << "\n";
  for (const ModelEffect& e : truth.hidden_effects)
    out << "    - {name: " << quoted(e.name) << ", description: " << quoted(e.description) << ", value: " << number(e.value)
        << ", nominal_value: " << (std::isinf(e.nominal_value) ? std::string(".inf") : number(e.nominal_value)) << "}\n";
  if (!truth.other_differences.empty()) out << "  other_differences: " << quoted(truth.other_differences) << "\n";
  out << "  parameters:" << (truth.parameters.empty() ? " {}" : "") << "\n";
  for (const auto& [name, value] : truth.parameters) out << "    " << quoted(name) << ": " << number(value) << "\n";
}

void write_mode(std::ostream& out, const MeasuredMode& m, const TruthModeRecord* truth) {
  out << "  - label: " << quoted(m.label) << "\n";
  out << "    frequency_hz: " << number(m.frequency_hz) << "\n";
  if (truth) out << "    truth_mode: " << truth->mode << "\n    truth_frequency_hz: " << number(truth->frequency_hz) << "\n";
  if (m.weight != 1) out << "    weight: " << number(m.weight) << "\n";
  if (m.shape_weight != 1) out << "    shape_weight: " << number(m.shape_weight) << "\n";
  switch (m.pairing.kind) {
    case PairingRule::Kind::Mac:
      out << "    pair: mac\n";
      break;
    case PairingRule::Kind::ModelIndex:
      out << "    pair: {model_mode: " << m.pairing.model_index << "}\n";
      break;
    case PairingRule::Kind::Family:
      out << "    pair: {family: " << quoted(m.pairing.family) << ", index: " << m.pairing.family_index << "}\n";
      break;
  }
  if (m.shape.size() == 0) return;
  out << "    shape: [";
  for (Eigen::Index s = 0; s < m.shape.size(); ++s) out << (s ? ", " : "") << number(m.shape[s]);
  out << "]\n";
}

}  // namespace

void write_measured_data(const std::string& path, const MeasuredData& data, const std::vector<std::string>& inputs) {
  std::ostringstream out;
  out << "# Measured modes" << (data.synthesized_from.empty() ? "" : ", synthesized by fullspace_calib synth") << ".\n"
      << "# A problem reads them with `measured: {file: <this file>}` (path relative to the problem file).\n";
  if (!data.synthesized_from.empty()) out << "synthesized_from: " << quoted(data.synthesized_from) << "\n";
  if (data.noise)
    out << "noise:   # frequency: f (1 + frequency N(0,1)); shape (largest |value| scaled to 1): "
           "value + shape N(0,1)\n"
        << "  frequency: " << number(data.noise->frequency) << "\n"
        << "  shape: " << number(data.noise->shape) << "\n"
        << "  seed: " << data.noise->seed << "\n";
  if (!data.sensors.empty()) {
    out << "sensors:   # the problem's sensors must be these DOFs, in this order (matched by position)\n";
    const char* const directions[3] = {"x", "y", "z"};
    for (const SensorRecord& s : data.sensors)
      out << "  - {node: " << s.node_id << ", direction: " << directions[s.component] << ", at: " << point(s.position)
          << "}\n";
  }
  if (data.truth) write_truth(out, *data.truth);
  out << "modes:\n";
  for (size_t i = 0; i < data.modes.size(); ++i)
    write_mode(out, data.modes[i], i < data.truth_modes.size() ? &data.truth_modes[i] : nullptr);
  write_file_atomically(path, out.str(), inputs);
}

}  // namespace modalcal
