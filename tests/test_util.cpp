#include "test_util.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace modalcal::testing {

::testing::AssertionResult IsClose(double a, double b, double rel_tol, double floor) {
  const double scale = std::max({std::abs(a), std::abs(b), floor});
  const double diff = std::abs(a - b);
  if (diff <= rel_tol * scale || (scale == 0 && diff == 0)) return ::testing::AssertionSuccess();
  std::ostringstream s;
  s.precision(12);
  s << a << " vs " << b << ": relative difference " << diff / scale << " > " << rel_tol;
  return ::testing::AssertionFailure() << s.str();
}

double RelativeDifference(const Matrix& a, const Matrix& b) {
  const double scale = b.cwiseAbs().maxCoeff();
  return (a - b).cwiseAbs().maxCoeff() / (scale > 0 ? scale : 1.0);
}

std::string SourcePath(const std::string& relative) { return std::string(MODALCAL_SOURCE_DIR) + "/" + relative; }

std::string WriteTempFile(const std::string& name, const std::string& text) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::filesystem::path dir = std::filesystem::temp_directory_path() / "modalcal_tests";
  if (info) dir /= std::string(info->test_suite_name()) + "." + info->name();
  std::filesystem::create_directories(dir);
  const std::filesystem::path path = dir / name;
  std::ofstream(path) << text;
  return path.string();
}

Model MakeChain(int n, double m, double k, bool grounded) {
  Model model;
  for (int i = 0; i <= n; ++i) model.add_node(i + 1, Vec3(i, 0, 0));
  FixedDofs lateral;
  lateral.name = "lateral";
  lateral.components = {false, true, true, false, false, false};
  for (int i = 0; i <= n; ++i) lateral.nodes.push_back(i);
  model.fixed.push_back(lateral);
  if (grounded) {
    FixedDofs ground;
    ground.name = "ground";
    ground.nodes = {0};
    ground.components = {true, false, false, false, false, false};
    model.fixed.push_back(ground);
  }
  for (int i = grounded ? 1 : 0; i <= n; ++i) {
    PointMass pm;
    pm.name = "mass" + std::to_string(i);
    pm.node = i;
    pm.mass = model.add_property(pm.name + ".mass", m);
    model.point_masses.push_back(pm);
  }
  for (int i = 1; i <= n; ++i) {
    Joint j;
    j.name = "joint" + std::to_string(i);
    j.node_a = i - 1;
    j.node_b = i;
    j.stiffness[0] = model.add_property(j.name + ".kx", k);
    model.joints.push_back(j);
  }
  return model;
}

}  // namespace modalcal::testing
