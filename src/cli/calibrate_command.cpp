// `fullspace_calib calibrate PROBLEM`: calibration with a report in the style of the report's
// Tables 1-4 (parameters: initial, computed, true, bounds) and Table 7 (measured vs predicted).

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli/calibration_report.hpp"
#include "cli/cli_common.hpp"
#include "cli/commands.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/vtu.hpp"

namespace modalcal::cli {

namespace {

struct CalibrateArgs {
  std::string problem;
  std::string method = "fullspace";
  std::string scaling;
  bool no_bounds = false;
  std::string json;
  std::string vtu;
  double refine = 0;
  int max_iterations = 100;
  double start_factor = 1;
  ParameterChoice start;  // --params / --set: where to start
  double regularization = 0;
  bool quiet = false;
  // Full-space tuning, for studies of what each safeguard buys.
  int globalization = FullSpaceOptions().globalization_iterations;
  bool no_guard = false;
  double mu_init = FullSpaceOptions().mu_init;
  bool limited_memory = false;
  int print_level = 0;
};

Scaling parse_scaling(const std::string& name) {
  if (name == "none") return Scaling::None;
  if (name == "linear") return Scaling::Linear;
  if (name == "log") return Scaling::Log;
  throw InputError("--scaling " + name + ": expected none, linear or log");
}

void print_iteration(const IterationRecord& r) {
  std::fprintf(stderr, "  iter %3d  J = %.6e  |pg| = %.3e  solves %d%s\n", r.iteration, r.objective, r.gradient_norm,
               r.forward_solves,
               std::isnan(r.parameter_error) ? "" : ("  param err " + std::to_string(r.parameter_error)).c_str());
}

void print_kkt(const KktRecord& r) {
  std::fprintf(stderr, "  newton %3d  J = %.6e  inf_pr %.2e  inf_du %.2e  compl %.2e  guard MAC %.4f%s\n", r.iteration,
               r.objective, r.primal_infeasibility, r.dual_infeasibility, r.complementarity, r.min_mac,
               std::isnan(r.parameter_error) ? "" : ("  param err " + std::to_string(r.parameter_error)).c_str());
}

int run_calibrate(const CalibrateArgs& args) {
  Problem problem = load_problem(args.problem, LoadOptions{args.refine});
  print_warnings(problem);
  ObjectiveOptions objective_options;
  objective_options.regularization = args.regularization;
  Objective objective(problem, objective_options);
  const std::optional<Scaling> scaling =
      args.scaling.empty() ? std::nullopt : std::optional<Scaling>(parse_scaling(args.scaling));
  const Vector p0 = choose_parameters(&problem, args.start) * args.start_factor;
  std::printf("%s: %d parameters, %zu measured modes, %d DOFs, method %s\n", problem.path.c_str(),
              objective.num_parameters(), problem.measured.size(), objective.system().num_dofs(), args.method.c_str());
  CalibrationReport report;
  bool usable = false;
  Vector final_p;
  if (args.method == "fullspace") {
    if (args.no_bounds) throw InputError("--no-bounds: the full-space method always uses the parameters' bounds");
    FullSpaceOptions options;
    options.max_iterations = std::max(1, args.max_iterations);
    options.scaling = scaling;
    options.globalization_iterations = args.globalization;
    options.mode_guard = !args.no_guard;
    options.mu_init = args.mu_init;
    options.print_level = args.print_level;
    if (args.limited_memory) options.hessian = FullSpaceOptions::Hessian::LimitedMemory;
    if (!args.quiet) options.progress = print_kkt;
    std::fflush(stdout);
    const FullSpaceSummary summary = minimize_fullspace(objective, p0, options);
    std::printf("%s\n%s\n\n", summary.BriefReport().c_str(), summary.message.c_str());
    report = make_report(objective, summary.initial, summary.final);
    report.summary = summary_json(problem, summary);
    usable = summary.converged();
    final_p = summary.final;
  } else {
    ReducedOptions options;
    options.method = parse_method(args.method);
    options.max_iterations = args.max_iterations;
    options.use_bounds = !args.no_bounds;
    options.scaling = scaling;
    if (!args.quiet) options.progress = print_iteration;
    const ReducedSummary summary = minimize_reduced(objective, p0, options);
    std::printf("%s\n%s\n\n", summary.BriefReport().c_str(), summary.message.c_str());
    report = make_report(objective, summary.initial, summary.final);
    report.summary = summary_json(problem, summary);
    // L-BFGS often ends on its line search at the rounding floor with a perfect fit: any end
    // with a final iterate is a result; the status in the report says how it ended.
    usable = summary.termination != TerminationType::ForwardSolveFailed && summary.final.size() > 0;
    final_p = summary.final;
  }
  report.settings = {{"scaling", args.scaling.empty() ? "problem file" : args.scaling},
                     {"bounds", !args.no_bounds},
                     {"start_factor", args.start_factor},
                     {"regularization", args.regularization}};
  std::fputs(report.text.c_str(), stdout);
  write_json(args.json, report.json(), problem);
  if (!args.vtu.empty() && usable) {
    // The calibrated model for ParaView: blocks with their calibrated properties, the computed
    // modes at the final parameters, and the measured shapes at the sensors.
    const Evaluation at_final = objective.evaluate(final_p, Need::Value);
    if (!at_final.ok) throw std::runtime_error("--vtu: forward solve at the final parameters failed: " + at_final.message);
    VtuFields fields;
    add_mode_fields(at_final.modal, -1, &fields);
    for (const std::string& path : write_vtu_set(args.vtu, "calibrated", problem, objective.system(), final_p, fields))
      std::printf("wrote %s\n", path.c_str());
  }
  return usable ? 0 : 1;
}

}  // namespace

void register_calibrate_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand("calibrate", "Calibrate the parameters against the measured modes");
  cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--method", args->method, "fullspace (default), reduced-lbfgs, reduced-gauss-newton or reduced-newton")
      ->check(CLI::IsMember(calibration_method_names()));
  cmd->add_option("--scaling", args->scaling, "none, linear or log for every parameter (default: the problem file's)")
      ->check(CLI::IsMember({"none", "linear", "log"}));
  cmd->add_flag("--no-bounds", args->no_bounds, "ignore the parameters' bounds");
  cmd->add_option("--json", args->json, "write the report as JSON to this file");
  cmd->add_option("--vtu", args->vtu,
                  "write the calibrated model for ParaView to this directory: calibrated.vtu (blocks, calibrated "
                  "properties, mode shapes), calibrated_sensors.vtu (measured shapes) and calibrated.pvd");
  cmd->add_option("--refine", args->refine, "mesh refinement factor")->check(CLI::PositiveNumber);
  cmd->add_option("--max-iterations", args->max_iterations, "iteration limit (default 100)")->check(CLI::NonNegativeNumber);
  cmd->add_option("--params", args->start.source, "start from: initial (default), truth, or a report JSON");
  cmd->add_option("--set", args->start.assignments, "start value NAME=VALUE (repeatable)");
  cmd->add_option("--start-factor", args->start_factor, "multiply the initial values by this factor")->check(CLI::PositiveNumber);
  cmd->add_option("--regularization", args->regularization, "Tikhonov weight toward the initial values (scaled variables)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--quiet", args->quiet, "no progress lines");
  cmd->add_option("--globalization", args->globalization,
                  "fullspace: reduced L-BFGS iterations before the Newton phase, at most (default 50; 0: none)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-guard", args->no_guard, "fullspace: no forward-solve mode check at every iteration");
  cmd->add_option("--mu-init", args->mu_init, "fullspace: Ipopt's initial barrier parameter")->check(CLI::PositiveNumber);
  cmd->add_flag("--limited-memory", args->limited_memory, "fullspace: Ipopt's L-BFGS Hessian instead of the exact one");
  cmd->add_option("--ipopt-print-level", args->print_level, "fullspace: Ipopt's own output (0-12, default 0)")
      ->check(CLI::Range(0, 12));
  cmd->callback([args, exit_code] { *exit_code = run_calibrate(*args); });
}

}  // namespace modalcal::cli
