// fullspace_calib: calibrate finite-element modal models against measured modes.
// Exit codes: 0 success, 1 numerical failure (solver did not succeed), 2 bad input.

#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string>

#include "cli/cli_common.hpp"
#include "cli/cli_validators.hpp"
#include "cli/commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"fullspace_calib: calibrate finite-element modal models against measured modes"};
  app.require_subcommand(1);
  int exit_code = 0;
  modalcal::cli::register_modes_command(app, &exit_code);
  modalcal::cli::register_calibrate_command(app, &exit_code);
  modalcal::cli::register_campaign_command(app, &exit_code);
  modalcal::cli::register_check_command(app, &exit_code);
  modalcal::cli::register_study_command(app, &exit_code);
  modalcal::cli::register_import_test_data_command(app, &exit_code);
  modalcal::cli::register_synth_command(app, &exit_code);
  modalcal::cli::register_compare_command(app, &exit_code);
  modalcal::cli::register_localize_command(app, &exit_code);
  modalcal::cli::register_diagnose_command(app, &exit_code);
  for (CLI::App* command : app.get_subcommands([](CLI::App*) { return true; }))
    command->parse_complete_callback([command] { modalcal::cli::check_distinct_outputs(*command); });
  // CLI11 answers an unknown command with "A subcommand is required": name it and the commands.
  if (argc > 1 && argv[1][0] != '-') {
    std::string commands;
    bool known = false;
    for (const CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) {
      known = known || command->get_name() == argv[1];
      commands += (commands.empty() ? "" : ", ") + command->get_name();
    }
    if (!known) {
      const std::string name = argv[1];
      std::cerr << "error: unknown command '" << name.substr(0, 40) << (name.size() > 40 ? "..." : "")
                << "'; the commands are " << commands << " (fullspace_calib --help)\n";
      return 2;
    }
  }
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
