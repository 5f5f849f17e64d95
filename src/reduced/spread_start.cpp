#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "modalcal/reduced.hpp"

namespace modalcal {

namespace {

/// The radical inverse of k in `base`: k's digits in that base mirrored about the point, in [0, 1).
double radical_inverse(int k, int base) {
  double place = 1, value = 0;
  for (int rest = k; rest > 0; rest /= base) {
    place /= base;
    value += place * (rest % base);
  }
  return value;
}

/// The first `count` primes (2, 3, 5, ...), by trial division: a few hundred at most.
std::vector<int> first_primes(size_t count) {
  std::vector<int> primes;
  for (int n = 2; primes.size() < count; ++n) {
    bool prime = true;
    for (int q : primes) {
      if (q * q > n) break;
      if (n % q == 0) {
        prime = false;
        break;
      }
    }
    if (prime) primes.push_back(n);
  }
  return primes;
}

}  // namespace

Vector spread_start(const std::vector<Parameter>& parameters, int k) {
  if (k < 1) throw std::invalid_argument("spread_start: k = " + std::to_string(k) + ": must be >= 1");
  const std::vector<int> bases = first_primes(parameters.size());
  const Eigen::Index n = static_cast<Eigen::Index>(parameters.size());
  Vector lower(n), upper(n), initial(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    const Parameter& q = parameters[static_cast<size_t>(j)];
    lower[j] = q.lower, upper[j] = q.upper, initial[j] = q.initial;
  }
  const ParameterScaling scaling(parameters);  // the optimizer's variables
  const Vector lo = scaling.to_scaled(lower), hi = scaling.to_scaled(upper);
  Vector x(n);
  for (Eigen::Index j = 0; j < n; ++j) x[j] = lo[j] + radical_inverse(k, bases[static_cast<size_t>(j)]) * (hi[j] - lo[j]);
  Vector p = scaling.to_physical(x);
  for (Eigen::Index j = 0; j < n; ++j)
    if (!std::isfinite(p[j])) p[j] = initial[j];  // no finite box to spread over
  return p;
}

}  // namespace modalcal
