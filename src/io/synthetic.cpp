#include "io/synthetic.hpp"

#include <new>

#include "modalcal/synthesis.hpp"

namespace modalcal::detail {

void synthesize_measured(Problem* problem, const SyntheticSpec& spec) {
  auto fail = [&](const std::string& message) {
    throw ProblemError(problem->path, spec.source_line, "measured.synthetic: " + message);
  };
  if (!problem->has_truth()) fail("every parameter needs a 'truth' value to synthesize measurements");
  SynthesisOptions options;
  options.modes = spec.modes;
  options.shapes = spec.shapes;
  try {
    const TruthModel truth = make_truth(*problem, nullptr, {});
    MeasuredData data = synthesize_measured_data(*problem, truth, problem->sensors, options);
    for (MeasuredMode& m : data.modes) m.source_line = spec.source_line;
    problem->measured = std::move(data.modes);
    problem->synthetic_truth = truth.record;
  } catch (const std::bad_alloc&) {
    throw;  // not a mistake in the problem file's synthetic section
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

}  // namespace modalcal::detail
