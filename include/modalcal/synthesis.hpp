#pragma once
/// \file synthesis.hpp
/// Synthetic measured modes from a truth model that may hold physics the nominal model lacks:
/// the test bed of model-form diagnosis. The truth is the nominal model at its parameters'
/// truth values, or a truth problem file, with any number of changes (model_change.hpp) on top;
/// what it hides is recorded (SyntheticTruth) so that a diagnosis can be checked against it.
///
/// Noise (MeasurementNoise): the draws come from std::mt19937_64 seeded with `seed` and a
/// Box-Muller transform written out here (std::normal_distribution is implementation defined),
/// so the same seed gives the same noise draws on every platform; the noise-free modes agree
/// across CPUs to the eigen-solve's accuracy, not bit for bit. Draw order: for each mode in turn its
/// frequency, then its shape values in sensor order; the draws do not depend on the noise levels.
///
/// \code
/// modalcal::TruthModel truth = modalcal::make_truth(nominal, nullptr, {modalcal::parse_model_change("joint2.krx=3e5")});
/// modalcal::SynthesisOptions options;
/// options.modes = {1, 2, 3};
/// options.noise.frequency = 0.005;
/// modalcal::MeasuredData data = modalcal::synthesize_measured_data(nominal, truth, nominal.sensors, options);
/// \endcode

#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/measured_data.hpp"
#include "modalcal/model_change.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

/// A truth model ready to solve: `problem.model` has every value substituted (it has no
/// parameters), `problem.options` decide the solve, and `record` says what it hides.
struct MODALCAL_EXPORT TruthModel {
  Problem problem;
  SyntheticTruth record;
};

/// Builds the truth model.
/// - Without `truth_file`: the nominal model with the nominal parameters' truth values
///   substituted, then `changes` applied in order.
/// - With `truth_file` (a problem, typically one that `extends:` the nominal model's file): its
///   model, with the nominal parameters' truth values substituted into properties of the same
///   name, then its own parameters' truth values, then `changes`.
///
/// The record lists as hidden effects every property that differs from the nominal model and is
/// not a nominal parameter's target, and the nominal parameters' truth-model values.
/// \throws std::invalid_argument naming the change and cause if a change fails to apply or sets
///   a calibration parameter's target (that is not hidden: give the parameter a `truth` instead),
///   or sets a property an earlier change set.
MODALCAL_EXPORT TruthModel make_truth(const Problem& nominal, const Problem* truth_file,
                                      const std::vector<ModelChange>& changes);

/// The records of sensors of `model` (node id, direction and position of each).
MODALCAL_EXPORT std::vector<SensorRecord> sensor_records(const Model& model, const std::vector<Sensor>& sensors);

struct MODALCAL_EXPORT SynthesisOptions {
  /// 1-based elastic modes of the truth model to measure, in this order. Range: non-empty,
  /// each >= 1, no repeats.
  std::vector<int> modes;
  /// Measure shapes at the sensors (pair by MAC); without, frequencies only, paired by mode index.
  bool shapes = true;
  MeasurementNoise noise;
  /// Returns false and names the field, its value and the violated condition.
  bool IsValid(std::string* error) const;
};

/// Measured modes of `truth` at `sensors` (sensors of the nominal model, located in the truth
/// model by position), with noise; the data records sensors, noise, truth and per mode the truth
/// mode and its noise-free frequency. Shapes are scaled to a largest magnitude of 1 (largest entry
/// positive) before noise is added.
/// \throws std::invalid_argument for invalid options, a mode beyond the truth model's DOFs, a
///   sensor with no truth-model node at its position, or a mode that no sensor sees;
///   std::runtime_error if the truth model's solve fails.
MODALCAL_EXPORT MeasuredData synthesize_measured_data(const Problem& nominal, const TruthModel& truth,
                                                      const std::vector<Sensor>& sensors,
                                                      const SynthesisOptions& options);

/// Fills problem->measured as its `measured: synthetic:` section asks: the section's modes of the
/// model at the parameters' truth values (frequency, and shape at the sensors unless the section
/// says `shapes: false`; noise free), paired by MAC with shapes and by mode index without; sets
/// problem->synthetic_truth (no hidden effect). Does nothing for a problem without that section.
/// load_problem() reads the section but computes nothing, so this call comes between them:
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/portal-frame/synthetic.yaml");
/// modalcal::synthesize_measured(&problem);
/// \endcode
/// \throws ProblemError at the section's line if a parameter has no truth value or the truth
///   model's solve fails.
MODALCAL_EXPORT void synthesize_measured(Problem* problem);

}  // namespace modalcal
