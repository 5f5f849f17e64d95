// `fullspace_calib check-derivatives PROBLEM`: the adjoint gradient against central finite
// differences, parameter by parameter (the public gradient checker).

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>

#include "cli/cli_common.hpp"
#include "cli/commands.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/gradient_check.hpp"
#include "modalcal/problem_file.hpp"

namespace modalcal::cli {

namespace {

struct CheckArgs {
  std::string problem;
  ParameterChoice params;
  double step = 1e-5;
  double tolerance = 1e-4;
  double refine = 0;
  double fullspace_step = 1e-6;
  bool reduced_only = false;
};

int run_check(const CheckArgs& args) {
  Problem problem = load_problem_with_measurements(args.problem, LoadOptions{args.refine});
  require_parameters(problem);
  const Vector p = choose_parameters(&problem, args.params);
  Objective objective(problem);
  GradientCheckOptions options;
  options.relative_step = args.step;
  options.tolerance = args.tolerance;
  const GradientCheck check = check_gradient(objective, p, options);
  std::printf("reduced gradient (adjoint) vs central differences, relative step %.1e, at %s\n", args.step,
              args.params.source.c_str());
  std::fputs(check.report.c_str(), stdout);
  bool ok = check.ok;
  if (!args.reduced_only) {
    const FullSpaceDerivativeCheck full = check_fullspace_derivatives(objective, p, args.fullspace_step);
    std::printf("\nfull-space derivatives vs central differences along random directions, relative step %.1e\n",
                args.fullspace_step);
    for (const std::string& line : full.lines) std::printf("  %s\n", line.c_str());
    const double worst = std::max({full.gradient_error, full.jacobian_error, full.hessian_error});
    std::printf("max relative error %.2e (tolerance %.1e): %s\n", worst, args.tolerance,
                worst <= args.tolerance ? "OK" : "FAILED");
    ok = ok && worst <= args.tolerance;
  }
  return ok ? 0 : 1;
}

}  // namespace

void register_check_command(CLI::App& app, int* exit_code) {
  auto args = std::make_shared<CheckArgs>();
  CLI::App* cmd = app.add_subcommand("check-derivatives", "Compare analytic derivatives with finite differences");
  cmd->add_option("problem", args->problem, "problem file (YAML)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--params", args->params.source, "where to check: initial, truth, or a report JSON");
  cmd->add_option("--set", args->params.assignments, "NAME=VALUE (repeatable)");
  cmd->add_option("--step", args->step, "relative finite-difference step (default 1e-5)")->check(positive_number());
  cmd->add_option("--tolerance", args->tolerance, "largest acceptable relative error (default 1e-4)")
      ->check(positive_number());
  cmd->add_option("--fullspace-step", args->fullspace_step, "relative step of the full-space check (default 1e-6)")
      ->check(positive_number());
  cmd->add_flag("--reduced-only", args->reduced_only, "check only the reduced gradient");
  cmd->add_option("--refine", args->refine, "mesh refinement factor")->check(positive_number());
  cmd->callback([args, exit_code] { *exit_code = run_check(*args); });
}

}  // namespace modalcal::cli
