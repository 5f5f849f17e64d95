// The command-line program as users run it: output tables and JSON, exit codes, and that bad
// input produces a message naming the file and cause without touching any input file.

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "modalcal/reduced.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::CliRun;
using testing::ReadFile;
using testing::RunCli;
using testing::WriteTempFile;

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

// A modulus the model cannot take is the user's input, refused before any solve, naming the
// parameter and the block it sets.
TEST(Cli, NegativeModulusParameterIsBadInputNamingIt) {
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  const CliRun run = RunCli("modes " + problem + " --set E=-1000");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("parameter 'E' = -1000"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("must be positive"), std::string::npos) << run.output;
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

/// Rows of a CSV file split at commas (the tested files have no quoted cells).
std::vector<std::vector<std::string>> ReadCsv(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> cells(1);
    for (char c : line) {
      if (c == ',')
        cells.emplace_back();
      else
        cells.back().push_back(c);
    }
    rows.push_back(cells);
  }
  return rows;
}

TEST(Cli, BorderedSolvesThroughOneSharedFactorizationAreChosenAndReported) {
  const std::string json_path = WriteTempFile("shared.json", "");
  const std::string problem = testing::SourcePath("problems/portal-frame/synthetic.yaml");
  const CliRun run = RunCli("calibrate " + problem + " --bordered-solves shared --quiet --json " + json_path);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json j = nlohmann::json::parse(ReadFile(json_path));
  EXPECT_TRUE(j["converged"].get<bool>());
  EXPECT_EQ(j["bordered_solves"]["method"], "shared");
  EXPECT_GT(j["bordered_solves"]["shared_eliminations"].get<int>(), 0);
  EXPECT_EQ(j["bordered_solves"]["shared_failures"], 0);
  const CliRun bad = RunCli("calibrate " + problem + " --bordered-solves sometimes --quiet");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--bordered-solves"), std::string::npos) << bad.output;
}

TEST(Cli, FullSpaceCalibrationWritesTheDocumentedJson) {
  const std::string json_path = WriteTempFile("report.json", "");
  const std::string dir = std::filesystem::path(json_path).parent_path().string();
  const CliRun run = RunCli("calibrate " + testing::SourcePath("problems/portal-frame/synthetic.yaml") +
                            " --quiet --json " + json_path + " --csv " + dir + "/report --history-plot " + dir +
                            "/history.svg");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("measured"), std::string::npos) << run.output;  // the mode table
  const nlohmann::json j = nlohmann::json::parse(ReadFile(json_path));
  EXPECT_EQ(j["method"], "fullspace");
  EXPECT_TRUE(j["converged"].get<bool>());
  EXPECT_EQ(j["status"], "Converged");
  // Ipopt ends either way at this tolerance, depending on the rounding of the last iterate.
  EXPECT_TRUE(j["ipopt_status"] == "Solve_Succeeded" || j["ipopt_status"] == "Solved_To_Acceptable_Level")
      << j["ipopt_status"];
  EXPECT_EQ(j["kkt_solver"], "structured");  // the default: Ipopt on the structured KKT solver
  EXPECT_GT(j["kkt_factorizations"]["structured"].get<int>(), 0);
  EXPECT_EQ(j["bordered_solves"]["method"], "per-mode");  // a small model: one factorization per mode
  EXPECT_EQ(j["bordered_solves"]["shared_eliminations"], 0);
  EXPECT_TRUE(j["mode_check"]["passed"].get<bool>()) << j["mode_check"].dump();
  for (const auto& mac : j["mode_check"]["mac"]) EXPECT_GT(mac.get<double>(), 0.99);
  ASSERT_FALSE(j["kkt_history"].empty());
  const auto& last = j["kkt_history"].back();
  EXPECT_LT(last["kkt_error"].get<double>(), 1e-8);
  EXPECT_LT(last["parameter_error"].get<double>(), 1e-6);
  // Newton's tail takes full steps; the very last one may be cut where the merit function sits on
  // its rounding floor, so one of the last two records must hold a full step.
  const auto& kkt_history = j["kkt_history"];
  const double full_step = kkt_history.size() < 2 ? last["step_length"].get<double>()
                                              : std::max(last["step_length"].get<double>(),
                                                         kkt_history[kkt_history.size() - 2]["step_length"].get<double>());
  EXPECT_EQ(full_step, 1.0) << kkt_history.dump();
  EXPECT_TRUE(last["hessian_shift"].is_number());
  ASSERT_TRUE(j["crossing_escapes"].is_array());
  EXPECT_TRUE(j["crossing_escapes"].empty());  // the truth pairs in order: nothing to escape from
  // The order is measured where the tail has two steps that each gain a factor 2 above the
  // rounding floor; a tail too short for that (it depends on the last digits) gives null.
  if (j["convergence_order"].is_number()) {
    EXPECT_GT(j["convergence_order"].get<double>(), 1.2) << kkt_history.dump();  // Newton: superlinear
  } else {
    EXPECT_TRUE(j["convergence_order"].is_null());
    // The estimator's input, as the driver makes it: max(primal, dual infeasibility) of the last
    // attempt (which begins with a record of no step); complementarity sits at mu and has no rate.
    std::vector<double> errors;
    for (const auto& record : kkt_history) {
      if (record["step_length"].get<double>() == 0) errors.clear();
      errors.push_back(std::max(record["primal_infeasibility"].get<double>(), record["dual_infeasibility"].get<double>()));
    }
    EXPECT_TRUE(std::isnan(estimate_convergence_order(errors))) << kkt_history.dump();
  }
  for (const char* key : {"iterations", "forward_solves", "kkt_solves", "time_s", "history", "modes"})
    EXPECT_TRUE(j.contains(key)) << key;
  for (const auto& p : j["parameters"]) {
    for (const char* key : {"name", "initial", "final", "truth", "lower", "upper"}) EXPECT_TRUE(p.contains(key)) << key;
    EXPECT_NEAR(p["final"].get<double>() / p["truth"].get<double>(), 1.0, 1e-6) << p["name"];
    // The uncertainty: noise-free data leave a residual at the rounding floor, so the noise
    // estimated from it is tiny and every interval hugs the value.
    ASSERT_TRUE(p["standard_error"].is_number()) << p.dump();
    EXPECT_LT(p["standard_error"].get<double>(), 1e-4 * p["final"].get<double>()) << p.dump();
    EXPECT_LE(p["interval"][0].get<double>(), p["final"].get<double>());
    EXPECT_GE(p["interval"][1].get<double>(), p["final"].get<double>());
    EXPECT_TRUE(p["profile_interval"].is_null()) << p.dump();  // well identified: not profiled
    EXPECT_EQ(p["correlation"].size(), j["parameters"].size());
  }
  EXPECT_EQ(j["uncertainty"]["noise"], "estimated from the residual");
  EXPECT_NE(run.output.find("parameter uncertainty"), std::string::npos) << run.output;
  for (const auto& m : j["modes"]) EXPECT_GT(m["mac"].get<double>(), 0.999);

  // The CSV tables hold the JSON's rows: one per parameter, measured mode and iteration.
  const auto parameters = ReadCsv(dir + "/report_parameters.csv");
  ASSERT_EQ(parameters.size(), j["parameters"].size() + 1);
  EXPECT_EQ(parameters[0], (std::vector<std::string>{"name", "initial", "final", "truth", "error_percent", "lower",
                                                      "upper"}));
  for (size_t k = 0; k < j["parameters"].size(); ++k) {
    EXPECT_EQ(parameters[k + 1][0], j["parameters"][k]["name"]);
    EXPECT_NEAR(std::stod(parameters[k + 1][2]) / j["parameters"][k]["final"].get<double>(), 1, 1e-9);
    EXPECT_LT(std::abs(std::stod(parameters[k + 1][4])), 1e-4);  // error in percent
  }
  const auto modes = ReadCsv(dir + "/report_modes.csv");
  ASSERT_EQ(modes.size(), j["modes"].size() + 1);
  EXPECT_EQ(modes[0][2], "measured_hz");
  EXPECT_NEAR(std::stod(modes[1][3]), j["modes"][0]["predicted_hz"].get<double>(), 1e-6);
  const auto history = ReadCsv(dir + "/report_history.csv");
  ASSERT_EQ(history.size(), j["history"].size() + 1);
  EXPECT_EQ(history.back()[1], "newton");
  EXPECT_NE(ReadFile(dir + "/history.svg").find("<svg"), std::string::npos);
}

// The multi-start study with two runs at a time: every (start, method) pair reported once, in
// order, judged against the truth (the propped cantilever converges from every start).
TEST(Cli, FullVsReducedStudyRunsEveryStartAndMethodInParallel) {
  const std::string json_path = WriteTempFile("study.json", "");
  const std::string dir = std::filesystem::path(json_path).parent_path().string() + "/study";
  const CliRun run = RunCli("study full-vs-reduced " + testing::SourcePath("problems/propped-cantilever/synthetic.yaml") +
                            " --starts 2 --seed 3 --jobs 2 --methods fullspace reduced-lbfgs --out " + dir +
                            " --json " + json_path);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json j = nlohmann::json::parse(ReadFile(json_path));
  ASSERT_EQ(j["runs"].size(), 6u);
  for (size_t k = 0; k < 6; ++k) {
    const auto& r = j["runs"][k];
    EXPECT_EQ(r["start"], k / 2);
    EXPECT_EQ(r["method"], k % 2 ? "reduced-lbfgs" : "fullspace");
    EXPECT_TRUE(r["success"].get<bool>()) << r.dump();
    EXPECT_LT(r["parameter_error"].get<double>(), 1e-4);
    EXPECT_EQ(r["start_parameters"], j["runs"][k - k % 2]["start_parameters"]);  // both methods, same start
  }
  EXPECT_NE(j["runs"][0]["start_parameters"], j["runs"][2]["start_parameters"]);
  EXPECT_EQ(j["methods"]["fullspace"]["successes"], 3);
  EXPECT_EQ(j["methods"]["reduced-lbfgs"]["successes"], 3);
  EXPECT_TRUE(std::filesystem::file_size(dir + "/full_vs_reduced.png") > 0);
  for (const auto& entry : std::filesystem::directory_iterator(dir))  // no run reports left behind
    EXPECT_EQ(entry.path().extension(), ".png") << entry.path();
}

// The square bar's bending modes come in pairs: the reduced tools on it, as a user runs them.
// check-derivatives passes, calibrate warns that the paired eigenvalues nearly repeat, and the
// bounds-scaling study writes its four histories and the plot.
TEST(Cli, CheckDerivativesRepeatedModesAndBoundsScalingStudyOnASquareBar) {
  const std::string problem =
      WriteTempFile("square_bar.yaml", std::string(kBar) + "measured:\n  synthetic: {modes: [1, 2, 3], shapes: false}\n");
  const std::string dir = std::filesystem::path(problem).parent_path().string() + "/bounds_scaling";
  CliRun run = RunCli("check-derivatives " + problem);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("max relative error"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find(": OK"), std::string::npos) << run.output;

  run = RunCli("calibrate " + problem + " --method reduced-lbfgs --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("model mode 1, whose eigenvalue nearly repeats that of mode 2"), std::string::npos)
      << run.output;

  run = RunCli("study bounds-scaling " + problem + " --out " + dir);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const std::string csv = ReadFile(dir + "/bounds_scaling.csv");
  for (const char* name : {"no bounds, no scaling", "bounds, no scaling", "scaling, no bounds", "bounds and scaling"})
    EXPECT_NE(run.output.find(name), std::string::npos) << name << "\n" << run.output;
  EXPECT_GT(std::count(csv.begin(), csv.end(), '\n'), 4) << csv;
  EXPECT_GT(std::filesystem::file_size(dir + "/bounds_scaling.png"), 0u);
}

TEST(Cli, ImportTestDataPrintsTheFileAndMapsOntoAProblem) {
  const std::string uff = testing::SourcePath("tests/data/uff/uff55_translation.uff");
  const std::string problem = WriteTempFile("bar.yaml", kBar);
  const std::string csv = WriteTempFile("modes.csv", "");
  const CliRun run = RunCli("import-test-data " + uff + " --problem " + problem + " --csv " + csv);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* expected : {"line     21     55  read", "modes: 3", "12.0000", "4 of 4 test nodes matched a model node by id",
                               "no node geometry"})
    EXPECT_NE(run.output.find(expected), std::string::npos) << expected << " not in\n" << run.output;
  std::istringstream lines(ReadFile(csv));
  int rows = 0;
  for (std::string line; std::getline(lines, line);) ++rows;
  EXPECT_EQ(rows, 1 + 3 * 4 * 3);  // header + 3 modes × 4 nodes × 3 directions
}

TEST(Cli, ImportTestDataNamesTheBadLineAndKeepsInputs) {
  const std::string uff = WriteTempFile("bad.uff", "    -1\n    55\nNONE\n");
  const CliRun bad = RunCli("import-test-data " + uff);
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find(uff + ":2: dataset 55 starting here has no closing '-1'"), std::string::npos) << bad.output;
  const std::string good = WriteTempFile("good.uff", ReadFile(testing::SourcePath("tests/data/uff/uff55_translation.uff")));
  const CliRun overwrite = RunCli("import-test-data " + good + " --csv " + good);
  EXPECT_EQ(overwrite.exit_code, 2) << overwrite.output;
  EXPECT_NE(overwrite.output.find("refusing to write"), std::string::npos) << overwrite.output;
  EXPECT_EQ(ReadFile(good), ReadFile(testing::SourcePath("tests/data/uff/uff55_translation.uff")));
}

// The bar with sensors on its top edge and Young's modulus to calibrate (its truth unknown: the
// truth model keeps the file's value).
const std::string kSensedBar = testing::SensedBar();

TEST(Cli, DiagnoseFindsTheHiddenEffectAndCalibrateAddsIt) {
  const std::string study = testing::WriteTipMassStudy();
  const std::string dir = std::filesystem::path(study).parent_path().string();
  CliRun run = RunCli("diagnose " + study + " --quiet --json " + dir + "/diagnose.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* part : {"residual test: chi-square", "where the model fails", "which effect is missing",
                           "Add added_mass_tip.mass", "hidden effect added_mass_tip.mass: ranked 1"})
    EXPECT_NE(run.output.find(part), std::string::npos) << part << "\n" << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/diagnose.json"));
  EXPECT_EQ(d["model_form_error"], true);
  ASSERT_GE(d["ranking"].size(), 3u);
  const nlohmann::json& first = d["ranking"][0];
  for (const char* key : {"name", "description", "predicted_reduction", "achieved_reduction", "value", "significant"})
    EXPECT_TRUE(first.contains(key)) << key;
  EXPECT_EQ(first["name"], "added_mass_tip.mass");
  EXPECT_EQ(first["significant"], true);
  EXPECT_NEAR(first["value"].get<double>(), 0.05, 0.005);
  EXPECT_TRUE(d["ranking"].back()["achieved_reduction"].is_null());  // not refitted
  EXPECT_EQ(d["residual_before"]["model_form_error"], true);
  EXPECT_EQ(d["residual_after"]["model_form_error"], false);
  EXPECT_LT(d["residual_after"]["statistic"].get<double>(), d["residual_before"]["statistic"].get<double>());
  EXPECT_EQ(d["hidden_effect"][0]["name"], "added_mass_tip.mass");
  EXPECT_EQ(d["hidden_effect_rank"][0]["rank"], 1);
  EXPECT_EQ(d["recommended"], "added_mass_tip.mass");
  EXPECT_EQ(RunCli("compare " + study + " --params " + dir + "/diagnose.json").exit_code, 0);  // its calibration

  // The stepwise loop's record: one step with its place (the tip's nodes), the accepted list and
  // the final residual.
  ASSERT_EQ(d["steps"].size(), 1u) << d["steps"].dump();
  const nlohmann::json& step = d["steps"][0];
  for (const char* key : {"step", "name", "description", "change", "location", "value", "standard_error",
                          "chi2_before", "chi2_after", "p_value_after", "delta_bic", "alternatives"})
    EXPECT_TRUE(step.contains(key)) << key;
  for (const auto& a : step["alternatives"]) {
    ASSERT_TRUE(a.contains("tell_apart")) << a.dump();
    ASSERT_TRUE(a.contains("prior_overruled") && a["prior_overruled"].is_boolean()) << a.dump();
    ASSERT_TRUE(a.contains("data_favour") && a["data_favour"].is_boolean()) << a.dump();
    if (a["prior_overruled"].get<bool>()) {
      EXPECT_TRUE(a["data_favour"].get<bool>()) << a.dump();
    }
    const auto& reading = a["tell_apart"]["reading"];
    if (!reading.is_null()) {
      for (const char* key : {"node", "location", "direction", "measured_mode", "separation"})
        EXPECT_TRUE(reading.contains(key)) << key;
    }
  }
  EXPECT_EQ(step["name"], "added_mass_tip.mass");
  ASSERT_TRUE(step["location"].is_array());
  EXPECT_NEAR(step["location"][0].get<double>(), 4, 1e-12);  // the tip is the face x = 4
  // Its place spread: a distance, and at least its own place.
  ASSERT_TRUE(step.contains("place_spread") && step["place_spread"].is_number()) << step.dump();
  EXPECT_GE(step["place_spread"].get<double>(), 0) << step.dump();
  EXPECT_GE(step["places"].get<int>(), 1) << step.dump();
  EXPECT_EQ(d["accepted"], nlohmann::json::array({"added_mass_tip.mass"}));
  EXPECT_EQ(d["residual_final"]["model_form_error"], false);
  EXPECT_LT(d["residual_final"]["statistic"].get<double>(), step["chi2_before"].get<double>());
  // One step that ends consistent with the noise walks no other first step.
  ASSERT_TRUE(d["paths"].is_array()) << d.dump();
  EXPECT_TRUE(d["paths"].empty()) << d["paths"].dump();
  // The first step's screen and the one with its effect in: neither a model screened before.
  EXPECT_GE(d["screens"]["run"].get<int>(), 2) << d["screens"].dump();
  EXPECT_EQ(d["screens"]["taken_again"].get<int>(), 0) << d["screens"].dump();
  bool block_wide_is_null = false;
  for (const auto& r : d["ranking"])
    if (r["name"] == "bar.stiffness_scale" || r["name"] == "bar.mass_scale") block_wide_is_null = r["location"].is_null();
  EXPECT_TRUE(block_wide_is_null);

  // The plot, and a problem with the effect that calibrate continues from.
  run = RunCli("diagnose " + study + " --quiet --plot " + dir + "/steps.png --write-problem " + dir + "/with.yaml");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_GT(std::filesystem::file_size(dir + "/steps.png"), 0u);
  run = RunCli("calibrate " + dir + "/with.yaml --method reduced-lbfgs --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output << ReadFile(dir + "/with.yaml");
  EXPECT_NE(run.output.find("(added: mass of point mass added_mass_tip)"), std::string::npos) << run.output;
  // ... and diagnose on it starts from the model with the effect: nothing more to add.
  run = RunCli("diagnose " + dir + "/with.yaml --quiet --json " + dir + "/again.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json again = nlohmann::json::parse(ReadFile(dir + "/again.json"));
  EXPECT_EQ(again["started_with"], nlohmann::json::array({"added_mass_tip.mass"}));
  EXPECT_TRUE(again["steps"].empty()) << run.output;
  EXPECT_EQ(again["residual_final"]["model_form_error"], false);

  // The engineer adds it: calibrate again with it, before and after side by side.
  run = RunCli("calibrate " + study + " --method reduced-lbfgs --quiet --add point_mass@tip:mass --json " + dir +
               "/added.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* part : {"--- before and after adding the effects", "without [Hz]", "with [Hz]",
                           "(added: mass of point mass added_mass_tip)", "without: chi-square", "with: chi-square"})
    EXPECT_NE(run.output.find(part), std::string::npos) << part << "\n" << run.output;
  const nlohmann::json a = nlohmann::json::parse(ReadFile(dir + "/added.json"));
  ASSERT_EQ(a["effects"].size(), 1u);
  EXPECT_EQ(a["effects"][0]["name"], "added_mass_tip.mass");
  EXPECT_NEAR(a["effects"][0]["value"].get<double>(), 0.05, 0.005);
  EXPECT_EQ(a["residual_before"]["model_form_error"], true);
  EXPECT_EQ(a["residual_after"]["model_form_error"], false);
  // Its report still serves as --params for the problem without the effect.
  EXPECT_EQ(RunCli("compare " + study + " --params " + dir + "/added.json").exit_code, 0);

  // The same through an effect the problem file enables.
  const std::string enabled = WriteTempFile(
      "enabled.yaml", std::string(kSensedBar) +
                          "measured: {file: data.yaml}\neffects:\n  - {effect: \"point_mass@tip:mass\", enable: true}\n");
  run = RunCli("calibrate " + enabled + " --method reduced-lbfgs --quiet");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("(added: mass of point mass added_mass_tip)"), std::string::npos) << run.output;

  run = RunCli("calibrate " + study + " --method reduced-lbfgs --quiet --add bar.nosuch");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("--add: effect 'bar.nosuch'"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("no property 'nosuch'"), std::string::npos) << run.output;
}

// The README's two-effect walk-through: the first path takes both effects and ends consistent with
// the noise, so the loop is walked from no other first step unless
// --alternatives-after-consistent-end asks for it; either way it keeps two effects.
TEST(Cli, DiagnoseWalksOtherPathsAfterAConsistentEndOnlyWhenAsked) {
  const std::string dir =
      std::filesystem::path(testing::WriteTempFile("consistent_end_marker.txt", "")).parent_path().string();
  const std::string problem = testing::SourcePath("problems/portal-frame/two-effects.yaml");
  for (const bool asked : {false, true}) {
    const std::string json = dir + (asked ? "/walked_again.json" : "/first_path.json");
    const CliRun run = RunCli("diagnose " + problem + " --quiet" +
                              (asked ? " --alternatives-after-consistent-end" : "") + " --json " + json);
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const nlohmann::json d = nlohmann::json::parse(ReadFile(json));
    ASSERT_EQ(d["accepted"].size(), 2u) << d["accepted"].dump();
    EXPECT_EQ(d["residual_final"]["model_form_error"], false) << d["residual_final"].dump();
    ASSERT_TRUE(d["paths"].is_array()) << d.dump();
    EXPECT_EQ(d["paths"].empty(), !asked) << d["paths"].dump();
  }
}

// A bundled synthetic problem: noise-free data of the right model, no noise stated. The JSON
// says the fit meets the data to their resolution, and where the calibration started.
TEST(Cli, DiagnoseOfNoiseFreeDataOfTheRightModelAsksForNothing) {
  const std::string dir =
      std::filesystem::path(testing::WriteTempFile("noise_free_marker.txt", "")).parent_path().string();
  const CliRun run = RunCli("diagnose " + testing::SourcePath("problems/portal-frame/synthetic.yaml") +
                            " --quiet --jobs 1 --json " + dir + "/noise_free.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("No model-form error: with no stated noise"), std::string::npos) << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/noise_free.json"));
  EXPECT_EQ(d["model_form_error"], false);
  EXPECT_EQ(d["residual_final"]["at_resolution"], true);
  EXPECT_TRUE(d["residual_final"]["p_value"].is_null());
  EXPECT_EQ(d["parameters"][0]["name"], "conn_kry");
  EXPECT_EQ(d["parameters"][0]["initial"], 200.0);  // the file's start, not where a later walk began
  EXPECT_EQ(d["accepted"].size(), 0u);
}

/// A portal-frame problem measured by six frequencies of its right model with 0.2 % noise and
/// no shapes, written to the test's temporary directory; returns its path.
std::string WriteSixFrequenciesProblem() {
  testing::WriteTempFile("frequencies_only.yaml",
                         "noise: {frequency: 0.002, shape: 0.01, seed: 1}\n"
                         "modes:\n"
                         "  - {frequency_hz: 22.73250288946627, pair: {model_mode: 1}}\n"
                         "  - {frequency_hz: 32.404108204235115, pair: {model_mode: 2}}\n"
                         "  - {frequency_hz: 80.27471898534337, pair: {model_mode: 3}}\n"
                         "  - {frequency_hz: 141.63470789815477, pair: {model_mode: 4}}\n"
                         "  - {frequency_hz: 197.42548190786124, pair: {model_mode: 5}}\n"
                         "  - {frequency_hz: 310.1125154555781, pair: {model_mode: 6}}\n");
  return testing::WriteTempFile("frequencies_only_problem.yaml",
                                "extends: " + testing::SourcePath("problems/portal-frame/synthetic.yaml") +
                                    "\nmeasured: {file: frequencies_only.yaml}\n");
}

// Six frequencies of the portal frame's right model with 0.2 % noise, no shapes: from the file's
// start the first calibration stops far from the truth (chi-square 1.7e4, conn_krx on its upper
// bound). Whatever path a machine's calibration takes, the diagnosis must end at the right model
// calibrated near its truth, and say so; when it had to leave a local minimum it says that too.
TEST(Cli, DiagnoseLeavesALocalMinimumOfTheFirstCalibration) {
  const std::string problem = WriteSixFrequenciesProblem();
  const std::string dir = std::filesystem::path(problem).parent_path().string();
  // Without further starts, which would leave the minimum before the loop does.
  const CliRun run =
      RunCli("diagnose " + problem + " --quiet --jobs 1 --calibration-starts 0 --json " + dir + "/local_minimum.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/local_minimum.json"));
  EXPECT_EQ(d["model_form_error"], false) << run.output;
  EXPECT_LT(d["residual_before"]["statistic"].get<double>(), 20) << run.output;
  EXPECT_NEAR(d["parameters"][1]["final"].get<double>(), 500, 50);  // conn_krx, truth 500
  EXPECT_EQ(d["parameters"][1]["initial"], 1500.0);
  if (!d["first_calibration_local_minimum"].is_null()) {
    EXPECT_GT(d["first_calibration_local_minimum"].get<double>(), d["residual_before"]["statistic"].get<double>());
    EXPECT_NE(run.output.find("The first calibration stopped in a local minimum"), std::string::npos);
  }
}

// Six frequencies of the portal frame's right model, no shapes: from the file's start the
// calibration stops in a local minimum (misfit 0.12 here, conn_krx 58 against its truth 500).
// With --starts the kept run is the lowest of all, which three of the four further starts reach
// here; whatever path a machine takes, one of four must, and the JSON lists every start.
TEST(Cli, CalibrateFromFurtherStartsKeepsTheLowestMisfit) {
  const std::string problem = WriteSixFrequenciesProblem();
  const std::string dir = std::filesystem::path(problem).parent_path().string();
  const CliRun run = RunCli("calibrate " + problem + " --starts 4 --quiet --uncertainty none --json " + dir +
                            "/starts.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/starts.json"));
  ASSERT_EQ(d["starts"].size(), 5u);
  double lowest = INFINITY;
  for (const auto& s : d["starts"])
    if (s["misfit"].is_number()) lowest = std::min(lowest, s["misfit"].get<double>());
  EXPECT_EQ(d["starts"][d["start"].get<size_t>()]["misfit"].get<double>(), lowest);
  EXPECT_NEAR(d["parameters"][1]["final"].get<double>(), 500, 50) << run.output;  // conn_krx
  EXPECT_NE(run.output.find("kept the calibration from"), std::string::npos);
  EXPECT_EQ(RunCli("calibrate " + problem + " --starts -1").exit_code, 2);
}

// The portal frame read by three sensor DOFs, with 20 g hidden on column 2 and noise. From the
// file's start the first calibration stops in a minimum with a chi-square near 1.4e5, against
// 345 at the truth's (conn_kry on its lower bound, E far off). Further starts spread over the
// bounds reach the right minimum, whatever path this machine's first calibration takes; the
// diagnosis, not misled by the local minimum, ends consistent with the noise.
TEST(Cli, DiagnoseCalibratesFromFurtherStartsWhenTheFirstStopsFarFromTheData) {
  const std::string few = testing::WriteTempFile(
      "few_sensors.yaml", "extends: " + testing::SourcePath("problems/portal-frame/synthetic.yaml") +
                              "\nname: few-sensors\nsensors:\n"
                              "  - {at: [0.0, 0.01, 0.45], tolerance: 0.0125, directions: [x, y]}\n"
                              "  - {at: [0.245, 0.01, 0.525], tolerance: 0.0125, directions: [z]}\n");
  const std::string dir = std::filesystem::path(few).parent_path().string();
  ASSERT_EQ(RunCli("synth " + few + " --truth 'point_mass@[0.4,0,0.3]:mass=0.02' --noise-freq 0.002 "
                   "--noise-shape 0.01 --seed 1 -o " + dir + "/few_sensors_data.yaml")
                .exit_code,
            0);
  const std::string problem = testing::WriteTempFile(
      "few_sensors_mass.yaml", "extends: few_sensors.yaml\nmeasured: {file: few_sensors_data.yaml}\n");
  const CliRun run =
      RunCli("diagnose " + problem + " --jobs 1 --mesh-check 0 --json " + dir + "/few_sensors.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/few_sensors.json"));
  EXPECT_LT(d["residual_before"]["statistic"].get<double>(), 1000) << run.output;  // 345 at the truth's minimum
  EXPECT_EQ(d["residual_final"]["model_form_error"], false) << run.output;
  EXPECT_EQ(d["parameters"][1]["initial"], 1500.0);  // the file's start, wherever the kept run began
  if (d["calibration"]["start"].get<int>() > 0) {
    EXPECT_GT(d["first_calibration_local_minimum"].get<double>(), d["residual_before"]["statistic"].get<double>());
    EXPECT_NE(run.output.find("a calibration from another start"), std::string::npos) << run.output;
    // The progress display says what the further starts are doing meanwhile.
    EXPECT_NE(run.output.find("calibrating again from 4 further starts"), std::string::npos) << run.output;
  }
}

// Bounds that keep every parameter from the values the data ask for: every calibration, and
// refits with the parameters held on their bounds, end on a corner of the box. The check of a
// walk's end there had no free direction left and read an empty matrix (exit 139).
TEST(Cli, DiagnoseWithEveryParameterHeldOnABoundRunsToAVerdict) {
  const std::string problem = testing::WriteTempFile(
      "held_on_bounds.yaml",
      "extends: " + testing::SourcePath("problems/portal-frame/hidden-mass.yaml") +
          "\nparameters:\n"
          "  conn_kry: {targets: [conn_1.kry, conn_2.kry], initial: 75, lower: 50, upper: 100, scaling: log}\n"
          "  conn_krx: {targets: [conn_1.krx, conn_2.krx], initial: 1500, lower: 1000, upper: 2000, scaling: log}\n"
          "  E: {targets: [column_1.E, column_2.E, beam.E], initial: 2.5e9, lower: 2e9, upper: 3e9, scaling: log}\n"
          "  payload_mass: {targets: [payload.mass], initial: 3, lower: 2, upper: 4, scaling: log}\n");
  const std::string json = std::filesystem::path(problem).parent_path().string() + "/held_on_bounds.json";
  const CliRun run = RunCli("diagnose " + problem +
                            " --quiet --jobs 1 --mesh-check 0 --max-steps 1 --first-step-alternatives 0 --json " + json);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(json));
  EXPECT_EQ(d["model_form_error"], true);
  EXPECT_NEAR(d["parameters"][0]["final"].get<double>(), 100, 1e-6);  // held on conn_kry's upper bound
  EXPECT_NEAR(d["parameters"][2]["final"].get<double>(), 3e9, 1e-6 * 3e9);
  ASSERT_EQ(d["calibration_on_bounds"].size(), 4u);
  EXPECT_EQ(d["calibration_on_bounds"][0], "conn_kry (upper bound 100)");
  EXPECT_NE(run.output.find("on a bound of the range you gave"), std::string::npos) << run.output;
}

// The loop started from an enabled effect that releases a support (which, once released, could
// not be described again on the changed model); the same effect added again is bad input; and
// with no effect kept, --write-problem still writes a problem that calibrate loads.
TEST(Cli, DiagnoseStartsFromAnEnabledSupportAndWritesAProblemWithNoEffectKept) {
  const std::string study = testing::WriteTipMassStudy();
  const std::string dir = std::filesystem::path(study).parent_path().string();
  const std::string support = WriteTempFile(
      "support.yaml", kSensedBar + "measured: {file: data.yaml}\neffects:\n  - {effect: \"support@root:kx\", enable: true}\n");
  CliRun run = RunCli("diagnose " + support + " --quiet --max-steps 0 --mesh-check 0 --json " + dir + "/support.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const nlohmann::json d = nlohmann::json::parse(ReadFile(dir + "/support.json"));
  EXPECT_EQ(d["started_with"], nlohmann::json::array({"support_root.kx"}));
  run = RunCli("diagnose " + support + " --quiet --max-steps 0 --add support@root:kx");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("is support_root.kx, which the problem's enabled effects or an earlier --add already add"),
            std::string::npos)
      << run.output;

  run = RunCli("diagnose " + study + " --quiet --max-steps 0 --mesh-check 0 --write-problem " + dir + "/none.yaml");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(ReadFile(dir + "/none.yaml").find("effects: []"), std::string::npos) << ReadFile(dir + "/none.yaml");
  run = RunCli("calibrate " + dir + "/none.yaml --method reduced-lbfgs --quiet");
  EXPECT_EQ(run.exit_code, 0) << run.output << ReadFile(dir + "/none.yaml");
}

TEST(Cli, SynthThenCompareAndCalibrateShowTheHiddenEffect) {
  const std::string nominal = WriteTempFile("nominal.yaml", kSensedBar);
  const std::string dir = std::filesystem::path(nominal).parent_path().string();
  const std::string synth = "synth " + nominal + " --truth bar.density=1.1 --truth 'point_mass@tip:mass=0.05' " +
                            "--modes 1,2,3,4 --noise-freq 0.002 --noise-shape 0.01 --seed 3 -o ";
  CliRun run = RunCli(synth + dir + "/data.yaml");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("hidden effect: added_mass_tip.mass = 0.05 (nominal 0): added point mass at node set tip"),
            std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("hidden effect: bar.density = 1.1 (nominal 1)"), std::string::npos) << run.output;
  ASSERT_EQ(RunCli(synth + dir + "/again.yaml").exit_code, 0);
  EXPECT_EQ(ReadFile(dir + "/data.yaml"), ReadFile(dir + "/again.yaml"));  // same seed, same file

  // The nominal problem pointed at the data (it takes its sensors from them).
  const std::string study = WriteTempFile("study.yaml", kSensedBar + "measured: {file: data.yaml}\n");
  const std::string json_path = dir + "/compare.json";
  run = RunCli("compare " + study + " --set E=1100 --json " + json_path + " --mac-plot " + dir + "/mac.png --error-plot " +
               dir + "/errors.svg");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("MAC matrix"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("COMAC per sensor DOF"), std::string::npos) << run.output;
  const nlohmann::json j = nlohmann::json::parse(ReadFile(json_path));
  ASSERT_EQ(j["pairs"].size(), 4u);
  for (const auto& pair : j["pairs"]) {
    // The tip mass changes the shapes a little (the fourth mode: MAC 0.83, cross-orthogonality 0.80).
    EXPECT_EQ(pair["model_mode"], pair["measured"]);
    EXPECT_GT(pair["mac"].get<double>(), 0.8);
    EXPECT_GT(pair["cross_orthogonality"].get<double>(), 0.75);
    // The model (E = 1100, without the extra density and mass) is stiffer and lighter than the truth.
    EXPECT_GT(pair["error_percent"].get<double>(), 5);
  }
  ASSERT_EQ(j["hidden_effect"].size(), 2u);
  EXPECT_EQ(j["hidden_effect"][1]["name"], "added_mass_tip.mass");
  EXPECT_EQ(j["hidden_effect"][1]["value"], 0.05);
  EXPECT_EQ(j["hidden_effect"][1]["nominal_value"], 0);
  EXPECT_EQ(j["mac_matrix"].size(), 4u);
  EXPECT_EQ(j["mac_matrix"][0].size(), j["model_modes_hz"].size());
  EXPECT_EQ(j["comac"].size(), 27u);
  EXPECT_TRUE(j["comac"][0]["comac"].is_null());  // the clamped root
  EXPECT_EQ(j["parameters"][0]["value"], 1100);
  EXPECT_TRUE(std::filesystem::file_size(dir + "/mac.png") > 0);
  EXPECT_NE(ReadFile(dir + "/errors.svg").find("<svg"), std::string::npos);

  run = RunCli("calibrate " + study + " --method reduced-lbfgs --quiet --json " + dir + "/calibrate.json --vtu " + dir +
               "/vtu");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("hidden effect: added_mass_tip.mass"), std::string::npos) << run.output;
  const nlohmann::json calibrated = nlohmann::json::parse(ReadFile(dir + "/calibrate.json"));
  EXPECT_EQ(calibrated["hidden_effect"][1]["name"], "added_mass_tip.mass");
  // The calibrated model for ParaView: the final E on every cell, the measured shapes at the sensors.
  const std::string grid = ReadFile(dir + "/vtu/calibrated.vtu");
  EXPECT_NE(grid.find("Name=\"parameter_E\""), std::string::npos);
  EXPECT_NE(grid.find("Name=\"mode_1_"), std::string::npos);
  EXPECT_NE(ReadFile(dir + "/vtu/calibrated_sensors.vtu").find("Name=\"measured_1_"), std::string::npos);

  // --sensors measures every node of a node set in x, y and z (the tip: 2 x 3 nodes).
  ASSERT_EQ(RunCli("synth " + nominal + " --modes 1,2 --sensors tip -o " + dir + "/tip.yaml").exit_code, 0);
  const std::string tip = ReadFile(dir + "/tip.yaml");
  size_t sensors = 0;
  for (size_t at = tip.find("  - {node:"); at != std::string::npos; at = tip.find("  - {node:", at + 1)) ++sensors;
  EXPECT_EQ(sensors, 18u) << tip;

  // Bad input names the cause and exits with 2; the problem file is never overwritten.
  run = RunCli("synth " + nominal + " --modes 1 --truth nosuch.kx=1 -o " + dir + "/bad.yaml");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("unknown entity 'nosuch'; known blocks, joints, springs and point masses: bar"),
            std::string::npos)
      << run.output;
  run = RunCli("synth " + nominal + " --modes 1 --truth bar.E=900 -o " + dir + "/bad.yaml");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("calibration parameter's target"), std::string::npos) << run.output;
  const std::string before = ReadFile(nominal);
  run = RunCli("synth " + nominal + " --modes 1 -o " + nominal);
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.output.find("refusing"), std::string::npos) << run.output;
  EXPECT_EQ(ReadFile(nominal), before);
}

TEST(Cli, CampaignCalibratesEachDataSetAndTellsTestToTestVariationFromNoise) {
  const std::string nominal = WriteTempFile("campaign-nominal.yaml", kSensedBar);
  const std::string dir = std::filesystem::path(nominal).parent_path().string();
  std::filesystem::create_directories(dir + "/campaign");
  const std::string synth = "synth " + nominal + " --modes 1,2,3,4 --noise-freq 0.002 --noise-shape 0.01 ";
  for (int seed = 1; seed <= 5; ++seed)
    ASSERT_EQ(RunCli(synth + "--seed " + std::to_string(seed) + " -o " + dir + "/campaign/unit" + std::to_string(seed) +
                     ".yaml")
                  .exit_code,
              0);
  // Five tests of one structure: E spreads as each calibration's own uncertainty says (tested at
  // 0.1 %, so that a false "varies" has a chance of one in a thousand for any draw of the noise).
  CliRun run = RunCli("campaign " + nominal + " " + dir + "/campaign --significance 0.001 --json " + dir +
                      "/campaign.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  nlohmann::json j = nlohmann::json::parse(ReadFile(dir + "/campaign.json"));
  ASSERT_EQ(j["runs"].size(), 5u);
  for (const auto& r : j["runs"]) {
    EXPECT_TRUE(r["ok"].get<bool>()) << r.dump();
    EXPECT_NEAR(r["parameters"][0]["value"].get<double>() / 1000, 1, 0.01) << r.dump();
    EXPECT_GT(r["parameters"][0]["standard_error"].get<double>(), 0);
  }
  ASSERT_EQ(j["summary"].size(), 1u);
  EXPECT_EQ(j["summary"][0]["runs"], 5);
  EXPECT_FALSE(j["summary"][0]["varies_between_tests"].get<bool>()) << j["summary"].dump();

  // A sixth unit 20 % denser (its E calibrates 20 % lower: f ~ sqrt(E / density)) and a data
  // file that does not parse:
  // the bad one is reported and skipped, and E now varies beyond the noise.
  ASSERT_EQ(RunCli(synth + "--truth bar.density=1.2 --seed 4 -o " + dir + "/heavy.yaml").exit_code, 0);
  const std::string bad = WriteTempFile("campaign-bad.yaml", "modes: [oops\n");
  run = RunCli("campaign " + nominal + " " + dir + "/campaign " + dir + "/heavy.yaml " + bad +
               " --significance 0.001 --json " + dir + "/campaign2.json");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("FAILED, skipped"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("varies between tests"), std::string::npos) << run.output;
  j = nlohmann::json::parse(ReadFile(dir + "/campaign2.json"));
  ASSERT_EQ(j["runs"].size(), 7u);
  EXPECT_FALSE(j["runs"][6]["ok"].get<bool>());
  EXPECT_NE(j["runs"][6]["reason"].get<std::string>().find("campaign-bad.yaml"), std::string::npos);
  EXPECT_NEAR(j["runs"][5]["parameters"][0]["value"].get<double>() * 1.2 / 1000, 1, 0.01) << j["runs"][5].dump();
  EXPECT_EQ(j["summary"][0]["runs"], 6);
  EXPECT_TRUE(j["summary"][0]["varies_between_tests"].get<bool>()) << j["summary"].dump();

  // Nothing usable: bad input, exit 2.
  run = RunCli("campaign " + nominal + " " + bad);
  EXPECT_EQ(run.exit_code, 2) << run.output;
}

}  // namespace
}  // namespace modalcal
