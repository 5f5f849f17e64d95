// "Safe on every input": hostile and broken inputs get exit code 2 and a short message naming
// the file, line or item and the likely cause; numerical failures exit 1 with the cause; no
// input file is ever overwritten. The cases run through the command-line program are rows of
// the robustness table (tests/test_robustness_table.cpp, docs/robustness.md); these are the ones
// that call the library directly or check more than an exit code and a message.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "modalcal/fullspace.hpp"
#include "modalcal/gradient_check.hpp"
#include "modalcal/identifiability.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/test_data.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::CliRun;
using testing::ReadFile;
using testing::RunCli;
using testing::WriteTempFile;

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

#define EXPECT_CONTAINS(text, part) \
  EXPECT_TRUE(Contains((text), (part))) << "expected '" << (part) << "' in:\n" << (text)

/// The cantilever bar with two measured frequencies and no calibration parameters.
std::string BarWithoutParameters() {
  return testing::CantileverBar() +
         "measured:\n  modes: [{frequency_hz: 1.0}, {frequency_hz: 2.0}]\noptions: {num_modes: 4}\n";
}

/// The cantilever bar with Young's modulus to calibrate against two synthetic frequencies.
std::string BarWithModulus(const std::string& parameter_options = "") {
  return testing::CantileverBar() +
         "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, truth: 1200" + parameter_options +
         "}\nmeasured:\n  synthetic: {modes: [1, 2], shapes: false}\noptions: {num_modes: 4}\n";
}

// --- the library refuses what the command-line program refuses ---

TEST(HostileInputs, LibraryEntryPointsRefuseAProblemWithoutParameters) {
  const Problem problem = LoadProblem(WriteTempFile("bare.yaml", BarWithoutParameters()));
  Objective objective(problem);
  const Vector none(0);
  EXPECT_THROW(minimize_reduced(objective, none, ReducedOptions()), std::invalid_argument);
  EXPECT_THROW(minimize_fullspace(objective, none, FullSpaceOptions()), std::invalid_argument);
  EXPECT_THROW(check_gradient(objective, none, GradientCheckOptions()), std::invalid_argument);
  EXPECT_THROW(check_fullspace_derivatives(objective, none), std::invalid_argument);
  EXPECT_THROW(analyze_identifiability(objective, none, ParameterScaling(problem.parameters)), std::invalid_argument);
  // And a start of the wrong size where there are parameters.
  const Problem with = LoadProblem(WriteTempFile("bar.yaml", BarWithModulus()));
  Objective with_objective(with);
  EXPECT_THROW(minimize_reduced(with_objective, Vector::Ones(2), ReducedOptions()), std::invalid_argument);
}

TEST(HostileInputs, LoadProblemRefusesARefinementThatIsNotPositiveAndFinite) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  EXPECT_THROW(LoadProblem(problem, LoadOptions{std::nan("")}), std::invalid_argument);
  EXPECT_THROW(LoadProblem(problem, LoadOptions{-2}), std::invalid_argument);
}

// --- real test files ---

TEST(HostileInputs, ComplexModeWithoutImaginaryPartIsTakenAsItIsWithoutRotation) {
  std::string text = ReadFile(testing::SourcePath("tests/data/uff/uff55_complex_poma_export.uff"));
  for (const char* imaginary : {" 9.111111E-02", " 4.111111E-03", "-1.111111E-02"})
    text.replace(text.find(imaginary), 13, " 0.000000E+00");
  const TestData data = read_test_data(WriteTempFile("real.uff", text));
  ASSERT_EQ(data.modes.size(), 1u);
  for (const std::string& w : data.warnings) EXPECT_FALSE(Contains(w, "rotating it")) << w;
  EXPECT_FALSE(data.modes[0].from_complex);
  EXPECT_EQ(*data.modes[0].value(111111, 1), 0.1111111);
  EXPECT_EQ(*data.modes[0].value(60101, 2), -0.04111111);
}

const char* const kModulus = "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5}\n";

TEST(HostileInputs, SynthOnARefinedMeshRecordsTheMeshDifference) {
  const std::string nominal = WriteTempFile(
      "nominal.yaml", testing::CantileverBar() + kModulus + "sensors:\n  - {node_set: tip, directions: [y]}\n");
  const std::string data = std::filesystem::path(nominal).parent_path().string() + "/data.yaml";
  const CliRun run = RunCli("synth " + nominal + " --modes 1,2 --refine 2 -o " + data);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_FALSE(Contains(run.output, "the nominal model form is right")) << run.output;
  EXPECT_CONTAINS(run.output, "other differences: mesh: made on the generated mesh with refinement 2");
  EXPECT_CONTAINS(ReadFile(data), "other_differences: \"mesh: made on the generated mesh with refinement 2");
}

}  // namespace
}  // namespace modalcal
