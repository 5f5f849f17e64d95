#pragma once
// The calibration report shared by calibrate and the studies: parameter and mode tables as text
// and the documented JSON schema.

#include <nlohmann/json.hpp>

#include <string>

#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"

namespace modalcal::cli {

struct CalibrationReport {
  std::string text;           ///< parameter table and measured-vs-predicted table
  nlohmann::json parameters;  ///< [{name, initial, final, truth?, lower, upper}]
  nlohmann::json modes;       ///< [{label, measured_hz, predicted_hz, error_percent, model_mode, mac?}]
  nlohmann::json summary;     ///< converged, status, iterations, history, counts, time
  nlohmann::json settings;
  nlohmann::json json() const;
};

/// Evaluates the objective at the summary's final parameters to tabulate the modes.
CalibrationReport make_report(Objective& objective, const ReducedSummary& summary);

}  // namespace modalcal::cli
