#include "cli/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <stdexcept>
#include <unistd.h>

#include "modalcal/output.hpp"

namespace modalcal {

namespace fs = std::filesystem;

std::string plot_name_problem(const std::string& path) {
  const std::string extension = fs::path(path).extension().string();
  return extension == ".png" || extension == ".svg" ? "" : "the file name must end in .png or .svg";
}

namespace {

std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

/// Runs a gnuplot script that `write_body` completes (after the terminal and output lines; data
/// files go to the work directory it is given) and writes the rendering to `path`
/// (write_file_atomically: a device such as /dev/stdout stays one).
void render(const std::string& path, int width, int height,
            const std::function<void(std::ostream& script, const fs::path& work)>& write_body) {
  if (const std::string problem = plot_name_problem(path); !problem.empty())
    throw std::invalid_argument("plot '" + path + "': " + problem);
  const std::string extension = fs::path(path).extension().string();
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0)
    throw std::runtime_error("plot '" + path + "': gnuplot is not installed (Debian: apt-get install gnuplot-nox)");
  const fs::path work = fs::temp_directory_path() / ("modalcal-plot-" + std::to_string(::getpid()));
  fs::create_directories(work);
  const fs::path rendered = work / ("plot" + extension);
  std::ofstream script(work / "plot.gp");
  script << (extension == ".png" ? "set terminal pngcairo size " : "set terminal svg size ") << width << "," << height
         << " font 'sans,10'\n";
  script << "set output " << quoted(rendered.string()) << "\n";
  write_body(script, work);
  script.close();
  const std::string command = "gnuplot " + quoted((work / "plot.gp").string()) + " 2>" + quoted((work / "err").string());
  const int status = std::system(command.c_str());
  std::string error, image;
  {
    std::ifstream err(work / "err");
    std::getline(err, error, '\0');
    std::ifstream in(rendered, std::ios::binary);
    image.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  fs::remove_all(work);
  if (status != 0 || image.empty())
    throw std::runtime_error("plot '" + path + "': gnuplot failed: " + error.substr(0, 200));
  write_file_atomically(path, image);
}

/// gnuplot tic list: ("a" 0, "b" 1, ...).
std::string tics(const std::vector<std::string>& labels) {
  std::string out = "(";
  for (size_t i = 0; i < labels.size(); ++i)
    out += (i ? ", " : "") + quoted(labels[i]) + " " + std::to_string(i);
  return out + ")";
}

}  // namespace

void plot_panels(const std::string& path, const std::string& title, const std::string& xlabel,
                 const std::vector<PlotPanel>& panels) {
  render(path, 560 * static_cast<int>(panels.size()), 460, [&](std::ostream& script, const fs::path& work) {
    script << "set multiplot layout 1," << panels.size() << " title " << quoted(title) << "\n";
    script << "set grid\nset key bottom left\nset xlabel " << quoted(xlabel) << "\n";
    for (size_t k = 0; k < panels.size(); ++k) {
      const PlotPanel& panel = panels[k];
      script << (panel.log_y ? "set logscale y\nset format y '10^{%T}'\n" : "unset logscale y\nset format y '%g'\n");
      script << "set ylabel " << quoted(panel.ylabel) << "\nplot ";
      for (size_t s = 0; s < panel.series.size(); ++s) {
        const fs::path data = work / ("panel" + std::to_string(k) + "_" + std::to_string(s) + ".dat");
        std::ofstream out(data);
        out.precision(12);
        for (size_t i = 0; i < panel.series[s].x.size(); ++i)
          if (!panel.log_y || panel.series[s].y[i] > 0) out << panel.series[s].x[i] << " " << panel.series[s].y[i] << "\n";
        script << (s ? ", " : "") << quoted(data.string()) << " using 1:2 with linespoints lw 2 pt 7 ps 0.6 title "
               << quoted(panel.series[s].title);
      }
      script << "\n";
    }
    script << "unset multiplot\n";
  });
}

void plot_heat_map(const std::string& path, const std::string& title, const HeatMap& map) {
  const Eigen::Index rows = map.values.rows(), cols = map.values.cols();
  if (static_cast<Eigen::Index>(map.row_labels.size()) != rows ||
      static_cast<Eigen::Index>(map.column_labels.size()) != cols)
    throw std::invalid_argument("plot '" + path + "': " + std::to_string(map.row_labels.size()) + " row and " +
                                std::to_string(map.column_labels.size()) + " column labels for a " +
                                std::to_string(rows) + " x " + std::to_string(cols) + " matrix");
  const int width = std::max(420, 160 + 48 * static_cast<int>(cols));
  const int height = std::max(320, 140 + 36 * static_cast<int>(rows));
  render(path, width, height, [&](std::ostream& script, const fs::path& work) {
    const fs::path data = work / "cells.dat";
    std::ofstream out(data);
    out.precision(12);
    // Row 0 at the top, as a matrix is read.
    for (Eigen::Index i = 0; i < rows; ++i)
      for (Eigen::Index k = 0; k < cols; ++k)
        if (std::isfinite(map.values(i, k))) out << k << " " << i << " " << map.values(i, k) << "\n";
    script << "set title " << quoted(title) << "\n";
    script << "set xlabel " << quoted(map.column_title) << "\nset ylabel " << quoted(map.row_title) << "\n";
    script << "set cblabel " << quoted(map.value_title) << "\n";
    script << "set xtics " << tics(map.column_labels) << "\nset ytics " << tics(map.row_labels) << "\n";
    script << "set xrange [-0.5:" << cols - 0.5 << "]\nset yrange [" << rows - 0.5 << ":-0.5]\n";
    script << "set cbrange [" << map.min << ":" << map.max << "]\n";
    script << "set palette defined (0 'white', 1 '#9ecae1', 2 '#3182bd')\nset tics nomirror out\nunset key\n";
    script << "plot " << quoted(data.string()) << " using 1:2:3 with image, '' using 1:2:(sprintf('%.2f', $3)) "
           << "with labels font 'sans,8'\n";
  });
}

void plot_point_cloud(const std::string& path, const std::string& title, const PointCloud& cloud) {
  if (cloud.points.cols() != 3 || static_cast<size_t>(cloud.points.rows()) != cloud.values.size())
    throw std::invalid_argument("plot '" + path + "': " + std::to_string(cloud.values.size()) + " values for " +
                                std::to_string(cloud.points.rows()) + " points");
  render(path, 900, 700, [&](std::ostream& script, const fs::path& work) {
    const fs::path background = work / "background.dat", valued = work / "valued.dat";
    std::ofstream grey(background), coloured(valued);
    grey.precision(9);
    coloured.precision(9);
    // Lowest values first, so that peaks are drawn on top.
    std::vector<Eigen::Index> order(cloud.values.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<Eigen::Index>(k);
    std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
      return !std::isnan(cloud.values[a]) && !std::isnan(cloud.values[b]) && cloud.values[a] < cloud.values[b];
    });
    for (Eigen::Index k : order) {
      const auto x = cloud.points.row(k);
      if (std::isnan(cloud.values[k]))
        grey << x[0] << " " << x[1] << " " << x[2] << "\n";
      else
        coloured << x[0] << " " << x[1] << " " << x[2] << " " << std::min(cloud.values[k], cloud.max) << "\n";
    }
    grey << "nan nan nan\n";  // gnuplot refuses an empty file
    coloured << "nan nan nan nan\n";
    script << "set title " << quoted(title) << "\n";
    script << "set xlabel 'x'\nset ylabel 'y'\nset zlabel 'z'\nset view equal xyz\nset view 60,30\n";
    script << "set cblabel " << quoted(cloud.value_title) << "\nset cbrange [" << cloud.min << ":" << cloud.max << "]\n";
    script << "set palette defined (0 '#f0f0f0', 1 '#fdae6b', 2 '#e6550d', 3 '#7f0000')\nunset key\n";
    script << "splot " << quoted(background.string()) << " using 1:2:3 with points pt 7 ps 0.3 lc rgb '#bbbbbb', "
           << quoted(valued.string()) << " using 1:2:3:4 with points pt 7 ps 0.8 lc palette\n";
  });
}

void plot_bars(const std::string& path, const std::string& title, const BarChart& chart) {
  if (chart.labels.size() != chart.values.size())
    throw std::invalid_argument("plot '" + path + "': " + std::to_string(chart.labels.size()) + " labels for " +
                                std::to_string(chart.values.size()) + " values");
  const int width = std::max(480, 160 + 40 * static_cast<int>(chart.values.size()));
  render(path, width, 400, [&](std::ostream& script, const fs::path& work) {
    const fs::path data = work / "bars.dat";
    std::ofstream out(data);
    out.precision(12);
    for (size_t i = 0; i < chart.values.size(); ++i) out << i << " " << chart.values[i] << "\n";
    script << "set title " << quoted(title) << "\nset ylabel " << quoted(chart.ylabel) << "\n";
    // Bars start at zero: the y range always holds it.
    double low = 0, high = 0;
    for (double v : chart.values) {
      low = std::min(low, v);
      high = std::max(high, v);
    }
    const double margin = high > low ? 0.08 * (high - low) : 1.0;
    script << "set yrange [" << (low < 0 ? low - margin : 0.0) << ":" << (high > 0 ? high + margin : 0.0) << "]\n";
    script << "set xtics " << tics(chart.labels) << " rotate by 30 right\nset xrange [-0.6:" << chart.values.size() - 0.4
           << "]\n";
    script << "set grid ytics\nset xzeroaxis lt -1\nset style fill solid 0.7 border -1\nset boxwidth 0.6\nunset key\n";
    script << "plot " << quoted(data.string()) << " using 1:2 with boxes lc rgb '#3182bd'\n";
  });
}

void plot_sample_matrix(const std::string& path, const std::string& title, const SampleMatrix& m) {
  const Eigen::Index n = m.samples.cols();
  if (static_cast<Eigen::Index>(m.names.size()) != n || (!m.log_scale.empty() && m.log_scale.size() != m.names.size()))
    throw std::invalid_argument("plot '" + path + "': " + std::to_string(m.names.size()) + " names for " +
                                std::to_string(n) + " variables");
  const auto logarithmic = [&](Eigen::Index j) {
    return !m.log_scale.empty() && m.log_scale[static_cast<size_t>(j)] && (m.samples.col(j).array() > 0).all();
  };
  render(path, 60 + 240 * static_cast<int>(n), 40 + 220 * static_cast<int>(n), [&](std::ostream& script,
                                                                                   const fs::path& work) {
    const fs::path data = work / "samples.dat";
    std::ofstream out(data);
    out.precision(12);
    for (Eigen::Index i = 0; i < m.samples.rows(); ++i) {
      for (Eigen::Index j = 0; j < n; ++j) out << (j ? " " : "") << m.samples(i, j);
      out << "\n";
    }
    // noenhanced: parameter names are printed as they are (joint1_kx, not joint1 with subscript kx).
    script << "set termoption noenhanced\nset multiplot layout " << n << "," << n << " title " << quoted(title) << "\n";
    // Axes fitted to the values (a log axis would otherwise widen to whole decades).
    script << "set xtics rotate by 30 right\nset autoscale fix\nset offsets graph 0.08, graph 0.08, graph 0.08, graph 0.08\n";
    script << "unset key\nset tics font 'sans,7'\nset format x '%.3g'\nset format y '%.3g'\n";
    script << "set style fill solid 0.6 border -1\n";
    for (Eigen::Index row = 0; row < n; ++row)
      for (Eigen::Index col = 0; col < n; ++col) {
        if (col > row) {  // above the diagonal: nothing, the pair is drawn below it
          script << "set multiplot next\n";
          continue;
        }
        script << "set xlabel " << quoted(row == n - 1 ? m.names[static_cast<size_t>(col)] + (logarithmic(col) ? " (log10)" : "") : "")
               << "\nset ylabel "
               << quoted(col == 0 ? (row == col ? "count" : m.names[static_cast<size_t>(row)] + (logarithmic(row) ? " (log10)" : ""))
                                  : "")
               << "\n";
        const std::string x = "$" + std::to_string(col + 1);
        if (col == row) {
          // A histogram of about sqrt(samples) bins, in the variable or its log10.
          const bool lg = logarithmic(col);
          const Vector v = lg ? Vector(m.samples.col(col).array().log10()) : Vector(m.samples.col(col));
          const double width = std::max((v.maxCoeff() - v.minCoeff()) /
                                            std::max(3.0, std::ceil(std::sqrt(static_cast<double>(v.size())))),
                                        1e-6 * std::max(1.0, std::abs(v.maxCoeff())));
          const std::string value = lg ? "log10(" + x + ")" : x;
          script << "set boxwidth " << 0.9 * width << "\nplot " << quoted(data.string()) << " using ("
                 << width << "*floor(" << value << "/" << width << ")+" << 0.5 * width
                 << "):(1.0) smooth frequency with boxes lc rgb '#3182bd'\n";
        } else {
          // Log-scaled variables as log10 on linear axes, as their histograms: a log axis within
          // less than a decade has no labelled tics.
          auto column = [&](Eigen::Index j) {
            const std::string c = "$" + std::to_string(j + 1);
            return logarithmic(j) ? "(log10(" + c + "))" : "(" + c + ")";
          };
          script << "plot " << quoted(data.string()) << " using " << column(col) << ":" << column(row)
                 << " with points pt 7 ps 0.6 lc rgb '#3182bd'\n";
        }
      }
    script << "unset multiplot\n";
  });
}

}  // namespace modalcal
