#pragma once
// Pieces every subcommand shares: loading a problem, choosing parameter values
// (--params/--set), and writing JSON next to the printed report.

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal::cli {

/// Input errors (exit code 2) as opposed to numerical failures (exit code 1).
struct InputError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

struct ParameterChoice {
  std::string source = "initial";        ///< initial | truth | path of a report JSON
  std::vector<std::string> assignments;  ///< NAME=VALUE, NAME a parameter or a property
};

/// Parameter values chosen by `choice`; property assignments (names that are not parameters)
/// are applied to problem->model.
Vector choose_parameters(Problem* problem, const ParameterChoice& choice);

/// The reduced-space methods by their CLI names, and the reverse.
std::vector<std::string> method_names();
/// fullspace and the reduced-space methods.
std::vector<std::string> calibration_method_names();
ReducedOptions::Method parse_method(const std::string& name);

/// Prints each of problem.warnings (e.g. unmatched test nodes) as "warning: ..." to stderr.
void print_warnings(const Problem& problem);

/// Writes `json` (pretty, atomically) unless `path` is empty; refuses to overwrite the problem.
void write_json(const std::string& path, const nlohmann::json& json, const Problem& problem);

}  // namespace modalcal::cli
