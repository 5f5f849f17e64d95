// The calibration objective: MAC pairing, value, adjoint gradient and residual Jacobian against
// central finite differences for every parameter kind (E, nu, K, G, density, scales, joint,
// spring, point mass and inertia) with eigenvalue and mode-shape terms and regularization.

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "modalcal/gradient_check.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/problem_file.hpp"
#include "objective/deflated_solve.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::WriteTempFile;

using testing::kEveryParameterKindModel;

Problem LoadModel() { return LoadProblem(WriteTempFile("model.yaml", kEveryParameterKindModel)); }

// A measured shape in odd units (or scaled far down) must pair as well as one of unit size.
TEST(Objective, MacDoesNotDependOnTheShapesScales) {
  Vector a(4), b(4);
  a << 1.0, -0.5, 0.25, 2.0;
  b << 0.9, -0.4, 0.3, 2.2;
  const double reference = mac(a, b);
  EXPECT_GT(reference, 0.9);
  for (double scale : {1e-300, 1e-200, 1e-160, 1e+160, 1e+300}) {
    SCOPED_TRACE(scale);
    EXPECT_NEAR(mac(scale * a, b), reference, 1e-14);
    EXPECT_NEAR(mac(a, scale * b), reference, 1e-14);
  }
  EXPECT_EQ(mac(Vector::Zero(4), b), 0.0);
  EXPECT_EQ(mac(Vector(), Vector()), 0.0);
}

TEST(Objective, VanishesAtTheTruthAndIsPositiveElsewhere) {
  const Problem problem = LoadModel();
  Objective objective(problem);
  const Evaluation at_truth = objective.evaluate(problem.truth_values());
  ASSERT_TRUE(at_truth.ok) << at_truth.message;
  EXPECT_LT(at_truth.value, 1e-16);
  for (const PairedMode& pair : at_truth.pairs) {
    EXPECT_EQ(pair.model, pair.measured);  // synthetic modes k pair with model mode k
    EXPECT_GT(pair.mac, 1 - 1e-12);
  }
  const Evaluation at_start = objective.evaluate(problem.initial_values());
  ASSERT_TRUE(at_start.ok) << at_start.message;
  EXPECT_GT(at_start.eigenvalue_term, 1e-4);
  EXPECT_GT(at_start.shape_term, 0.0);
  EXPECT_CLOSE(at_start.value, 0.5 * at_start.residuals.squaredNorm(), 1e-12);
}

// The derivative tests run on both eigenvalue misfit forms: (name, options) pairs.
std::vector<std::pair<const char*, ObjectiveOptions>> MisfitForms(double regularization) {
  ObjectiveOptions relative, logarithmic;
  relative.regularization = logarithmic.regularization = regularization;
  logarithmic.eigenvalue_misfit = ObjectiveOptions::EigenvalueMisfit::Logarithmic;
  return {{"relative", relative}, {"logarithmic", logarithmic}};
}

TEST(Objective, AdjointGradientMatchesCentralDifferencesForEveryParameterKind) {
  const Problem problem = LoadModel();
  for (const auto& [name, options] : MisfitForms(1e-3)) {
    SCOPED_TRACE(name);
    Objective objective(problem, options);
    GradientCheckOptions check_options;
    check_options.tolerance = 1e-5;
    const GradientCheck check = check_gradient(objective, problem.initial_values(), check_options);
    EXPECT_TRUE(check.ok) << check.report;
    EXPECT_LT(check.max_relative_error, 1e-5) << check.report;
    // Every parameter acts on the objective.
    for (int j = 0; j < check.analytic.size(); ++j) EXPECT_GT(std::abs(check.analytic[j]), 0.0) << j;
  }
}

// The relative misfit saturates where the model is far too soft (r -> -1, slope lambda/lambda_m
// in log-parameters -> 0); the logarithmic one keeps a slope of one, and near a fit both agree.
TEST(Objective, LogarithmicMisfitKeepsItsSlopeWhereTheRelativeOneSaturates) {
  Problem problem = LoadModel();
  for (MeasuredMode& m : problem.measured) m.shape.resize(0);  // eigenvalues only
  problem.sensors.clear();
  for (MeasuredMode& m : problem.measured) m.pairing.kind = PairingRule::Kind::ModelIndex;
  ObjectiveOptions log_options;
  log_options.eigenvalue_misfit = ObjectiveOptions::EigenvalueMisfit::Logarithmic;
  Objective relative(problem), logarithmic(problem, log_options);
  // Every stiffness parameter at 1e-2 of its truth: eigenvalues near 1e-2 of the measured ones.
  Vector soft = problem.truth_values();
  const std::set<std::string> stiffness = {"E", "K", "G", "kscale", "kx", "krz", "spring"};
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    if (stiffness.count(problem.parameters[j].name)) soft[static_cast<Eigen::Index>(j)] *= 1e-2;
  const Evaluation r = relative.evaluate(soft, Need::Gradient), l = logarithmic.evaluate(soft, Need::Gradient);
  ASSERT_TRUE(r.ok && l.ok) << r.message << l.message;
  // Slope along log p of the stiffnesses (sum of p_j dJ/dp_j): the relative form's is tiny, the
  // logarithmic one's is not.
  double relative_slope = 0, log_slope = 0;
  for (size_t j = 0; j < problem.parameters.size(); ++j)
    if (stiffness.count(problem.parameters[j].name)) {
      const Eigen::Index k = static_cast<Eigen::Index>(j);
      relative_slope += soft[k] * r.gradient[k];
      log_slope += soft[k] * l.gradient[k];
    }
  EXPECT_LT(std::abs(relative_slope), 1e-2 * std::abs(log_slope)) << relative_slope << " vs " << log_slope;
  EXPECT_LT(log_slope, 0);  // stiffening lowers the misfit
  // Near the truth the two agree to first order in the relative errors.
  Vector near = problem.truth_values() * 1.001;
  const Evaluation rn = relative.evaluate(near), ln = logarithmic.evaluate(near);
  ASSERT_TRUE(rn.ok && ln.ok);
  EXPECT_NEAR(ln.value / rn.value, 1.0, 1e-2);
  for (const PairedMode& pair : ln.pairs) EXPECT_NE(pair.relative_error, 0.0);  // reported as relative
}

TEST(Objective, EigenvalueOnlyGradientNeedsNoLinearSolve) {
  Problem problem = LoadModel();
  for (MeasuredMode& m : problem.measured) m.shape.resize(0);
  problem.sensors.clear();
  for (MeasuredMode& m : problem.measured) {
    m.pairing.kind = PairingRule::Kind::ModelIndex;
  }
  Objective objective(problem);
  const Evaluation e = objective.evaluate(problem.initial_values(), Need::Gradient);
  ASSERT_TRUE(e.ok) << e.message;
  EXPECT_EQ(e.linear_solves, 0);
  const GradientCheck check = check_gradient(objective, problem.initial_values());
  EXPECT_LT(check.max_relative_error, 1e-4) << check.report;
}

TEST(Objective, ResidualJacobianMatchesCentralDifferences) {
  const Problem problem = LoadModel();
  for (const auto& [name, options] : MisfitForms(0)) {
    SCOPED_TRACE(name);
    Objective objective(problem, options);
    const Vector p = problem.initial_values();
    const Evaluation e = objective.evaluate(p, Need::Jacobian);
    ASSERT_TRUE(e.ok) << e.message;
    ASSERT_EQ(e.jacobian.rows(), objective.num_residuals());
    // Gauss-Newton consistency: gradient = J^T r (no regularization here).
    EXPECT_LT((e.gradient - e.jacobian.transpose() * e.residuals).norm(), 1e-8 * e.gradient.norm());
    for (int j = 0; j < p.size(); ++j) {
      const double h = 1e-5 * std::abs(p[j]);
      Vector plus = p, minus = p;
      plus[j] += h;
      minus[j] -= h;
      const Evaluation ep = objective.evaluate(plus), em = objective.evaluate(minus);
      const Vector fd = (ep.residuals - em.residuals) / (2 * h);
      EXPECT_LT((fd - e.jacobian.col(j)).norm(), 1e-4 * (fd.norm() + 1e-12))
          << problem.parameters[j].name << "\nFD " << fd.transpose() << "\nJ  " << e.jacobian.col(j).transpose();
    }
  }
}

// In the span span_at(p) gives (the modes and the directions of their derivatives at p), the
// objective equals the whole model's at p, stays close to it a step away, and its gradient and
// Jacobian are the exact derivatives of the reduced model it then evaluates.
TEST(Objective, InTheSpanOfAPointItAgreesThereAndItsDerivativesAreExact) {
  const Problem problem = LoadModel();
  Objective whole(problem), reduced(problem);
  const Vector p = problem.initial_values();
  Matrix span = reduced.span_at(p);
  EXPECT_FALSE(reduced.in_span());
  ASSERT_LT(span.cols(), reduced.system().num_dofs());
  reduced.set_span(std::move(span));
  EXPECT_TRUE(reduced.in_span());
  const Evaluation at_whole = whole.evaluate(p), at_span = reduced.evaluate(p);
  ASSERT_TRUE(at_whole.ok && at_span.ok) << at_whole.message << at_span.message;
  EXPECT_NEAR(at_span.value, at_whole.value, 1e-8 * at_whole.value);
  // A step of 3 % in every parameter: the span's modes are good to first order, their
  // eigenvalues to second, so the misfit moves by a far smaller share than the step.
  const Vector q = p * 1.03;
  const Evaluation near_whole = whole.evaluate(q), near_span = reduced.evaluate(q);
  ASSERT_TRUE(near_whole.ok && near_span.ok) << near_whole.message << near_span.message;
  EXPECT_NEAR(near_span.value, near_whole.value, 1e-3 * near_whole.value);
  EXPECT_GT(std::abs(near_whole.value - at_whole.value), 1e-2 * at_whole.value) << "the step changes nothing";
  GradientCheckOptions check_options;
  check_options.tolerance = 1e-5;
  const GradientCheck check = check_gradient(reduced, q, check_options);
  EXPECT_TRUE(check.ok) << check.report;
  const Evaluation e = reduced.evaluate(q, Need::Jacobian);
  ASSERT_TRUE(e.ok) << e.message;
  for (int j = 0; j < q.size(); ++j) {
    const double h = 1e-5 * std::abs(q[j]);
    Vector plus = q, minus = q;
    plus[j] += h;
    minus[j] -= h;
    const Vector fd = (reduced.evaluate(plus).residuals - reduced.evaluate(minus).residuals) / (2 * h);
    EXPECT_LT((fd - e.jacobian.col(j)).norm(), 1e-4 * (fd.norm() + 1e-12)) << problem.parameters[j].name;
  }
  reduced.set_span(Matrix());
  EXPECT_NEAR(reduced.evaluate(q).value, near_whole.value, 1e-10 * near_whole.value);
  EXPECT_THROW(reduced.set_span(Matrix::Ones(3, 2)), std::invalid_argument);
}

// A span made at p for a model, extended for the model with one more parameter (its spring
// stiffness, as a diagnosis's candidate effect is added), serves the wider model as its own
// span_at would: it holds the wider model's modes at p, and a step in every parameter, the new
// one included, moves the misfit in the span as on the whole model. Without the extension the
// step in the new parameter is met less well.
TEST(Objective, ASpanExtendedForAWiderModelServesItAsItsOwnWould) {
  Problem wider_problem = LoadModel();
  std::vector<Parameter>& parameters = wider_problem.parameters;
  const auto spring = std::find_if(parameters.begin(), parameters.end(), [](const Parameter& q) { return q.name == "spring"; });
  ASSERT_NE(spring, parameters.end());
  std::rotate(spring, spring + 1, parameters.end());
  Problem narrow_problem = wider_problem;
  narrow_problem.parameters.pop_back();
  const Eigen::Index last = static_cast<Eigen::Index>(parameters.size()) - 1;
  Vector p = wider_problem.initial_values();
  p[last] = wider_problem.model.properties[parameters.back().targets.front()].value;  // where the narrow model is
  const Vector head = p.head(last);

  Objective narrow(narrow_problem), wider(wider_problem), whole(wider_problem), own_only(wider_problem);
  const Matrix own = narrow.span_at(head);
  const Matrix span = narrow.extend_span(own, head, wider.system(), p);
  EXPECT_FALSE(narrow.in_span());
  ASSERT_GT(span.cols(), own.cols());
  ASSERT_LT(span.cols(), wider.system().num_dofs());
  EXPECT_LE((span.leftCols(own.cols()) - own).norm(), 1e-14 * own.norm()) << "the narrow model's span is kept as it was";
  wider.set_span(span);
  own_only.set_span(own);
  const Evaluation at_whole = whole.evaluate(p), at_span = wider.evaluate(p);
  ASSERT_TRUE(at_whole.ok && at_span.ok) << at_whole.message << at_span.message;
  EXPECT_NEAR(at_span.value, at_whole.value, 1e-8 * at_whole.value);

  Vector q = p * 1.03;
  q[last] = 1.5 * p[last];
  const Evaluation near_whole = whole.evaluate(q), near_span = wider.evaluate(q), near_own = own_only.evaluate(q);
  ASSERT_TRUE(near_whole.ok && near_span.ok && near_own.ok) << near_whole.message << near_span.message;
  EXPECT_GT(std::abs(near_whole.value - at_whole.value), 1e-2 * at_whole.value) << "the step changes nothing";
  const double error = std::abs(near_span.value - near_whole.value);
  EXPECT_LT(error, 1e-3 * near_whole.value);
  EXPECT_LT(error, std::abs(near_own.value - near_whole.value)) << "the extension adds nothing";

  EXPECT_THROW(narrow.extend_span(own, head, narrow.system(), head), std::invalid_argument);  // nothing wider
  EXPECT_THROW(narrow.extend_span(own, head, wider.system(), head), std::invalid_argument);   // no value for it
  EXPECT_THROW(narrow.extend_span(Matrix::Ones(3, 2), head, wider.system(), p), std::invalid_argument);
}

TEST(Objective, SensorAdjointJacobianEqualsDirectSensitivities) {
  const Problem problem = LoadModel();
  ObjectiveOptions direct_options, adjoint_options;
  direct_options.jacobian = ObjectiveOptions::Jacobian::DirectSensitivities;
  adjoint_options.jacobian = ObjectiveOptions::Jacobian::SensorAdjoint;
  Objective direct(problem, direct_options), adjoint(problem, adjoint_options);
  const Vector p = problem.initial_values();
  const Evaluation a = direct.evaluate(p, Need::Jacobian), b = adjoint.evaluate(p, Need::Jacobian);
  ASSERT_TRUE(a.ok && b.ok) << a.message << b.message;
  EXPECT_LT(testing::RelativeDifference(b.jacobian, a.jacobian), 1e-8);
  // Automatic picks the sensor adjoint only when parameters outnumber sensor readings.
  Objective automatic(problem);
  const Evaluation c = automatic.evaluate(p, Need::Jacobian);
  ASSERT_TRUE(c.ok) << c.message;
  const bool more_parameters = p.size() > static_cast<int>(problem.sensors.size());
  EXPECT_EQ(c.linear_solves, more_parameters ? b.linear_solves : a.linear_solves);
}

// A chain of n masses on springs, fixed at one end: K tridiagonal, M diagonal (masses 1-2).
std::pair<SparseMatrix, SparseMatrix> SpringChain(int n) {
  std::vector<Eigen::Triplet<double>> k, m;
  for (int i = 0; i < n; ++i) {
    const double spring = 1.0 + 0.5 * std::sin(i), next = 1.0 + 0.5 * std::sin(i + 1);
    k.emplace_back(i, i, spring + (i + 1 < n ? next : 0.0));
    if (i + 1 < n) {
      k.emplace_back(i, i + 1, -next);
      k.emplace_back(i + 1, i, -next);
    }
    m.emplace_back(i, i, 1.5 + 0.5 * std::cos(3 * i));
  }
  SparseMatrix K(n, n), M(n, n);
  K.setFromTriplets(k.begin(), k.end());
  M.setFromTriplets(m.begin(), m.end());
  return {K, M};
}

// Modes sharing right-hand sides (the sensor adjoints) solve in one Krylov space: the same
// solutions as each mode's own conjugate gradients, the defining equations met, for a fraction
// of the preconditioner's columns; and when the space may not grow, each mode on its own.
TEST(DeflatedSolve, ModesSharingRightHandSidesShareOneKrylovSpace) {
  const int n = 300, computed = 10, readings = 6;
  const auto [K, M] = SpringChain(n);
  Eigen::GeneralizedSelfAdjointEigenSolver<Matrix> dense{Matrix(K), Matrix(M)};
  detail::DeflationBasis basis{dense.eigenvectors().leftCols(computed), dense.eigenvalues().head(computed), Matrix()};
  basis.mass_modes = M * basis.modes;
  const Eigen::LLT<Matrix> shifted{Matrix(K) - (-0.5 * basis.eigenvalues[0]) * Matrix(M)};
  auto precondition = [&](const Matrix& rhs) { return Matrix(shifted.solve(rhs)); };
  Matrix B = Matrix::Zero(n, readings);  // unit readings at a few DOFs, as sensors give
  for (int c = 0; c < readings; ++c) B(37 * c + 11, c) = 1.0;
  const std::vector<int> own = {0, 2, 3, 5, 6};
  std::vector<int> own_of_column;
  for (int mode : own) own_of_column.insert(own_of_column.end(), readings, mode);
  const double tolerance = 1e-10;

  const detail::DeflatedSolveResult alone = detail::solve_deflated(
      K, M, basis, own_of_column, B.replicate(1, static_cast<Eigen::Index>(own.size())), precondition, tolerance, 300);
  const detail::DeflatedSolveResult shared =
      detail::solve_deflated_shared(K, M, basis, own, B, precondition, tolerance, 300, n);
  ASSERT_TRUE(alone.converged && shared.converged) << alone.message << shared.message;
  EXPECT_LT(testing::RelativeDifference(shared.solution, alone.solution), 1e-7);
  EXPECT_LT(2 * shared.column_solves, alone.column_solves) << shared.column_solves << " against " << alone.column_solves;
  for (size_t k = 0; k < own.size(); ++k) {  // (K - lambda M) x = b less its own mode's part; x M-orthogonal to it
    const Eigen::Index first = static_cast<Eigen::Index>(k) * readings;
    const Vector u = basis.modes.col(own[k]);
    const Matrix X = shared.solution.middleCols(first, readings);
    const Matrix rhs = B - M * u * (u.transpose() * B);
    const Matrix residual = K * X - basis.eigenvalues[own[k]] * (M * X) - rhs;
    EXPECT_LT(residual.norm(), 1e-8 * rhs.norm()) << "mode " << own[k];
    EXPECT_LT((u.transpose() * M * X).norm(), 1e-8 * X.norm()) << "mode " << own[k];
  }
  const detail::DeflatedSolveResult narrow =
      detail::solve_deflated_shared(K, M, basis, own, B, precondition, tolerance, 300, readings);
  ASSERT_TRUE(narrow.converged) << narrow.message;
  EXPECT_LT(testing::RelativeDifference(narrow.solution, alone.solution), 1e-7);
  EXPECT_GT(narrow.column_solves, alone.column_solves) << "no fallback to each mode on its own";
}

TEST(Objective, ExactHessianMatchesCentralDifferencesOfTheGradient) {
  const Problem problem = LoadModel();
  for (const auto& [name, options] : MisfitForms(1e-3)) {
    SCOPED_TRACE(name);
    Objective objective(problem, options);
    // Away from the truth so that the second-order (residual-weighted) terms matter.
    const Vector p = problem.initial_values();
    const Evaluation e = objective.evaluate(p, Need::Hessian);
    ASSERT_TRUE(e.ok) << e.message;
    ASSERT_EQ(e.hessian.rows(), p.size());
    const Matrix gauss_newton = e.jacobian.transpose() * e.jacobian;
    Matrix fd(p.size(), p.size());
    for (int k = 0; k < p.size(); ++k) {
      const double h = 1e-5 * std::abs(p[k]);
      Vector plus = p, minus = p;
      plus[k] += h;
      minus[k] -= h;
      const Evaluation ep = objective.evaluate(plus, Need::Gradient), em = objective.evaluate(minus, Need::Gradient);
      ASSERT_TRUE(ep.ok && em.ok);
      fd.col(k) = (ep.gradient - em.gradient) / (2 * h);
    }
    // Compare column by column, scaled by each parameter so that units do not hide errors.
    const Matrix D = p.asDiagonal();
    const Matrix scaled_fd = D * fd * D, scaled = D * e.hessian * D, scaled_gn = D * gauss_newton * D;
    EXPECT_LT((scaled - scaled_fd).norm(), 1e-4 * scaled_fd.norm()) << "exact\n" << scaled << "\nFD\n" << scaled_fd;
    // And the second-order terms are really there: Gauss-Newton alone is clearly different.
    EXPECT_GT((scaled_gn - scaled_fd).norm(), 1e-2 * scaled_fd.norm());
  }
}

// A point evaluated again (the line search's accepted point, the final check) is not solved
// again; another point is. Also with no parameters at all, where every point is the empty vector.
TEST(Objective, ASecondEvaluationAtTheSamePointReusesItsForwardSolve) {
  const Problem problem = LoadModel();
  Objective objective(problem);
  const Vector p = problem.initial_values();
  const Evaluation first = objective.evaluate(p, Need::Value);
  const int after_first = objective.forward_solves();
  const Evaluation again = objective.evaluate(p, Need::Gradient);
  ASSERT_TRUE(first.ok && again.ok) << first.message << again.message;
  EXPECT_EQ(objective.forward_solves(), after_first);
  EXPECT_CLOSE(again.value, first.value, 1e-12);
  EXPECT_EQ(again.gradient.size(), p.size());
  objective.evaluate(p * 1.01, Need::Value);
  EXPECT_EQ(objective.forward_solves(), after_first + 1);

  const Problem fixed = LoadProblem(WriteTempFile(
      "fixed.yaml", testing::CantileverBar() + "measured:\n  modes: [{frequency_hz: 1.0}, {frequency_hz: 2.0}]\n"
                                               "options: {num_modes: 4}\n"));
  Objective no_parameters(fixed);
  EXPECT_EQ(no_parameters.forward_solves(), 0);
  const Evaluation e = no_parameters.evaluate(Vector(), Need::Value);
  ASSERT_TRUE(e.ok) << e.message;
  EXPECT_EQ(no_parameters.forward_solves(), 1);
  EXPECT_CLOSE(no_parameters.evaluate(Vector(), Need::Value).value, e.value, 1e-12);
  EXPECT_EQ(no_parameters.forward_solves(), 1);
}

TEST(Objective, CentralDifferenceGradientAgreesWithTheAdjointAndCostsTwoSolvesPerParameter) {
  const Problem problem = LoadModel();
  Objective adjoint(problem);
  ObjectiveOptions options;
  options.gradient = ObjectiveOptions::Gradient::CentralDifferences;
  Objective differences(problem, options);
  const Vector p = problem.initial_values();
  const Evaluation a = adjoint.evaluate(p, Need::Gradient);
  const int before = differences.forward_solves();
  const Evaluation d = differences.evaluate(p, Need::Gradient);
  ASSERT_TRUE(a.ok && d.ok);
  EXPECT_EQ(differences.forward_solves() - before, 1 + 2 * static_cast<int>(p.size()));
  EXPECT_LT((a.gradient - d.gradient).norm(), 1e-4 * a.gradient.norm());
}

TEST(Objective, MacPairingFollowsModesThatSwapOrder) {
  // Measured modes listed in reverse order with MAC pairing: each must find its own model mode.
  Problem problem = LoadModel();
  std::reverse(problem.measured.begin(), problem.measured.end());
  for (MeasuredMode& m : problem.measured) m.pairing.kind = PairingRule::Kind::Mac;
  Objective objective(problem);
  const Evaluation e = objective.evaluate(problem.truth_values());
  ASSERT_TRUE(e.ok) << e.message;
  for (const PairedMode& pair : e.pairs) EXPECT_EQ(pair.model, 5 - pair.measured);
  EXPECT_LT(e.value, 1e-16);
}

// Measured modes 1 and 2 carry each other's shapes: their MAC pairs cross (measured 1 on model
// 2, measured 2 on model 1), as at a minimum where a model mode would have to pass another. In
// frequency order the eigenvalue terms compare 1 with 1 and 2 with 2 again.
TEST(Objective, FrequencyOrderComparesEigenvaluesInOrderWithinTheMacPairs) {
  Problem problem = LoadModel();
  for (MeasuredMode& m : problem.measured) {
    m.pairing.kind = PairingRule::Kind::Mac;
    m.shape_weight = 0;
  }
  std::swap(problem.measured[0].shape, problem.measured[1].shape);
  const Vector truth = problem.truth_values();
  Objective paired(problem);
  const Evaluation crossed = paired.evaluate(truth);
  ASSERT_TRUE(crossed.ok) << crossed.message;
  EXPECT_EQ(crossed.pairs[0].model, 1);
  EXPECT_EQ(crossed.pairs[1].model, 0);
  EXPECT_GT(crossed.value, 1e-2);

  ObjectiveOptions options;
  options.eigenvalues_in_frequency_order = true;
  Objective in_order(problem, options);
  const Evaluation e = in_order.evaluate(truth);
  ASSERT_TRUE(e.ok) << e.message;
  for (const PairedMode& pair : e.pairs) EXPECT_EQ(pair.model, pair.measured);
  EXPECT_LT(e.value, 1e-16);
  // Its gradient away from the truth (the pairs still crossed by MAC) is the reordered pairs'
  // (the loosest entry, krz's, is 1e-5 of the largest: its differences carry 1e-5 truncation).
  GradientCheckOptions check_options;
  check_options.tolerance = 1e-4;
  const GradientCheck check = check_gradient(in_order, problem.initial_values(), check_options);
  EXPECT_TRUE(check.ok) << check.report;

  // With a weighted shape the reordering would compare a shape with another mode's: refused.
  problem.measured[3].shape_weight = 1;
  try {
    Objective refused(problem, options);
    ADD_FAILURE() << "a weighted shape was accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("eigenvalues_in_frequency_order"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("weighted shape"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace modalcal
