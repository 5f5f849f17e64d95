// Coverage of the calibration's confidence intervals (uncertainty.hpp): how often the stated
// 95 % intervals hold the truth over many noise draws.
//
//   uncertainty_benchmark [--problem FILE] [--draws N] [--seed-base B] [--noise-freq F]
//                         [--noise-shape S] [--confidence C] [--start truth|initial]
//
// Each draw: noisy measured data from the problem's nominal model at its parameters' truth
// values (the model form is right: the intervals claim nothing else), a calibration as
// `calibrate --method reduced-lbfgs` makes it (the problem's own objective weights, started at the
// truth by default so that the coverage measures the intervals, not the search from a far start),
// then estimate_uncertainty() with the noise stated, profiles off (Laplace intervals). Printed per
// parameter: the coverage with its binomial standard error, the mean standard error, the spread
// of the calibrated values (both in the optimizer's variable) and their ratio.
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/synthesis.hpp"
#include "modalcal/uncertainty.hpp"
#include "modalcal/problem_file.hpp"

using namespace modalcal;

namespace {

struct Args {
  std::string problem = std::string(MODALCAL_SOURCE_DIR) + "/problems/portal-frame/synthetic.yaml";
  int draws = 200;
  std::uint64_t seed_base = 5000;
  MeasurementNoise noise{0.002, 0.02, 1};
  double confidence = 0.95;
  bool start_at_truth = true;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(arg + ": missing value");
      return argv[++i];
    };
    if (arg == "--problem") a.problem = next();
    else if (arg == "--draws") a.draws = std::stoi(next());
    else if (arg == "--seed-base") a.seed_base = std::stoull(next());
    else if (arg == "--noise-freq") a.noise.frequency = std::stod(next());
    else if (arg == "--noise-shape") a.noise.shape = std::stod(next());
    else if (arg == "--confidence") a.confidence = std::stod(next());
    else if (arg == "--start") a.start_at_truth = next() == "truth";
    else throw std::invalid_argument("unknown argument " + arg);
  }
  if (a.draws < 2) throw std::invalid_argument("--draws must be >= 2");
  return a;
}

int run(const Args& args) {
  Problem nominal = load_problem(args.problem);
  synthesize_measured(&nominal);
  if (!nominal.synthetic || !nominal.has_truth())
    throw std::invalid_argument(args.problem + ": needs synthetic measured data and truth values");
  const int np = static_cast<int>(nominal.parameters.size());
  const ParameterScaling scaling(nominal.parameters);
  const Vector truth = nominal.truth_values(), x_truth = scaling.to_scaled(truth);
  const TruthModel model = make_truth(nominal, nullptr, {});
  std::printf("# coverage of %.0f %% Laplace intervals: %s, %d draws (noise seeds %llu+), noise %g (frequency), %g "
              "(shape), start at the %s\n# load average %s\n",
              100 * args.confidence, args.problem.c_str(), args.draws, static_cast<unsigned long long>(args.seed_base),
              args.noise.frequency, args.noise.shape, args.start_at_truth ? "truth" : "initial values",
              bench::load_average().c_str());
  std::vector<int> covered(np, 0);
  std::vector<double> se_sum(np, 0), dev_sum(np, 0), dev2_sum(np, 0);
  int usable = 0;
  const auto t0 = bench::Clock::now();
  for (int d = 0; d < args.draws; ++d) {
    Problem problem = nominal;
    SynthesisOptions options;
    options.modes = nominal.synthetic->modes;
    options.shapes = nominal.synthetic->shapes;
    options.noise = args.noise;
    options.noise.seed = args.seed_base + static_cast<std::uint64_t>(d);
    const MeasuredData data = synthesize_measured_data(nominal, model, nominal.sensors, options);
    problem.measured = data.modes;
    problem.synthetic.reset();
    problem.measurement_noise = data.noise;
    Objective objective(problem);
    const ReducedSummary fit =
        minimize_reduced(objective, args.start_at_truth ? truth : problem.initial_values(), ReducedOptions());
    if (fit.final.size() != np) continue;
    UncertaintyOptions uo;
    uo.confidence = args.confidence;
    uo.profiles = false;
    const Uncertainty u = estimate_uncertainty(problem, fit.final, uo);
    ++usable;
    const Vector x = scaling.to_scaled(fit.final);
    for (int j = 0; j < np; ++j) {
      const ParameterUncertainty& pu = u.parameters[j];
      if (pu.lower <= truth[j] && truth[j] <= pu.upper) ++covered[j];
      se_sum[j] += pu.scaled_standard_error;
      dev_sum[j] += x[j] - x_truth[j];
      dev2_sum[j] += (x[j] - x_truth[j]) * (x[j] - x_truth[j]);
    }
  }
  std::printf("%-16s %10s %10s %12s %12s %8s\n", "parameter", "coverage", "+/-", "mean s.e.", "spread", "ratio");
  int all = 0;
  for (int j = 0; j < np; ++j) {
    const double c = static_cast<double>(covered[j]) / usable;
    const double mean = dev_sum[j] / usable;
    const double spread = std::sqrt(std::max(0.0, (dev2_sum[j] - usable * mean * mean) / (usable - 1)));
    const double se = se_sum[j] / usable;
    std::printf("%-16s %9.1f%% %9.1f%% %12.4g %12.4g %8.3f\n", nominal.parameters[j].name.c_str(), 100 * c,
                100 * std::sqrt(c * (1 - c) / usable), se, spread, spread / se);
    all += covered[j];
  }
  const double c = static_cast<double>(all) / (usable * np);
  std::printf("%-16s %9.1f%% %9.1f%%   (%d usable draws of %d; target %.0f +/- 3 %%)\n", "all", 100 * c,
              100 * std::sqrt(c * (1 - c) / (usable * np)), usable, args.draws, 100 * args.confidence);
  std::printf("# %.1f s; load average %s\n", bench::seconds_since(t0), bench::load_average().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "uncertainty_benchmark: %s\n", e.what());
    return 2;
  }
}
