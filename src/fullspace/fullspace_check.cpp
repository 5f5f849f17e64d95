// Directional central-difference check of the full-space objective gradient, constraint
// Jacobian and Lagrangian Hessian. Directions, not whole matrices: the check costs a few
// evaluations per block of unknowns at any model size.

#include <cstdio>

#include "fullspace/fullspace_problem.hpp"
#include "modalcal/fullspace.hpp"
#include "support/random_draws.hpp"

namespace modalcal {

namespace {

// y = A d for a layout's entries; with `symmetric` the stored lower triangle stands for both.
Vector apply(const detail::SparseLayout& layout, const Vector& values, const Vector& d, int rows, bool symmetric) {
  std::vector<int> r(layout.nonzeros()), c(layout.nonzeros());
  layout.structure(r.data(), c.data());
  Vector out = Vector::Zero(rows);
  for (int k = 0; k < layout.nonzeros(); ++k) {
    out[r[k]] += values[k] * d[c[k]];
    if (symmetric && r[k] != c[k]) out[c[k]] += values[k] * d[r[k]];
  }
  return out;
}

// Transposed product J^T y.
Vector apply_transpose(const detail::SparseLayout& layout, const Vector& values, const Vector& y, int cols) {
  std::vector<int> r(layout.nonzeros()), c(layout.nonzeros());
  layout.structure(r.data(), c.data());
  Vector out = Vector::Zero(cols);
  for (int k = 0; k < layout.nonzeros(); ++k) out[c[k]] += values[k] * y[r[k]];
  return out;
}

double relative(const Vector& analytic, const Vector& difference) {
  const double scale = std::max(analytic.norm(), difference.norm());
  return scale > 0 ? (analytic - difference).norm() / scale : 0.0;
}

}  // namespace

FullSpaceDerivativeCheck check_fullspace_derivatives(Objective& objective, const Vector& p, double relative_step,
                                                     unsigned seed) {
  objective.require_parameters(p, "check_fullspace_derivatives");
  const Problem& problem = objective.problem();
  const ParameterScaling scaling(problem.parameters);
  detail::FullSpaceProblem fp(objective, scaling, p);
  const Evaluation e = objective.evaluate(p, Need::Value);
  if (!e.ok) throw std::runtime_error("check_fullspace_derivatives: forward solve failed: " + e.message);
  const int N = fp.num_variables(), m = fp.num_constraints(), n = fp.num_dofs(), l = fp.num_modes();
  Matrix U(n, l);
  Vector lambda(l);
  for (int i = 0; i < l; ++i) {
    const int k = e.pairs[fp.measured_of(i)].model;
    U.col(i) = e.modal.modes.col(k);
    lambda[i] = e.modal.eigenvalues[k];
  }
  // A generic point near the solution manifold, and generic multipliers, so that no term
  // vanishes by accident.
  detail::Uniform uniform(seed);
  auto noise = [&](int size) {
    Vector v(size);
    for (int k = 0; k < size; ++k) v[k] = uniform(-1.0, 1.0);
    return v;
  };
  Vector x = fp.pack(U, lambda, p);
  x += 1e-2 * x.cwiseAbs().cwiseMax(1e-3).cwiseProduct(noise(N));
  const Vector y = noise(m);
  const double sigma = 0.7;

  auto gradient_of = [&](const Vector& at) {
    Vector g(N);
    fp.objective_gradient(at.data(), g.data());
    return g;
  };
  auto constraints_of = [&](const Vector& at) {
    Vector c(m);
    fp.constraints(at.data(), c.data());
    return c;
  };
  auto jacobian_values = [&](const Vector& at) {
    Vector v(fp.jacobian_layout().nonzeros());
    fp.jacobian_values(at.data(), v.data());
    return v;
  };
  auto lagrangian_gradient = [&](const Vector& at) {
    return Vector(sigma * gradient_of(at) + apply_transpose(fp.jacobian_layout(), jacobian_values(at), y, N));
  };
  Vector hessian(fp.hessian_layout().nonzeros());
  fp.hessian_values(x.data(), sigma, y.data(), hessian.data());
  const Vector jacobian = jacobian_values(x), gradient = gradient_of(x);

  FullSpaceDerivativeCheck check;
  const struct { const char* name; int begin, size; } blocks[] = {
      {"modes u", 0, l * n}, {"eigenvalues t", l * n, l}, {"parameters q", l * (n + 1), fp.num_parameters()}};
  for (const auto& block : blocks) {
    Vector d = Vector::Zero(N);
    d.segment(block.begin, block.size) = noise(block.size);
    d /= d.norm();
    const double h = relative_step * std::max(1.0, x.segment(block.begin, block.size).cwiseAbs().maxCoeff());
    const Vector plus = x + h * d, minus = x - h * d;
    const double g_error = std::abs(gradient.dot(d) - (fp.objective(plus.data()) - fp.objective(minus.data())) / (2 * h)) /
                           std::max(std::abs(gradient.dot(d)), 1e-300);
    const double j_error = relative(apply(fp.jacobian_layout(), jacobian, d, m, false),
                                    (constraints_of(plus) - constraints_of(minus)) / (2 * h));
    const double h_error = relative(apply(fp.hessian_layout(), hessian, d, N, true),
                                    (lagrangian_gradient(plus) - lagrangian_gradient(minus)) / (2 * h));
    const bool has_gradient = gradient.dot(d) != 0;
    if (has_gradient) check.gradient_error = std::max(check.gradient_error, g_error);
    check.jacobian_error = std::max(check.jacobian_error, j_error);
    check.hessian_error = std::max(check.hessian_error, h_error);
    char line[200];
    std::snprintf(line, sizeof line, "%-14s objective gradient %-8s  Jacobian %.2e  Lagrangian Hessian %.2e", block.name,
                  has_gradient ? (std::to_string(g_error).substr(0, 8)).c_str() : "(zero)  ", j_error, h_error);
    check.lines.push_back(line);
  }
  return check;
}

}  // namespace modalcal
