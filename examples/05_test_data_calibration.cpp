// Example 5: measured modes from a universal file, compared with the model and calibrated.
//
// Shows: reading a universal file (what it holds: header, nodes, modes), a problem that takes
// its sensors and measured modes from the file (`measured: test_data:`, test nodes mapped onto
// model nodes by coordinates), test-analysis correlation (frequency errors, MAC,
// cross-orthogonality) before and after calibration, and what the calibrated value means.
//
// The data are a real export: ten modes of a 1 m square cantilever plate from Permas
// (tests/data/uff/nodes2411_results2414.uff, 441 nodes). Its thickness is not in the file, so
// the model (examples/data/permas_plate.yaml) is an equivalent 20 mm plate whose modulus is
// calibrated; thin-plate bending frequencies depend on E h^2 / rho only, which turns the
// calibrated modulus into the steel thickness the data belong to.
//
// Run:   build/bin/example_05_test_data_calibration [problem.yaml]
//        (default: examples/data/permas_plate.yaml; about ten seconds)

#include <cmath>
#include <cstdio>
#include <string>

#include "modalcal/comparison.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/test_data.hpp"
#include "modalcal/problem_file.hpp"

namespace {

void print_comparison(const modalcal::ModalComparison& c) {
  std::printf("  measured  model  measured [Hz]  model [Hz]  error %%     MAC     XOR\n");
  for (const modalcal::ComparedPair& pair : c.pairs)
    std::printf("  %8d  %5d  %13.4f  %10.4f  %7.2f  %6.4f  %6.3f\n", pair.measured + 1, pair.model + 1,
                pair.measured_hz, pair.model_hz, pair.error_percent, pair.mac, pair.cross_orthogonality);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace modalcal;
  const std::string source = MODALCAL_SOURCE_DIR;
  const std::string path = argc > 1 ? argv[1] : source + "/examples/data/permas_plate.yaml";

  // 1. Look into the universal file first: who wrote it, its nodes and modes. Lengths without
  //    a units dataset (164) are used as written (here metres, like the model).
  const TestData data = read_test_data(source + "/tests/data/uff/nodes2411_results2414.uff");
  if (data.header) std::printf("%s: written by %s\n", data.path.c_str(), data.header->file_program.c_str());
  std::printf("%zu nodes, %zu modes:", data.nodes.size(), data.modes.size());
  for (const TestMode& m : data.modes) std::printf(" %.3f", m.frequency_hz);
  std::printf(" Hz\n");

  // 2. The problem maps the test nodes onto model nodes and builds one sensor per matched node
  //    and measured direction; the mapping report (unmatched nodes, distances) is in warnings.
  const Problem problem = load_problem(path);
  for (const std::string& warning : problem.warnings) std::printf("warning: %s\n", warning.c_str());
  std::printf("%zu sensor DOFs, %zu measured modes\n", problem.sensors.size(), problem.measured.size());

  // 3. Correlate before calibrating: the shapes already agree (MAC near 1), the frequencies do
  //    not, so the model's form is right and a stiffness is off. XOR is the cross-orthogonality
  //    with a SEREP test-analysis mass (near 1 for a good pair).
  std::printf("before calibration (E = %.4g Pa):\n", problem.initial_values()[0]);
  print_comparison(compare_modes(problem, problem.initial_values()));

  // 4. Calibrate E by projected L-BFGS in log10 E. The data are not the model's own (a shell
  //    model against solid elements), so J stays above zero and its projected gradient stalls
  //    near 1e-7 in rounding: stop at 1e-6 rather than at the default 1e-10.
  Objective objective(problem);
  ReducedOptions options;
  options.gradient_tolerance = 1e-6;
  options.max_iterations = 50;
  const ReducedSummary summary = minimize_reduced(objective, problem.initial_values(), options);
  std::printf("%s\n", summary.BriefReport().c_str());
  if (!summary.converged()) return 1;

  // 5. Correlate again, and read the result: the steel (210 GPa) plate of the same bending
  //    stiffness per mass is h = 20 mm * sqrt(E / 210 GPa) thick. MAC and XOR do not change: a
  //    modulus scales frequencies and leaves shapes alone, so the last pair's lower XOR is a
  //    shape difference no value of E removes.
  const double E = summary.final[0];
  std::printf("after calibration (E = %.4g Pa):\n", E);
  print_comparison(compare_modes(problem, summary.final));
  std::printf("equivalent steel plate thickness: %.3f mm\n", 20.0 * std::sqrt(E / 2.1e11));
  return 0;
}
