#pragma once
// Each subcommand registers itself on the application and reports its exit code.
#include <CLI/CLI.hpp>

namespace modalcal::cli {
void register_modes_command(CLI::App& app, int* exit_code);
void register_calibrate_command(CLI::App& app, int* exit_code);
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
