#include <cmath>
#include <stdexcept>

#include "modalcal/objective.hpp"

namespace modalcal {

namespace {
constexpr double kLn10 = 2.302585092994046;
}

ParameterScaling::ParameterScaling(const std::vector<Parameter>& parameters) {
  reference_.resize(parameters.size());
  for (size_t j = 0; j < parameters.size(); ++j) {
    scaling_.push_back(parameters[j].scaling);
    reference_[j] = parameters[j].reference;
    if (scaling_[j] == Scaling::Linear && reference_[j] == 0)
      throw std::invalid_argument("parameter '" + parameters[j].name + "': linear scaling needs a nonzero reference");
  }
}

ParameterScaling::ParameterScaling(const std::vector<Parameter>& parameters, Scaling scaling)
    : ParameterScaling([&] {
        std::vector<Parameter> copy = parameters;
        for (Parameter& p : copy) {
          p.scaling = scaling;
          if (scaling == Scaling::Log && !(p.lower > 0))
            throw std::invalid_argument("parameter '" + p.name + "': log scaling needs a positive lower bound");
        }
        return copy;
      }()) {}

Vector ParameterScaling::to_scaled(const Vector& p) const {
  Vector x(p.size());
  for (int j = 0; j < p.size(); ++j) {
    switch (scaling_[j]) {
      case Scaling::None: x[j] = p[j]; break;
      case Scaling::Linear: x[j] = p[j] / reference_[j]; break;
      case Scaling::Log: x[j] = std::log10(p[j]); break;
    }
  }
  return x;
}

Vector ParameterScaling::to_physical(const Vector& x) const {
  Vector p(x.size());
  for (int j = 0; j < x.size(); ++j) {
    switch (scaling_[j]) {
      case Scaling::None: p[j] = x[j]; break;
      case Scaling::Linear: p[j] = x[j] * reference_[j]; break;
      case Scaling::Log: p[j] = std::pow(10.0, x[j]); break;
    }
  }
  return p;
}

Vector ParameterScaling::first_derivative(const Vector& x) const {
  Vector d(x.size());
  for (int j = 0; j < x.size(); ++j) {
    switch (scaling_[j]) {
      case Scaling::None: d[j] = 1; break;
      case Scaling::Linear: d[j] = reference_[j]; break;
      case Scaling::Log: d[j] = kLn10 * std::pow(10.0, x[j]); break;
    }
  }
  return d;
}

Vector ParameterScaling::second_derivative(const Vector& x) const {
  Vector d = Vector::Zero(x.size());
  for (int j = 0; j < x.size(); ++j)
    if (scaling_[j] == Scaling::Log) d[j] = kLn10 * kLn10 * std::pow(10.0, x[j]);
  return d;
}

}  // namespace modalcal
