// "Safe on every input": hostile and broken inputs get exit code 2 and a short message naming
// the file, line or item and the likely cause; numerical failures exit 1 with the cause; no
// input file is ever overwritten. Each test reproduces one defect found by feeding the program
// such inputs.

#include <nlohmann/json.hpp>

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
#include "test_util.hpp"

namespace modalcal {
namespace {

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

// --- 2. hangs and resources: refused up front, with the estimate ---

TEST(HostileInputs, HugeRefinementIsRefusedBeforeMeshingWithTheEstimate) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  const CliRun run = RunCli("modes " + problem + " --refine 1e9");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "not enough memory for a mesh of about");
  EXPECT_CONTAINS(run.output, "GB and this machine has");
  EXPECT_CONTAINS(run.output, "--refine 1000000000");
  EXPECT_LT(run.output.size(), 400u) << run.output;
}

TEST(HostileInputs, TinyElementsAndHugeBoxesAreRefusedAsInput) {
  std::string fine = BarWithModulus();
  fine.replace(fine.find("element_size: 0.5"), 17, "element_size: 1.0e-7");
  CliRun run = RunCli("modes " + WriteTempFile("fine.yaml", fine));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "fine.yaml:4: mesh: not enough memory");
  EXPECT_CONTAINS(run.output, "use a larger element_size or a smaller refinement");
  std::string long_box = BarWithModulus();
  long_box.replace(long_box.find("max: [4, 0.5, 0.75]"), 19, "max: [1e12, 0.5, 0.75]");
  run = RunCli("modes " + WriteTempFile("long.yaml", long_box));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "not enough memory for a mesh of about");
}

TEST(HostileInputs, RefinementMustBeAPositiveFiniteNumber) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  for (const char* refine : {"nan", "0", "-1", "inf"}) {
    const CliRun run = RunCli("modes " + problem + " --refine " + refine);
    EXPECT_EQ(run.exit_code, 2) << refine << "\n" << run.output;
    EXPECT_CONTAINS(run.output, "--refine");
  }
  EXPECT_THROW(load_problem(problem, LoadOptions{std::nan("")}), std::invalid_argument);
  EXPECT_THROW(load_problem(problem, LoadOptions{-2}), std::invalid_argument);
}

TEST(HostileInputs, StartFactorsMustBePositiveFiniteWithAShortMessage) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  for (const char* factors : {"0 -1 nan", "nan", "-1"}) {
    const CliRun run = RunCli("study starts " + problem + " --factors " + factors);
    EXPECT_EQ(run.exit_code, 2) << factors << "\n" << run.output;
    EXPECT_CONTAINS(run.output, "--factors: '");
    // Not the largest double in 309 digits, as CLI11's own range check prints it.
    EXPECT_LT(run.output.size(), 120u) << run.output;
  }
}

TEST(HostileInputs, AbsurdNumberOfStartsIsRefusedBeforeAllocating) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  const CliRun run = RunCli("study full-vs-reduced " + problem + " --starts 1000000000");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "--starts");
}

TEST(HostileInputs, HugeProblemFileIsRefusedUpFront) {
  // A valid problem padded with a comment to 17 MB: refused by its size, before it is parsed.
  const std::string problem = WriteTempFile("huge.yaml", BarWithModulus() + "# " + std::string(17000000, 'x') + "\n");
  const CliRun run = RunCli("modes " + problem);
  EXPECT_EQ(run.exit_code, 2) << run.output.substr(0, 400);
  EXPECT_CONTAINS(run.output, "huge.yaml' has 17 MB; a problem file has at most 16 MB");
  EXPECT_LT(run.output.size(), 400u);
}

TEST(HostileInputs, DeviceAsExtendedFileIsRefusedWithTheLine) {
  const std::string problem = WriteTempFile("zero.yaml", "extends: /dev/zero\n" + BarWithModulus());
  const CliRun run = RunCli("modes " + problem);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "zero.yaml:1: extends '/dev/zero': '/dev/zero' is not a regular file");
}

// --- 3. no output replaces a file the run read ---

const char* const kModulus = "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5}\n";

TEST(HostileInputs, OutputsNeverReplaceAFileTheProblemWasReadFrom) {
  const std::string base = WriteTempFile("base.yaml", testing::CantileverBar());
  const std::string data = WriteTempFile("data.yaml", "modes:\n  - {frequency_hz: 1.0}\n  - {frequency_hz: 3.0}\n");
  const std::string report = WriteTempFile("report.json", R"({"parameters": [{"name": "E", "final": 900}]})");
  const std::string problem =
      WriteTempFile("problem.yaml", "extends: base.yaml\n" + std::string(kModulus) +
                                        "measured: {file: data.yaml}\noptions: {num_modes: 4}\n");
  for (const std::string& input : {problem, base, data, report}) {
    const std::string before = ReadFile(input);
    const CliRun run = RunCli("modes " + problem + " --params " + report + " --json " + input);
    EXPECT_EQ(run.exit_code, 2) << input << "\n" << run.output;
    EXPECT_CONTAINS(run.output, "refusing to write '" + input + "': it is an input");
    EXPECT_EQ(ReadFile(input), before) << input;
  }
  // A VTU set and a plot are outputs too.
  const std::string dir = std::filesystem::path(problem).parent_path().string();
  const std::string vtu_named_like_data = WriteTempFile("modes.pvd", "mine");
  const std::string named = WriteTempFile("named.yaml", "extends: base.yaml\n" + std::string(kModulus) +
                                                            "measured: {file: modes.pvd}\noptions: {num_modes: 4}\n");
  CliRun run = RunCli("modes " + named + " --vtu " + dir);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_EQ(ReadFile(vtu_named_like_data), "mine");
}

TEST(HostileInputs, CsvTablesNeverReplaceTheProblemsTestData) {
  std::string csv = "mode,frequency_hz,node,direction,value\n";
  for (int mode = 1; mode <= 2; ++mode)
    for (int node = 50; node <= 54; ++node)
      csv += std::to_string(mode) + "," + (mode == 1 ? "1.5" : "9.0") + "," + std::to_string(node) + ",y," +
             std::to_string(mode == 1 ? 0.1 * node : 0.2 * (52 - node)) + "\n";
  const std::string tables = WriteTempFile("run_modes.csv", csv);
  const std::string problem = WriteTempFile(
      "problem.yaml", testing::CantileverBar() + kModulus + "measured:\n  test_data: {file: run_modes.csv}\n");
  const std::string prefix = std::filesystem::path(problem).parent_path().string() + "/run";
  const CliRun run =
      RunCli("calibrate " + problem + " --method reduced-lbfgs --max-iterations 1 --quiet --csv " + prefix);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "refusing to write '" + tables + "': it is an input");
  EXPECT_EQ(ReadFile(tables), csv);
}

/// A Gmsh 2.2 mesh of one hex8 element [0,1]^3 in the physical volume "part", with its x = 0 face
/// in the physical surface "root"; `node_lines` replaces the $Nodes section's lines when given.
std::string OneHexMsh(const std::string& node_lines = "") {
  const std::string nodes =
      node_lines.empty() ? "1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n" : node_lines;
  return "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 1 \"root\"\n3 2 \"part\"\n$EndPhysicalNames\n"
         "$Nodes\n8\n" +
         nodes + "$EndNodes\n$Elements\n2\n1 3 2 1 1 1 4 8 5\n2 5 2 2 1 1 2 3 4 5 6 7 8\n$EndElements\n";
}

/// A problem on the mesh file `msh` (relative to the problem's folder).
std::string OneHexProblem(const std::string& msh) {
  return "mesh: {file: " + msh +
         "}\nblocks:\n  part: {E: 1000, nu: 0.3, density: 1}\nfixed:\n"
         "  - {node_set: root, dofs: [x, y, z]}\noptions: {num_modes: 3}\n";
}

TEST(HostileInputs, OutputsNeverReplaceTheMeshFile) {
  const std::string msh = WriteTempFile("part.msh", OneHexMsh());
  const std::string problem = WriteTempFile("part.yaml", OneHexProblem("part.msh"));
  const CliRun run = RunCli("modes " + problem + " --json " + msh);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "refusing to write '" + msh + "': it is an input");
  EXPECT_EQ(ReadFile(msh), OneHexMsh());
}

TEST(HostileInputs, OutputsToDevicesAreWrittenThroughThemAndDirectoriesRefused) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  CliRun run = RunCli("modes " + problem + " --json /dev/stdout");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "\"modes\": [");
  // Renaming a temporary file onto it would have replaced the device link with a regular file.
  EXPECT_TRUE(std::filesystem::is_symlink("/dev/stdout"));
  EXPECT_FALSE(std::filesystem::is_regular_file(std::filesystem::symlink_status("/dev/stdout")));
  run = RunCli("modes " + problem + " --json /dev/null");
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(std::filesystem::is_character_file("/dev/null"));
  run = RunCli("modes " + problem + " --json " + std::filesystem::path(problem).parent_path().string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "is a directory");
}

// --- 4. bad input exits with 2, whatever part of the program finds it ---

TEST(HostileInputs, EmptySetValueIsAnInputErrorNotAZeroModulus) {
  const CliRun run = RunCli("modes " + WriteTempFile("bar.yaml", BarWithModulus()) + " --set E=");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "--set E: no value after '='");
}

TEST(HostileInputs, SymbolicLinkLoopInExtendsIsAnInputError) {
  const std::string problem = WriteTempFile("problem.yaml", "extends: loop.yaml\n" + BarWithModulus());
  const std::filesystem::path loop = std::filesystem::path(problem).parent_path() / "loop.yaml";
  std::filesystem::remove(loop);
  std::filesystem::create_symlink("loop.yaml", loop);
  const CliRun run = RunCli("modes " + problem);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "problem.yaml:1: extends 'loop.yaml': cannot open the problem file");
  EXPECT_CONTAINS(run.output, "symbolic links");
}

TEST(HostileInputs, ParameterNameThatIsNotUtf8KeepsTheCalibrationResult) {
  std::string text = BarWithModulus();
  text.replace(text.find("  E: {targets"), 4, "  E\xff:");
  const std::string problem = WriteTempFile("latin1.yaml", text);
  const std::string json = WriteTempFile("report.json", "");
  const CliRun run =
      RunCli("calibrate " + problem + " --method reduced-lbfgs --max-iterations 3 --quiet --json " + json);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json report = nlohmann::json::parse(ReadFile(json));
  EXPECT_EQ(report["parameters"][0]["name"], "E\xEF\xBF\xBD");  // U+FFFD for the byte JSON cannot hold
}

TEST(HostileInputs, ModelsTheSolverCannotSolveAreNamedAtTheirSection) {
  const std::string msh = WriteTempFile("part.msh", OneHexMsh());
  std::string problem = OneHexProblem("part.msh");
  problem.replace(problem.find("num_modes: 3"), 12, "num_modes: 20");
  CliRun run = RunCli("modes " + WriteTempFile("many.yaml", problem));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output,
                  "many.yaml:6: options: num_modes 20 ask for 20 modes, but the model has only 12 free DOFs");
  problem = OneHexProblem("part.msh");
  problem.replace(problem.find("fixed:"), 6, "node_sets:\n  all: {box: {min: [0, 0, 0], max: [1, 1, 1]}}\nfixed:");
  problem.replace(problem.find("node_set: root"), 14, "node_set: all");
  run = RunCli("modes " + WriteTempFile("all_fixed.yaml", problem));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "all_fixed.yaml:6: fixed: the supports and couplings leave no degree of freedom free");
  run = RunCli("modes " + WriteTempFile("bar.yaml", BarWithModulus()) + " --num-modes 1000");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "--num-modes 1000: the model of");
}

// --- 5. messages name the cause, in the user's words, without echoing the input ---

TEST(HostileInputs, PoissonRatioNearOneHalfIsNamedAsTheCauseNotTheSupports) {
  const CliRun run =
      RunCli("modes " + WriteTempFile("bar.yaml", BarWithModulus()) + " --refine 2 --set bar.nu=0.4999999");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_CONTAINS(run.output,
                  "block 'bar' has Poisson's ratio 0.4999999, so near 0.5, which makes the material nearly "
                  "incompressible");
}

TEST(HostileInputs, GmshFaultsAreNamedByTheirCause) {
  std::string nodes = "1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n";
  const std::string full = OneHexMsh();
  struct Case {
    std::string msh, expected;
  };
  std::string duplicate = nodes, not_finite = nodes;
  duplicate.replace(duplicate.find("6 1 0 1"), 7, "5 1 0 1");
  not_finite.replace(not_finite.find("2 1 0 0"), 7, "2 nan 0 0");
  for (const Case& c : {Case{OneHexMsh(duplicate), "a node id is defined twice (node 5, at lines 15 and 16)"},
                        Case{OneHexMsh(not_finite), "node 2 has a coordinate that is not a finite number"},
                        Case{full.substr(0, full.size() * 2 / 3), "it is probably truncated"}}) {
    WriteTempFile("part.msh", c.msh);
    const CliRun run = RunCli("modes " + WriteTempFile("part.yaml", OneHexProblem("part.msh")));
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_CONTAINS(run.output, "part.yaml:1: mesh: ");
    EXPECT_CONTAINS(run.output, c.expected);
  }
}

TEST(HostileInputs, AbsurdMeasuredFrequencyIsRefusedAtItsLine) {
  std::string text = BarWithModulus();
  const std::string synthetic = "  synthetic: {modes: [1, 2], shapes: false}";
  text.replace(text.find(synthetic), synthetic.size(), "  modes: [{frequency_hz: 1.0e-300}]");
  const CliRun run = RunCli("calibrate " + WriteTempFile("tiny.yaml", text) + " --quiet");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output,
                  "tiny.yaml:17: measured mode 1: 'frequency_hz' is 1e-300: measured frequencies must lie between");
}

TEST(HostileInputs, MessagesNeverEchoMoreThanAnExcerptOfTheInput) {
  const std::string huge(2000000, 'x');
  // A whole file given as 'extends', a huge scalar where a name belongs, a 2 MB field in a
  // universal file, a 2 MB field in a test CSV.
  const std::string extends =
      WriteTempFile("extends.yaml", "extends: \"" + BarWithModulus() + huge + "\"\n" + BarWithModulus());
  std::string named = BarWithModulus();
  named.replace(named.find("  bar: {E"), 5, "  bar: {E: 1, nu: 0.3, density: 1, " + huge + ": 1}\n  bar2:");
  const std::string uff = WriteTempFile("field.uff", "    -1\n   164\n         1" + huge + "\n    -1\n");
  const std::string csv =
      WriteTempFile("field.csv", "mode,frequency_hz,node,direction,value\n1,2.0,3,x," + huge + "\n");
  for (const std::string& command : {"modes " + extends, "modes " + WriteTempFile("named.yaml", named),
                                     "import-test-data " + uff, "import-test-data " + csv}) {
    const CliRun run = RunCli(command);
    EXPECT_EQ(run.exit_code, 2) << run.output.substr(0, 300);
    EXPECT_LT(run.output.size(), 1200u) << run.output.substr(0, 300);
  }
}

TEST(HostileInputs, CsvWithTheByteOrderMarkExcelWritesIsRead) {
  const std::string csv =
      WriteTempFile("excel.csv", "\xEF\xBB\xBFmode,frequency_hz,node,direction,value\r\n1,2.5,3,x,1.0\r\n");
  const CliRun run = RunCli("import-test-data " + csv);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "modes: 1");
}

TEST(HostileInputs, DeepNestingIsNamedAsSuchNotABadFile) {
  const std::string problem =
      WriteTempFile("deep.yaml", "mesh: " + std::string(2000, '[') + std::string(2000, ']') + "\n");
  const CliRun run = RunCli("modes " + problem);
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "levels deep; a problem file needs a few");
}

TEST(HostileInputs, EmptyUniversalFileThroughAProblemNamesBothFiles) {
  WriteTempFile("empty.uff", "\n");
  const CliRun run = RunCli("modes " + WriteTempFile("problem.yaml", testing::CantileverBar() +
                                                                         "measured: {test_data: {file: empty.uff}}\n"));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "problem.yaml:14: ");
  EXPECT_CONTAINS(run.output, "empty.uff: no datasets found");
}

TEST(HostileInputs, TooManyModesForLanczosIsAnInputErrorNotSpectrasWords) {
  const CliRun run = RunCli("modes " + WriteTempFile("bar.yaml", BarWithModulus()) + " --refine 1.4 --num-modes 432");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "has 432 free DOFs, of which at most 431 modes can be found");
}

TEST(HostileInputs, UnwritableOutputDirectoryIsNamedBeforeTheStudyRuns) {
  const CliRun run =
      RunCli("study bounds-scaling " + WriteTempFile("bar.yaml", BarWithModulus()) + " --out /dev/null/x");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_CONTAINS(run.output, "--out /dev/null/x: cannot create the directory");
  EXPECT_FALSE(Contains(run.output, "filesystem error")) << run.output;
  EXPECT_FALSE(Contains(run.output, "L-BFGS")) << run.output;  // refused before the four runs
}

// --- 6. nothing wrong is accepted without a word ---

TEST(HostileInputs, WrongTypedSectionsOfAnExtendedFileAreRefusedInThatFile) {
  const std::string top = WriteTempFile("top.yaml", "extends: base.yaml\nname: top\n");
  for (const std::string& wrong : {"description: [1, 2]", "name: {a: 1}", "units: [1]"}) {
    WriteTempFile("base.yaml", wrong + "\n" + BarWithModulus());
    const CliRun run = RunCli("modes " + top);
    EXPECT_EQ(run.exit_code, 2) << wrong << "\n" << run.output;
    EXPECT_CONTAINS(run.output, "base.yaml:1: expected a text value for '");
  }
}

TEST(HostileInputs, StartOutsideTheBoundsIsRefusedNotClamped) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  for (const std::string& start : {"--set E=1e9", "--start-factor 1000"}) {
    const CliRun run = RunCli("calibrate " + problem + " --quiet " + start);
    EXPECT_EQ(run.exit_code, 2) << start << "\n" << run.output;
    EXPECT_CONTAINS(run.output, "the start of parameter 'E' (from --params, --set or --start-factor)");
    EXPECT_CONTAINS(run.output, "lies outside its bounds [10, 100000]");
  }
  EXPECT_EQ(RunCli("diagnose " + problem + " --quiet --set E=1").exit_code, 2);
  // Without bounds there is nothing to clamp to.
  EXPECT_EQ(RunCli("calibrate " + problem + " --quiet --method reduced-lbfgs --no-bounds --set E=1e6").exit_code, 0);
}

TEST(HostileInputs, ZeroIterationsOfTheFullSpaceMethodMakeNone) {
  const std::string problem = WriteTempFile("bar.yaml", BarWithModulus());
  const std::string json = WriteTempFile("report.json", "");
  const CliRun run = RunCli("calibrate " + problem + " --quiet --max-iterations 0 --json " + json);
  EXPECT_EQ(run.exit_code, 1) << run.output;  // no result: the start is not a minimum
  EXPECT_CONTAINS(run.output, "fullspace: MaxIterations");
  const nlohmann::json report = nlohmann::json::parse(ReadFile(json));
  EXPECT_EQ(report["status"], "MaxIterations");
  EXPECT_EQ(report["iterations"], 0);
  EXPECT_EQ(report["globalization_iterations"], 0);
  EXPECT_EQ(report["converged"], false);
  EXPECT_EQ(report["parameters"][0]["final"], 1000);
}

// --- 7. real test files ---

TEST(HostileInputs, BinaryFunctionDatasetIsSkippedByItsByteCount) {
  // An FRF in binary (58b) between two modes, its bytes holding line feeds and a "-1" line.
  const std::string binary = std::string("\x01\x02\n    -1\n\x00\xff", 12) + std::string(100, '\x7f') + "\n\xfe";
  char header[120];
  std::snprintf(header, sizeof header, "    -1\n    58b%6d%6d%12d%12zu%6d%6d%12d%12d\n", 1, 2, 11, binary.size(), 0, 0,
                0, 0);
  std::string frf = header;
  for (int k = 0; k < 11; ++k) frf += "NONE\n";
  frf += binary + "    -1\n";
  const std::string sample = testing::SourcePath("tests/data/uff/uff55_translation.uff");
  const std::string modes = ReadFile(sample);
  const size_t second = modes.find("    -1\n    -1\n") + 7;
  const TestData data =
      read_test_data(WriteTempFile("with_frf.uff", modes.substr(0, second) + frf + modes.substr(second)));
  const TestData plain = read_test_data(sample);
  ASSERT_EQ(data.modes.size(), plain.modes.size());
  const auto frf_entry =
      std::find_if(data.datasets.begin(), data.datasets.end(), [](const UffDatasetEntry& d) { return d.number == 58; });
  ASSERT_NE(frf_entry, data.datasets.end());
  EXPECT_FALSE(frf_entry->read);
  EXPECT_CONTAINS(frf_entry->note, std::to_string(binary.size()) + " bytes skipped");
  // The modes after it keep their lines as a text editor counts them.
  EXPECT_EQ(data.modes[1].line, plain.modes[1].line + static_cast<int>(std::count(frf.begin(), frf.end(), '\n')));
}

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
