// Synthetic data with hidden effects: the truth model, the noise (deterministic, right
// statistics), the data file written and read back by a problem, and the data file's errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "support/random_draws.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/measured_data.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/synthesis.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

namespace fs = std::filesystem;
using testing::LoadProblem;
using testing::WriteTempFile;

// A cantilevered bar (non-square section, so no repeated eigenvalues) with triaxial sensors on
// its top edge (9 nodes, the first at the clamped root) and Young's modulus to calibrate.
const std::string kBase = testing::CantileverBar() + R"(options: {num_modes: 8}
)";

const char* const kSensors = R"(
sensors:
  - {node_set: top_edge, directions: [x, y, z]}
)";

std::string Nominal(const std::string& truth = "truth: 1200, ") {
  return kBase + kSensors + "parameters:\n  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, " +
         truth + "scaling: log}\n";
}

Problem LoadNominal() {
  return LoadProblem(WriteTempFile("nominal.yaml", Nominal() + "measured:\n  synthetic: {modes: [1, 2, 3, 4, 5, 6]}\n"));
}

SynthesisOptions Options(double frequency_noise, double shape_noise, std::uint64_t seed) {
  SynthesisOptions o;
  o.modes = {1, 2, 3, 4, 5, 6};
  o.noise.frequency = frequency_noise;
  o.noise.shape = shape_noise;
  o.noise.seed = seed;
  return o;
}

TEST(StandardNormal, IsDeterministicWithTheRightMoments) {
  detail::StandardNormal a(7), b(7), c(8);
  const int n = 200000;
  double sum = 0, squares = 0, fourth = 0;
  int within_one = 0, same_as_other_seed = 0;
  for (int i = 0; i < n; ++i) {
    const double z = a();
    ASSERT_EQ(z, b());  // same seed, same draws
    same_as_other_seed += z == c();
    sum += z;
    squares += z * z;
    fourth += z * z * z * z;
    within_one += std::abs(z) < 1;
  }
  EXPECT_EQ(same_as_other_seed, 0);
  // Standard errors: mean 1/sqrt(n) = 0.0022, variance sqrt(2/n) = 0.0032, P(|z|<1) 0.001.
  EXPECT_NEAR(sum / n, 0.0, 0.01);
  EXPECT_NEAR(squares / n, 1.0, 0.015);
  EXPECT_NEAR(fourth / n, 3.0, 0.1);  // kurtosis of a normal
  EXPECT_NEAR(static_cast<double>(within_one) / n, 0.682689, 0.005);
}

TEST(Synthesis, ZeroNoiseReproducesTheTruthModelExactly) {
  const Problem nominal = LoadNominal();
  // A hidden stiffness multiplier of 0.81 on the block: the truth is the nominal model at
  // E = 1200 * 0.81, whose frequencies we compute independently through the parameter.
  const TruthModel truth = make_truth(nominal, nullptr, {parse_model_change("bar.stiffness_scale=0.81")});
  ASSERT_EQ(truth.record.hidden_effects.size(), 1u);
  EXPECT_EQ(truth.record.hidden_effects[0].name, "bar.stiffness_scale");
  EXPECT_EQ(truth.record.hidden_effects[0].value, 0.81);
  EXPECT_EQ(truth.record.hidden_effects[0].nominal_value, 1);
  ASSERT_EQ(truth.record.parameters.size(), 1u);
  EXPECT_EQ(truth.record.parameters[0], std::make_pair(std::string("E"), 1200.0));
  EXPECT_EQ(truth.record.changes, std::vector<std::string>{"bar.stiffness_scale=0.81"});
  EXPECT_TRUE(truth.record.other_differences.empty()) << truth.record.other_differences;

  const MeasuredData data = synthesize_measured_data(nominal, truth, nominal.sensors, Options(0, 0, 1));
  ParametricSystem system(nominal.model, nominal.parameter_targets());
  SparseMatrix K, M;
  system.assemble(Vector::Constant(1, 1200 * 0.81), &K, &M);
  ModalOptions options;
  options.num_modes = 8;
  options.max_rigid_modes = 0;
  ModalSolver solver(system.pattern(), options);
  const ModalResult r = solver.solve(K, M);
  ASSERT_EQ(data.modes.size(), 6u);
  for (int k = 0; k < 6; ++k) {
    EXPECT_CLOSE(data.modes[k].frequency_hz, frequency_hz(r.eigenvalues[k]), 1e-9);
    EXPECT_EQ(data.modes[k].frequency_hz, data.truth_modes[k].frequency_hz);  // no noise at all
    EXPECT_EQ(data.truth_modes[k].mode, k + 1);
    EXPECT_EQ(data.modes[k].pairing.kind, PairingRule::Kind::Mac);
    // The shape is the mode at the sensors, scaled to a largest entry of +1.
    Vector exact(static_cast<Eigen::Index>(nominal.sensors.size()));
    for (size_t s = 0; s < nominal.sensors.size(); ++s)
      exact[s] = system.dof_map().value(r.modes.col(k), nominal.sensors[s].node, nominal.sensors[s].component);
    EXPECT_NEAR(mac(data.modes[k].shape, exact), 1.0, 1e-9);
    EXPECT_EQ(data.modes[k].shape.maxCoeff(), 1.0);
  }
}

TEST(Synthesis, NoiseIsDeterministicBySeedWithTheStatedSpread) {
  const Problem nominal = LoadNominal();
  const TruthModel truth = make_truth(nominal, nullptr, {});
  EXPECT_TRUE(truth.record.hidden_effects.empty());
  const MeasuredData exact = synthesize_measured_data(nominal, truth, nominal.sensors, Options(0, 0, 3));
  const MeasuredData a = synthesize_measured_data(nominal, truth, nominal.sensors, Options(0.01, 0.02, 3));
  const MeasuredData b = synthesize_measured_data(nominal, truth, nominal.sensors, Options(0.01, 0.02, 3));
  const MeasuredData c = synthesize_measured_data(nominal, truth, nominal.sensors, Options(0.01, 0.02, 4));
  double squares = 0;
  int n = 0;
  for (size_t k = 0; k < a.modes.size(); ++k) {
    EXPECT_EQ(a.modes[k].frequency_hz, b.modes[k].frequency_hz);
    EXPECT_EQ(a.modes[k].shape, b.modes[k].shape);
    EXPECT_NE(a.modes[k].frequency_hz, c.modes[k].frequency_hz);
    const double z = (a.modes[k].frequency_hz / exact.modes[k].frequency_hz - 1) / 0.01;
    EXPECT_NE(z, 0.0);
    EXPECT_LT(std::abs(z), 5.0);
    // Shape noise: 0.02 times the largest |value|, which is 1.
    const Vector shape_z = (a.modes[k].shape - exact.modes[k].shape) / 0.02;
    squares += shape_z.squaredNorm();
    n += static_cast<int>(shape_z.size());
  }
  // 6 modes x 27 sensor DOFs = 162 draws: the sample standard deviation is 1 +- 0.06.
  EXPECT_NEAR(std::sqrt(squares / n), 1.0, 0.2);
}

TEST(Synthesis, RefusesToHideACalibratedProperty) {
  const Problem nominal = LoadNominal();
  try {
    make_truth(nominal, nullptr, {parse_model_change("bar.E=1300")});
    ADD_FAILURE() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("calibration parameter's target"), std::string::npos) << e.what();
  }
}

TEST(Synthesis, TruthFileAddsPhysicsTheNominalModelLacks) {
  const Problem nominal = LoadNominal();
  WriteTempFile("base.yaml", kBase);
  const std::string truth_path = WriteTempFile("truth.yaml", R"(extends: base.yaml
reference_nodes:
  tip_ref: [4.25, 0.25, 0.375]
rigid_couplings:
  - {reference: tip_ref, node_set: tip}
point_masses:
  payload: {node: tip_ref, mass: 0.2, inertia: [0.01, 0.01, 0.01]}
)");
  const Problem truth_file = LoadProblem(truth_path);
  const TruthModel truth = make_truth(nominal, &truth_file, {});
  std::vector<std::string> names;
  for (const ModelEffect& e : truth.record.hidden_effects) names.push_back(e.name);
  EXPECT_EQ(names, (std::vector<std::string>{"payload.mass", "payload.Ixx", "payload.Iyy", "payload.Izz"}));
  EXPECT_EQ(truth.record.hidden_effects[0].nominal_value, 0);
  EXPECT_EQ(truth.record.hidden_effects[0].value, 0.2);
  EXPECT_NE(truth.record.other_differences.find("55 nodes against 54"), std::string::npos)
      << truth.record.other_differences;
  // The nominal parameter's truth applies to the truth file's model too.
  EXPECT_EQ(truth.problem.model.properties[truth.problem.model.find_property("bar.E")].value, 1200);
  const MeasuredData data = synthesize_measured_data(nominal, truth, nominal.sensors, Options(0, 0, 1));
  const MeasuredData plain = synthesize_measured_data(nominal, make_truth(nominal, nullptr, {}), nominal.sensors, Options(0, 0, 1));
  EXPECT_LT(data.modes[0].frequency_hz, plain.modes[0].frequency_hz);  // the payload lowers it
}

// ---------------------------------------------------------------------------- data files

/// Writes the data of `changes` next to a problem that reads them and returns the problem's path.
std::string WriteStudy(const std::string& problem_text, const std::vector<std::string>& changes, double noise = 0) {
  const Problem nominal = LoadNominal();
  std::vector<ModelChange> parsed;
  for (const std::string& c : changes) parsed.push_back(parse_model_change(c));
  const MeasuredData data =
      synthesize_measured_data(nominal, make_truth(nominal, nullptr, parsed), nominal.sensors, Options(noise, noise, 5));
  write_measured_data(WriteTempFile("data.yaml", ""), data, {});
  return WriteTempFile("study.yaml", problem_text);
}

TEST(MeasuredDataFile, RoundTripsIntoTheNominalProblem) {
  const Problem nominal = LoadNominal();
  const MeasuredData data = synthesize_measured_data(
      nominal, make_truth(nominal, nullptr, {parse_model_change("point_mass@tip:mass=0.01")}), nominal.sensors,
      Options(0.003, 0.01, 9));
  const std::string data_path = WriteTempFile("data.yaml", "");
  write_measured_data(data_path, data, {});
  // The nominal problem without a truth value: the data's truth completes it.
  const Problem p = LoadProblem(WriteTempFile("study.yaml", Nominal("") + "measured: {file: data.yaml}\n"));
  EXPECT_EQ(p.measured_file, data_path);
  ASSERT_EQ(p.measured.size(), data.modes.size());
  for (size_t k = 0; k < data.modes.size(); ++k) {
    EXPECT_EQ(p.measured[k].frequency_hz, data.modes[k].frequency_hz);  // bit for bit
    EXPECT_EQ(p.measured[k].shape, data.modes[k].shape);
    EXPECT_EQ(p.measured[k].label, data.modes[k].label);
    EXPECT_EQ(p.measured[k].pairing.kind, PairingRule::Kind::Mac);
  }
  ASSERT_TRUE(p.parameters[0].truth);
  EXPECT_EQ(*p.parameters[0].truth, 1200);
  ASSERT_TRUE(p.synthetic_truth);
  ASSERT_EQ(p.synthetic_truth->hidden_effects.size(), 1u);
  const ModelEffect& e = p.synthetic_truth->hidden_effects[0];
  EXPECT_EQ(e.name, "added_mass_tip.mass");
  EXPECT_EQ(e.value, 0.01);
  EXPECT_EQ(e.nominal_value, 0);
  EXPECT_EQ(e.description, data.truth->hidden_effects[0].description);
  EXPECT_EQ(p.synthetic_truth->changes, std::vector<std::string>{"point_mass@tip:mass=0.01"});
  ASSERT_TRUE(p.measurement_noise);
  EXPECT_EQ(p.measurement_noise->frequency, 0.003);
  EXPECT_EQ(p.measurement_noise->seed, 9u);

  // Without its own sensors, a problem takes the data's (same nodes, same order).
  const Problem adopted = LoadProblem(WriteTempFile(
      "adopt.yaml", kBase + "measured: {file: data.yaml}\n"));
  ASSERT_EQ(adopted.sensors.size(), nominal.sensors.size());
  for (size_t s = 0; s < nominal.sensors.size(); ++s) {
    EXPECT_EQ(adopted.sensors[s].node, nominal.sensors[s].node);
    EXPECT_EQ(adopted.sensors[s].component, nominal.sensors[s].component);
  }
  // A synthetic problem records its truth too: no hidden effect.
  ASSERT_TRUE(nominal.synthetic_truth);
  EXPECT_TRUE(nominal.synthetic_truth->hidden_effects.empty());
}

/// Loading `problem` must fail at `line` of `file` with every fragment in the message.
void ExpectLoadError(const std::string& problem, const std::string& file, int line,
                     const std::vector<std::string>& fragments) {
  try {
    LoadProblem(problem);
    ADD_FAILURE() << "expected a ProblemError";
  } catch (const ProblemError& e) {
    EXPECT_EQ(fs::path(e.file()).filename(), fs::path(file).filename()) << e.what();
    EXPECT_EQ(e.line(), line) << e.what();
    for (const std::string& f : fragments)
      EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << "'" << f << "' not in: " << e.what();
  }
}

int LineOf(const std::string& path, const std::string& fragment) {
  std::ifstream in(path);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    if (line.find(fragment) != std::string::npos) return n;
  ADD_FAILURE() << "no '" << fragment << "' in " << path;
  return 0;
}

/// Replaces the first `from` in a file by `to`.
void Edit(const std::string& path, const std::string& from, const std::string& to) {
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  std::ofstream(path) << text;
}

TEST(MeasuredDataFile, ErrorsNameTheDataFileAndLine) {
  const std::string study = WriteStudy(Nominal() + "measured: {file: data.yaml}\n", {});
  const std::string data = fs::path(study).parent_path() / "data.yaml";
  ASSERT_NO_THROW(LoadProblem(study));

  // A shape one value short (the first sensor is at the clamped root: 0).
  Edit(data, "shape: [0, ", "shape: [");
  ExpectLoadError(study, data, LineOf(data, "shape: ["), {"'shape' has 26 values but the sensors measure 27"});

  // A sensor that is not the problem's (the sensors list x of every node, then y, then z).
  WriteStudy(Nominal() + "measured: {file: data.yaml}\n", {});
  const int first_y = LineOf(data, "direction: y");
  Edit(data, "direction: y", "direction: z");
  ExpectLoadError(study, data, first_y, {"data sensor 10: is +z at [0, 0.5, 0.75] but the problem's sensor DOF 10 is node",
                                         "+y", "same order"});

  // A sensor missing from the list.
  WriteStudy(Nominal() + "measured: {file: data.yaml}\n", {});
  Edit(data, "  - {node:", "  # - {node:");
  ExpectLoadError(study, data, LineOf(data, "sensors:"), {"lists 26 sensor DOFs but the problem's 'sensors' measure 27"});

  // A sensor position with no node, in a problem that takes the data's sensors.
  const std::string adopt = WriteStudy(kBase + "measured: {file: data.yaml}\n", {});
  Edit(data, "at: [0, 0.5, 0.75]", "at: [0, 0.6, 0.75]");
  ExpectLoadError(adopt, data, LineOf(data, "at: [0, 0.6, 0.75]"), {"no node within"});

  // A truth that contradicts the problem's.
  const std::string contradicts = WriteStudy(Nominal("truth: 1100, ") + "measured: {file: data.yaml}\n", {});
  ExpectLoadError(contradicts, data, LineOf(data, "\"E\": 1200"), {"made with 'E' = 1200", "gives it the truth 1100"});

  // A missing data file is named at the problem's line.
  const std::string missing = WriteTempFile("missing.yaml", Nominal() + "measured: {file: nosuch.yaml}\n");
  ExpectLoadError(missing, missing, LineOf(missing, "nosuch.yaml"), {"no such data file", "relative to this file's folder"});
}

}  // namespace
}  // namespace modalcal
