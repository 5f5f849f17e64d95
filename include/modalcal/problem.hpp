#pragma once
/// \file problem.hpp
/// A calibration problem: the model, the calibration parameters (bounds, scaling, truth), the
/// sensors and measured modes, and solver options, as read from a problem file
/// (YAML; the format is documented in docs/problem-format.md).
///
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/lfu/synthetic.yaml");
/// modalcal::ParametricSystem system(problem.model, problem.parameter_targets());
/// \endcode

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "modalcal/model.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// How the optimizer sees a parameter: as is, divided by a reference value, or as log10.
enum class Scaling { None, Linear, Log };
std::string to_string(Scaling scaling);

struct Parameter {
  std::string name;
  std::vector<PropertyId> targets;  ///< properties this parameter sets
  double initial = 0;
  double lower = 0, upper = 0;      ///< lower < upper; initial in [lower, upper]
  Scaling scaling = Scaling::Linear;
  double reference = 1;             ///< for Linear scaling (default: initial value)
  std::optional<double> truth;      ///< known for synthetic problems
};

/// One measured DOF: the displacement of `node` along a global direction.
struct Sensor {
  int node = -1;
  int component = 0;  ///< 0..2 = x, y, z
  std::string label;  ///< e.g. "node 12 +x"
};

/// How a measured mode finds its model mode when its shape alone cannot tell.
struct PairingRule {
  enum class Kind { Mac, ModelIndex, Family };
  Kind kind = Kind::Mac;
  int model_index = 0;       ///< 1-based elastic mode index (ModelIndex)
  std::string family;        ///< mode family name (Family), e.g. "axial"
  int family_index = 0;      ///< 1-based index within the family (Family)
};

struct MeasuredMode {
  std::string label;          ///< e.g. "axial 1"
  double frequency_hz = 0;    ///< > 0
  double weight = 1;          ///< beta_i of the eigenvalue term; 0 switches it off
  double shape_weight = 1;    ///< kappa_i of the shape term; 0 switches it off
  Vector shape;               ///< at Problem::sensors, empty if not measured
  PairingRule pairing;
  int source_line = 0;        ///< line in the problem file, for messages
};

struct ProblemOptions {
  int num_modes = 10;          ///< elastic modes computed by the forward solve
  int max_rigid_modes = -1;    ///< -1: 6 if the model has no supports, else 0
  double tolerance = 1e-10;    ///< eigen-solver tolerance
};

/// Measured modes synthesized from the truth parameters at load time (noise free).
struct SyntheticSpec {
  std::vector<int> modes;     ///< 1-based elastic model mode indices
  bool shapes = true;         ///< include shapes at the sensors
  int source_line = 0;
};

struct Problem {
  std::string path;            ///< the file it came from
  std::string name, description;
  std::string units;           ///< free text, e.g. "in, lbf, s"
  Model model;
  std::vector<Parameter> parameters;
  std::vector<Sensor> sensors;
  std::vector<MeasuredMode> measured;
  ProblemOptions options;
  std::optional<SyntheticSpec> synthetic;  ///< set if `measured` was synthesized
  /// What loading accepted but a user should know, e.g. test nodes that matched no model node
  /// or complex test modes made real (`measured: test_data`).
  std::vector<std::string> warnings;

  std::vector<std::vector<PropertyId>> parameter_targets() const;
  Vector initial_values() const;
  Vector lower_bounds() const;
  Vector upper_bounds() const;
  bool has_truth() const;      ///< every parameter has a truth value
  Vector truth_values() const; ///< \throws std::invalid_argument if not has_truth()
  /// Index of the parameter called `name`, or -1.
  int find_parameter(const std::string& name) const;
  /// Rigid modes to expect: options.max_rigid_modes, or 6/0 from the model's supports.
  int expected_rigid_modes() const;
};

/// Settings that override a problem file at load time.
struct LoadOptions {
  double refinement = 0;       ///< > 0 overrides the mesh's refinement factor
};

/// Reads and validates a problem file.
/// \throws ProblemError naming the file, the line and what is wrong.
Problem load_problem(const std::string& path, const LoadOptions& options = {});

/// An error in user input, with its location. what() is "file:line: message".
class ProblemError : public std::invalid_argument {
 public:
  ProblemError(const std::string& file, int line, const std::string& message);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  /// The message without the "file:line: " location.
  const std::string& message() const { return message_; }
 private:
  std::string file_;
  int line_;
  std::string message_;
};

}  // namespace modalcal
