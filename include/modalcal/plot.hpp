#pragma once
/// \file plot.hpp
/// Convergence plots through gnuplot (Debian gnuplot-nox): the data and the script go to a
/// temporary directory, gnuplot renders to a temporary file, which is then renamed onto the
/// target, so a failed plot never leaves half a file.

#include <string>
#include <vector>

#include "modalcal/types.hpp"

namespace modalcal {

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

}  // namespace modalcal
