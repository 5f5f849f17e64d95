#include "cli/cli_common.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "modalcal/model_change.hpp"
#include "modalcal/output.hpp"
#include "modalcal/synthesis.hpp"
#include "support/text_util.hpp"

namespace modalcal::cli {

namespace {

double parse_value(const std::string& text, const std::string& what) {
  if (text.empty()) throw InputError(what + ": no value after '='; expected NAME=VALUE with a finite number");
  const std::optional<double> v = finite_number(text);
  if (!v)
    throw InputError(what + ": '" + text.substr(0, 40) + (text.size() > 40 ? "...'" : "'") + " is not a finite number");
  return *v;
}

Vector from_report(const Problem& problem, const std::string& path) {
  if (const std::string why = unreadable_input(path, "calibration report"); !why.empty())
    throw InputError("--params: " + why + " (expected initial, truth or a report JSON)");
  std::ifstream in(path);
  if (!in) throw InputError("--params " + path + ": cannot open the file (expected initial, truth or a report JSON)");
  nlohmann::json report;
  try {
    in >> report;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path + ": not valid JSON (" + e.what() + ")");
  }
  if (!report.contains("parameters") || !report["parameters"].is_array())
    throw InputError(path + ": has no 'parameters' array; is it a calibration report?");
  Vector p = problem.initial_values();
  std::vector<bool> seen(p.size(), false);
  for (const auto& entry : report["parameters"]) {
    if (entry.value("effect", false)) continue;  // added by calibrate --add: not a parameter of the problem
    const std::string name = entry.value("name", "");
    const int j = problem.find_parameter(name);
    if (j < 0) throw InputError(path + ": parameter '" + name + "' is not in the problem " + problem.path);
    if (seen[j]) throw InputError(path + ": parameter '" + name + "' is listed twice; which value is meant?");
    const char* key = entry.contains("final") ? "final" : "value";
    if (!entry.contains(key) || !entry[key].is_number())
      throw InputError(path + ": parameter '" + name + "' has no numeric 'final' value");
    p[j] = entry[key].get<double>();
    seen[j] = true;
  }
  for (size_t j = 0; j < seen.size(); ++j)
    if (!seen[j]) throw InputError(path + ": parameter '" + problem.parameters[j].name + "' is missing");
  return p;
}

}  // namespace

std::optional<double> finite_number(const std::string& text) {
  // An underflow (1e-320) is the tiny number it is, as in problem files; an overflow (1e400) is
  // no finite number.
  double v = 0;
  if (detail::read_number(text, &v) != detail::NumberRead::kOk) return std::nullopt;
  return v;
}

Problem load_problem_with_measurements(const std::string& path, const LoadOptions& options) {
  Problem problem = load_problem(path, options);
  synthesize_measured(&problem);
  return problem;
}

// A value the model cannot take (a negative modulus, a Poisson's ratio of 0.5) would otherwise fail
// later as a factorization error, exit 1, naming no parameter. Set in order, the first parameter
// that makes the model invalid is the one named.
namespace {
void check_parameter_values(const Problem& problem, const Vector& p) {
  Model model = problem.model;
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    const Parameter& q = problem.parameters[j];
    const double value = p[static_cast<Eigen::Index>(j)];
    for (PropertyId id : q.targets) model.properties[id].value = value;
    try {
      model.validate();
    } catch (const std::invalid_argument& e) {
      throw InputError("parameter '" + q.name + "' = " + format_round_trip(value) +
                       " (from the problem, --params or --set) is not a value the model can take: " + e.what());
    }
  }
}
}  // namespace

Vector choose_parameters(Problem* problem, const ParameterChoice& choice) {
  Vector p;
  if (choice.source == "initial") {
    p = problem->initial_values();
  } else if (choice.source == "truth") {
    if (!problem->has_truth())
      throw InputError("--params truth: " + problem->path + " does not give a truth value for every parameter");
    p = problem->truth_values();
  } else {
    p = from_report(*problem, choice.source);
    problem->source_files.push_back(choice.source);  // read too: no output may replace it
  }
  std::vector<std::string> set;  // names given to --set: a second value would silently win
  for (const std::string& a : choice.assignments) {
    const size_t eq = a.find('=');
    if (eq == std::string::npos) throw InputError("--set " + a + ": expected NAME=VALUE");
    const std::string name = a.substr(0, eq);
    if (std::find(set.begin(), set.end(), name) != set.end()) throw InputError("--set " + name + " is given twice");
    set.push_back(name);
    const double value = parse_value(a.substr(eq + 1), "--set " + name);
    const int j = problem->find_parameter(name);
    if (j >= 0) {
      p[j] = value;
      continue;
    }
    const PropertyId id = problem->model.find_property(name);
    if (id == kNoProperty) {
      std::string known;
      for (const Parameter& q : problem->parameters) known += (known.empty() ? "" : ", ") + q.name;
      throw InputError("--set " + name + ": neither a parameter (" + (known.empty() ? "none" : known) +
                       ") nor a property the model has (<entity>.<property>, e.g. foam.G; a scale factor or a "
                       "joint's component exists only where the problem file gives it)");
    }
    for (const Parameter& q : problem->parameters)
      for (PropertyId t : q.targets)
        if (t == id) throw InputError("--set " + name + ": this property is set by parameter '" + q.name + "'; set that instead");
    if (const std::string why = property_range_violation(name, value); !why.empty())
      throw InputError("--set " + name + ": " + why);
    problem->model.properties[id].value = value;
  }
  check_parameter_values(*problem, p);
  return p;
}

std::vector<std::string> method_names() { return {"reduced-lbfgs", "reduced-gauss-newton", "reduced-newton"}; }

std::vector<std::string> calibration_method_names() {
  std::vector<std::string> names = method_names();
  names.insert(names.begin(), "fullspace");
  return names;
}

ReducedOptions::Method parse_method(const std::string& name) {
  if (name == "reduced-lbfgs") return ReducedOptions::Method::Lbfgs;
  if (name == "reduced-gauss-newton") return ReducedOptions::Method::GaussNewton;
  if (name == "reduced-newton") return ReducedOptions::Method::Newton;
  throw InputError("--method " + name + ": expected one of reduced-lbfgs, reduced-gauss-newton, reduced-newton");
}

void require_parameters(const Problem& problem) {
  if (problem.parameters.empty())
    throw InputError("no calibration parameters in " + problem.path +
                     ": add a 'parameters:' section naming what to calibrate (docs/problem-format.md)");
}

void append_added_effects(const Problem& problem, const std::vector<std::string>& texts,
                          std::vector<EffectCandidate>* effects) {
  for (const std::string& text : texts) {
    try {
      effects->push_back(make_candidate(problem, text));
    } catch (const std::invalid_argument& e) {
      throw InputError(std::string("--add: ") + e.what());
    }
    const std::string& name = effects->back().name;
    if (std::count_if(effects->begin(), effects->end(), [&](const EffectCandidate& c) { return c.name == name; }) > 1)
      throw InputError("--add: effect '" + text + "' is " + name + ", which the problem's enabled effects or an earlier --add already add");
  }
}

void require_start_within_bounds(const Problem& problem, const Vector& start) {
  for (size_t j = 0; j < problem.parameters.size(); ++j) {
    const Parameter& q = problem.parameters[j];
    const double value = start[static_cast<Eigen::Index>(j)];
    if (value >= q.lower && value <= q.upper) continue;
    char text[160];
    std::snprintf(text, sizeof text, "%.6g lies outside its bounds [%.6g, %.6g]", value, q.lower, q.upper);
    throw InputError("the start of parameter '" + q.name + "' (from --params, --set or --start-factor) " + text +
                     " in " + problem.path + "; start within them or widen them");
  }
}

void create_output_directory(const std::string& option, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw InputError(option + " " + dir + ": cannot create the directory" + (ec ? ": " + ec.message() : ""));
}

void print_warnings(const Problem& problem) {
  for (const std::string& w : problem.warnings) std::cerr << "warning: " << w << "\n";
}

void add_hidden_effect(const Problem& problem, nlohmann::json* json) {
  if (!problem.synthetic_truth) return;
  nlohmann::json effects = nlohmann::json::array();
  for (const ModelEffect& e : problem.synthetic_truth->hidden_effects)
    effects.push_back(
        {{"name", e.name}, {"description", e.description}, {"value", e.value}, {"nominal_value", e.nominal_value}});
  (*json)["hidden_effect"] = effects;
  if (!problem.synthetic_truth->other_differences.empty())
    (*json)["other_differences"] = problem.synthetic_truth->other_differences;
}

std::string hidden_effect_text(const SyntheticTruth& truth, const std::string& recorded_in) {
  std::string text = "truth of the measured data: " + (truth.source.empty() ? "recorded" : truth.source);
  if (!recorded_in.empty()) text += " (recorded in " + recorded_in + ")";
  text += "\n";
  if (truth.hidden_effects.empty())
    text += truth.other_differences.empty() ? "hidden effect: none (the nominal model form is right)\n"
                                            : "hidden effect: none among the properties\n";
  char line[64];
  for (const ModelEffect& e : truth.hidden_effects) {
    if (std::isinf(e.nominal_value))
      std::snprintf(line, sizeof line, " = %.6g (nominal rigid): ", e.value);
    else
      std::snprintf(line, sizeof line, " = %.6g (nominal %.6g): ", e.value, e.nominal_value);
    text += "hidden effect: " + e.name + line + e.description + "\n";
  }
  if (!truth.other_differences.empty()) text += "other differences: " + truth.other_differences + "\n";
  return text;
}

std::string hidden_effect_text(const Problem& problem) {
  return problem.synthetic_truth ? hidden_effect_text(*problem.synthetic_truth, problem.measured_file) : "";
}

nlohmann::json json_number(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

void write_json(const std::string& path, const nlohmann::json& json, const Problem& problem) {
  if (path.empty()) return;
  // Names come from the user's files and may not be UTF-8, which JSON requires: such bytes become
  // U+FFFD rather than an exception that would lose the result.
  write_file_atomically(path, json.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n",
                        problem.source_files);
}

VtuFields localization_fields(const Problem& problem, const Localization& result) {
  VtuFields fields;
  int highest = problem.options.num_modes;
  for (const ExpandedMode& m : result.modes) highest = std::max(highest, m.model_mode + 1);
  add_mode_fields(result.modal, highest, &fields);
  for (const ExpandedMode& m : result.modes)
    fields.shapes.push_back({shape_field_name("expanded", m.measured + 1, m.measured_hz), m.measured_hz, m.shape});
  const Vector& element = result.element_indicator;
  fields.element_data.push_back({"error_indicator", 1, std::vector<double>(element.data(), element.data() + element.size())});
  const Vector node = result.total_energy > 0 ? Vector(result.node_energy / result.total_energy) : result.node_energy;
  fields.node_data.push_back({"residual_energy_share", 1, std::vector<double>(node.data(), node.data() + node.size())});
  return fields;
}

}  // namespace modalcal::cli
