#pragma once
/// \file problem.hpp
/// A calibration problem: the model, the calibration parameters (bounds, scaling, truth), the
/// sensors and measured modes, and solver options. Every stage from the objective on works on
/// one; problem_file.hpp reads one from a problem file (YAML; the format is documented in
/// docs/problem-format.md).
///
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/lfu/synthetic.yaml");  // problem_file.hpp
/// modalcal::ParametricSystem system(problem.model, problem.parameter_targets());
/// \endcode

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/model.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

/// How the optimizer sees a parameter: as is, divided by a reference value, or as log10.
enum class Scaling { None, Linear, Log };
MODALCAL_EXPORT std::string to_string(Scaling scaling);

struct MODALCAL_EXPORT Parameter {
  std::string name;
  std::vector<PropertyId> targets;  ///< properties this parameter sets
  double initial = 0;
  double lower = 0, upper = 0;      ///< lower < upper; initial in [lower, upper]
  Scaling scaling = Scaling::Linear;
  double reference = 1;             ///< for Linear scaling (default: initial value)
  std::optional<double> truth;      ///< known for synthetic problems
};

/// One measured DOF: the displacement of `node` along a global direction.
struct MODALCAL_EXPORT Sensor {
  int node = -1;
  int component = 0;  ///< 0..2 = x, y, z
  std::string label;  ///< e.g. "node 12 +x"
};

/// How a measured mode finds its model mode when its shape alone cannot tell.
struct MODALCAL_EXPORT PairingRule {
  enum class Kind { Mac, ModelIndex, Family };
  Kind kind = Kind::Mac;
  int model_index = 0;       ///< 1-based elastic mode index (ModelIndex)
  std::string family;        ///< mode family name (Family), e.g. "axial"
  int family_index = 0;      ///< 1-based index within the family (Family)
};

struct MODALCAL_EXPORT MeasuredMode {
  std::string label;          ///< e.g. "axial 1"
  double frequency_hz = 0;    ///< > 0
  double weight = 1;          ///< beta_i of the eigenvalue term; 0 switches it off
  double shape_weight = 1;    ///< kappa_i of the shape term; 0 switches it off
  Vector shape;               ///< at Problem::sensors, empty if not measured
  PairingRule pairing;
  /// An allowance for model error in this mode's frequency, as a relative standard deviation:
  /// the chi-square test and the noise weights add it in quadrature to the stated frequency
  /// noise (residual_test.hpp). The diagnosis sets it from its discretization estimate. >= 0.
  double model_error = 0;
  int source_line = 0;        ///< line in the problem file, for messages
  /// Whether J has a shape term for this mode: a measured shape with a positive weight. (A shape
  /// with weight 0 still pairs the mode by MAC.)
  bool has_shape_term() const { return shape.size() > 0 && shape_weight > 0; }
};

struct MODALCAL_EXPORT ProblemOptions {
  int num_modes = 10;          ///< elastic modes computed by the forward solve
  int max_rigid_modes = -1;    ///< -1: 6 if the model has no supports, else 0
  double tolerance = 1e-10;    ///< eigen-solver tolerance
};

/// Measured modes synthesized from the truth parameters at load time (noise free).
struct MODALCAL_EXPORT SyntheticSpec {
  std::vector<int> modes;     ///< 1-based elastic model mode indices
  bool shapes = true;         ///< include shapes at the sensors
  int source_line = 0;
};

/// Gaussian noise of synthetic measurements (`fullspace_calib synth`), with \f$N(0,1)\f$ standard
/// normal draws: a frequency becomes \f$f\,(1 + \sigma_f N)\f$ and each shape value, the shape first
/// scaled to a largest magnitude of 1, \f$\phi_s + \sigma_\phi \max_s|\phi_s|\, N\f$.
struct MODALCAL_EXPORT MeasurementNoise {
  double frequency = 0;    ///< \f$\sigma_f\f$, relative standard deviation of a frequency. Range: [0, 0.2] (a frequency must stay positive).
  double shape = 0;        ///< \f$\sigma_\phi\f$, of a shape value relative to the largest. Range: [0, 1].
  std::uint64_t seed = 1;  ///< the same seed gives the same draws on every platform. Any value.
  /// Returns false and names the field, its value and the violated range.
  bool IsValid(std::string* error) const;
};

/// The truth synthetic measured data were made from, so that reports can show what was hidden
/// beside what a diagnosis found.
struct MODALCAL_EXPORT SyntheticTruth {
  /// Where the truth model came from, e.g. "the nominal model with 1 change" or a truth file.
  std::string source;
  /// The change strings applied to make the truth (canonical, see model_change.hpp); empty when
  /// the truth is a problem file alone.
  std::vector<std::string> changes;
  /// Properties of the truth model that are not calibration targets and differ from the nominal
  /// model or are absent from it: the physics the nominal model lacks. Empty when the nominal
  /// model form is right (only the calibration parameters differ).
  std::vector<ModelEffect> hidden_effects;
  /// Differences no property expresses (mesh, supports, couplings, where entities sit), in
  /// words; empty if there are none.
  std::string other_differences;
  /// The calibration parameters' values in the truth model, by parameter name.
  std::vector<std::pair<std::string, double>> parameters;
};

/// A candidate effect the problem file declares (`effects:`): the diagnosis ranks it beside the
/// candidates it generates from the model's structure (effects.hpp), and calibration adds it as a
/// parameter when it is enabled. Unset numbers take the defaults of automatic candidates.
struct MODALCAL_EXPORT DeclaredEffect {
  /// A change without its value (model_change.hpp), e.g. "joint2.kry", "point_mass@[9,4,3.5]:mass",
  /// "support@post_bottom:kx"; checked against the model at load time.
  std::string effect;
  std::string description;        ///< words for reports; empty: the change's own description
  std::optional<double> initial;  ///< start of its calibration; unset: the first-order estimate
  std::optional<double> lower, upper;
  bool enable = false;            ///< calibrate with it (as `calibrate --add`)
  std::string source_file;        ///< where it is declared, for messages
  int source_line = 0;
};

struct MODALCAL_EXPORT Problem {
  std::string path;            ///< the file it came from
  /// Every file loading read, as written in the files naming them: `path`, the files it extends,
  /// its measured-data, test-data and mesh files. No output may replace one of them
  /// (output.hpp: the writers take this list as their `inputs`).
  std::vector<std::string> source_files;
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

  /// `measured: {file: ...}`: the data file the measured modes were read from (else empty).
  std::string measured_file;
  /// The truth the measured modes came from, when known: a data file's `truth:` section, or for
  /// `measured: synthetic` the nominal model at the parameters' truth values (no hidden effect).
  std::optional<SyntheticTruth> synthetic_truth;
  /// The measurement noise: `measured: {noise: ...}` in the problem file, else a data file's
  /// `noise:` section, when either has one.
  std::optional<MeasurementNoise> measurement_noise;
  /// `effects:`: candidate effects declared for the diagnosis, in file order.
  std::vector<DeclaredEffect> effects;
  /// The refinement factor a generated mesh was made with (`mesh: refinement`, or
  /// LoadOptions::refinement); 0 for a mesh read from a file, which cannot be refined.
  double mesh_refinement = 0;

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

/// An error in user input, with its location. what() is "file:line: message".
class MODALCAL_EXPORT ProblemError : public std::invalid_argument {
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
