#include "io/measured_test_data.hpp"

#include <algorithm>
#include <filesystem>

#include "support/text_util.hpp"

namespace modalcal::detail {

namespace {

TestData read_for(const TestDataSelection& s) {
  try {
    return read_test_data(s.path);
  } catch (const ProblemError& e) {
    const std::string context = " (read for 'test_data' at " + s.problem_file + ":" + std::to_string(s.file_line) + ")";
    // A file-wide fault (missing, empty, not a universal file) at the problem's line, naming the file.
    std::error_code ec;
    if (e.line() == 0 && !std::filesystem::exists(s.path, ec))
      throw ProblemError(s.problem_file, s.file_line, e.message() + " (the path is relative to this file's folder)");
    if (e.line() == 0) throw ProblemError(s.problem_file, s.file_line, s.path + ": " + e.message());
    throw ProblemError(e.file(), e.line(), e.message() + context);
  }
}

std::vector<const TestMode*> select_modes(const TestDataSelection& s, const TestData& data) {
  std::vector<const TestMode*> selected;
  if (s.modes.empty()) {
    for (const TestMode& m : data.modes) selected.push_back(&m);
    if (selected.empty())
      throw ProblemError(s.problem_file, s.file_line, s.path + " holds no mode shapes (dataset 55 or 2414 at nodes)");
    return selected;
  }
  for (size_t k = 0; k < s.modes.size(); ++k) {
    const auto it =
        std::find_if(data.modes.begin(), data.modes.end(), [&](const TestMode& m) { return m.number == s.modes[k]; });
    if (it == data.modes.end()) {
      std::string known;
      for (const TestMode& m : data.modes) known += (known.empty() ? "" : ", ") + std::to_string(m.number);
      throw ProblemError(s.problem_file, s.mode_lines[k],
                         "mode " + std::to_string(s.modes[k]) + " is not in " + s.path +
                             "; its modes: " + (known.empty() ? "none" : known));
    }
    selected.push_back(&*it);
  }
  return selected;
}

}  // namespace

std::string unusable_frequency(double hz) {
  if (!(hz > 0)) return "measured frequencies must be positive";
  if (hz < 1e-6 || hz > 1e9)
    return "measured frequencies must lie between 1e-6 and 1e9 Hz (no structure has modes outside, and the "
           "eigenvalue misfits would overflow); check the unit (Hz) and the exponent";
  return "";
}

void measured_from_test_data(const TestDataSelection& s, Problem* problem) {
  problem->source_files.push_back(s.path);
  TestData data = read_for(s);
  const std::string conversion = convert_lengths(&data, s.lengths, problem->units);
  const std::vector<const TestMode*> selected = select_modes(s, data);

  TestData chosen = data;  // the mapping covers the nodes of the chosen modes only
  chosen.modes.clear();
  for (const TestMode* m : selected) chosen.modes.push_back(*m);
  const std::vector<long> shape_nodes = chosen.shape_node_ids();
  chosen.nodes.erase(std::remove_if(chosen.nodes.begin(), chosen.nodes.end(),
                                    [&](const TestNode& n) {
                                      return std::find(shape_nodes.begin(), shape_nodes.end(), n.id) ==
                                             shape_nodes.end();
                                    }),
                     chosen.nodes.end());
  NodeMapping mapping;
  try {
    mapping = map_test_nodes(chosen, problem->model, s.map);
  } catch (const std::invalid_argument& e) {
    throw ProblemError(s.problem_file, s.line, e.what());
  }

  std::vector<std::string> dropped;
  for (const NodeMatch& match : mapping.matches) {
    if (match.model_node < 0) continue;
    for (int c : s.directions) {
      const std::string label = "node " + std::to_string(problem->model.node_ids[match.model_node]) + " +" +
                                component_name(c) + " (test node " + std::to_string(match.test_node) + ")";
      const bool in_every_mode = std::all_of(selected.begin(), selected.end(), [&](const TestMode* m) {
        return m->value(match.test_node, c).has_value();
      });
      if (in_every_mode)
        problem->sensors.push_back({match.model_node, c, label});
      else
        dropped.push_back(label);
    }
  }
  if (problem->sensors.empty())
    throw ProblemError(s.problem_file, s.line,
                       "no sensor: no test node of " + s.path + " has a value in every chosen mode at a model node; " +
                           mapping.report());

  for (const TestMode* m : selected) {
    MeasuredMode measured;
    measured.label = "test mode " + std::to_string(m->number);
    measured.source_line = s.line;
    if (const std::string reason = unusable_frequency(m->frequency_hz); !reason.empty())
      throw ProblemError(s.problem_file, s.line,
                         "mode " + std::to_string(m->number) + " of " + s.path + " (line " + std::to_string(m->line) +
                             ") has frequency " + number_text(m->frequency_hz) + " Hz; " + reason);
    measured.frequency_hz = m->frequency_hz;
    measured.shape.resize(static_cast<Eigen::Index>(problem->sensors.size()));
    for (size_t k = 0; k < problem->sensors.size(); ++k) {
      const Sensor& sensor = problem->sensors[k];
      const long test_node = std::find_if(mapping.matches.begin(), mapping.matches.end(), [&](const NodeMatch& n) {
                               return n.model_node == sensor.node;
                             })->test_node;
      measured.shape[static_cast<Eigen::Index>(k)] = *m->value(test_node, sensor.component);
    }
    if (measured.shape.isZero(0))
      throw ProblemError(s.problem_file, s.line,
                         "mode " + std::to_string(m->number) + " of " + s.path +
                             " is zero at every sensor, so it pairs with nothing; choose other modes or directions");
    problem->measured.push_back(measured);
  }

  const std::string file = s.path + ": ";
  if (!conversion.empty()) problem->warnings.push_back(file + conversion);
  for (const std::string& w : data.warnings) problem->warnings.push_back(file + w);
  if (mapping.num_matched() < static_cast<int>(mapping.matches.size()))
    problem->warnings.push_back(file + mapping.report());
  if (!dropped.empty())
    problem->warnings.push_back(file + std::to_string(dropped.size()) +
                                " sensor DOF(s) dropped because not every chosen mode has a value there, e.g. " +
                                dropped.front());
}

}  // namespace modalcal::detail
