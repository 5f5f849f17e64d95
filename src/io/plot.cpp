#include "modalcal/plot.hpp"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <unistd.h>

#include "modalcal/output.hpp"

namespace modalcal {

namespace fs = std::filesystem;

namespace {
std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}
}  // namespace

void plot_panels(const std::string& path, const std::string& title, const std::string& xlabel,
                 const std::vector<PlotPanel>& panels) {
  const std::string extension = fs::path(path).extension().string();
  if (extension != ".png" && extension != ".svg")
    throw std::invalid_argument("plot '" + path + "': the file name must end in .png or .svg");
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0)
    throw std::runtime_error("plot '" + path + "': gnuplot is not installed (Debian: apt-get install gnuplot-nox)");
  const fs::path work = fs::temp_directory_path() / ("modalcal-plot-" + std::to_string(::getpid()));
  fs::create_directories(work);
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  const fs::path rendered = dir / ("." + target.filename().string() + ".rendering" + extension);
  std::ofstream script(work / "plot.gp");
  script << (extension == ".png" ? "set terminal pngcairo size " : "set terminal svg size ") << 560 * panels.size()
         << ",460 font 'sans,10'\n";
  script << "set output " << quoted(rendered.string()) << "\n";
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
  script.close();
  const std::string command = "gnuplot " + quoted((work / "plot.gp").string()) + " 2>" + quoted((work / "err").string());
  const int status = std::system(command.c_str());
  std::string error;
  {
    std::ifstream err(work / "err");
    std::getline(err, error, '\0');
  }
  fs::remove_all(work);
  if (status != 0 || !fs::exists(rendered)) {
    std::remove(rendered.c_str());
    throw std::runtime_error("plot '" + path + "': gnuplot failed: " + error);
  }
  fs::rename(rendered, target);
}

}  // namespace modalcal
