#include <cmath>
#include <stdexcept>
#include <string>

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

constexpr int kPrimes[] = {2,   3,   5,   7,   11,  13,  17,  19,  23,  29,  31,  37,  41,  43,  47,  53,
                           59,  61,  67,  71,  73,  79,  83,  89,  97,  101, 103, 107, 109, 113, 127, 131,
                           137, 139, 149, 151, 157, 163, 167, 173, 179, 181, 191, 193, 197, 199, 211, 223,
                           227, 229, 233, 239, 241, 251, 257, 263, 269, 271, 277, 281, 283, 293, 307, 311};

}  // namespace

Vector spread_start(const std::vector<Parameter>& parameters, int k) {
  if (k < 1) throw std::invalid_argument("spread_start: k = " + std::to_string(k) + ": must be >= 1");
  constexpr size_t kMaxParameters = sizeof kPrimes / sizeof kPrimes[0];
  if (parameters.size() > kMaxParameters)
    throw std::invalid_argument("spread_start: " + std::to_string(parameters.size()) + " parameters: at most " +
                                std::to_string(kMaxParameters));
  Vector p(static_cast<Eigen::Index>(parameters.size()));
  for (size_t j = 0; j < parameters.size(); ++j) {
    const Parameter& q = parameters[j];
    const double u = radical_inverse(k, kPrimes[j]);
    const bool in_log = q.scaling == Scaling::Log && q.lower > 0;
    p[static_cast<Eigen::Index>(j)] =
        !(std::isfinite(q.lower) && std::isfinite(q.upper)) ? q.initial  // no box to spread over
        : in_log ? std::pow(10.0, std::log10(q.lower) + u * (std::log10(q.upper) - std::log10(q.lower)))
               : q.lower + u * (q.upper - q.lower);
  }
  return p;
}

}  // namespace modalcal
