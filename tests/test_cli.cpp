// The command-line program as users run it: output tables and JSON, exit codes, and that bad
// input produces a message naming the file and cause without touching any input file.

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::WriteTempFile;

struct CliRun {
  int exit_code;
  std::string output;  // stdout and stderr
};

CliRun RunCli(const std::string& args) {
  const std::string command = std::string(MODALCAL_CLI) + " " + args + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  std::string out;
  char buffer[4096];
  while (size_t n = fread(buffer, 1, sizeof(buffer), pipe)) out.append(buffer, n);
  const int status = pclose(pipe);
  return {WEXITSTATUS(status), out};
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const char* kBar = R"(
mesh:
  element: hex8
  element_size: 0.5
  boxes: [{block: bar, min: [0, 0, 0], max: [4, 0.5, 0.5]}]
blocks:
  bar: {E: 1000, nu: 0.3, density: 1.0}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 0.5, 0.5]}}
fixed:
  - {node_set: root, dofs: [x, y, z]}
mode_families:
  axial: x
parameters:
  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, truth: 1200}
options:
  num_modes: 6
)";

TEST(Cli, ModesPrintsTableAndWritesJson) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  const std::string json_path = WriteTempFile("out.json", "");
  const CliRun run = RunCli("modes " + problem + " --json " + json_path);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("freq [Hz]"), std::string::npos);
  EXPECT_NE(run.output.find("axial"), std::string::npos);
  const nlohmann::json json = nlohmann::json::parse(ReadFile(json_path));
  EXPECT_GT(json["dofs"].get<int>(), 0);
  ASSERT_EQ(json["modes"].size(), 6u);
  for (const auto& m : json["modes"]) {
    EXPECT_TRUE(m.contains("index") && m.contains("frequency_hz") && m.contains("dominant_direction") &&
                m.contains("label"));
  }
  EXPECT_EQ(json["modes"][0]["index"], 1);
  bool has_axial = false;
  for (const auto& m : json["modes"]) has_axial |= m["label"] == "axial";
  EXPECT_TRUE(has_axial);
}

TEST(Cli, ParameterChoicesChangeFrequenciesAsPhysicsSays) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  auto first_frequency = [&](const std::string& extra) {
    const std::string out = WriteTempFile("f.json", "");
    const CliRun run = RunCli("modes " + problem + " --json " + out + " " + extra);
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return nlohmann::json::parse(ReadFile(out))["modes"][0]["frequency_hz"].get<double>();
  };
  const double initial = first_frequency("");
  // f ~ sqrt(E): truth E = 1200 vs initial 1000; --set E=4000 doubles f; density x4 halves it.
  EXPECT_CLOSE(first_frequency("--params truth"), initial * std::sqrt(1.2), 1e-9);
  EXPECT_CLOSE(first_frequency("--set E=4000"), initial * 2, 1e-9);
  EXPECT_CLOSE(first_frequency("--set bar.density=4"), initial / 2, 1e-9);
  // A calibration report's final values are accepted as a parameter source.
  const std::string report = WriteTempFile("report.json", R"({"parameters": [{"name": "E", "final": 250}]})");
  EXPECT_CLOSE(first_frequency("--params " + report), initial / 2, 1e-9);
}

TEST(Cli, BadInputIsNamedAndExitsWithTwo) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  CliRun run = RunCli("modes " + problem + " --set nosuch=3");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("nosuch"), std::string::npos) << run.output;
  run = RunCli("modes " + problem + " --set E=abc");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("not a finite number"), std::string::npos) << run.output;
  run = RunCli("modes " + problem + " --params truth --params /nonexistent.json");
  EXPECT_EQ(run.exit_code, 2);
  const std::string broken = WriteTempFile("broken.yaml", "mesh: {element: hex9}\nblocks: {}\n");
  run = RunCli("modes " + broken);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("broken.yaml:"), std::string::npos) << run.output;
}

TEST(Cli, NegativeModulusIsANumericalFailureWithLikelyCause) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  const CliRun run = RunCli("modes " + problem + " --set E=-1000");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("negative"), std::string::npos) << run.output;
}

TEST(Cli, NeverOverwritesTheProblemFile) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  const CliRun run = RunCli("modes " + problem + " --json " + problem);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("refusing"), std::string::npos) << run.output;
  EXPECT_EQ(ReadFile(problem), kBar);
}

TEST(Cli, ModesWritesVtuFilesButNeverOverAnInput) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  const std::filesystem::path dir = std::filesystem::path(problem).parent_path() / "vtu";
  CliRun run = RunCli("modes " + problem + " --vtu " + dir.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(ReadFile((dir / "modes.vtu").string()).find("Name=\"mode_6_"), std::string::npos);
  EXPECT_NE(ReadFile((dir / "modes.pvd").string()).find("file=\"modes.vtu\""), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir / "modes_sensors.vtu")) << "the bar has no sensors";
  // A problem file named like an output in the output directory stays as it is.
  const std::string input = (dir / "modes.pvd").string();
  std::ofstream(input) << kBar;
  run = RunCli("modes " + input + " --vtu " + dir.string());
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("refusing"), std::string::npos) << run.output;
  EXPECT_EQ(ReadFile(input), kBar);
}

TEST(Cli, LocalizeRanksTheRegionTheModelGetsWrong) {
  // The model's column 1 is 30 % heavier than the test article the measurements came from.
  const std::string json_path = WriteTempFile("localize.json", "");
  const std::filesystem::path dir = std::filesystem::path(json_path).parent_path() / "vtu";
  const CliRun run = RunCli("localize " + testing::SourcePath("problems/portal-frame/synthetic.yaml") +
                            " --params truth --set column_1.density=3510 --rows 3 --json " + json_path + " --vtu " +
                            dir.string());
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("   1  column_1 "), std::string::npos) << run.output;
  const nlohmann::json j = nlohmann::json::parse(ReadFile(json_path));
  EXPECT_EQ(j["ranking"][0]["region"], "column_1");
  EXPECT_EQ(j["ranking"][0]["kind"], "block");
  EXPECT_GT(j["ranking"][0]["share"].get<double>(), 0.5);
  ASSERT_EQ(j["modes"].size(), 6u);
  EXPECT_EQ(j["modes"][0]["measured"], 1);
  EXPECT_GT(j["total_energy"].get<double>(), 0.0);
  for (const char* file : {"localize.vtu", "localize_sensors.vtu", "localize.pvd"})
    EXPECT_TRUE(std::filesystem::exists(dir / file)) << file;
  EXPECT_NE(ReadFile((dir / "localize.vtu").string()).find("Name=\"error_indicator\""), std::string::npos);
}

TEST(Cli, LocalizeWithoutMeasuredShapesIsAnInputError) {
  const CliRun run = RunCli("localize " + WriteTempFile("bar.yaml", kBar));
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("no measured mode has a shape"), std::string::npos) << run.output;
}

TEST(Cli, FullSpaceCalibrationWritesTheDocumentedJson) {
  const std::string json_path = WriteTempFile("report.json", "");
  const CliRun run =
      RunCli("calibrate " + testing::SourcePath("problems/portal-frame/synthetic.yaml") + " --quiet --json " + json_path);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("measured"), std::string::npos) << run.output;  // the mode table
  const nlohmann::json j = nlohmann::json::parse(ReadFile(json_path));
  EXPECT_EQ(j["method"], "fullspace");
  EXPECT_TRUE(j["converged"].get<bool>());
  EXPECT_EQ(j["status"], "Converged");
  EXPECT_EQ(j["ipopt_status"], "Solve_Succeeded");
  EXPECT_TRUE(j["mode_check"]["passed"].get<bool>()) << j["mode_check"].dump();
  for (const auto& mac : j["mode_check"]["mac"]) EXPECT_GT(mac.get<double>(), 0.99);
  ASSERT_FALSE(j["kkt_history"].empty());
  const auto& last = j["kkt_history"].back();
  EXPECT_LT(last["kkt_error"].get<double>(), 1e-8);
  EXPECT_LT(last["parameter_error"].get<double>(), 1e-6);
  EXPECT_TRUE(j["convergence_order"].is_number());
  for (const char* key : {"iterations", "forward_solves", "kkt_solves", "time_s", "history", "modes"})
    EXPECT_TRUE(j.contains(key)) << key;
  for (const auto& p : j["parameters"]) {
    for (const char* key : {"name", "initial", "final", "truth", "lower", "upper"}) EXPECT_TRUE(p.contains(key)) << key;
    EXPECT_NEAR(p["final"].get<double>() / p["truth"].get<double>(), 1.0, 1e-6) << p["name"];
  }
  for (const auto& m : j["modes"]) EXPECT_GT(m["mac"].get<double>(), 0.999);
}

}  // namespace
}  // namespace modalcal
