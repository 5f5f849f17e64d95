#include "test_util.hpp"

#include "modalcal/synthesis.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <vector>

namespace modalcal::testing {

Problem LoadProblem(const std::string& path, const LoadOptions& options) {
  Problem problem = load_problem(path, options);
  synthesize_measured(&problem);
  return problem;
}

// A two-block cantilever with a joint to a
// reference node carrying a point mass, springs at the root, sensors on the top edge, and six
// measured modes with shapes synthesized at the truth values. The section is not square, so no
// two modes share an eigenvalue (their shapes would not be differentiable).
const char* const kEveryParameterKindModel = R"(
mesh:
  element: hex8
  element_size: 0.5
  boxes:
    - {block: a, min: [0, 0, 0], max: [3, 1, 1.25]}
    - {block: b, min: [3, 0, 0], max: [5, 1, 1.25]}
blocks:
  a: {E: 2.0e3, nu: 0.3, density: 1.0, stiffness_scale: 1.0, mass_scale: 1.0}
  b: {K: 1.5e3, G: 0.8e3, density: 2.0}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 1, 1.25]}}
  tip: {box: {min: [5, 0, 0], max: [5, 1, 1.25]}}
reference_nodes:
  r: [5.5, 0.5, 0.625]
  g: [5.5, 0.5, 0.625]
rigid_couplings:
  - {reference: r, node_set: tip}
joints:
  j: {nodes: [r, g], kx: 100, ky: 200, kz: 300, krx: 10, kry: 20, krz: 30}
springs:
  s: {node_set: root, kx: 5.0e3, ky: 6.0e3, kz: 7.0e3}
point_masses:
  pm: {node: g, mass: 0.5, inertia: [0.01, 0.02, 0.03]}
parameters:
  E: {targets: [a.E], initial: 2.0e3, lower: 1, upper: 1e5, truth: 2.4e3, scaling: log}
  nu: {targets: [a.nu], initial: 0.3, lower: 0.0, upper: 0.45, truth: 0.25}
  K: {targets: [b.K], initial: 1.5e3, lower: 1, upper: 1e5, truth: 1.2e3}
  G: {targets: [b.G], initial: 0.8e3, lower: 1, upper: 1e5, truth: 0.9e3}
  rho: {targets: [a.density, b.density], initial: 1.5, lower: 0.1, upper: 10, truth: 1.4}
  kscale: {targets: [a.stiffness_scale], initial: 1.2, lower: 0.1, upper: 10, truth: 1.0}
  mscale: {targets: [a.mass_scale], initial: 0.9, lower: 0.1, upper: 10, truth: 1.1}
  kx: {targets: [j.kx], initial: 100, lower: 1, upper: 1e4, truth: 150}
  krz: {targets: [j.krz], initial: 30, lower: 1, upper: 1e4, truth: 20}
  spring: {targets: [s.ky], initial: 6.0e3, lower: 1, upper: 1e5, truth: 5.0e3}
  mass: {targets: [pm.mass], initial: 0.5, lower: 0.01, upper: 10, truth: 0.6}
  inertia: {targets: [pm.Ixx], initial: 0.01, lower: 0.001, upper: 1, truth: 0.012}
sensors:
  - {node_set: tip, directions: [x, y, z]}
  - {at: [2.5, 1, 1.25], directions: [y, z]}
measured:
  synthetic: {modes: [1, 2, 3, 4, 5, 6], shapes: true}
options:
  num_modes: 8
)";

::testing::AssertionResult IsClose(double a, double b, double rel_tol, double floor) {
  const double scale = std::max({std::abs(a), std::abs(b), floor});
  const double diff = std::abs(a - b);
  if (diff <= rel_tol * scale || (scale == 0 && diff == 0)) return ::testing::AssertionSuccess();
  std::ostringstream s;
  s.precision(12);
  s << a << " vs " << b << ": relative difference " << diff / scale << " > " << rel_tol;
  return ::testing::AssertionFailure() << s.str();
}

double RelativeDifference(const Matrix& a, const Matrix& b) {
  const double scale = b.cwiseAbs().maxCoeff();
  return (a - b).cwiseAbs().maxCoeff() / (scale > 0 ? scale : 1.0);
}

namespace {

// The text split into alternating non-number and number tokens; numbers parsed with strtod.
struct Token {
  std::string text;
  bool is_number = false;
  double value = 0;
  int line = 1;
};

std::vector<Token> Tokenize(const std::string& text) {
  static const std::regex number(R"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)");
  std::vector<Token> tokens;
  int line = 1;
  auto add_text = [&](std::string piece) {
    if (piece.empty()) return;
    tokens.push_back({piece, false, 0, line});
    line += static_cast<int>(std::count(piece.begin(), piece.end(), '\n'));
  };
  auto begin = std::sregex_iterator(text.begin(), text.end(), number);
  size_t end_of_last = 0;
  for (auto it = begin; it != std::sregex_iterator(); ++it) {
    add_text(text.substr(end_of_last, it->position() - end_of_last));
    tokens.push_back({it->str(), true, std::strtod(it->str().c_str(), nullptr), line});
    end_of_last = it->position() + it->length();
  }
  add_text(text.substr(end_of_last));
  return tokens;
}

}  // namespace

std::string NumericTextDifference(const std::string& actual, const std::string& expected, double relative,
                                  double absolute) {
  const std::vector<Token> a = Tokenize(actual), b = Tokenize(expected);
  for (size_t k = 0; k < std::min(a.size(), b.size()); ++k) {
    const bool same = a[k].is_number && b[k].is_number
                          ? std::abs(a[k].value - b[k].value) <= absolute + relative * std::abs(b[k].value)
                          : a[k].text == b[k].text;
    if (!same)
      return "line " + std::to_string(b[k].line) + ": '" + a[k].text + "' where '" + b[k].text + "' was expected";
  }
  if (a.size() != b.size()) return "one text ends before the other (" + std::to_string(a.size()) + " against " +
                                   std::to_string(b.size()) + " tokens)";
  return "";
}

std::string SourcePath(const std::string& relative) { return std::string(MODALCAL_SOURCE_DIR) + "/" + relative; }

std::string WriteTempFile(const std::string& name, const std::string& text) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::filesystem::path dir = std::filesystem::temp_directory_path() / "modalcal_tests";
  if (info) dir /= std::string(info->test_suite_name()) + "." + info->name();
  std::filesystem::create_directories(dir);
  const std::filesystem::path path = dir / name;
  std::ofstream(path) << text;
  return path.string();
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

CliRun RunShell(const std::string& command) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  std::string out;
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof(buffer), pipe)) out.append(buffer, n);
  const int status = pclose(pipe);
  return {WEXITSTATUS(status), out};
}

CliRun RunCli(const std::string& args) { return RunShell(std::string(MODALCAL_CLI) + " " + args); }

std::string SensedBar() {
  return CantileverBar() + R"(parameters:
  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, scaling: log}
sensors:
  - {node_set: top_edge, directions: [x, y, z]}
options:
  num_modes: 6
)";
}

std::string WriteTipMassStudy() {
  const std::string nominal = WriteTempFile("nominal.yaml", SensedBar());
  const std::string dir = std::filesystem::path(nominal).parent_path().string();
  const CliRun synth = RunCli("synth " + nominal + " --truth 'point_mass@tip:mass=0.05' --modes 1,2,3,4 " +
                              "--noise-freq 0.002 --noise-shape 0.01 --seed 3 -o " + dir + "/data.yaml");
  EXPECT_EQ(synth.exit_code, 0) << synth.output;
  return WriteTempFile("study.yaml", SensedBar() + "measured: {file: data.yaml}\n");
}

Model MakeChain(int n, double m, double k, bool grounded) {
  Model model;
  for (int i = 0; i <= n; ++i) model.add_node(i + 1, Vec3(i, 0, 0));
  FixedDofs lateral;
  lateral.name = "lateral";
  lateral.components = {false, true, true, false, false, false};
  for (int i = 0; i <= n; ++i) lateral.nodes.push_back(i);
  model.fixed.push_back(lateral);
  if (grounded) {
    FixedDofs ground;
    ground.name = "ground";
    ground.nodes = {0};
    ground.components = {true, false, false, false, false, false};
    model.fixed.push_back(ground);
  }
  for (int i = grounded ? 1 : 0; i <= n; ++i) {
    PointMass pm;
    pm.name = "mass" + std::to_string(i);
    pm.node = i;
    pm.mass = model.add_property(pm.name + ".mass", m);
    model.point_masses.push_back(pm);
  }
  for (int i = 1; i <= n; ++i) {
    Joint j;
    j.name = "joint" + std::to_string(i);
    j.node_a = i - 1;
    j.node_b = i;
    j.stiffness[0] = model.add_property(j.name + ".kx", k);
    model.joints.push_back(j);
  }
  return model;
}

std::string CantileverBar(const std::string& extra_node_sets, const std::string& extra_fixed) {
  return R"(
mesh:
  element: hex8
  element_size: 0.5
  boxes: [{block: bar, min: [0, 0, 0], max: [4, 0.5, 0.75]}]
blocks:
  bar: {E: 1000, nu: 0.3, density: 1.0}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 0.5, 0.75]}}
  tip: {box: {min: [4, 0, 0], max: [4, 0.5, 0.75]}}
  top_edge: {box: {min: [0, 0.5, 0.75], max: [4, 0.5, 0.75]}}
)" + extra_node_sets + R"(fixed:
  - {node_set: root, dofs: [x, y, z]}
)" + extra_fixed;
}

}  // namespace modalcal::testing
