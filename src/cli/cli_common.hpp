#pragma once
// Pieces every subcommand shares: loading a problem, choosing parameter values
// (--params/--set), and writing JSON next to the printed report.

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

#include "modalcal/effects.hpp"
#include "modalcal/localization.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/vtu.hpp"

namespace modalcal::cli {

/// Input errors (exit code 2) as opposed to numerical failures (exit code 1).
struct InputError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// The problem file at `path` with its measured modes: load_problem(), then synthesize_measured()
/// for a `measured: synthetic:` section.
Problem load_problem_with_measurements(const std::string& path, const LoadOptions& options = {});

struct ParameterChoice {
  std::string source = "initial";        ///< initial | truth | path of a report JSON
  std::vector<std::string> assignments;  ///< NAME=VALUE, NAME a parameter or a property
};

/// Parameter values chosen by `choice`; property assignments (names that are not parameters)
/// are applied to problem->model. A report read for them joins problem->source_files.
Vector choose_parameters(Problem* problem, const ParameterChoice& choice);

/// The reduced-space methods by their CLI names, and the reverse.
std::vector<std::string> method_names();
/// fullspace and the reduced-space methods.
std::vector<std::string> calibration_method_names();
ReducedOptions::Method parse_method(const std::string& name);

/// \throws InputError naming the file if the problem has no calibration parameters (for the
/// commands that vary them: calibrate, check-derivatives, diagnose, the studies).
void require_parameters(const Problem& problem);

/// \throws InputError naming the first parameter whose start value (from --params, --set or
/// --start-factor) lies outside its bounds: a bounded calibration would move it onto the bound
/// without a word.
void require_start_within_bounds(const Problem& problem, const Vector& start);

/// Appends the effects of --add's `texts` (make_candidate()) to `effects`.
/// \throws InputError naming a text that does not apply to the model, or that names an effect
/// already in `effects` (one effect cannot be calibrated as two parameters), e.g. the problem's
/// enabled ones.
void append_added_effects(const Problem& problem, const std::vector<std::string>& texts,
                          std::vector<EffectCandidate>* effects);

/// Creates the output directory `dir` (of option `option`, e.g. "--out") if need be, before any
/// computation. \throws InputError naming it if it cannot be a directory.
void create_output_directory(const std::string& option, const std::string& dir);

/// Prints each of problem.warnings (e.g. unmatched test nodes) as "warning: ..." to stderr.
void print_warnings(const Problem& problem);

/// Writes `json` (pretty, atomically) unless `path` is empty; refuses to overwrite any file the
/// problem was read from (Problem::source_files).
void write_json(const std::string& path, const nlohmann::json& json, const Problem& problem);
/// JSON has no NaN or infinity: a number that is not finite (unknown, undefined) is written as null.
/// `text` as a number when all of it is one and it is finite; nullopt otherwise (NaN, inf, "1x").
std::optional<double> finite_number(const std::string& text);

nlohmann::json json_number(double value);

/// Adds `hidden_effect: [{name, description, value, nominal_value}]` to `json` when the truth the
/// measured modes came from is known (an empty list: the nominal model form is right), and
/// `other_differences` when the truth differs in more than properties.
void add_hidden_effect(const Problem& problem, nlohmann::json* json);

/// The VTU fields of a localization: the model's modes, the expanded measured shapes, the element
/// indicator and each node's share of the residual energy (localize and diagnose --vtu).
VtuFields localization_fields(const Problem& problem, const Localization& result);

/// The same for people: "hidden effect: NAME = VALUE (nominal N): DESCRIPTION" lines, or "" when
/// the truth is unknown.
std::string hidden_effect_text(const Problem& problem);
/// The lines for `truth`; `recorded_in` names the data file it was read from, if any.
std::string hidden_effect_text(const SyntheticTruth& truth, const std::string& recorded_in);

}  // namespace modalcal::cli
