#include "modalcal/problem.hpp"

#include <cmath>

#include "support/text_util.hpp"
#include "modalcal/model_change.hpp"

namespace modalcal {

namespace {

// A file-level error (missing, unreadable) has no line; "file:0:" would suggest one.
std::string located(const std::string& file, int line, const std::string& message) {
  return line > 0 ? file + ":" + std::to_string(line) + ": " + message : file + ": " + message;
}

template <class Get>
Vector collect(const std::vector<Parameter>& parameters, Get get) {
  Vector v(static_cast<Eigen::Index>(parameters.size()));
  for (size_t i = 0; i < parameters.size(); ++i)
    v[static_cast<Eigen::Index>(i)] = get(parameters[i]);
  return v;
}

}  // namespace

// A net under the excerpts of each message: no error echoes more than about 1000 characters of
// input, whatever it quotes.
ProblemError::ProblemError(const std::string& file, int line, const std::string& message)
    : std::invalid_argument(located(detail::excerpt(file), line, detail::excerpt(message, 1000))),
      file_(file),
      line_(line),
      message_(detail::excerpt(message, 1000)) {}

bool MeasurementNoise::IsValid(std::string* error) const {
  auto check = [&](const char* field, double value, double upper) {
    if (value >= 0 && value <= upper) return true;
    if (error)
      *error = std::string(field) + " = " + format_round_trip(value) + ": must be in [0, " + format_round_trip(upper) + "]";
    return false;
  };
  return check("frequency", frequency, 0.2) && check("shape", shape, 1);
}

std::string to_string(Scaling scaling) {
  switch (scaling) {
    case Scaling::None:
      return "none";
    case Scaling::Linear:
      return "linear";
    case Scaling::Log:
      return "log";
  }
  return "?";
}

std::vector<std::vector<PropertyId>> Problem::parameter_targets() const {
  std::vector<std::vector<PropertyId>> targets;
  for (const Parameter& p : parameters) targets.push_back(p.targets);
  return targets;
}

Vector Problem::initial_values() const {
  return collect(parameters, [](const Parameter& p) { return p.initial; });
}

Vector Problem::lower_bounds() const {
  return collect(parameters, [](const Parameter& p) { return p.lower; });
}

Vector Problem::upper_bounds() const {
  return collect(parameters, [](const Parameter& p) { return p.upper; });
}

bool Problem::has_truth() const {
  for (const Parameter& p : parameters)
    if (!p.truth) return false;
  return true;
}

Vector Problem::truth_values() const {
  for (const Parameter& p : parameters)
    if (!p.truth) throw std::invalid_argument("parameter '" + p.name + "' has no truth value");
  return collect(parameters, [](const Parameter& p) { return *p.truth; });
}

int Problem::find_parameter(const std::string& parameter) const {
  for (size_t i = 0; i < parameters.size(); ++i)
    if (parameters[i].name == parameter) return static_cast<int>(i);
  return -1;
}

int Problem::expected_rigid_modes() const {
  if (options.max_rigid_modes >= 0) return options.max_rigid_modes;
  for (const FixedDofs& f : model.fixed)
    for (bool fixed : f.components)
      if (fixed && !f.nodes.empty()) return 0;
  return model.ground_springs.empty() ? 6 : 0;
}

}  // namespace modalcal
