// fullspace_calib: calibrate finite-element modal models against measured modes.
// Exit codes: 0 success, 1 numerical failure (solver did not succeed), 2 bad input.

#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <new>
#include <stdexcept>

#include "cli/cli_common.hpp"
#include "cli/commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fullspace_calib: calibrate finite-element modal models against measured modes"};
  app.require_subcommand(1);
  int exit_code = 0;
  modalcal::cli::register_modes_command(app, &exit_code);
  modalcal::cli::register_calibrate_command(app, &exit_code);
  modalcal::cli::register_check_command(app, &exit_code);
  modalcal::cli::register_study_command(app, &exit_code);
  modalcal::cli::register_import_test_data_command(app, &exit_code);
  modalcal::cli::register_synth_command(app, &exit_code);
  modalcal::cli::register_compare_command(app, &exit_code);
  modalcal::cli::register_localize_command(app, &exit_code);
  modalcal::cli::register_diagnose_command(app, &exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const std::invalid_argument& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  } catch (const std::filesystem::filesystem_error& e) {
    // Its what() is "filesystem error: <operation>: <reason> [<path>]".
    std::cerr << "error: '" << e.path1().string() << "': " << e.code().message() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    // Inputs too large for the memory are refused with their estimate before it runs out (exit 2);
    // running out anyway is a failure of the run, as any other resource would be.
    std::cerr << "error: not enough memory for this run on this machine (a model or an input file too large "
                 "for it?)\n";
    return 1;
  } catch (const std::length_error&) {
    std::cerr << "error: not enough memory for this run: a size computed from the input exceeds what a vector can "
                 "hold (a count in an input file too large or negative?)\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return exit_code;
}
