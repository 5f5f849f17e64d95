#pragma once
/// \file plot.hpp
/// Internal (the tool's, not the library's API): plots through gnuplot (Debian gnuplot-nox),
/// convergence curves, heat maps (MAC matrices) and bar charts (frequency errors). The data and
/// the script go to a temporary directory, gnuplot renders to a temporary file, which is then
/// renamed onto the target, so a failed plot never leaves half a file. The file name's extension
/// (.png or .svg) chooses the format.

#include <string>
#include <vector>

#include "modalcal/types.hpp"

namespace modalcal {

/// Why `path` cannot name a plot ("" when it can): its extension must be .png or .svg.
std::string plot_name_problem(const std::string& path);

struct PlotSeries {
  std::string title;
  std::vector<double> x, y;
};

struct PlotPanel {
  std::string ylabel;
  bool log_y = true;
  std::vector<PlotSeries> series;
};

/// Renders panels stacked side by side into `path` (.png or .svg, by extension), sharing the x
/// label. \throws std::runtime_error naming the cause if gnuplot is missing or fails.
void plot_panels(const std::string& path, const std::string& title, const std::string& xlabel,
                 const std::vector<PlotPanel>& panels);

/// A matrix drawn as coloured cells with their values printed, e.g. a MAC matrix.
/// \code
/// modalcal::HeatMap map;
/// map.values = mac_matrix;                       // measured x model modes, in [0, 1]
/// map.row_labels = {"mode 1", "mode 2"};
/// map.column_labels = {"1", "2", "3"};
/// modalcal::plot_heat_map("out/mac.png", "MAC matrix", map);
/// \endcode
struct HeatMap {
  std::vector<std::string> row_labels;     ///< one per row of `values`, drawn top to bottom
  std::vector<std::string> column_labels;  ///< one per column
  std::string row_title, column_title, value_title;
  Matrix values;                           ///< NaN cells are left blank
  double min = 0, max = 1;                 ///< colour range
};

/// \throws as plot_panels, and std::invalid_argument if the labels do not match `values`.
void plot_heat_map(const std::string& path, const std::string& title, const HeatMap& map);

/// Bars with a label each, e.g. the frequency error of every measured mode.
struct BarChart {
  std::vector<std::string> labels;
  std::vector<double> values;
  std::string ylabel;
};

/// \throws as plot_panels, and std::invalid_argument if labels and values differ in number.
void plot_bars(const std::string& path, const std::string& title, const BarChart& chart);

/// Points in 3D coloured by a value, e.g. where a screen predicts a missing effect. Points with a
/// NaN value are drawn small and grey (the geometry for orientation).
struct PointCloud {
  Matrix points;               ///< n x 3 coordinates
  std::vector<double> values;  ///< one per point
  std::string value_title;
  double min = 0, max = 1;     ///< colour range (values above max take its colour)
};
/// \throws as plot_panels, and std::invalid_argument if points and values differ in number.
void plot_point_cloud(const std::string& path, const std::string& title, const PointCloud& cloud);

/// Samples of several variables (rows: samples; columns: variables) as a scatter-plot matrix:
/// each variable's histogram on the diagonal, each pair's scatter below it. Log axes for the
/// variables flagged in `log_scale` (positive values only).
struct SampleMatrix {
  std::vector<std::string> names;  ///< one per column
  std::vector<bool> log_scale;     ///< one per column, or empty for none
  Matrix samples;
};
void plot_sample_matrix(const std::string& path, const std::string& title, const SampleMatrix& m);

}  // namespace modalcal
