#include "fullspace/box_qp.hpp"

#include <Eigen/Cholesky>

#include <vector>

namespace modalcal::detail {

BoxQpResult solve_box_qp(const Matrix& H, const Vector& h, const Vector& lower, const Vector& upper) {
  const int m = static_cast<int>(h.size());
  BoxQpResult out;
  out.d = Vector::Zero(m);
  // Working set: -1 at lower, +1 at upper, 0 free. Start from d = 0 with the bounds that are
  // already touched (a parameter on its bound) in the working set.
  std::vector<int> bound(m, 0);
  for (int j = 0; j < m; ++j) {
    if (lower[j] >= 0) bound[j] = -1;
    else if (upper[j] <= 0) bound[j] = 1;
  }
  for (int iteration = 0; iteration < 10 * m + 10; ++iteration) {
    std::vector<int> free;
    for (int j = 0; j < m; ++j)
      if (bound[j] == 0) free.push_back(j);
    // Minimizer on the working set's face: H_FF d_F = h_F - H_FB d_B.
    Vector target = out.d;
    if (!free.empty()) {
      const int f = static_cast<int>(free.size());
      Matrix Hf(f, f);
      Vector rhs(f);
      for (int a = 0; a < f; ++a) {
        rhs[a] = h[free[a]];
        for (int j = 0; j < m; ++j)
          if (bound[j] != 0) rhs[a] -= H(free[a], j) * out.d[j];
        for (int b = 0; b < f; ++b) Hf(a, b) = H(free[a], free[b]);
      }
      const Vector dF = Hf.llt().solve(rhs);
      for (int a = 0; a < f; ++a) target[free[a]] = dF[a];
    }
    // Step toward it as far as the bounds allow.
    double step = 1;
    int blocking = -1;
    for (int j : free) {
      const double move = target[j] - out.d[j];
      if (move < 0 && out.d[j] + move < lower[j]) {
        const double t = (lower[j] - out.d[j]) / move;
        if (t < step) step = t, blocking = j;
      } else if (move > 0 && out.d[j] + move > upper[j]) {
        const double t = (upper[j] - out.d[j]) / move;
        if (t < step) step = t, blocking = j;
      }
    }
    out.d += step * (target - out.d);
    if (blocking >= 0) {
      bound[blocking] = target[blocking] < out.d[blocking] ? -1 : 1;
      out.d[blocking] = bound[blocking] < 0 ? lower[blocking] : upper[blocking];
      continue;
    }
    // At the face's minimizer: a bound stays if the objective pushes against it.
    const Vector gradient = H * out.d - h;
    int release = -1;
    double worst = 0;
    for (int j = 0; j < m; ++j) {
      const double push = bound[j] < 0 ? gradient[j] : bound[j] > 0 ? -gradient[j] : 0;  // >= 0 holds it
      if (push < worst) worst = push, release = j;
    }
    if (release < 0) {
      out.converged = true;
      break;
    }
    bound[release] = 0;
  }
  out.at_bound.resize(m);
  for (int j = 0; j < m; ++j) out.at_bound[j] = bound[j] != 0;
  return out;
}

}  // namespace modalcal::detail
