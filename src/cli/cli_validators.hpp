#pragma once
// Internal: validators for command-line options beyond CLI11's own.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cli/cli_common.hpp"
#include "cli/plot.hpp"
#include "modalcal/output.hpp"

namespace modalcal::cli {

/// CLI11's Range for a real-valued option, refusing NaN and infinities as well (NaN compares
/// false with both ends, so CLI::Range lets it through) and printing the ends as given (1e-12,
/// where CLI::Range prints 0.000000).
inline CLI::Validator FiniteRange(double min, double max) {
  const auto text_of = [](double v) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%g", v);
    return std::string(buffer);
  };
  const std::string range = text_of(min) + " to " + text_of(max);
  return CLI::Validator(
      [min, max, range](std::string& text) -> std::string {
        const std::optional<double> v = finite_number(text);
        if (v && *v >= min && *v <= max) return "";
        return "Value " + text + " not in range " + range;
      },
      "[" + range + "]");
}

/// A seed written as the digits of an unsigned 64-bit integer: CLI11 would wrap "-1" and clamp
/// 2^64 to 2^64 - 1 without a word, and the data would then not be the ones the seed names.
inline CLI::Validator SeedText() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        const bool digits = !text.empty() && text.size() <= 20 &&
                            text.find_first_not_of("0123456789") == std::string::npos;
        if (digits && (text.size() < 20 || text <= "18446744073709551615")) return "";
        return "seed " + text + " is not an integer from 0 to 18446744073709551615";
      },
      "UINT64");
}

/// The name OutputFile() and PlotFile() give their validators, by which check_distinct_outputs()
/// finds the outputs.
inline const char* const kOutputFileValidator = "output-file";

/// Why `path` cannot be written (check_output_path()), or "" when it can.
inline std::string output_path_problem(const std::string& path) {
  try {
    check_output_path(path, {});
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

/// An output file that can be written: its folder exists and takes a new file, its name is within
/// the file system's limit (check_output_path()). Checked when the options are parsed, so that
/// every command refuses it before it computes anything; whether it names an input is checked
/// once the inputs are known.
inline CLI::Validator OutputFile() {
  return CLI::Validator([](std::string& text) { return output_path_problem(text); }, "FILE").name(kOutputFileValidator);
}

/// An output file for a plot: as OutputFile(), and named .png or .svg, checked before the run
/// rather than after it.
inline CLI::Validator PlotFile() {
  return CLI::Validator(
             [](std::string& text) {
               const std::string problem = plot_name_problem(text);
               return problem.empty() ? output_path_problem(text) : problem;
             },
             "FILE")
      .name(kOutputFileValidator);
}

/// The first pair (earlier, later) of `paths` that name one file (through `./`, `..` or a
/// symlink too), or nullopt. Empty paths and devices (/dev/stdout, which several may share) are
/// passed over.
inline std::optional<std::pair<size_t, size_t>> same_file_twice(const std::vector<std::string>& paths) {
  namespace fs = std::filesystem;
  std::vector<std::pair<fs::path, size_t>> seen;  // the file, the index of the path that names it
  for (size_t k = 0; k < paths.size(); ++k) {
    std::error_code error;
    if (paths[k].empty() || (fs::exists(paths[k], error) && !fs::is_regular_file(paths[k], error))) continue;
    const fs::path file = fs::weakly_canonical(paths[k], error);
    for (const auto& [other, index] : seen)
      if (other == file) return std::make_pair(index, k);
    seen.emplace_back(file, k);
  }
  return std::nullopt;
}

/// Refuses two of `outputs` (the option, its file) that name one file: only the one written last
/// would be left, with exit 0.
/// \throws std::invalid_argument naming both options.
inline void check_outputs_apart(const std::vector<std::pair<std::string, std::string>>& outputs) {
  std::vector<std::string> paths;
  for (const auto& output : outputs) paths.push_back(output.second);
  if (const auto twice = same_file_twice(paths))
    throw std::invalid_argument(outputs[twice->first].first + " and " + outputs[twice->second].first + " both name '" +
                                paths[twice->second] + "': one would overwrite the other; give each output its own file");
}

/// check_outputs_apart() on `command`'s output files (options checked by OutputFile() or
/// PlotFile()), once parsing completes: before the run.
inline void check_distinct_outputs(CLI::App& command) {
  std::vector<std::pair<std::string, std::string>> outputs;
  for (CLI::Option* option : command.get_options()) {
    if (option->count() == 0) continue;
    try {
      option->get_validator(kOutputFileValidator);
    } catch (const CLI::OptionNotFound&) {
      continue;
    }
    for (const std::string& path : option->results()) outputs.emplace_back(option->get_name(), path);
  }
  check_outputs_apart(outputs);
}

}  // namespace modalcal::cli
