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
  Vector p(static_cast<Eigen::Index>(parameters.size()));
  for (size_t j = 0; j < parameters.size(); ++j) {
    const Parameter& q = parameters[j];
    const double u = radical_inverse(k, bases[j]);
    const bool in_log = q.scaling == Scaling::Log && q.lower > 0;
    p[static_cast<Eigen::Index>(j)] =
        !(std::isfinite(q.lower) && std::isfinite(q.upper)) ? q.initial  // no box to spread over
        : in_log ? std::pow(10.0, std::log10(q.lower) + u * (std::log10(q.upper) - std::log10(q.lower)))
               : q.lower + u * (q.upper - q.lower);
  }
  return p;
}

}  // namespace modalcal
