#pragma once
// Each subcommand registers itself on the application and reports its exit code.
#include <CLI/CLI.hpp>

#include <cmath>
#include <string>

namespace modalcal::cli {

/// A finite number at least `lowest` (above it if `strict`). CLI11's PositiveNumber, NonNegativeNumber
/// and Range let NaN through (every comparison with it is false) and print their bounds with all 309
/// digits of the largest double: options taking numbers check these instead.
inline CLI::Validator number_from(double lowest, bool strict, const std::string& name) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        const std::string given = "'" + text.substr(0, 40) + (text.size() > 40 ? "...'" : "'");
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value)) return given + " is not a finite number";
        if (strict ? value > lowest : value >= lowest) return "";
        return given + (lowest == 0 ? (strict ? " must be positive" : " must not be negative") : " is too small");
      },
      name);
}
inline CLI::Validator finite_number() { return number_from(-HUGE_VAL, false, "FINITE"); }
inline CLI::Validator positive_number() { return number_from(0, true, "POSITIVE"); }
inline CLI::Validator non_negative_number() { return number_from(0, false, "NONNEGATIVE"); }

void register_modes_command(CLI::App& app, int* exit_code);
void register_calibrate_command(CLI::App& app, int* exit_code);
void register_campaign_command(CLI::App& app, int* exit_code);
void register_check_command(CLI::App& app, int* exit_code);
void register_localize_command(CLI::App& app, int* exit_code);
/// `study full-vs-reduced`, a subcommand of `study`.
void register_full_vs_reduced_study(CLI::App* study, int* exit_code);
void register_study_command(CLI::App& app, int* exit_code);
void register_import_test_data_command(CLI::App& app, int* exit_code);
void register_synth_command(CLI::App& app, int* exit_code);
void register_compare_command(CLI::App& app, int* exit_code);
void register_diagnose_command(CLI::App& app, int* exit_code);
}  // namespace modalcal::cli
