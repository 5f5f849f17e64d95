#pragma once
// The calibration report shared by calibrate and the studies: parameter and mode tables as text
// and the documented JSON schema.

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "modalcal/fullspace.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/reduced.hpp"
#include "modalcal/uncertainty.hpp"

namespace modalcal::cli {

struct CalibrationReport {
  std::string text;           ///< parameter table and measured-vs-predicted table
  nlohmann::json parameters;  ///< [{name, initial, final, truth?, error_percent?, lower, upper}]
  nlohmann::json modes;       ///< [{label, measured_hz, predicted_hz, error_percent, model_mode, mac?}]
  nlohmann::json summary;     ///< converged, status, iterations, history, counts, time
  nlohmann::json settings;
  nlohmann::json json() const;
};

/// Parameter and mode tables; evaluates the objective at `final` to tabulate the modes (no mode
/// table when `final` is empty). `summary` is left for the method to fill.
CalibrationReport make_report(Objective& objective, const Vector& initial, const Vector& final);

/// Adds `u` to `report`: its table to the text, and per parameter `standard_error`, `interval`
/// [lower, upper], `profile_interval` ([lower, upper], a side null where open, or null when not
/// profiled) and `correlation` (its row) to the JSON; `uncertainty` {confidence, noise, note}.
void add_uncertainty(const Uncertainty& u, CalibrationReport* report);

/// The report's tables as three CSV files beside each other, for spreadsheets:
/// `<prefix>_parameters.csv` (name,initial,final,truth,error_percent,lower,upper),
/// `<prefix>_modes.csv` (label,model_mode,measured_hz,predicted_hz,error_percent,mac) and
/// `<prefix>_history.csv` (iteration,phase,objective,gradient_norm); unknown values are empty
/// cells. Built from `report` (CalibrationReport::json()), so the CSV and JSON cannot disagree.
/// Every target is checked against the inputs before the first is written. Returns the paths.
std::vector<std::string> write_csv_report(const std::string& prefix, const nlohmann::json& report,
                                          const Problem& problem);

/// Objective and gradient norm (the projected gradient, or Ipopt's dual infeasibility in the
/// Newton phase) against iteration, from the report's `history`, to a .png or .svg file.
void plot_history(const std::string& path, const nlohmann::json& report, const Problem& problem);

/// The method's part of the JSON: converged, status, iterations, history, counts, time.
nlohmann::json summary_json(const Problem& problem, const ReducedSummary& summary);
/// Same keys, plus mode_check, kkt_history, convergence_order and ipopt_status.
nlohmann::json summary_json(const Problem& problem, const FullSpaceSummary& summary);

}  // namespace modalcal::cli
