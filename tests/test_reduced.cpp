// Reduced-space calibration: recovery from far starts (L-BFGS and Gauss-Newton), modes that
// swap order on the way, failed forward solves during a line search, the LFU synthetic study,
// and the identifiability flag of the LFU experimental case.

#include <cmath>

#include "modalcal/identifiability.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/problem_file.hpp"
#include "reduced/scaled_problem.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::SourcePath;

// Two independent oscillators (point masses on springs to ground, moving along x only):
// omega_a^2 = ka / m, omega_b^2 = kb / m. One sensor on each mass, so each measured shape
// names its mass.
Problem TwoOscillators(double ka_true, double kb_true, double ka0, double kb0) {
  Problem problem;
  problem.path = "two-oscillators";
  Model& model = problem.model;
  for (int i = 0; i < 2; ++i) model.add_node(i + 1, Vec3(i, 0, 0));
  FixedDofs lateral;
  lateral.name = "lateral";
  lateral.nodes = {0, 1};
  lateral.components = {false, true, true, false, false, false};
  model.fixed.push_back(lateral);
  const char* names[2] = {"a", "b"};
  const double truth[2] = {ka_true, kb_true}, start[2] = {ka0, kb0};
  const double m = 2.0;
  for (int i = 0; i < 2; ++i) {
    PointMass pm;
    pm.name = std::string("mass_") + names[i];
    pm.node = i;
    pm.mass = model.add_property(pm.name + ".mass", m);
    model.point_masses.push_back(pm);
    GroundSpring s;
    s.name = std::string("spring_") + names[i];
    s.nodes = {i};
    s.stiffness[0] = model.add_property(s.name + ".kx", start[i]);
    model.ground_springs.push_back(s);
    Parameter p;
    p.name = std::string("k") + names[i];
    p.targets = {s.stiffness[0]};
    p.initial = start[i];
    p.lower = 1.0;
    p.upper = 1e7;
    p.scaling = Scaling::Log;
    p.reference = start[i];
    p.truth = truth[i];
    problem.parameters.push_back(p);
    problem.sensors.push_back({i, 0, std::string("mass ") + names[i]});
  }
  for (int i = 0; i < 2; ++i) {
    MeasuredMode mode;
    mode.label = std::string("mass ") + names[i];
    mode.frequency_hz = std::sqrt(truth[i] / m) / (2 * M_PI);
    mode.shape = Vector::Zero(2);
    mode.shape[i] = (i == 0 ? -3.0 : 0.5);  // arbitrary sign and scale, as test data come
    mode.pairing.kind = PairingRule::Kind::Mac;
    problem.measured.push_back(mode);
  }
  problem.options.num_modes = 1;
  problem.options.max_rigid_modes = 0;
  return problem;
}

double MaxRelativeError(const Vector& p, const Vector& truth) {
  return (p.array() / truth.array() - 1).abs().maxCoeff();
}

class Recovery : public ::testing::TestWithParam<ReducedOptions::Method> {};

TEST_P(Recovery, ModesThatSwapOrderStillConvergeToTheTruth) {
  // Truth: mass a's mode is the higher one; start: it is the lower one. Pairing follows the
  // shapes, so each measured mode keeps its mass's model mode through the crossing.
  const Problem problem = TwoOscillators(4.0e4, 1.0e4, 1.0e3, 2.0e4);
  ObjectiveOptions objective_options;
  objective_options.extra_modes = 1;
  Objective objective(problem, objective_options);
  const Evaluation start = objective.evaluate(problem.initial_values());
  ASSERT_TRUE(start.ok) << start.message;
  EXPECT_EQ(start.pairs[0].model, 0);  // mass a is the lowest mode at the start
  ReducedOptions options;
  options.method = GetParam();
  const ReducedSummary s = minimize_reduced(objective, problem.initial_values(), options);
  EXPECT_TRUE(s.converged()) << s.FullReport();
  EXPECT_LT(MaxRelativeError(s.final, problem.truth_values()), 1e-6) << s.FullReport();
  const Evaluation end = objective.evaluate(s.final);
  EXPECT_EQ(end.pairs[0].model, 1);  // and the highest at the truth
}

INSTANTIATE_TEST_SUITE_P(Methods, Recovery,
                         ::testing::Values(ReducedOptions::Method::Lbfgs, ReducedOptions::Method::GaussNewton),
                         [](const auto& test) {
                           return test.param == ReducedOptions::Method::Lbfgs ? "Lbfgs" : "GaussNewton";
                         });

TEST(Reduced, FailedForwardSolveInTheLineSearchBacktracks) {
  // A search direction whose full step makes a stiffness negative: K is indefinite there, the
  // forward solve fails, and the search must back off to a point it can evaluate.
  const Problem problem = TwoOscillators(4.0e4, 1.0e4, 3.0e5, 2.0e5);
  Objective objective(problem);
  ReducedOptions options;
  options.use_bounds = false;
  options.scaling = Scaling::None;
  detail::ScaledProblem scaled(objective, options);
  const auto from = scaled.evaluate(problem.initial_values(), Need::Gradient);
  ASSERT_TRUE(from.ok) << from.message;
  Vector direction(2);
  direction << 0.0, -4.0e5;  // the full step takes kb from 2e5 to -2e5
  const auto accepted = scaled.line_search(from, direction, Need::Gradient, 1.0);
  ASSERT_TRUE(accepted.ok) << accepted.message;
  EXPECT_GE(scaled.failed_evaluations(), 1);
  EXPECT_GT(accepted.p[1], 0.0);
  EXPECT_LT(accepted.value, from.value);
}

TEST(Reduced, UnevaluableStartEndsWithStatusAndReason) {
  Problem problem = TwoOscillators(4.0e4, 1.0e4, 1.0e3, 2.0e4);
  Objective objective(problem);
  Vector start = problem.initial_values();
  start[0] = -5.0e4;  // indefinite K
  ReducedOptions options;
  options.use_bounds = false;
  options.scaling = Scaling::None;
  const ReducedSummary s = minimize_reduced(objective, start, options);
  EXPECT_EQ(s.status, ReducedStatus::ForwardSolveFailed);
  EXPECT_NE(s.message.find("indefinite"), std::string::npos) << s.message;
}

TEST(Reduced, FunctionToleranceStopsWhenTheObjectiveStopsMoving) {
  // A measured frequency the model cannot meet exactly (the first mode's shape is measured on the
  // wrong mass): the misfit stays positive, and the run ends when it stops falling.
  Problem problem = TwoOscillators(4.0e4, 1.0e4, 1.0e3, 2.0e4);
  problem.measured[0].shape << 1.0, 0.3;
  Objective objective(problem);
  ReducedOptions options;
  options.function_tolerance = 1e-6;
  const ReducedSummary s = minimize_reduced(objective, problem.initial_values(), options);
  ASSERT_TRUE(s.converged()) << s.FullReport();
  EXPECT_NE(s.message.find("lowered the objective by"), std::string::npos) << s.message;
  const IterationRecord& last = s.history.back();
  const IterationRecord& before = s.history[s.history.size() - 2];
  EXPECT_LE(before.objective - last.objective, 1e-6 * std::max(1.0, last.objective));
  options.function_tolerance = 1.5;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("function_tolerance"), std::string::npos) << error;
}

TEST(Reduced, OptionsAreValidatedNamingTheField) {
  ReducedOptions options;
  options.memory = 0;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("memory"), std::string::npos);
  options = ReducedOptions();
  options.armijo = 0.7;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("armijo"), std::string::npos);
  options = ReducedOptions();
  options.initial_damping = 0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("initial_damping"), std::string::npos);
}

TEST(Reduced, ALightlyDampedFirstStepFromANearStartGoesFurtherToTheSameMinimum) {
  // From 20 % and 10 % off the truth the Gauss-Newton model is nearly exact: the first step
  // damped by 1e-2 lowers J by more than 99 %, the one damped by 1 goes about half way (J falls by
  // about three quarters). Both runs end at the truth.
  const Problem problem = TwoOscillators(4.0e4, 1.0e4, 4.8e4, 1.1e4);
  ReducedOptions options;
  options.method = ReducedOptions::Method::GaussNewton;
  options.gradient_tolerance = 1e-12;
  std::vector<ReducedSummary> runs;
  for (double damping : {1.0, 1e-2}) {
    options.initial_damping = damping;
    Objective objective(problem);
    runs.push_back(minimize_reduced(objective, problem.initial_values(), options));
    ASSERT_TRUE(runs.back().converged()) << runs.back().FullReport();
    EXPECT_LT(MaxRelativeError(runs.back().final, problem.truth_values()), 1e-6) << runs.back().FullReport();
    ASSERT_GE(runs.back().history.size(), 2u);
  }
  const double start = runs[0].history[0].objective;
  EXPECT_GT(runs[0].history[1].objective, 0.05 * start) << runs[0].FullReport();
  EXPECT_LT(runs[1].history[1].objective, 0.05 * start) << runs[1].FullReport();
}

TEST(Lfu, SyntheticStudyLbfgsRecoversAllParametersWithin25Iterations) {
  const Problem problem = LoadProblem(SourcePath("problems/lfu/synthetic.yaml"));
  Objective objective(problem);
  ReducedOptions options;  // L-BFGS, bounds on, log scaling from the problem file
  options.max_iterations = 25;
  const ReducedSummary s = minimize_reduced(objective, problem.initial_values(), options);
  ASSERT_EQ(s.final.size(), 5);
  EXPECT_LT(MaxRelativeError(problem.initial_values(), problem.truth_values()), 0.91);  // 10x low start
  EXPECT_LT(MaxRelativeError(s.final, problem.truth_values()), 0.005) << s.FullReport();
  EXPECT_LE(s.iterations, 25);
}

TEST(SpreadStart, FillsTheBoxEvenlyInTheOptimizersVariables) {
  std::vector<Parameter> parameters(3);
  parameters[0].lower = 10, parameters[0].upper = 1e4, parameters[0].scaling = Scaling::Log;
  parameters[1].lower = -2, parameters[1].upper = 4, parameters[1].scaling = Scaling::Linear;
  parameters[2].lower = 1, parameters[2].upper = 2, parameters[2].scaling = Scaling::None;
  // Point 1 lies at 1/2, 1/3 and 1/5 of the ranges: of log10 for a log-scaled parameter
  // (10^2.5), of the value otherwise.
  const Vector first = spread_start(parameters, 1);
  EXPECT_NEAR(first[0], std::pow(10.0, 2.5), 1e-9 * first[0]);
  EXPECT_NEAR(first[1], 0.0, 1e-12);
  EXPECT_NEAR(first[2], 1.2, 1e-12);
  // The first 2^m - 1 points put one value in each of the 2^m strata of the first parameter's
  // range (base 2), and the first 3^m - 1 in each of the second's 3^m, but for the one at 0.
  std::vector<int> halves(8, 0), thirds(9, 0);
  for (int k = 1; k <= 8; ++k) {
    const Vector p = spread_start(parameters, k);
    for (int j = 0; j < 3; ++j) {
      EXPECT_GE(p[j], parameters[j].lower);
      EXPECT_LE(p[j], parameters[j].upper);
    }
    const double u0 = (std::log10(p[0]) - 1) / 3, u1 = (p[1] + 2) / 6;
    if (k <= 7) ++halves[static_cast<size_t>(std::floor(u0 * 8 + 1e-9))];
    ++thirds[static_cast<size_t>(std::floor(u1 * 9 + 1e-9))];
  }
  EXPECT_EQ(halves, std::vector<int>({0, 1, 1, 1, 1, 1, 1, 1}));
  EXPECT_EQ(thirds, std::vector<int>({0, 1, 1, 1, 1, 1, 1, 1, 1}));
  parameters[2].upper = INFINITY, parameters[2].initial = 1.25;  // no box: the initial value
  EXPECT_EQ(spread_start(parameters, 3)[2], 1.25);
  EXPECT_THROW(spread_start(parameters, 0), std::invalid_argument);
  std::vector<Parameter> many(200);  // the 200th prime is 1223: u = 3 / 1223 at k = 3
  for (Parameter& q : many) q.lower = 0, q.upper = 1;
  EXPECT_NEAR(spread_start(many, 3)[199], 3.0 / 1223, 1e-15);
}

TEST(Lfu, ExperimentalCaseMatchesTheAxialModesAndFlagsAPoorlyIdentifiedParameter) {
  const Problem problem = LoadProblem(SourcePath("problems/lfu/experimental.yaml"));
  Objective objective(problem);
  ReducedOptions options;
  const ReducedSummary s = minimize_reduced(objective, problem.initial_values() * 10, options);
  ASSERT_TRUE(s.converged()) << s.FullReport();
  const Evaluation e = objective.evaluate(s.final);
  ASSERT_TRUE(e.ok);
  ASSERT_EQ(e.pairs.size(), 2u);
  EXPECT_NEAR(e.pairs[0].model_hz, 1195.0, 0.1);
  EXPECT_NEAR(e.pairs[1].model_hz, 2085.0, 0.1);
  // Three parameters, two frequencies: one direction is unconstrained, and the tool names the
  // parameter that carries it; the joint stiffness, which both modes feel, is identified.
  const Identifiability id = analyze_identifiability(objective, s.final, ParameterScaling(problem.parameters));
  EXPECT_EQ(id.singular_values[2], 0.0);
  EXPECT_FALSE(id.poorly_identified[0]) << id.report;
  EXPECT_TRUE(id.poorly_identified[1] || id.poorly_identified[2]) << id.report;
}

}  // namespace
}  // namespace modalcal
