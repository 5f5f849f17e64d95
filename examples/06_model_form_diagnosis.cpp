// Example 6: which physics is the model missing? The model-form diagnosis loop on a case whose
// measured modes come from a truth model with a point mass the nominal model lacks.
//
// Shows: calibrating (in the chi-square metric of the stated noise), the test-analysis comparison
// at the calibrated values, the residual's chi-square test flagging a model-form error, where
// the residual forces of the expanded shapes point, the ranking of candidate effects (first-order
// screen of all, refits of the best), and the recalibration with the best effect, before and
// after per mode. The steps are what `fullspace_calib diagnose` runs (docs/design.md:
// "Diagnosis: which physics is missing").
//
// Run:   build/bin/example_06_model_form_diagnosis [problem.yaml]
//        (default: problems/lfu-hidden/top-mass.yaml; takes about a minute)

#include <cstdio>
#include <iostream>
#include <string>

#include "modalcal/comparison.hpp"
#include "modalcal/diagnosis.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

int main(int argc, char** argv) {
  using namespace modalcal;
  const std::string path = argc > 1 ? argv[1] : std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu-hidden/top-mass.yaml";

  // 1. The problem: nominal model, five calibration parameters, measured modes with their noise
  //    (the data file's `noise:`), and, for synthetic data, the truth they were made from.
  Problem problem = load_problem(path);
  synthesize_measured(&problem);  // a synthetic section's modes, from the truth model (none: no-op)
  if (!problem.measurement_noise) {
    std::cerr << path << " states no measurement noise (measured: {noise: ...}): nothing to test against\n";
    return 1;
  }

  // 2. The whole loop from the file's start: calibrate, test, localize, rank, refit, recommend.
  DiagnosisOptions options;
  options.calibration.progress = [](const IterationRecord& r) {
    std::printf("  calibration %2d  chi-square/2 = %.4e\n", r.iteration, r.objective);
  };
  const Diagnosis d = diagnose(problem, problem.initial_values(), options);

  // 3. How the calibrated model meets the test: pairs, frequency errors, MAC.
  const ModalComparison comparison = compare_modes(problem, d.calibration.final);
  std::printf("\n%-10s %12s %12s %9s %7s\n", "measured", "meas [Hz]", "model [Hz]", "error %", "MAC");
  for (const ComparedPair& p : comparison.pairs)
    std::printf("%-10d %12.3f %12.3f %9.3f %7.4f\n", p.measured + 1, p.measured_hz, p.model_hz, p.error_percent, p.mac);

  // 4. The flag: is the residual more than the noise?
  std::cout << "\nresidual test: " << d.before.test->verdict << "\n";

  // 5. Where: residual forces of the measured shapes expanded on the model's modes.
  if (d.localization) std::cout << "\n" << format_ranking(*d.localization, 5);

  // 6. What: candidate effects ranked by the misfit each removes.
  std::cout << "\n" << format_effect_ranking(d.ranking, 8) << "\n" << d.recommendation << "\n";

  // 7. The error falling: the recommended effect added and everything recalibrated.
  if (d.after) {
    const RankedEffect& best = d.ranking.effects[d.recommended];
    const Problem with = problem_with_effects(problem, {best.candidate}, {best.value});
    std::cout << "\n" << format_before_after(with, d.before, *d.after, "nominal", "with effect");
  }

  // 8. What was hidden (synthetic data only), and where the diagnosis ranked it.
  if (problem.synthetic_truth)
    for (const ModelEffect& e : problem.synthetic_truth->hidden_effects)
      std::printf("\nhidden: %s = %.4g (%s), ranked %d\n", e.name.c_str(), e.value, e.description.c_str(),
                  rank_of(d.ranking, e.name));
  return d.recommended == 0 || !d.before.test->model_form_error ? 0 : 1;
}
