// Reads a list of model changes from a YAML file (see load_model_changes in model_change.hpp).
#include <yaml-cpp/yaml.h>

#include <filesystem>

#include "io/input_file.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

std::optional<std::vector<ModelChange>> load_model_changes(const std::string& path) {
  const YAML::Node root = detail::load_yaml_file(path, "changes or problem file");
  if (!root.IsMap() || !root["changes"]) return std::nullopt;
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>("");
    if (key != "changes" && key != "description")
      throw ProblemError(path, kv.first.Mark().line + 1,
                         "unknown key '" + key + "' in a changes file, which holds only 'changes' and 'description'; "
                         "a truth model with more than changes is a problem file (it may 'extends:' the nominal one)");
  }
  const YAML::Node list = root["changes"];
  if (!list.IsSequence() || list.size() == 0)
    throw ProblemError(path, list.Mark().line + 1, "'changes' must be a non-empty list of change strings, e.g. "
                                                   "[\"joint2.krx=3e5\", \"point_mass@top:mass=0.05\"]");
  std::vector<ModelChange> changes;
  for (const YAML::Node& item : list) {
    const int line = item.Mark().line + 1;
    if (!item.IsScalar()) throw ProblemError(path, line, "expected a change string, e.g. joint2.krx=3e5");
    try {
      changes.push_back(parse_model_change(item.Scalar()));
    } catch (const std::invalid_argument& e) {
      throw ProblemError(path, line, e.what());
    }
  }
  return changes;
}

}  // namespace modalcal
