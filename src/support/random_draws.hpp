#pragma once
// Internal: random draws that are the same on every platform. std::mt19937_64 is fully specified
// by the C++ standard; std::uniform_real_distribution and std::normal_distribution are not
// (libstdc++ and libc++ give different numbers), so the transforms are written out here: the top
// 53 bits of one engine output for a uniform draw, and Marsaglia's polar form of Box-Muller, which
// needs only sqrt (correctly rounded by IEEE 754) and log, for a normal one.

#include <cmath>
#include <cstdint>
#include <random>

namespace modalcal::detail {

/// Uniform on [0, 1) from the top 53 bits of one engine output: exact in a double.
inline double unit_uniform(std::mt19937_64& engine) { return static_cast<double>(engine() >> 11) * 0x1.0p-53; }

/// Uniform draws on [lower, upper), the same sequence for a seed on every platform.
class Uniform {
 public:
  explicit Uniform(std::uint64_t seed) : engine_(seed) {}
  double operator()(double lower, double upper) { return lower + (upper - lower) * unit_uniform(engine_); }

 private:
  std::mt19937_64 engine_;
};

/// Standard normal draws, the same sequence for a seed on every platform.
class StandardNormal {
 public:
  explicit StandardNormal(std::uint64_t seed) : engine_(seed) {}

  /// One N(0, 1) draw. Pairs (v1, v2) uniform on the square (-1, 1)^2 are drawn until
  /// \f$0 < s = v_1^2 + v_2^2 < 1\f$; then \f$v_{1,2}\sqrt{-2\ln s / s}\f$ are two independent
  /// standard normal draws (Marsaglia & Bray 1964); the second is kept for the next call.
  double operator()() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double v1 = 0, v2 = 0, s = 0;
    do {
      v1 = 2 * uniform() - 1;
      v2 = 2 * uniform() - 1;
      s = v1 * v1 + v2 * v2;
    } while (s >= 1 || s == 0);
    const double factor = std::sqrt(-2 * std::log(s) / s);
    spare_ = v2 * factor;
    has_spare_ = true;
    return v1 * factor;
  }

 private:
  double uniform() { return unit_uniform(engine_); }

  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0;
};

}  // namespace modalcal::detail
