// The robustness table: bad inputs, each run through the command-line program in a fresh folder,
// with the exit code and a part of the message it must give, and a check that no file the run
// was given changed. The same test renders the table as docs/robustness.md and fails when the
// file differs, so the document cannot drift from what the program does. Regenerate it with
//   MODALCAL_UPDATE_ROBUSTNESS_DOC=1 build/bin/modalcal_tests --gtest_filter='RobustnessTable.*'
//
// Exit codes (src/cli/main.cpp): 0 success, 1 numerical failure, 2 bad input.

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "test_util.hpp"

namespace modalcal {
namespace {

namespace fs = std::filesystem;
using testing::CliRun;
using testing::ReadFile;
using testing::RunCli;

/// Files of a row: name (relative to the row's folder) and content.
using Files = std::vector<std::pair<std::string, std::string>>;

struct Row {
  std::string id;       ///< short, unique: also the name of the row's folder
  std::string bad;      ///< what is bad, one line
  Files files;          ///< written into the row's fresh folder
  std::string args;     ///< fullspace_calib's arguments; <dir> is the row's folder
  int exit_code;        ///< expected
  std::string message;  ///< a part of the output it must contain; <dir> is the row's folder
  /// Optional: more preparation in the folder (links, folders), before the files are checksummed.
  std::function<void(const fs::path&)> prepare = nullptr;
  /// Optional: more checks after the run (an output's content, a device still a device).
  std::function<void(const fs::path&, const CliRun&)> check = nullptr;
  size_t max_output = 1200;  ///< most characters of a failing run's output from the message's line on
  std::vector<std::string> must_not_contain = {};  ///< e.g. a library's words the user should not see
};

// --- inputs ---

/// `text` with the first `from` replaced by `to`; throws if `from` is not in it (a row that no
/// longer makes the input it says it makes).
std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("row input: '" + from + "' not found");
  return text.replace(at, from.size(), to);
}

/// The cantilever bar (tests/test_util.cpp) with Young's modulus to calibrate against two
/// synthetic frequencies: a valid problem that rows spoil one way each.
std::string CrLineEnds(std::string text) {
  std::replace(text.begin(), text.end(), '\n', '\r');
  return text;
}

std::string Bar() {
  return testing::CantileverBar() +
         "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, truth: 1200}\n"
         "measured:\n  synthetic: {modes: [1, 2], shapes: false}\noptions: {num_modes: 4}\n";
}

/// The bar with two measured frequencies and no calibration parameters.
std::string BarWithoutParameters() {
  return testing::CantileverBar() +
         "measured:\n  modes: [{frequency_hz: 1.0}, {frequency_hz: 2.0}]\noptions: {num_modes: 4}\n";
}

/// The bar without parameters and measured modes: a model only.
std::string PlainBar() { return testing::CantileverBar() + "options: {num_modes: 4}\n"; }

const char* const kModulus = "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5}\n";

/// A Gmsh 2.2 mesh of one hex8 element [0,1]^3 in the physical volume "part", with its x = 0 face
/// in the physical surface "root"; `node_lines` replaces the $Nodes section's lines when given.
std::string OneHexMsh(const std::string& node_lines = "") {
  const std::string nodes =
      node_lines.empty() ? "1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n" : node_lines;
  return "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 1 \"root\"\n3 2 \"part\"\n$EndPhysicalNames\n"
         "$Nodes\n8\n" +
         nodes + "$EndNodes\n$Elements\n2\n1 3 2 1 1 1 4 8 5\n2 5 2 2 1 1 2 3 4 5 6 7 8\n$EndElements\n";
}

const char* const kHexNodes = "1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0 0 1\n6 1 0 1\n7 1 1 1\n8 0 1 1\n";

/// A problem on the mesh file `msh` (relative to the problem's folder).
std::string OneHexProblem(const std::string& msh, const std::string& extra_mesh_keys = "") {
  return "mesh: {file: " + msh + extra_mesh_keys +
         "}\nblocks:\n  part: {E: 1000, nu: 0.3, density: 1}\nfixed:\n"
         "  - {node_set: root, dofs: [x, y, z]}\noptions: {num_modes: 3}\n";
}

const char* const kCsvHeader = "mode,frequency_hz,node,direction,value\n";

/// Test data in CSV for the bar: two modes at five top-edge nodes in y.
std::string BarCsv() {
  std::string csv = kCsvHeader;
  for (int mode = 1; mode <= 2; ++mode)
    for (int node = 50; node <= 54; ++node)
      csv += std::to_string(mode) + "," + (mode == 1 ? "1.5" : "9.0") + "," + std::to_string(node) + ",y," +
             std::to_string(mode == 1 ? 0.1 * node : 0.2 * (52 - node)) + "\n";
  return csv;
}

/// An FRF in binary (58b), its bytes holding line feeds and a "-1" line: a whole dataset.
std::string BinaryFunctionDataset() {
  const std::string binary = std::string("\x01\x02\n    -1\n\x00\xff", 12) + std::string(100, '\x7f') + "\n\xfe";
  char header[120];
  std::snprintf(header, sizeof header, "    -1\n    58b%6d%6d%12d%12zu%6d%6d%12d%12d\n", 1, 2, 11, binary.size(), 0, 0,
                0, 0);
  std::string frf = header;
  for (int k = 0; k < 11; ++k) frf += "NONE\n";
  return frf + binary + "    -1\n";
}

/// tests/data/uff/uff55_translation.uff (modes at lines 2, 21 and 40) with that FRF between its
/// first two modes.
std::string UffWithBinaryFunction() {
  const std::string modes = ReadFile(testing::SourcePath("tests/data/uff/uff55_translation.uff"));
  const size_t second = modes.find("    -1\n    -1\n") + 7;
  return modes.substr(0, second) + BinaryFunctionDataset() + modes.substr(second);
}

/// The modes after the FRF keep their lines as a text editor counts them.
void ModesAfterTheFrfKeepTheirLines(const fs::path&, const CliRun& run) {
  const std::string frf = BinaryFunctionDataset();
  const long lines = std::count(frf.begin(), frf.end(), '\n');
  for (long line : {2L, 21 + lines, 40 + lines})
    EXPECT_NE(run.output.find("dataset 55, line " + std::to_string(line)), std::string::npos)
        << "no mode at line " << line << " in:\n"
        << run.output;
}

const std::string& Huge() {
  static const std::string huge(2000000, 'x');
  return huge;
}

/// `text` padded with a comment to 17 MB, one more than a YAML input may have.
std::string Padded(const std::string& text) { return text + "# " + std::string(17000000, 'x') + "\n"; }

void Symlink(const fs::path& dir, const std::string& target, const std::string& name) {
  fs::create_symlink(target, dir / name);
}

/// Checks that the report JSON `name` in the row's folder holds `key` == `value`.
std::function<void(const fs::path&, const CliRun&)> ReportHas(const std::string& name, const std::string& pointer,
                                                              const nlohmann::json& value) {
  return [=](const fs::path& dir, const CliRun&) {
    const std::string text = ReadFile((dir / name).string());
    ASSERT_TRUE(nlohmann::json::accept(text)) << name << ":\n" << text.substr(0, 300);
    EXPECT_EQ(nlohmann::json::parse(text).at(nlohmann::json::json_pointer(pointer)), value) << name << pointer;
  };
}

// --- the rows ---

std::vector<Row> Rows() {
  const std::string bare = BarWithoutParameters();
  const std::string empty_parameters = bare + "parameters: {}\n";
  const std::string base = testing::CantileverBar();
  const std::string csv = BarCsv();
  const std::string full_msh = OneHexMsh();
  const std::string uff = ReadFile(testing::SourcePath("tests/data/uff/uff55_translation.uff"));
  // A penalty far past where rounding decides: at 1e17 the modes' residuals came out near the
  // 1e-3 limit, above it with one OpenBLAS kernel and below with another.
  const std::string penalty_frame =
      Replace(ReadFile(testing::SourcePath("problems/portal-frame/frame.yaml")),
              "conn_1: {nodes: [conn_1_column, conn_1_beam], kx: 1.0e8", "conn_1: {nodes: [conn_1_column, conn_1_beam], kx: 1e20");
  std::string negative_uff = uff;  // its first mode at -10 Hz
  negative_uff.replace(negative_uff.find("\n  1.00000e+01  0.00000e+00"), 14, "\n -1.00000e+01");
  const std::string data_yaml = "modes:\n  - {frequency_hz: 1.0}\n  - {frequency_hz: 3.0}\n";
  const std::string report_json = R"({"parameters": [{"name": "E", "final": 900}]})";
  const std::string read_everything =
      "extends: base.yaml\n" + std::string(kModulus) + "measured: {file: data.yaml}\noptions: {num_modes: 4}\n";
  const Files everything = {
      {"base.yaml", base}, {"data.yaml", data_yaml}, {"report.json", report_json}, {"problem.yaml", read_everything}};
  const std::string modes_everything = "modes <dir>/problem.yaml --params <dir>/report.json --json ";
  auto device_untouched = [](const char* device) {
    return [device](const fs::path&, const CliRun&) {
      EXPECT_FALSE(fs::is_regular_file(fs::symlink_status(device))) << device << " was replaced by a regular file";
    };
  };

  // One row a few lines, in the order of the table.
  // clang-format off
  return {
      // --- no calibration parameters ---
      {"no-params-calibrate", "problem without a `parameters` section: calibrate", {{"bare.yaml", bare}},
       "calibrate <dir>/bare.yaml", 2, "no calibration parameters in <dir>/bare.yaml"},
      {"no-params-check", "problem without parameters: check-derivatives", {{"bare.yaml", bare}},
       "check-derivatives <dir>/bare.yaml", 2, "no calibration parameters in <dir>/bare.yaml"},
      {"no-params-diagnose", "problem without parameters: diagnose", {{"bare.yaml", bare}},
       "diagnose <dir>/bare.yaml", 2, "no calibration parameters in <dir>/bare.yaml"},
      {"study-starts-out", "`study starts --out DIR`: it writes no files there (only --json), so the option is not taken",
       {{"bar.yaml", Bar()}}, "study starts <dir>/bar.yaml --out <dir>/out", 2,
       "The following arguments were not expected: <dir>/out --out"},
      {"no-params-study-starts", "problem without parameters: study starts", {{"bare.yaml", bare}},
       "study starts <dir>/bare.yaml", 2, "no calibration parameters in <dir>/bare.yaml"},
      {"no-params-study-bounds", "problem without parameters: study bounds-scaling", {{"bare.yaml", bare}},
       "study bounds-scaling <dir>/bare.yaml --out <dir>/out", 2, "no calibration parameters in <dir>/bare.yaml"},
      {"no-params-study-fvr", "problem without parameters: study full-vs-reduced", {{"bare.yaml", bare}},
       "study full-vs-reduced <dir>/bare.yaml --starts 1 --out <dir>/out", 2,
       "no calibration parameters in <dir>/bare.yaml"},
      {"empty-params-fullspace", "`parameters: {}`: calibrate --method fullspace", {{"empty.yaml", empty_parameters}},
       "calibrate <dir>/empty.yaml --method fullspace", 2, "no calibration parameters in <dir>/empty.yaml"},
      {"empty-params-reduced", "`parameters: {}`: calibrate --method reduced-lbfgs",
       {{"empty.yaml", empty_parameters}}, "calibrate <dir>/empty.yaml --method reduced-lbfgs", 2,
       "no calibration parameters in <dir>/empty.yaml"},
      {"empty-params-diagnose", "`parameters: {}`: diagnose", {{"empty.yaml", empty_parameters}},
       "diagnose <dir>/empty.yaml", 2, "no calibration parameters in <dir>/empty.yaml"},

      // --- resources: refused up front, with the estimate ---
      {"refine-huge", "`--refine 1e9`: a mesh of 10^28 nodes", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --refine 1e9", 2, "use a smaller refinement (--refine 1000000000)", nullptr, nullptr,
       400},
      {"element-size-tiny", "`element_size: 1.0e-7` on a 4 m bar",
       {{"fine.yaml", Replace(Bar(), "element_size: 0.5", "element_size: 1.0e-7")}}, "modes <dir>/fine.yaml", 2,
       "fine.yaml:4: mesh: not enough memory"},
      {"box-1e12-long", "a box 1e12 long",
        {{"long.yaml", Replace(Bar(), "max: [4, 0.5, 0.75]", "max: [1e12, 0.5, 0.75]")}},
       "modes <dir>/long.yaml", 2, "not enough memory for a mesh of about"},
      {"starts-huge", "`--starts 1000000000`", {{"bar.yaml", Bar()}},
       "study full-vs-reduced <dir>/bar.yaml --starts 1000000000 --out <dir>/out", 2, "--starts"},
      {"problem-17mb", "problem file of 17 MB (a valid problem and a long comment)", {{"huge.yaml", Padded(Bar())}},
       "modes <dir>/huge.yaml", 2, "huge.yaml' has 17 MB; a problem file has at most 16 MB", nullptr, nullptr, 400},
      {"extends-17mb", "`extends:` a file of 17 MB",
       {{"big.yaml", Padded(base)}, {"problem.yaml", "extends: big.yaml\n" + std::string(kModulus)}},
       "modes <dir>/problem.yaml", 2, "big.yaml' has 17 MB; a problem file has at most 16 MB", nullptr, nullptr, 400},
      {"data-file-17mb", "`measured: {file:}` a data file of 17 MB",
       {{"base.yaml", base}, {"data.yaml", Padded(data_yaml)},
        {"problem.yaml", "extends: base.yaml\nmeasured: {file: data.yaml}\n"}},
       "modes <dir>/problem.yaml", 2, "data.yaml' has 17 MB; a data file has at most 16 MB", nullptr, nullptr, 400},
      {"extends-2mb-name", "`extends:` a 2 MB string (a whole file pasted as the name)",
       {{"extends.yaml", "extends: \"" + Bar() + Huge() + "\"\n" + Bar()}}, "modes <dir>/extends.yaml", 2,
       "extends.yaml:1: extends '"},
      {"element-2mb-value", "`element:` a 2 MB word",
        {{"named.yaml", Replace(Bar(), "element: hex8", "element: " + Huge())}},
       "modes <dir>/named.yaml", 2, "named.yaml:3: mesh: expected one of hex8, tet4, tet10 for 'element', got 'xxxx",
       nullptr, nullptr, 400},
      {"uff-2mb-field", "universal file with a 2 MB field",
       {{"field.uff", "    -1\n   164\n         1" + Huge() + "\n    -1\n"}}, "import-test-data <dir>/field.uff", 2,
       "field.uff:4: dataset 164: the dataset ends"},
      {"csv-2mb-field", "test CSV with a 2 MB value",
        {{"field.csv", kCsvHeader + std::string("1,2.0,3,x,") + Huge() + "\n"}},
       "import-test-data <dir>/field.csv", 2, "field.csv:2: value '"},

      // --- bad numbers on the command line ---
      {"refine-nan", "`--refine nan`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --refine nan", 2,
       "--refine: 'nan' is not a finite number"},
      {"refine-inf", "`--refine inf`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --refine inf", 2,
       "--refine: 'inf' is not a finite number"},
      {"refine-zero", "`--refine 0`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --refine 0", 2,
       "--refine: '0' must be positive"},
      {"refine-negative", "`--refine -1`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --refine -1", 2,
       "--refine: '-1' must be positive"},
      {"factors-mixed", "`--factors 0 -1 nan`", {{"bar.yaml", Bar()}},
       "study starts <dir>/bar.yaml --factors 0 -1 nan", 2, "--factors: '0' must be positive",
       nullptr, nullptr, 120},
      {"factors-nan", "`--factors nan`", {{"bar.yaml", Bar()}},
        "study starts <dir>/bar.yaml --factors nan",
       2, "--factors: 'nan' is not a finite number", nullptr, nullptr, 120},
      {"factors-negative", "`--factors -1`", {{"bar.yaml", Bar()}},
       "study starts <dir>/bar.yaml --factors -1", 2, "--factors: '-1' must be positive", nullptr,
       nullptr, 120},
      {"set-empty-value", "`--set E=` (no value)", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --set E=", 2,
       "--set E: no value after '='"},
      {"set-not-a-number", "`--set E=abc`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --set E=abc", 2,
       "--set E: 'abc' is not a finite number"},
      {"set-nan", "`--set E=nan`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --set E=nan", 2,
       "--set E: 'nan' is not a finite number"},
      {"set-no-equals", "`--set E` (no `=`)", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --set E", 2,
       "--set E: expected NAME=VALUE"},
      {"set-unknown-name", "`--set nosuch=1`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --set nosuch=1", 2,
       "--set nosuch: neither a parameter (E) nor a property the model has"},
      {"set-parameter-target", "`--set bar.E=5` where parameter E sets bar.E", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --set bar.E=5", 2, "this property is set by parameter 'E'; set that instead"},
      {"set-negative-modulus", "`--set bar.E=-5`: a negative Young's modulus", {{"plain.yaml", PlainBar()}},
       "modes <dir>/plain.yaml --set bar.E=-5", 2, "--set bar.E: E must be positive, got -5"},
      {"set-zero-modulus", "`--set bar.E=0`", {{"plain.yaml", PlainBar()}}, "modes <dir>/plain.yaml --set bar.E=0", 2,
       "--set bar.E: E must be positive, got 0"},
      {"set-negative-density", "`--set bar.density=-1`", {{"plain.yaml", PlainBar()}},
       "modes <dir>/plain.yaml --set bar.density=-1", 2, "--set bar.density: density must not be negative, got -1"},
      {"set-poisson-above-half", "`--set bar.nu=0.7` beside a parameter E: the property is named, not E",
       {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --set bar.nu=0.7", 2,
       "--set bar.nu: Poisson's ratio must lie in (-1, 0.5), got 0.7"},
      {"set-twice", "`--set E=1000 --set E=2000`: the second would silently win", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --set E=1000 --set E=2000", 2, "--set E is given twice"},
      {"set-negative-parameter", "`--set E=-5` where parameter E sets the modulus", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --set E=-5", 2,
       "parameter 'E' = -5 (from the problem, --params or --set) is not a value the model can take: property "
       "'bar.E': E must be positive, got -5"},
      {"num-modes-zero", "`--num-modes 0`", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --num-modes 0", 2,
       "--num-modes: '0' must be positive"},
      {"max-iterations-negative", "`--max-iterations -1`", {{"bar.yaml", Bar()}},
       "calibrate <dir>/bar.yaml --max-iterations -1", 2, "--max-iterations: '-1' must not be negative"},
      {"start-factor-nan", "`--start-factor nan`", {{"bar.yaml", Bar()}}, "calibrate <dir>/bar.yaml --start-factor nan",
       2, "--start-factor: 'nan' is not a finite number"},

      // --- the command line ---
      {"problem-missing", "problem file that does not exist", {}, "modes <dir>/nosuch.yaml", 2,
       "File does not exist: <dir>/nosuch.yaml"},
      {"problem-is-directory", "a directory given as the problem file", {}, "modes <dir>", 2,
       "File is actually a directory: <dir>"},
      {"unknown-command", "a command that does not exist", {{"bar.yaml", Bar()}}, "frobnicate <dir>/bar.yaml", 2,
       "unknown command 'frobnicate'"},
      {"unknown-option", "an option that does not exist", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --frobnicate", 2,
       "The following argument was not expected: --frobnicate"},
      {"params-missing", "`--params` a report that does not exist", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --params <dir>/nosuch.json", 2,
       "--params: cannot open the calibration report '<dir>/nosuch.json': no such file"},
      {"params-dev-zero", "`--params /dev/zero`: a device that never ends", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --params /dev/zero", 2,
       "--params: '/dev/zero' is not a regular file (a device, FIFO or socket)"},
      {"params-twice", "`--params` a report that lists a parameter twice",
       {{"bar.yaml", Bar()},
        {"report.json", R"({"parameters": [{"name": "E", "final": 900}, {"name": "E", "final": 1100}]})"}},
       "modes <dir>/bar.yaml --params <dir>/report.json", 2, "<dir>/report.json: parameter 'E' is listed twice"},
      {"option-nan", "`diagnose --mesh-check nan`", {{"bar.yaml", Bar()}}, "diagnose <dir>/bar.yaml --mesh-check nan",
       2, "--mesh-check: Value nan not in range 0 to 4"},
      {"synth-mode-beyond", "`synth --modes 1000` on a model with fewer DOFs", {{"bar.yaml", Bar()}},
       "synth <dir>/bar.yaml --modes 1000 -o <dir>/d.yaml", 2, "error: mode 1000 of the truth model: it has"},
      {"synth-truth-twice", "`synth --truth bar.density=2 --truth bar.density=3`", {{"bar.yaml", Bar()}},
       "synth <dir>/bar.yaml --truth bar.density=2 --truth bar.density=3 -o <dir>/d.yaml", 2,
       "change 'bar.density=3': bar.density is already set by change 'bar.density=2'; give each property once"},
      {"seed-negative", "`synth --seed -1`", {{"bar.yaml", Bar()}}, "synth <dir>/bar.yaml --seed -1 -o <dir>/d.yaml",
       2, "--seed: seed -1 is not an integer from 0 to 18446744073709551615"},
      {"localize-basis-huge", "`localize --basis-modes 2000` with 27 sensor readings",
       {{"bar.yaml", Replace(testing::SensedBar(), "scaling: log}", "scaling: log, truth: 1200}") +
                        "measured:\n  synthetic: {modes: [1, 2]}\n"}}, "localize <dir>/bar.yaml --basis-modes 2000", 2,
       "basis_modes = 2000 is more than the"},
      {"localize-regularization-huge", "`localize --regularization 1e308`: the value as given, not 309 digits",
       {{"bar.yaml", Bar()}}, "localize <dir>/bar.yaml --regularization 1e308", 2,
       "regularization = 1e+308: must be in [0, 1)"},
      {"campaign-merge-dev-zero", "`campaign --merge /dev/zero`", {{"bar.yaml", Bar()}},
       "campaign <dir>/bar.yaml --merge /dev/zero", 2, "campaign --merge: '/dev/zero' is not a regular file"},
      {"campaign-data-twice", "a campaign's data file given twice, once as `./`", {{"bar.yaml", Bar()}, {"t.yaml", "modes: []\n"}},
       "campaign <dir>/bar.yaml <dir>/t.yaml <dir>/./t.yaml", 2,
       "campaign: data file <dir>/./t.yaml is given twice (also as <dir>/t.yaml); each test counts once"},
      {"campaign-data-not-utf8", "a campaign's data file with a byte that is not UTF-8",
       {{"bar.yaml", Bar()}, {"test1.yaml", "modes: \xa6\n"}}, "campaign <dir>/bar.yaml <dir>/test1.yaml", 2,
       "expected a list for 'modes'", nullptr, nullptr, 1200, {"json.exception"}},
      {"params-not-json", "`--params` a file that is not JSON", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --params <dir>/bar.yaml", 2, "<dir>/bar.yaml: not valid JSON"},
      {"params-unknown-parameter", "`--params` a report of another problem's parameters",
       {{"bar.yaml", Bar()}, {"report.json", R"({"parameters": [{"name": "F", "final": 900}]})"}},
       "modes <dir>/bar.yaml --params <dir>/report.json", 2, "parameter 'F' is not in the problem <dir>/bar.yaml"},
      {"params-truth-missing", "`--params truth` for a problem without truth values",
       {{"bar.yaml", testing::CantileverBar() + kModulus}}, "modes <dir>/bar.yaml --params truth", 2,
       "--params truth: <dir>/bar.yaml does not give a truth value for every parameter"},
      {"non-utf8-file-name", "problem file whose name is not UTF-8 (Latin-1 `é`), with a misspelt key",
       {{"b\xe9r.yaml", Replace(Bar(), "options:", "optoins:")}}, "modes <dir>/b\xe9r.yaml", 2,
       "r.yaml:18: unknown key 'optoins'"},

      // --- extends ---
      {"extends-dev-zero", "`extends: /dev/zero`", {{"zero.yaml", "extends: /dev/zero\n" + Bar()}},
       "modes <dir>/zero.yaml", 2, "zero.yaml:1: extends '/dev/zero': '/dev/zero' is not a regular file"},
      {"extends-symlink-loop", "`extends:` a symbolic link to itself",
        {{"problem.yaml", "extends: loop.yaml\n" + Bar()}},
       "modes <dir>/problem.yaml", 2, "problem.yaml:1: extends 'loop.yaml': cannot open the problem file",
       [](const fs::path& dir) { Symlink(dir, "loop.yaml", "loop.yaml"); }},
      {"extends-missing", "`extends:` a file that does not exist", {{"problem.yaml", "extends: nosuch.yaml\n"}},
       "modes <dir>/problem.yaml", 2,
        "problem.yaml:1: extends 'nosuch.yaml': cannot open the problem file '<dir>/nosuch.yaml': no such file"},
      {"extends-itself", "a file that extends itself", {{"self.yaml", "extends: self.yaml\n"}}, "modes <dir>/self.yaml",
       2, "self.yaml:1: extends 'self.yaml', which is already in the chain of extended files"},
      {"extends-cycle", "two files that extend each other",
        {{"a.yaml", "extends: b.yaml\n"}, {"b.yaml", "extends: a.yaml\n"}},
       "modes <dir>/a.yaml", 2, "b.yaml:1: extends 'a.yaml', which is already in the chain of extended files"},
      {"extends-directory", "`extends:` a directory", {{"problem.yaml", "extends: sub\n"}}, "modes <dir>/problem.yaml",
        2,
       "problem.yaml:1: extends 'sub': '<dir>/sub' is a directory, not a problem file",
       [](const fs::path& dir) { fs::create_directory(dir / "sub"); }},
      {"extends-list", "`extends:` a list", {{"problem.yaml", "extends: [a.yaml, b.yaml]\n"}},
        "modes <dir>/problem.yaml",
       2, "problem.yaml:1: 'extends' must name a problem file, got a list of 2 items"},
      {"extends-typed-description", "an extended file's `description` is a list",
       {{"top.yaml", "extends: base.yaml\nname: top\n"}, {"base.yaml", "description: [1, 2]\n" + Bar()}},
       "modes <dir>/top.yaml", 2, "base.yaml:1: expected a text value for 'description'"},
      {"extends-typed-name", "an extended file's `name` is a map",
       {{"top.yaml", "extends: base.yaml\nname: top\n"}, {"base.yaml", "name: {a: 1}\n" + Bar()}},
       "modes <dir>/top.yaml", 2, "base.yaml:1: expected a text value for 'name'"},
      {"extends-typed-units", "an extended file's `units` is a list",
       {{"top.yaml", "extends: base.yaml\nname: top\n"}, {"base.yaml", "units: [1]\n" + Bar()}},
       "modes <dir>/top.yaml", 2, "base.yaml:1: expected a text value for 'units'"},

      // --- YAML ---
      {"yaml-empty", "an empty problem file", {{"empty.yaml", ""}}, "modes <dir>/empty.yaml", 2,
       "empty.yaml:1: expected a map of the problem's sections"},
      {"yaml-syntax", "an unclosed `[`", {{"open.yaml", "mesh: [\n"}}, "modes <dir>/open.yaml", 2,
       "open.yaml:2: YAML syntax error"},
      {"yaml-tab", "a tab as indentation", {{"tab.yaml", "mesh:\n\telement: hex8\n"}}, "modes <dir>/tab.yaml", 2,
       "tab.yaml:2: YAML syntax error"},
      {"yaml-deep-nesting", "lists nested 2000 levels deep",
       {{"deep.yaml", "mesh: " + std::string(2000, '[') + std::string(2000, ']') + "\n"}}, "modes <dir>/deep.yaml", 2,
       "levels deep; a problem file needs a few"},
      {"yaml-cr-line-ends", "classic-Mac CR line ends: read line by line, so line numbers hold",
       {{"cr.yaml", CrLineEnds(Replace(Bar(), "options:", "optoins:"))}}, "modes <dir>/cr.yaml", 2,
       "cr.yaml:18: unknown key 'optoins'; allowed keys:"},
      {"yaml-second-document", "a second YAML document after `---`",
       {{"two.yaml", Bar() + "---\noptions: {num_modes: 2}\n"}}, "modes <dir>/two.yaml", 2,
       "two.yaml:20: a second YAML document (after '---') starts here; a problem file is one document"},
      {"yaml-duplicate-section", "a section given twice", {{"dup.yaml", Bar() + "options: {num_modes: 2}\n"}},
       "modes <dir>/dup.yaml", 2, "dup.yaml:19: 'options' is given twice in the file's top level (first at line 18)"},
      {"yaml-empty-key", "a block named `''`",
       {{"e.yaml", "blocks:\n  '': {E: 1, nu: 0.3, density: 1}\nmesh: {element_size: 1, boxes: []}\n"}},
       "modes <dir>/e.yaml", 2, "e.yaml:2: an empty name as a key in 'blocks'"},
      {"extends-nul", "`extends: \"base.yaml\\0x\"`: a NUL inside the name",
       {{"base.yaml", Bar()}, {"top.yaml", "extends: \"base.yaml\\0x\"\n"}}, "modes <dir>/top.yaml", 2,
       "top.yaml:1: 'extends' holds a NUL character"},
      {"measured-modes-empty", "`measured: {modes: []}`", {{"m.yaml", Replace(Bar(), "synthetic: {modes: [1, 2], shapes: false}", "modes: []")}},
       "modes <dir>/m.yaml", 2, "m.yaml:17: measured: 'modes' is empty; list the measured modes"},
      {"number-beyond-double", "`density: 1e400`: named as beyond a double's range, not as no number",
       {{"big.yaml", Replace(Bar(), "density: 1.0", "density: 1e400")}}, "modes <dir>/big.yaml", 2,
       "big.yaml:7: block 'bar': 'density' = 1e400 lies beyond the range of a double"},
      {"number-huge", "`density: 1e300`: a double, but the assembly would overflow (was exit 1 \"ill-conditioned\")",
       {{"big.yaml", Replace(Bar(), "density: 1.0", "density: 1e300")}}, "modes <dir>/big.yaml", 2,
       "big.yaml:7: block 'bar': 'density' = 1e+300 is larger than any value a problem takes (at most 1e+100)"},
      {"weight-huge", "a measured mode's `weight: 1e308` (was exit 1, Restoration_Failed)",
       {{"w.yaml", Replace(BarWithoutParameters(), "{frequency_hz: 1.0}", "{frequency_hz: 1.0, weight: 1e308}")}},
       "modes <dir>/w.yaml", 2, "w.yaml:15: measured mode 1: 'weight' = 1e+308 is larger than any value a problem takes"},
      {"reference-node-unused", "a reference node nothing acts on (was \"node 55 DOF x has neither stiffness nor mass\", no file or line)",
       {{"r.yaml", PlainBar() + "reference_nodes:\n  hub: [0, 0, 2]\n"}}, "modes <dir>/r.yaml", 2,
       "r.yaml:16: reference node 'hub' is used by no rigid coupling, joint, spring, point mass or support"},
      {"set-subnormal", "`--set bar.nu=1e-320`: a subnormal is the tiny value it is, as in a problem file",
       {{"bar.yaml", PlainBar()}}, "modes <dir>/bar.yaml --set bar.nu=1e-320 --json <dir>/m.json", 0,
       "144 DOFs, 16 elements"},
      {"set-huge", "`--set bar.E=1e200`", {{"bar.yaml", PlainBar()}}, "modes <dir>/bar.yaml --set bar.E=1e200", 2,
       "--set bar.E: E = 1e+200 is larger than any value a problem takes (at most 1e+100)"},
      {"unknown-section", "a misspelt section (`optoins`)", {{"typo.yaml", Replace(Bar(), "options:", "optoins:")}},
       "modes <dir>/typo.yaml", 2, "typo.yaml:18: unknown key 'optoins'; allowed keys:"},
      {"unknown-block-key", "an unknown key in a block",
        {{"colour.yaml", Replace(Bar(), "density: 1.0", "density: 1.0, colour: red")}},
       "modes <dir>/colour.yaml", 2, "colour.yaml:7: block 'bar': unknown key 'colour'"},

      // --- the model ---
      {"element-size-zero", "`element_size: 0`",
        {{"zero.yaml", Replace(Bar(), "element_size: 0.5", "element_size: 0")}},
       "modes <dir>/zero.yaml", 2, "zero.yaml:4: mesh: 'element_size' must be positive, got 0"},
      {"element-type-unknown", "`element: hex27`", {{"hex27.yaml", Replace(Bar(), "element: hex8", "element: hex27")}},
       "modes <dir>/hex27.yaml", 2, "hex27.yaml:3: mesh: expected one of hex8, tet4, tet10 for 'element'"},
      {"box-inside-out", "a box whose max lies below its min",
       {{"box.yaml", Replace(Bar(), "max: [4, 0.5, 0.75]}]", "max: [-4, 0.5, 0.75]}]")}}, "modes <dir>/box.yaml", 2,
       "box.yaml:5: mesh box 1: min [0, 0, 0] must be below max [-4, 0.5, 0.75]"},
      {"modulus-negative", "`E: -1000`", {{"neg.yaml", Replace(Bar(), "E: 1000, nu", "E: -1000, nu")}},
       "modes <dir>/neg.yaml", 2, "neg.yaml:7: block 'bar': E must be positive, got -1000"},
      {"modulus-nan", "`E: .nan`", {{"nan.yaml", Replace(Bar(), "E: 1000, nu", "E: .nan, nu")}}, "modes <dir>/nan.yaml",
       2, "nan.yaml:7: block 'bar': 'E' is NaN; expected a finite number"},
      {"modulus-text", "`E: abc`", {{"abc.yaml", Replace(Bar(), "E: 1000, nu", "E: abc, nu")}}, "modes <dir>/abc.yaml",
       2, "abc.yaml:7: block 'bar': expected a number for 'E', got 'abc'"},
      {"density-negative", "`density: -1`", {{"neg.yaml", Replace(Bar(), "density: 1.0", "density: -1")}},
       "modes <dir>/neg.yaml", 2, "neg.yaml:7: block 'bar': density must not be negative, got -1"},
      {"poisson-half", "`nu: 0.5`", {{"half.yaml", Replace(Bar(), "nu: 0.3", "nu: 0.5")}}, "modes <dir>/half.yaml", 2,
       "half.yaml:7: block 'bar': Poisson's ratio must lie in (-1, 0.5), got 0.5"},
      {"poisson-0.4999999", "`--set bar.nu=0.4999999`: nearly incompressible", {{"plain.yaml", PlainBar()}},
       "modes <dir>/plain.yaml --refine 2 --set bar.nu=0.4999999", 1,
       "block 'bar' has Poisson's ratio 0.4999999, so near 0.5, which makes the material nearly incompressible"},
      {"target-unknown-property", "a parameter targets `bar.Q`",
        {{"q.yaml", Replace(Bar(), "targets: [bar.E]", "targets: [bar.Q]")}},
       "modes <dir>/q.yaml", 2, "q.yaml:15: parameter 'E': block 'bar' has no property 'Q'"},
      {"target-unknown-entity", "a parameter targets `nobar.E`",
       {{"nobar.yaml", Replace(Bar(), "targets: [bar.E]", "targets: [nobar.E]")}}, "modes <dir>/nobar.yaml", 2,
       "nobar.yaml:15: parameter 'E': unknown entity 'nobar' in target 'nobar.E'"},
      {"bounds-reversed", "`lower` above `upper`",
        {{"lu.yaml", Replace(Bar(), "lower: 10, upper: 1e5", "lower: 1e5, upper: 10")}},
       "calibrate <dir>/lu.yaml", 2, "lu.yaml:15: parameter 'E': lower bound 100000 must be below the upper bound 10"},
      {"bound-outside-physics", "`lower: -10` for a Young's modulus",
        {{"neg.yaml", Replace(Bar(), "lower: 10, upper: 1e5", "lower: -10, upper: 1e5")}},
       "calibrate <dir>/neg.yaml", 2,
        "neg.yaml:15: parameter 'E': lower bound -10 is outside the range of 'bar.E': E must be positive, got -10"},
      {"initial-outside-bounds", "`initial` above `upper`",
        {{"init.yaml", Replace(Bar(), "initial: 1000", "initial: 1e7")}},
       "calibrate <dir>/init.yaml", 2,
        "init.yaml:15: parameter 'E': 'initial' 10000000 is outside the bounds [10, 100000]"},
      {"fixed-unknown-node-set", "`fixed:` names a node set that does not exist",
       {{"ns.yaml", Replace(Bar(), "node_set: root", "node_set: rooot")}}, "modes <dir>/ns.yaml", 2,
       "ns.yaml:13: fixed 1: unknown node set 'rooot'; known node sets: root, tip, top_edge"},
      {"fixed-bad-dof", "`dofs: [x, y, w]`", {{"dof.yaml", Replace(Bar(), "dofs: [x, y, z]", "dofs: [x, y, w]")}},
       "modes <dir>/dof.yaml", 2, "dof.yaml:13: fixed 1: expected one of x, y, z, rx, ry, rz for item 3 of 'dofs'"},
      {"num-modes-negative", "`num_modes: -4`", {{"nm.yaml", Replace(Bar(), "num_modes: 4", "num_modes: -4")}},
       "modes <dir>/nm.yaml", 2, "nm.yaml:18: options: 'num_modes' must be at least 1, got -4"},
      {"num-modes-beyond-int", "`num_modes: 2147483648`",
       {{"big.yaml", Replace(Bar(), "num_modes: 4", "num_modes: 2147483648")}}, "modes <dir>/big.yaml", 2,
       "big.yaml:18: options: 'num_modes' must be at most 2147483647, got 2147483648"},
      {"sensors-all-fixed", "every sensor on the clamped root: the model's shapes are zero there",
       {{"s.yaml", Bar() + "sensors:\n  - {node_set: root, directions: [x]}\n"}}, "modes <dir>/s.yaml", 2,
       "s.yaml:19: every sensor reads a fixed DOF (node 1 +x is fixed by 'root', and so on)"},
      {"sensors-some-fixed", "sensors on the clamped root and at the tip: the root's read zero in the model",
       {{"s.yaml", Bar() + "sensors:\n  - {node_set: root, directions: [x]}\n  - {node_set: tip, directions: [y]}\n"}},
       "modes <dir>/s.yaml", 0, "s.yaml:19: 6 of 12 sensors read a fixed DOF (node 1 +x is fixed by 'root', and so on)"},
      {"sensor-unknown-node", "a sensor on node 99999",
        {{"base.yaml", base}, {"s.yaml", "extends: base.yaml\nsensors:\n  - {node: 99999, directions: [x]}\n"}},
       "modes <dir>/s.yaml", 2, "s.yaml:3: sensor 1: there is no node with id 99999; mesh nodes are 1..54"},
      {"sensor-far-point", "a sensor at a point 96 away from the model",
       {{"base.yaml", base}, {"s.yaml", "extends: base.yaml\nsensors:\n  - {at: [100, 0, 0], directions: [x]}\n"}},
       "modes <dir>/s.yaml", 2, "s.yaml:3: sensor 1: no node within"},

      // --- mesh files ---
      {"gmsh-duplicate-node", "Gmsh file defining node 5 twice",
       {{"part.msh", OneHexMsh(Replace(kHexNodes, "6 1 0 1", "5 1 0 1"))}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "a node id is defined twice (node 5, at lines"},
      {"gmsh-node-beyond-int", "Gmsh node number 2^32 + 8 (Gmsh's MSH 2 reader would wrap it onto node 8)",
       {{"part.msh", OneHexMsh(Replace(kHexNodes, "8 0 1 1", "4294967304 0 1 1"))}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "node number 4294967304 is above 2147483647"},
      {"gmsh-duplicate-element", "Gmsh file defining element 1 twice (Gmsh would drop one)",
       {{"part.msh", Replace(OneHexMsh(), "2 5 2 2 1", "1 5 2 2 1")}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "an element id is defined twice (element 1, at lines"},
      {"gmsh-element-twice", "Gmsh file listing the hex8 twice under two numbers",
       {{"part.msh", Replace(Replace(OneHexMsh(), "$Elements\n2\n", "$Elements\n3\n"), "$EndElements",
                             "3 5 2 2 1 1 2 3 4 5 6 7 8\n$EndElements")},
        {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "elements 2 and 3 have the same nodes: that part would count twice"},
      {"gmsh-nan-coordinate", "Gmsh node with a NaN coordinate",
       {{"part.msh", OneHexMsh(Replace(kHexNodes, "2 1 0 0", "2 nan 0 0"))}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "node 2 has a coordinate that is not a finite number"},
      {"gmsh-truncated", "Gmsh file cut after two thirds",
       {{"part.msh", full_msh.substr(0, full_msh.size() * 2 / 3)}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "it is probably truncated"},
      {"gmsh-empty", "an empty .msh file", {{"part.msh", ""}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2,
        "part.msh: is not a Gmsh mesh file: it does not start with $MeshFormat (it is empty)"},
      {"gmsh-no-elements", "a .msh file with a header only",
       {{"part.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml", 2, "part.msh: has no elements; was the geometry meshed (gmsh -3)?"},
      {"mesh-missing", "`mesh: {file:}` a file that does not exist", {{"part.yaml", OneHexProblem("nosuch.msh")}},
       "modes <dir>/part.yaml", 2, "part.yaml:1: mesh: <dir>/nosuch.msh: no such mesh file"},
      {"mesh-geo-script", "`mesh: {file:}` a Gmsh .geo script",
       {{"part.geo", "Point(1) = {0, 0, 0};\n"}, {"part.yaml", OneHexProblem("part.geo")}}, "modes <dir>/part.yaml", 2,
       "cannot tell the mesh format from the extension '.geo'"},
      {"mesh-directory", "`mesh: {file:}` a directory", {{"part.yaml", OneHexProblem("dir.msh")}},
       "modes <dir>/part.yaml", 2, "part.yaml:1: mesh: <dir>/dir.msh: is a directory, not a mesh file",
       [](const fs::path& dir) { fs::create_directory(dir / "dir.msh"); }},
      {"mesh-device", "`mesh: {file: /dev/zero, format: gmsh}`",
        {{"part.yaml", OneHexProblem("/dev/zero", ", format: gmsh")}},
       "modes <dir>/part.yaml", 2, "part.yaml:1: mesh: /dev/zero: is not a regular file (a device, FIFO or socket)"},
      {"mesh-symlink-loop", "`mesh: {file:}` a symbolic link to itself", {{"part.yaml", OneHexProblem("loop.msh")}},
       "modes <dir>/part.yaml", 2,
        "part.yaml:1: mesh: <dir>/loop.msh: cannot open the mesh file: Too many levels of symbolic links",
       [](const fs::path& dir) { Symlink(dir, "loop.msh", "loop.msh"); }},
      {"mesh-refine", "`--refine` with a mesh file", {{"part.msh", full_msh}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml --refine 2", 2, "refinement (--refine) applies only to a generated mesh"},
      {"num-modes-above-dofs", "`num_modes: 20` on a model with 12 free DOFs",
       {{"part.msh", full_msh}, {"many.yaml", Replace(OneHexProblem("part.msh"), "num_modes: 3", "num_modes: 20")}},
       "modes <dir>/many.yaml", 2,
        "many.yaml:6: options: num_modes 20 ask for 20 modes, but the model has only 12 free DOFs"},
      {"all-dofs-fixed", "supports that fix every DOF",
       {{"part.msh", full_msh},
        {"all.yaml", Replace(Replace(OneHexProblem("part.msh"), "node_set: root", "node_set: all"), "fixed:",
                             "node_sets:\n  all: {box: {min: [0, 0, 0], max: [1, 1, 1]}}\nfixed:")}},
       "modes <dir>/all.yaml", 2, "all.yaml:6: fixed: the supports and couplings leave no degree of freedom free"},
      {"num-modes-1000", "`--num-modes 1000` on a model with 144 DOFs", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --num-modes 1000", 2, "--num-modes 1000: the model of <dir>/bar.yaml has 144 free DOFs"},
      {"num-modes-all-dofs", "`--num-modes` equal to the DOF count (432)", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --refine 1.4 --num-modes 432", 2,
        "has 432 free DOFs, of which at most 431 modes can be found"},

      // --- measured data ---
      {"frequency-1e-300", "a measured frequency of 1e-300 Hz",
       {{"tiny.yaml",
        Replace(Bar(), "  synthetic: {modes: [1, 2], shapes: false}", "  modes: [{frequency_hz: 1.0e-300}]")}},
       "calibrate <dir>/tiny.yaml --quiet", 2,
       "tiny.yaml:17: measured mode 1: 'frequency_hz' is 1e-300: measured frequencies must lie between"},
      {"frequency-negative", "a measured frequency of -3 Hz",
       {{"neg.yaml", Replace(Bar(), "  synthetic: {modes: [1, 2], shapes: false}", "  modes: [{frequency_hz: -3}]")}},
       "modes <dir>/neg.yaml", 2,
        "neg.yaml:17: measured mode 1: 'frequency_hz' is -3: measured frequencies must be positive"},
      {"shape-length", "a measured shape with 2 values and no sensors",
       {{"shape.yaml",
        Replace(Bar(), "  synthetic: {modes: [1, 2], shapes: false}", "  modes: [{frequency_hz: 3, shape: [1, 2]}]")}},
       "modes <dir>/shape.yaml", 2,
        "shape.yaml:17: measured mode 1: 'shape' has 2 values but the sensors measure 0 DOFs"},
      {"pair-model-mode-zero", "`pair: {model_mode: 0}`",
       {{"pair.yaml",
        Replace(Bar(), "  synthetic: {modes: [1, 2], shapes: false}",
        "  modes: [{frequency_hz: 3, pair: {model_mode: 0}}]")}},
       "modes <dir>/pair.yaml", 2, "pair.yaml:17: measured mode 1: 'model_mode' must be at least 1, got 0"},
      {"pair-model-mode-twice", "two measured modes paired with model mode 1",
       {{"pair.yaml",
        Replace(Bar(), "  synthetic: {modes: [1, 2], shapes: false}",
        "  modes:\n    - {frequency_hz: 3, pair: {model_mode: 1}}\n    - {frequency_hz: 4, pair: {model_mode: 1}}")}},
       "modes <dir>/pair.yaml", 2,
       "pair.yaml:19: measured mode 2: pairs with model mode 1, as measured mode 1 (line 18) does"},
      {"mode-pasted-twice", "a measured mode listed twice: the same frequency and shape",
       {{"dup.yaml",
        Replace(Bar(), "  synthetic: {modes: [1, 2], shapes: false}",
                "  modes:\n    - {frequency_hz: 3, shape: [1, 2, 3, 4, 5, 6]}\n"
                "    - {frequency_hz: 3, shape: [1, 2, 3, 4, 5, 6]}") +
            "sensors:\n  - {node_set: tip, directions: [y]}\n"}},
       "modes <dir>/dup.yaml", 2, "dup.yaml:19: measured mode 2: repeats measured mode 1 (line 18)"},
      {"add-twice", "`--add` naming one effect twice", {{"bar.yaml", Bar()}},
       "calibrate <dir>/bar.yaml --add support@root:kx --add support@root:kx", 2,
       "error: --add: effect 'support@root:kx' is support_root.kx, which the problem's enabled effects or an earlier --add already add"},
      {"add-point-far", "`--add` at a point 1e200 m away: every distance overflows",
       {{"bar.yaml", Bar()}}, "calibrate <dir>/bar.yaml --add point_mass@[1e200,0,0]:mass", 2,
       "the point [1e+200,0,0] lies too far from the model for any node to be nearest"},
      {"synthetic-mode-above", "`synthetic: {modes: [1, 99]}` with num_modes 4",
       {{"syn.yaml", Replace(Bar(), "modes: [1, 2]", "modes: [1, 99]")}}, "modes <dir>/syn.yaml", 2,
       "syn.yaml:17: measured synthetic: refers to elastic mode 99 but options.num_modes is 4"},
      {"effect-bound-outside", "an effect whose upper bound is a negative mass",
       {{"bar.yaml", Bar() + "effects:\n  - {effect: \"point_mass@tip:mass\", upper: -1}\n"}}, "modes <dir>/bar.yaml",
       2, "bar.yaml:20: effect 1: upper -1 is outside the range of 'point_mass@tip:mass'"},
      {"massless-block-point-mass", "`density: 0` and one point mass: 3 masses for 4 modes",
       {{"rho.yaml", Replace(PlainBar(), "density: 1.0", "density: 0") + "point_masses:\n  m: {node: 54, mass: 0.2}\n"}},
       "modes <dir>/rho.yaml", 1, "elastic mode 4 is no eigenpair"},
      {"joint-penalty", "the portal frame with one joint's kx 1e20, a penalty 1e12 times its 1e8",
       {{"frame.yaml", penalty_frame}}, "modes <dir>/frame.yaml", 1,
       "times its median one. Likely causes: a joint or spring stiffness used as a penalty"},
      {"synthetic-zero-mass", "`density: 0`: the truth model has no mass",
       {{"rho.yaml", Replace(Bar(), "density: 1.0", "density: 0")}}, "modes <dir>/rho.yaml", 2,
       "rho.yaml:17: measured.synthetic: the truth model's modal solve failed"},

      // --- test data (universal files and CSV) ---
      {"uff-empty-in-problem", "a problem's test data is an empty universal file",
       {{"empty.uff", "\n"}, {"problem.yaml", base + "measured: {test_data: {file: empty.uff}}\n"}},
       "modes <dir>/problem.yaml", 2, "empty.uff: no datasets found"},
      {"uff-empty", "an empty universal file", {{"empty.uff", ""}}, "import-test-data <dir>/empty.uff", 2,
       "empty.uff: no datasets found"},
      {"uff-truncated", "a dataset without its closing `-1`", {{"cut.uff", "    -1\n   164\n"}},
       "import-test-data <dir>/cut.uff", 2, "cut.uff:2: dataset 164 starting here has no closing '-1' line"},
      {"uff-no-dataset", "a universal file that is text", {{"text.uff", "hello\n"}}, "import-test-data <dir>/text.uff",
        2,
       "text.uff:1: expected '-1', which opens a dataset, found 'hello'"},
      {"uff-binary-58b", "a binary function (58b) between two modes: skipped by its byte count",
       {{"frf.uff", UffWithBinaryFunction()}}, "import-test-data <dir>/frf.uff", 0, "bytes skipped", nullptr,
       ModesAfterTheFrfKeepTheirLines},
      {"uff-negative-frequency", "a universal file's mode at -10 Hz: listed, with a warning",
       {{"negative.uff", negative_uff}}, "import-test-data <dir>/negative.uff", 0,
       "warning: mode 1 (line 2): -10 Hz: measured frequencies must be positive; a problem cannot select it"},
      {"uff-device", "`/dev/zero` as test data", {}, "import-test-data /dev/zero", 2,
       "'/dev/zero' is not a regular file (a device, FIFO or socket) and cannot be a test-data file"},
      {"test-data-missing", "test data that does not exist", {}, "import-test-data <dir>/nosuch.uff", 2,
       "File does not exist: <dir>/nosuch.uff"},
      {"length-unit-unknown", "`length_unit: furlong`",
       {{"u.uff", uff}, {"problem.yaml", base + "measured:\n  test_data: {file: u.uff, length_unit: furlong}\n"}},
       "modes <dir>/problem.yaml", 2, "problem.yaml:15: measured test_data: unknown length unit 'furlong'"},
      {"scale-length-negative", "`scale_length: -1`",
       {{"u.uff", uff}, {"problem.yaml", base + "measured:\n  test_data: {file: u.uff, scale_length: -1}\n"}},
       "modes <dir>/problem.yaml", 2, "problem.yaml:15: measured test_data: 'scale_length' must be positive, got -1"},
      {"uff-node-huge", "a universal file's node number 99999999999 (was printed as 99999999999.000000)",
       {{"big.uff", Replace(uff, "\n         1\n -1.46518e+00", "\n99999999999\n -1.46518e+00")}},
       "import-test-data <dir>/big.uff", 2, "big.uff:11: dataset 55: node number: 99999999999 is too large"},
      {"uff-cr-line-ends", "a universal file with classic-Mac CR line ends: read line by line",
       {{"cr.uff", CrLineEnds(uff)}}, "import-test-data <dir>/cr.uff", 0, "dataset 55, line 21"},
      {"csv-bom", "a CSV with the UTF-8 byte-order mark and CRLF lines (as Excel writes)",
       {{"excel.csv", "\xEF\xBB\xBF" "mode,frequency_hz,node,direction,value\r\n1,2.5,3,x,1.0\r\n"}},
       "import-test-data <dir>/excel.csv", 0, "modes: 1"},
      {"csv-columns", "a CSV row with 4 fields", {{"short.csv", kCsvHeader + std::string("1,2.0,3,x\n")}},
       "import-test-data <dir>/short.csv", 2, "short.csv:2: expected 5 comma-separated fields"},
      {"csv-direction", "a CSV direction `w`", {{"w.csv", kCsvHeader + std::string("1,2.0,3,w,1\n")}},
       "import-test-data <dir>/w.csv", 2, "w.csv:2: direction 'w' is not one of x, y, z, rx, ry, rz"},
      {"csv-frequency-text", "a CSV frequency `abc`", {{"f.csv", kCsvHeader + std::string("1,abc,3,x,1\n")}},
       "import-test-data <dir>/f.csv", 2, "f.csv:2: frequency_hz 'abc' is not a finite number"},
      {"csv-value-nan", "a CSV value `nan`", {{"v.csv", kCsvHeader + std::string("1,2.0,3,x,nan\n")}},
       "import-test-data <dir>/v.csv", 2, "v.csv:2: value 'nan' is not a finite number"},
      {"csv-header", "a CSV with another header", {{"h.csv", "mode,freq,node,direction,value\n1,2,3,x,1\n"}},
       "import-test-data <dir>/h.csv", 2, "h.csv:1: expected the header line 'mode,frequency_hz,node,direction,value'"},
      {"csv-empty", "an empty CSV", {{"e.csv", ""}}, "import-test-data <dir>/e.csv", 2, "e.csv: the file is empty"},
      {"csv-two-frequencies", "a CSV mode with two frequencies",
       {{"two.csv", kCsvHeader + std::string("1,2.0,3,x,1\n1,3.0,3,y,1\n")}}, "import-test-data <dir>/two.csv", 2,
       "two.csv:3: mode 1 has frequency 3.0 Hz here but 2 Hz at line 2"},
      {"csv-mode-beyond-int", "a CSV mode number of 2^31",
       {{"big.csv", kCsvHeader + std::string("2147483648,2.0,3,x,1\n")}},
       "import-test-data <dir>/big.csv", 2, "big.csv:2: mode 2147483648 is outside the range of mode numbers, ±2147483647"},
      {"csv-duplicate", "a CSV value given twice",
        {{"dup.csv", kCsvHeader + std::string("1,2.0,3,x,1\n1,2.0,3,x,2\n")}},
       "import-test-data <dir>/dup.csv", 2, "dup.csv:3: mode 1, node 3, direction x is given twice (first at line 2)"},

      // --- outputs never replace an input ---
      {"json-over-problem", "`--json` names the problem file", everything, modes_everything + "<dir>/problem.yaml", 2,
       "refusing to write '<dir>/problem.yaml': it is an input"},
      {"json-over-extended", "`--json` names the file the problem `extends:`", everything,
       modes_everything + "<dir>/base.yaml", 2, "refusing to write '<dir>/base.yaml': it is an input"},
      {"json-over-data", "`--json` names the measured data file", everything, modes_everything + "<dir>/data.yaml", 2,
       "refusing to write '<dir>/data.yaml': it is an input"},
      {"json-over-params", "`--json` names the `--params` report", everything, modes_everything + "<dir>/report.json",
       2, "refusing to write '<dir>/report.json': it is an input"},
      {"json-over-mesh", "`--json` names the mesh file",
        {{"part.msh", full_msh}, {"part.yaml", OneHexProblem("part.msh")}},
       "modes <dir>/part.yaml --json <dir>/part.msh", 2, "refusing to write '<dir>/part.msh': it is an input"},
      {"json-over-uff", "`--json` names the universal file of the test data",
       {{"u.uff", uff}, {"problem.yaml", base + "measured: {test_data: {file: u.uff}}\n"}},
       "modes <dir>/problem.yaml --json <dir>/u.uff", 2, "refusing to write '<dir>/u.uff': it is an input"},
      {"csv-prefix-over-test-data", "`--csv run` would write run_modes.csv, the test data",
       {{"run_modes.csv", csv}, {"problem.yaml", base + kModulus + "measured:\n  test_data: {file: run_modes.csv}\n"}},
       "calibrate <dir>/problem.yaml --method reduced-lbfgs --max-iterations 1 --quiet --csv <dir>/run", 2,
       "refusing to write '<dir>/run_modes.csv': it is an input"},
      {"vtu-over-data", "`--vtu` would write modes.pvd, the measured data file",
       {{"base.yaml", base}, {"modes.pvd", data_yaml},
        {"named.yaml",
        "extends: base.yaml\n" + std::string(kModulus) + "measured: {file: modes.pvd}\noptions: {num_modes: 4}\n"}},
       "modes <dir>/named.yaml --vtu <dir>", 2, "refusing to write '<dir>/modes.pvd': it is an input"},
      {"plot-over-problem", "`--history-plot` names the problem file (here named bar.png)", {{"bar.png", Bar()}},
       "calibrate <dir>/bar.png --quiet --history-plot <dir>/bar.png", 2,
        "refusing to write '<dir>/bar.png': it is an input"},
      {"uncertainty-plot-extension", "`--uncertainty-plot` names the problem file (not a .png or .svg)",
       {{"bar.yaml", Bar()}}, "calibrate <dir>/bar.yaml --quiet --uncertainty-plot <dir>/bar.yaml", 2,
       "--uncertainty-plot <dir>/bar.yaml: the file name must end in .png or .svg"},
      {"two-outputs-one-file", "`compare --mac-plot a.png --error-plot a.png`: one would be lost",
       {{"bar.yaml", Bar()}}, "compare <dir>/bar.yaml --mac-plot <dir>/a.png --error-plot <dir>/./a.png", 2,
       "--mac-plot and --error-plot both name '<dir>/./a.png': one would overwrite the other"},
      {"csv-table-over-json", "`calibrate --json run_modes.csv --csv run`: a CSV table would replace the JSON",
       {{"bar.yaml", Bar()}}, "calibrate <dir>/bar.yaml --json <dir>/run_modes.csv --csv <dir>/run", 2,
       "--json and --csv both name '<dir>/run_modes.csv': one would overwrite the other"},
      {"plot-extension", "`compare --error-plot e.txt`: refused before the run, not after",
       {{"bar.yaml", Bar()}}, "compare <dir>/bar.yaml --error-plot <dir>/e.txt", 2,
       "--error-plot: the file name must end in .png or .svg"},
      {"campaign-json-over-data", "`campaign --json` names one of its data files",
       {{"base.yaml", base + kModulus}, {"data.yaml", data_yaml}},
       "campaign <dir>/base.yaml <dir>/data.yaml --json <dir>/data.yaml", 2,
       "refusing to write '<dir>/data.yaml': it is an input"},
      {"campaign-empty-folder", "`campaign` given a folder with no data file", {{"base.yaml", base + kModulus}},
       "campaign <dir>/base.yaml <dir>/empty", 2, "campaign: folder <dir>/empty holds no .yaml data file",
       [](const fs::path& dir) { fs::create_directory(dir / "empty"); }},
      {"campaign-nothing-usable", "`campaign` whose only data file does not parse",
       {{"base.yaml", base + kModulus}, {"data.yaml", "modes: [oops\n"}}, "campaign <dir>/base.yaml <dir>/data.yaml", 2,
       "no data set could be calibrated"},
      {"output-folder-missing", "`synth -o` into a folder that does not exist", {{"bar.yaml", Bar()}},
       "synth <dir>/bar.yaml --modes 1 -o <dir>/nosuch/data.yaml", 2,
       "cannot write '<dir>/nosuch/data.yaml': directory '<dir>/nosuch' does not exist; create it first"},
      {"json-folder-missing", "`calibrate --json` into a folder that does not exist: refused before the run",
       {{"bar.yaml", Bar()}}, "calibrate <dir>/bar.yaml --quiet --json <dir>/nosuch/report.json", 2,
       "cannot write '<dir>/nosuch/report.json': directory '<dir>/nosuch' does not exist; create it first", nullptr,
       nullptr, 1200, {"measured modes"}},
      {"synth-over-problem", "`synth -o` names the problem file", {{"bar.yaml", Bar()}},
       "synth <dir>/bar.yaml --modes 1 -o <dir>/bar.yaml", 2, "refusing to write '<dir>/bar.yaml': it is an input"},
      {"import-csv-over-uff", "`import-test-data --csv` names the file it reads", {{"u.uff", uff}},
       "import-test-data <dir>/u.uff --csv <dir>/u.uff", 2, "refusing to write '<dir>/u.uff': it is an input"},
      {"import-csv-over-problem", "`import-test-data --csv` names the `--problem` file",
       {{"u.uff", uff}, {"bar.yaml", Bar()}},
        "import-test-data <dir>/u.uff --problem <dir>/bar.yaml --csv <dir>/bar.yaml",
       2, "refusing to write '<dir>/bar.yaml': it is an input"},
      {"json-symlink-to-problem", "`--json` a symbolic link to the problem file", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --json <dir>/link.json", 2, "refusing to write '<dir>/link.json': it is an input",
       [](const fs::path& dir) { Symlink(dir, "bar.yaml", "link.json"); }},
      {"json-hard-link-to-problem", "`--json` a hard link to the problem file", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --json <dir>/hard.json", 2, "refusing to write '<dir>/hard.json': it is an input",
       [](const fs::path& dir) { fs::create_hard_link(dir / "bar.yaml", dir / "hard.json"); }},
      {"json-dotdot-to-problem", "`--json` the problem file by another path (`sub/../`)", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --json <dir>/sub/../bar.yaml", 2, "it is an input",
       [](const fs::path& dir) { fs::create_directory(dir / "sub"); }},
      {"json-directory", "`--json` a directory", {{"bar.yaml", Bar()}}, "modes <dir>/bar.yaml --json <dir>", 2,
       "is a directory"},
      {"vtu-file", "`--vtu` (a directory) names the problem file", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --vtu <dir>/bar.yaml", 2, "--vtu <dir>/bar.yaml: cannot create the directory"},
      {"out-under-device", "`--out /dev/null/x`", {{"bar.yaml", Bar()}},
       "study bounds-scaling <dir>/bar.yaml --out /dev/null/x", 2, "--out /dev/null/x: cannot create the directory",
       nullptr, nullptr, 1200, {"filesystem error", "L-BFGS"}},  // refused before the study's runs
      {"json-dev-stdout", "`--json /dev/stdout`: written through, the link kept", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --json /dev/stdout", 0, "\"modes\": [", nullptr, device_untouched("/dev/stdout")},
      {"json-dev-null", "`--json /dev/null`: written through, the device kept", {{"bar.yaml", Bar()}},
       "modes <dir>/bar.yaml --json /dev/null", 0, "144 DOFs, 16 elements", nullptr, device_untouched("/dev/null")},

      // --- starts and iterations ---
      {"start-set-outside", "`--set E=1e9` beyond the upper bound 1e5", {{"bar.yaml", Bar()}},
       "calibrate <dir>/bar.yaml --quiet --set E=1e9", 2,
       "the start of parameter 'E' (from --params, --set or --start-factor) 1e+09 lies outside its bounds "
       "[10, 100000]"},
      {"start-factor-outside", "`--start-factor 1000` beyond the upper bound", {{"bar.yaml", Bar()}},
       "calibrate <dir>/bar.yaml --quiet --start-factor 1000", 2, "1e+06 lies outside its bounds [10, 100000]"},
      {"start-outside-diagnose", "`diagnose --set E=1` below the lower bound", {{"bar.yaml", Bar()}},
       "diagnose <dir>/bar.yaml --quiet --set E=1", 2, "1 lies outside its bounds [10, 100000]"},
      {"start-outside-no-bounds", "`--no-bounds --set E=1e6`: no bounds to be outside of", {{"bar.yaml", Bar()}},
       "calibrate <dir>/bar.yaml --quiet --method reduced-lbfgs --no-bounds --set E=1e6", 0,
       "1 parameters, 2 measured modes"},
      {"max-iterations-zero", "`--max-iterations 0`: no iteration, no result", {{"bar.yaml", Bar()}},
       "calibrate <dir>/bar.yaml --quiet --max-iterations 0 --json <dir>/report.json", 1, "fullspace: MaxIterations",
       nullptr,
       [](const fs::path& dir, const CliRun& run) {
         ReportHas("report.json", "/status", "MaxIterations")(dir, run);
         ReportHas("report.json", "/iterations", 0)(dir, run);
         ReportHas("report.json", "/globalization_iterations", 0)(dir, run);
         ReportHas("report.json", "/converged", false)(dir, run);
         ReportHas("report.json", "/parameters/0/final", 1000)(dir, run);
       }},
      {"parameter-name-latin1", "a parameter name that is not UTF-8 (byte 0xFF)",
       {{"latin1.yaml", Replace(Bar(), "  E: {targets", "  E\xff: {targets")}},
       "calibrate <dir>/latin1.yaml --method reduced-lbfgs --max-iterations 3 --quiet --json <dir>/report.json", 0,
       "1 parameters, 2 measured modes", nullptr, ReportHas("report.json", "/parameters/0/name", "E\xEF\xBF\xBD")},
  };
  // clang-format on
}

// --- running a row ---

/// Every file under `dir` (symbolic links by their target, files by their content), to see that a
/// run changed none of them.
std::map<std::string, std::string> Snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir)) {
    const fs::path& p = e.path();
    if (fs::is_symlink(fs::symlink_status(p)))
      files[p.string()] = "symlink to " + fs::read_symlink(p).string();
    else if (fs::is_regular_file(fs::symlink_status(p)))
      files[p.string()] = "file " + std::to_string(std::hash<std::string>()(ReadFile(p.string())));
  }
  return files;
}

std::string ReplaceAll(std::string text, const std::string& from, const std::string& to) {
  if (from.empty()) return text;
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

/// Text the same on every machine: the row's folder as <dir>, the source tree as <src>, the
/// machine's memory as <N>, times as <t>; bytes that are not printable ASCII or UTF-8 as \xHH.
std::string Normalized(std::string text, const fs::path& dir) {
  text = ReplaceAll(text, dir.string(), "<dir>");
  std::error_code ec;
  const fs::path canonical = fs::canonical(dir, ec);
  if (!ec) text = ReplaceAll(text, canonical.string(), "<dir>");
  text = ReplaceAll(text, MODALCAL_SOURCE_DIR, "<src>");
  text = std::regex_replace(text, std::regex("this machine has [0-9.e+]+ ([kMGT]?B)"), "this machine has <N> $1");
  text = std::regex_replace(text, std::regex("\\b[0-9]+\\.[0-9]+ s\\b"), "<t> s");
  std::string out;
  for (size_t k = 0; k < text.size(); ++k) {
    const unsigned char c = text[k];
    size_t length = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
    for (size_t j = 1; j < length; ++j)
      if (k + j >= text.size() || (static_cast<unsigned char>(text[k + j]) >> 6) != 2) length = 0;
    if (length == 1 && c >= 0x20 && c != 0x7f) {
      out += text[k];
    } else if (length > 1) {
      out += text.substr(k, length);
      k += length - 1;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", c);
      out += hex;
    }
  }
  return out;
}

/// The line of `output` that holds `part`.
std::string MessageLine(const std::string& output, const std::string& part) {
  size_t at = output.find(part);
  if (at == std::string::npos) at = 0;
  const size_t begin = output.rfind('\n', at) == std::string::npos ? 0 : output.rfind('\n', at) + 1;
  const size_t end = output.find('\n', at);
  std::string line = output.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return line;
}

/// `line` cut to about 160 characters.
std::string Shortened(std::string line) {
  if (line.size() > 160) {
    size_t cut = 160;
    while (cut > 0 && (static_cast<unsigned char>(line[cut]) >> 6) == 2) --cut;  // not inside a UTF-8 character
    line = line.substr(0, cut) + "...";
  }
  return line;
}

/// `text` as a Markdown code span inside a table cell.
std::string Code(const std::string& text) {
  const std::string escaped = ReplaceAll(text, "|", "\\|");
  return escaped.find('`') == std::string::npos ? "`" + escaped + "`" : "`` " + escaped + " ``";
}

std::string Cell(const std::string& text) { return ReplaceAll(text, "|", "\\|"); }

const char* const kIntro = R"(# Robustness: what bad input gets

Each row below is a bad input given to `fullspace_calib`: what is wrong with it, the command
(`<dir>` is a fresh folder holding the row's input files), the exit code and the line of the
message that names the cause. Exit codes: **2** bad input (the message names the file, line or
option and the likely cause, and quotes at most a short excerpt of the input), **1** a numerical
failure (the message gives the cause), **0** success (rows that show an input the program takes
as it should, such as a byte-order mark or a device as an output). No row changes a file it was
given: the test checks every input file's content before and after the run.

The table is generated by `tests/test_robustness_table.cpp`, which runs every row and fails if
this file differs from what it renders. After changing a row or a message, regenerate it with

    MODALCAL_UPDATE_ROBUSTNESS_DOC=1 build/bin/modalcal_tests --gtest_filter='RobustnessTable.*'

Messages are shown up to about 160 characters, with `<dir>` for the row's folder and `<N>` for
the memory of the machine that ran them. The input files of each row are in the test source.

| id | bad input | command | exit | message |
|---|---|---|---|---|
)";

/// One row run in its folder: the output, and the folder's files before and after.
struct Outcome {
  fs::path dir;
  std::string args, message;  ///< with the folder's path
  CliRun run{-1, ""};
  std::map<std::string, std::string> before, after;
  double seconds = 0;
};

Outcome RunRow(const Row& row, const fs::path& root) {
  Outcome o;
  o.dir = root / row.id;
  fs::create_directories(o.dir);
  for (const auto& [name, content] : row.files) std::ofstream(o.dir / name, std::ios::binary) << content;
  if (row.prepare) row.prepare(o.dir);
  o.before = Snapshot(o.dir);
  o.args = ReplaceAll(row.args, "<dir>", o.dir.string());
  o.message = ReplaceAll(row.message, "<dir>", o.dir.string());
  const auto start = std::chrono::steady_clock::now();
  o.run = RunCli(o.args);
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  o.after = Snapshot(o.dir);
  return o;
}

TEST(RobustnessTable, EveryBadInputGetsItsExitCodeAndMessageAndTheDocIsCurrent) {
  const std::vector<Row> rows = Rows();
  const fs::path root = fs::temp_directory_path() / ("modalcal_robustness." + std::to_string(getpid()));
  fs::remove_all(root);
  // Most of a row's time is the program's start (loading its libraries): two rows at a time.
  std::vector<Outcome> outcomes(rows.size());
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t k = next++; k < rows.size(); k = next++) outcomes[k] = RunRow(rows[k], root);
  };
  std::thread helper(work);
  work();
  helper.join();

  std::string table = kIntro;
  std::set<std::string> ids;
  for (size_t k = 0; k < rows.size(); ++k) {
    const Row& row = rows[k];
    const Outcome& o = outcomes[k];
    const CliRun& run = o.run;
    SCOPED_TRACE("row " + row.id);
    EXPECT_TRUE(ids.insert(row.id).second) << "two rows named " << row.id;
    if (std::getenv("MODALCAL_ROBUSTNESS_TIMES")) std::printf("%-28s %6.2f s\n", row.id.c_str(), o.seconds);
    const std::string shown = run.output.size() > 2000 ? run.output.substr(0, 2000) + "..." : run.output;
    EXPECT_EQ(run.exit_code, row.exit_code) << o.args.substr(0, 300) << "\n" << shown;
    const size_t at = run.output.find(o.message);
    EXPECT_NE(at, std::string::npos) << "expected '" << o.message << "' in:\n" << shown;
    if (row.exit_code != 0 && at != std::string::npos) {  // the message is short whatever the input holds
      const size_t line = run.output.rfind('\n', at) == std::string::npos ? 0 : run.output.rfind('\n', at) + 1;
      EXPECT_LE(run.output.size() - line, row.max_output) << shown;
    }
    for (const std::string& absent : row.must_not_contain)
      EXPECT_EQ(run.output.find(absent), std::string::npos) << "'" << absent << "' in:\n" << shown;
    for (const auto& [path, state] : o.before) {
      const auto found = o.after.find(path);
      EXPECT_TRUE(found != o.after.end() && found->second == state) << "input changed: " << path;
    }
    if (row.check) row.check(o.dir, run);

    table += "| " + row.id + " | " + Cell(row.bad) + " | " + Code(Normalized("fullspace_calib " + o.args, o.dir)) +
             " | " + std::to_string(run.exit_code) + " | " +
             Code(Shortened(Normalized(MessageLine(run.output, o.message), o.dir))) + " |\n";
  }
  EXPECT_GE(rows.size(), 60u);
  fs::remove_all(root);

  const std::string doc_path = std::string(MODALCAL_SOURCE_DIR) + "/docs/robustness.md";
  const char* update = std::getenv("MODALCAL_UPDATE_ROBUSTNESS_DOC");
  if (update && std::string(update) == "1") {
    std::ofstream(doc_path, std::ios::binary) << table;
    std::printf("wrote %s (%zu rows)\n", doc_path.c_str(), rows.size());
    return;
  }
  const std::string doc = ReadFile(doc_path);
  if (doc != table) {
    std::istringstream a(doc), b(table);
    std::string la, lb;
    int line = 0;
    while (true) {
      ++line;
      const bool more_a = static_cast<bool>(std::getline(a, la)), more_b = static_cast<bool>(std::getline(b, lb));
      if (!more_a && !more_b) break;
      if (!more_a || !more_b || la != lb) break;
    }
    ADD_FAILURE() << doc_path << " is not what the rows give (first difference at line " << line << ":\n  file: " << la
                  << "\n  rows: " << lb
                  << ")\nRegenerate it with MODALCAL_UPDATE_ROBUSTNESS_DOC=1 build/bin/modalcal_tests "
                     "--gtest_filter='RobustnessTable.*' and review the difference.";
  }
}

}  // namespace
}  // namespace modalcal
