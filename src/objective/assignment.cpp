#include "objective/assignment.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace modalcal::detail {

std::vector<int> maximize_assignment(const Matrix& score) {
  const int n = static_cast<int>(score.rows()), m = static_cast<int>(score.cols());
  if (n > m) throw std::invalid_argument("maximize_assignment: more rows than columns");
  const double inf = std::numeric_limits<double>::infinity();
  // Minimize cost = -score with row/column potentials u, v (1-based, column 0 is a sentinel).
  std::vector<double> u(n + 1, 0.0), v(m + 1, 0.0);
  std::vector<int> owner(m + 1, 0), way(m + 1, 0);
  auto cost = [&](int i, int j) {
    const double s = score(i - 1, j - 1);
    return std::isfinite(s) ? -s : 1e12;  // forbidden pairs: prohibitively expensive
  };
  for (int i = 1; i <= n; ++i) {
    owner[0] = i;
    int j0 = 0;
    std::vector<double> minimum(m + 1, inf);
    std::vector<bool> used(m + 1, false);
    do {
      used[j0] = true;
      const int i0 = owner[j0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
        if (used[j]) continue;
        const double reduced = cost(i0, j) - u[i0] - v[j];
        if (reduced < minimum[j]) {
          minimum[j] = reduced;
          way[j] = j0;
        }
        if (minimum[j] < delta) {
          delta = minimum[j];
          j1 = j;
        }
      }
      for (int j = 0; j <= m; ++j) {
        if (used[j]) {
          u[owner[j]] += delta;
          v[j] -= delta;
        } else {
          minimum[j] -= delta;
        }
      }
      j0 = j1;
    } while (owner[j0] != 0);
    do {
      const int j1 = way[j0];
      owner[j0] = owner[j1];
      j0 = j1;
    } while (j0);
  }
  std::vector<int> column_of(n, -1);
  for (int j = 1; j <= m; ++j)
    if (owner[j] > 0) column_of[owner[j] - 1] = j - 1;
  return column_of;
}

}  // namespace modalcal::detail
