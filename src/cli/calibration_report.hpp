#pragma once
// The calibration report shared by calibrate and the studies: parameter and mode tables as text
// and the documented JSON schema.

#include <nlohmann/json.hpp>

#include <string>

#include "modalcal/fullspace.hpp"
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

/// Parameter and mode tables; evaluates the objective at `final` to tabulate the modes (no mode
/// table when `final` is empty). `summary` is left for the method to fill.
CalibrationReport make_report(Objective& objective, const Vector& initial, const Vector& final);

/// The method's part of the JSON: converged, status, iterations, history, counts, time.
nlohmann::json summary_json(const Problem& problem, const ReducedSummary& summary);
/// Same keys, plus mode_check, kkt_history, convergence_order and ipopt_status.
nlohmann::json summary_json(const Problem& problem, const FullSpaceSummary& summary);

}  // namespace modalcal::cli
