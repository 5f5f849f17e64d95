// "Safe on every input": hostile and broken inputs get exit code 2 and a short message naming
// the file, line or item and the likely cause; numerical failures exit 1 with the cause; no
// input file is ever overwritten. Each test reproduces one defect found by feeding the program
// such inputs.

#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "modalcal/fullspace.hpp"
#include "modalcal/gradient_check.hpp"
#include "modalcal/identifiability.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/reduced.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::CliRun;
using testing::ReadFile;
using testing::RunCli;
using testing::WriteTempFile;

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

#define EXPECT_CONTAINS(text, part) EXPECT_TRUE(Contains((text), (part))) << "expected '" << (part) << "' in:\n" << (text)

/// The cantilever bar with two measured frequencies and no calibration parameters.
std::string BarWithoutParameters() {
  return testing::CantileverBar() + "measured:\n  modes: [{frequency_hz: 1.0}, {frequency_hz: 2.0}]\noptions: {num_modes: 4}\n";
}

/// The cantilever bar with Young's modulus to calibrate against two synthetic frequencies.
std::string BarWithModulus(const std::string& parameter_options = "") {
  return testing::CantileverBar() + "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, truth: 1200" +
         parameter_options + "}\nmeasured:\n  synthetic: {modes: [1, 2], shapes: false}\noptions: {num_modes: 4}\n";
}

// --- 1. no calibration parameters: a crash (SIGSEGV) in every command that varies them ---

/// Runs each command on `problem`, a problem without calibration parameters.
void ExpectEveryCommandRefuses(const std::string& problem, const std::vector<std::string>& commands) {
  const std::string out = std::filesystem::path(problem).parent_path().string();
  for (const std::string& command : commands) {
    const bool study = command.rfind("study", 0) == 0;
    const CliRun run = RunCli(command + " " + problem + (study ? " --out " + out : ""));
    EXPECT_EQ(run.exit_code, 2) << command << "\n" << run.output;
    EXPECT_CONTAINS(run.output, "no calibration parameters in " + problem);
  }
}

TEST(HostileInputs, NoParametersSectionIsAnInputErrorInEveryCommand) {
  ExpectEveryCommandRefuses(WriteTempFile("bare.yaml", BarWithoutParameters()),
                            {"calibrate", "check-derivatives", "diagnose", "study starts", "study bounds-scaling",
                             "study full-vs-reduced --starts 1"});
}

TEST(HostileInputs, EmptyParametersSectionIsAnInputError) {
  ExpectEveryCommandRefuses(WriteTempFile("empty.yaml", BarWithoutParameters() + "parameters: {}\n"),
                            {"calibrate --method fullspace", "calibrate --method reduced-lbfgs", "diagnose"});
}

TEST(HostileInputs, LibraryEntryPointsRefuseAProblemWithoutParameters) {
  const Problem problem = load_problem(WriteTempFile("bare.yaml", BarWithoutParameters()));
  Objective objective(problem);
  const Vector none(0);
  EXPECT_THROW(minimize_reduced(objective, none, ReducedOptions()), std::invalid_argument);
  EXPECT_THROW(minimize_fullspace(objective, none, FullSpaceOptions()), std::invalid_argument);
  EXPECT_THROW(check_gradient(objective, none, GradientCheckOptions()), std::invalid_argument);
  EXPECT_THROW(check_fullspace_derivatives(objective, none), std::invalid_argument);
  EXPECT_THROW(analyze_identifiability(objective, none, ParameterScaling(problem.parameters)), std::invalid_argument);
  // And a start of the wrong size where there are parameters.
  const Problem with = load_problem(WriteTempFile("bar.yaml", BarWithModulus()));
  Objective with_objective(with);
  EXPECT_THROW(minimize_reduced(with_objective, Vector::Ones(2), ReducedOptions()), std::invalid_argument);
}

}  // namespace
}  // namespace modalcal
