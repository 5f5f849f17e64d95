#pragma once
/// \file measured_data.hpp
/// A measured-modes data file: modes (frequency, shape at the sensors, pairing, label), the
/// sensors they were measured at, and, for synthetic data, the noise levels, the seed and the
/// truth they came from. `fullspace_calib synth` writes one; a problem reads it with
/// `measured: {file: data.yaml}` (format in docs/problem-format.md), and the truth it records
/// becomes Problem::synthetic_truth.
///
/// \code
/// modalcal::MeasuredData data = modalcal::synthesize_measured_data(problem, truth, sensors, options);
/// modalcal::write_measured_data("out/data.yaml", data, {problem.path});  // problem_file.hpp
/// \endcode

#include <optional>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

/// A sensor as a data file records it: it is matched to a problem's sensor by position and
/// direction, so that it survives a change of mesh numbering.
struct MODALCAL_EXPORT SensorRecord {
  long node_id = 0;   ///< the node's id in the model the data were made with (for people)
  int component = 0;  ///< 0..2 = x, y, z
  Vec3 position = Vec3::Zero();
};

/// Where a synthetic mode came from, for provenance.
struct MODALCAL_EXPORT TruthModeRecord {
  int mode = 0;              ///< 1-based elastic mode of the truth model
  double frequency_hz = 0;   ///< its frequency before noise
};

struct MODALCAL_EXPORT MeasuredData {
  std::string synthesized_from;        ///< the nominal problem file (empty for test data)
  std::vector<SensorRecord> sensors;
  std::vector<MeasuredMode> modes;     ///< shapes in the order of `sensors`
  std::vector<TruthModeRecord> truth_modes;  ///< one per mode for synthetic data, else empty
  std::optional<MeasurementNoise> noise;
  std::optional<SyntheticTruth> truth;
};


}  // namespace modalcal
