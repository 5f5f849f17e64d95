#include "io/synthetic.hpp"

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"

namespace modalcal::detail {

void synthesize_measured(Problem* problem, const SyntheticSpec& spec) {
  auto fail = [&](const std::string& message) {
    throw ProblemError(problem->path, spec.source_line, "measured.synthetic: " + message);
  };
  if (!problem->has_truth()) fail("every parameter needs a 'truth' value to synthesize measurements");
  int highest = 0;
  for (int k : spec.modes) {
    if (k < 1) fail("mode indices are 1-based; got " + std::to_string(k));
    highest = std::max(highest, k);
  }
  if (spec.shapes && problem->sensors.empty()) fail("shapes requested but no sensors are defined");
  ParametricSystem system(problem->model, problem->parameter_targets());
  const Vector truth = problem->truth_values();
  SparseMatrix K, M;
  system.assemble(truth, &K, &M);
  ModalOptions options;
  options.num_modes = std::max(highest, problem->options.num_modes);
  options.max_rigid_modes = problem->expected_rigid_modes();
  options.tolerance = problem->options.tolerance;
  ModalSolver solver(system.pattern(), options);
  const ModalResult result = solver.solve(K, M);
  if (result.status != EigenStatus::Successful) fail("forward solve at the truth values failed: " + result.message);
  const std::vector<ModeDescription> described = describe_modes(system, truth, M, result);
  problem->measured.clear();
  for (int k : spec.modes) {
    MeasuredMode m;
    m.frequency_hz = frequency_hz(result.eigenvalues[k - 1]);
    m.label = described[k - 1].label.empty() ? "mode " + std::to_string(k) : described[k - 1].label;
    // With shapes, pair by MAC as for real test data: index pairing would tie a measured mode to
    // whichever mode happens to be k-th while modes cross on the way from a far start.
    m.pairing.kind = spec.shapes ? PairingRule::Kind::Mac : PairingRule::Kind::ModelIndex;
    m.pairing.model_index = k;
    m.source_line = spec.source_line;
    if (spec.shapes) {
      m.shape.resize(problem->sensors.size());
      for (size_t s = 0; s < problem->sensors.size(); ++s)
        m.shape[s] = system.dof_map().value(result.modes.col(k - 1), problem->sensors[s].node,
                                            problem->sensors[s].component);
    }
    problem->measured.push_back(m);
  }
}

}  // namespace modalcal::detail
