// Test data: the universal-file reader on real exports (tests/data/uff, see SOURCE.md there) and
// on malformed variants made from them, coordinate-system rotation, unit conversion, node
// mapping, the CSV form, and a problem file whose measured modes come from a universal file.
// Expected values were read by eye from the sample files; line numbers are the files' own.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "modalcal/problem.hpp"
#include "modalcal/test_data.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

using testing::LoadProblem;
using testing::SourcePath;
using testing::WriteTempFile;

std::string Sample(const std::string& name) { return SourcePath("tests/data/uff/" + name); }

std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string text;
  for (const std::string& l : lines) text += l + "\n";
  return text;
}

/// Reading `path` must fail at `line` with every fragment in the message, and the message must
/// start with "path:line: " ("path: " for line 0, an error of the whole file).
void ExpectReadError(const std::string& path, int line, const std::vector<std::string>& fragments) {
  try {
    read_test_data(path);
    ADD_FAILURE() << "expected a ProblemError reading " << path;
  } catch (const ProblemError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), line) << what;
    const std::string location = line > 0 ? path + ":" + std::to_string(line) + ": " : path + ": ";
    EXPECT_EQ(what.rfind(location, 0), 0u) << what;
    for (const std::string& f : fragments)
      EXPECT_NE(what.find(f), std::string::npos) << "'" << f << "' not in: " << what;
  }
}

/// A sample with lines replaced (1-based line -> new text), dropped (new text "<drop>") or
/// the file cut after `keep` lines (0: keep all).
std::string Variant(const std::string& sample, const std::vector<std::pair<int, std::string>>& edits, size_t keep = 0) {
  std::vector<std::string> lines = Lines(Sample(sample));
  for (auto it = edits.rbegin(); it != edits.rend(); ++it) {
    if (it->second == "<drop>")
      lines.erase(lines.begin() + it->first - 1);
    else
      lines[static_cast<size_t>(it->first - 1)] = it->second;
  }
  if (keep) lines.resize(keep);
  return WriteTempFile(sample, Join(lines));
}

bool HasWarning(const std::vector<std::string>& warnings, const std::string& fragment) {
  for (const std::string& w : warnings)
    if (w.find(fragment) != std::string::npos) return true;
  return false;
}

int NumNodes(const TestMode& m) {
  int n = 0;
  for (size_t k = 0; k < m.values.size(); ++k) n += k == 0 || m.values[k].node != m.values[k - 1].node;
  return n;
}

// ---------------------------------------------------------------------------- real samples

TEST(UffSamples, TranslationModesLoad) {
  const TestData d = read_test_data(Sample("uff55_translation.uff"));
  ASSERT_EQ(d.modes.size(), 3u);
  const double frequencies[] = {10.0, 12.0, 13.0};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(d.modes[k].number, k + 1);
    EXPECT_EQ(d.modes[k].frequency_hz, frequencies[k]);
    EXPECT_EQ(d.modes[k].values_per_node, 3);
    EXPECT_EQ(NumNodes(d.modes[k]), 4);
    EXPECT_FALSE(d.modes[k].damping_ratio);  // written as 0
    EXPECT_EQ(d.modes[k].dataset, 55);
  }
  EXPECT_EQ(d.modes[1].line, 21);
  EXPECT_EQ(*d.modes[0].value(1, 0), -1.46518);
  EXPECT_EQ(*d.modes[1].value(4, 2), 1.98289);
  EXPECT_FALSE(d.modes[0].value(5, 0));
  EXPECT_TRUE(d.nodes.empty());
  EXPECT_FALSE(d.units);
  EXPECT_TRUE(HasWarning(d.warnings, "no node geometry"));
}

TEST(UffSamples, SixValuesPerNodeLoad) {
  const TestData d = read_test_data(Sample("uff55_translation_rotation.uff"));
  ASSERT_EQ(d.modes.size(), 1u);
  const TestMode& m = d.modes[0];
  EXPECT_EQ(m.frequency_hz, 97.013);
  EXPECT_EQ(m.values_per_node, 6);
  EXPECT_EQ(NumNodes(m), 43);
  EXPECT_EQ(m.values.size(), 43u * 6);
  EXPECT_EQ(*m.value(1, 0), 5.3569e-02);
  EXPECT_EQ(*m.value(1, 1), 2.0271e-02);
  EXPECT_EQ(*m.value(43, 2), -8.1751e-01);
  EXPECT_EQ(*m.value(43, 5), 0.0);
}

TEST(UffSamples, ComplexModeIsMadeRealWithAWarning) {
  const TestData d = read_test_data(Sample("uff55_complex_poma_export.uff"));
  ASSERT_EQ(d.modes.size(), 1u);
  const TestMode& m = d.modes[0];
  EXPECT_TRUE(m.from_complex);
  EXPECT_EQ(m.values_per_node, 3);
  EXPECT_EQ(NumNodes(m), 2);
  EXPECT_EQ(m.description, "TESTTEST:Cfg=0:C1:trans:111121");
  // Record 8: eigenvalue -1.111111E-01 + 4.111111E+01 i (rad/s).
  const double omega = std::hypot(-0.1111111, 41.11111);
  EXPECT_CLOSE(m.frequency_hz, omega / (2 * M_PI), 1e-12);
  ASSERT_TRUE(m.damping_ratio);
  EXPECT_CLOSE(*m.damping_ratio, 0.1111111 / omega, 1e-12);
  EXPECT_TRUE(HasWarning(d.warnings, "is complex: made real"));
  EXPECT_TRUE(HasWarning(d.warnings, "MPC"));

  // Independent check of the real shape: scan the phase for the largest real part.
  const std::vector<std::complex<double>> phi = {{0, 0},
                                                 {0, 0},
                                                 {-0.04111111, -0.01111111},  // node 60101
                                                 {0, 0},
                                                 {0.1111111, 0.09111111},
                                                 {0.007111111, 0.004111111}};  // 111111
  double best_norm = -1, best_theta = 0;
  for (int k = 0; k < 200000; ++k) {
    const double theta = M_PI * k / 200000.0;
    double norm = 0;
    for (const auto& c : phi) norm += std::pow((std::polar(1.0, theta) * c).real(), 2);
    if (norm > best_norm) best_norm = norm, best_theta = theta;
  }
  const long nodes[] = {60101, 111111};
  double sign = 0;
  for (int n = 0; n < 2; ++n)
    for (int c = 0; c < 3; ++c) {
      const double expected = (std::polar(1.0, best_theta) * phi[static_cast<size_t>(3 * n + c)]).real();
      const double got = *m.value(nodes[n], c);
      if (sign == 0 && expected != 0) sign = got / expected > 0 ? 1 : -1;  // θ and θ + π are both best
      EXPECT_NEAR(got, sign * expected, 1e-5) << "node " << nodes[n] << " component " << c;
    }
  EXPECT_GT(m.phase_collinearity, 0.9);
  EXPECT_LT(m.phase_collinearity, 1.0);
}

TEST(UffSamples, TestLabGeometryLoadsWithItsCoordinateSystems) {
  const TestData d = read_test_data(Sample("testlab_geometry_151_164_18_15_82.uff"));
  ASSERT_TRUE(d.header);
  EXPECT_EQ(d.header->model_name, "AME_Test");
  EXPECT_EQ(d.header->file_program, "LMS Test.Lab Rev project-15A");
  EXPECT_EQ(d.header->file_written, "17-Oct-17 13:50:13");
  ASSERT_TRUE(d.units);
  EXPECT_EQ(d.units->code, 9);
  EXPECT_EQ(d.units->description, "USER_DEFINED");
  EXPECT_EQ(d.units->length_factor, 1.0);
  EXPECT_EQ(d.units->temperature_offset, -273.15);
  EXPECT_EQ(d.coordinate_systems.size(), 36u);
  EXPECT_EQ(d.nodes.size(), 36u);
  EXPECT_TRUE(d.modes.empty());
  // Node 1 is given in the global frame; its shapes would be in SYS1.
  const TestNode* n1 = d.find_node(1);
  ASSERT_NE(n1, nullptr);
  EXPECT_EQ(n1->coordinates, Vec3(-2.4, -0.95, 0.0));
  EXPECT_EQ(n1->displacement_system, 1);
  // SYS1: origin (-2.4, -0.95, 0), +x point (-3.4, -0.95, ~0), +xz point (-3.4, -0.95, -1):
  // x = -X, z = -Z, y = z × x = +Y.
  const CoordinateSystem& sys1 = d.coordinate_systems[0];
  ASSERT_EQ(sys1.id, 1);
  EXPECT_EQ(sys1.name, "SYS1");
  Mat3 expected;
  expected << -1, 0, 0, 0, 1, 0, 0, 0, -1;
  EXPECT_LT((sys1.axes - expected).cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_EQ(sys1.origin, Vec3(-2.4, -0.95, 0.0));
  // SYS7: x = +Z, the +xz point lies towards -Y, so y = (-1, 0, 0) and z = (0, -1, 0).
  const CoordinateSystem& sys7 = d.coordinate_systems[6];
  expected << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  EXPECT_LT((sys7.axes - expected).cwiseAbs().maxCoeff(), 1e-7);
  int skipped_trace_lines = 0;
  for (const UffDatasetEntry& e : d.datasets)
    if (e.number == 82) {
      EXPECT_FALSE(e.read);
      EXPECT_NE(e.note.find("trace lines"), std::string::npos);
      ++skipped_trace_lines;
    }
  EXPECT_EQ(skipped_trace_lines, 3);
}

TEST(UffSamples, PermasModeShapesIn2414Load) {
  const TestData d = read_test_data(Sample("nodes2411_results2414.uff"));
  ASSERT_TRUE(d.header);
  EXPECT_EQ(d.header->model_name, "tulay_01.unvo");
  EXPECT_EQ(d.nodes.size(), 441u);
  EXPECT_EQ(d.find_node(1)->coordinates, Vec3(1.0, 0.0, 0.0));
  ASSERT_EQ(d.modes.size(), 10u);
  const double frequencies[] = {0.956363, 2.34163, 5.88075, 7.50675, 8.54122,
                                14.9563,  17.0424, 17.8180, 19.7208, 25.7643};
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(d.modes[k].number, k + 1);
    EXPECT_EQ(d.modes[k].frequency_hz, frequencies[k]);
    EXPECT_EQ(d.modes[k].dataset, 2414);
    EXPECT_EQ(NumNodes(d.modes[k]), 441);
    EXPECT_EQ(d.modes[k].values_per_node, 6);
  }
  EXPECT_EQ(*d.modes[0].value(1, 2), -7.08571e-01);
  EXPECT_EQ(*d.modes[0].value(1, 4), 1.0);
  EXPECT_EQ(d.datasets[2].number, 2412);
  EXPECT_FALSE(d.datasets[2].read);
  EXPECT_TRUE(d.warnings.empty());
}

TEST(UffSamples, SimcenterStaticResultIsSkippedWithANote) {
  const TestData d = read_test_data(Sample("simcenter_exported_result.uff"));
  EXPECT_EQ(d.nodes.size(), 11520u);
  EXPECT_EQ(d.find_node(1)->coordinates, Vec3(500.0, 11500.0, 10000.0));
  EXPECT_TRUE(d.modes.empty());
  ASSERT_EQ(d.datasets.size(), 4u);
  EXPECT_EQ(d.datasets[3].number, 2414);
  EXPECT_EQ(d.datasets[3].line, 61185);
  EXPECT_NE(d.datasets[3].note.find("analysis type 1 (static)"), std::string::npos) << d.datasets[3].note;
}

// ---------------------------------------------------------------------------- malformed variants

TEST(UffErrors, TruncatedFileNamesTheOpenDataset) {
  ExpectReadError(Variant("uff55_translation.uff", {}, 30), 21, {"dataset 55", "no closing '-1'", "truncated"});
}

TEST(UffErrors, TruncatedRecordNamesTheNode) {
  // Line 18 holds node 4's values in the first mode; the dataset's '-1' then comes too soon.
  ExpectReadError(Variant("uff55_translation.uff", {{18, "<drop>"}}), 18, {"dataset 55", "values of node 4"});
}

TEST(UffErrors, WrongValueCountPerNode) {
  // Record 6 says 6 components (data characteristic 3), node 1 has 3 values on line 12.
  ExpectReadError(
      Variant("uff55_translation.uff", {{8, "         1         2         3         8         2         6"}}), 12,
      {"dataset 55", "values of node 1", "expected 6 numbers", "found 3"});
}

TEST(UffErrors, CharacteristicAndValueCountDisagree) {
  ExpectReadError(
      Variant("uff55_translation.uff", {{8, "         1         2         2         8         2         6"}}), 8,
      {"dataset 55", "disagree"});
}

TEST(UffErrors, WrongRealCountInRecord7) {
  // Six reals announced, four on line 10, which FORMAT(6E13.5) would fill.
  ExpectReadError(Variant("uff55_translation.uff", {{9, "         2         6         1         1"}}), 10,
                  {"dataset 55", "record 8", "expected 6 numbers on this line, found 4"});
}

TEST(UffErrors, NonNumericFieldIsQuoted) {
  ExpectReadError(Variant("uff55_translation.uff", {{14, "  1.50162e-01  1.5O162e-01  1.50162e-01"}}), 14,
                  {"dataset 55", "values of node 2", "'1.5O162e-01' is not a number"});
}

TEST(UffErrors, MissingTerminatorBetweenDatasets) {
  // Without line 19 the second dataset's opening '-1' closes the first; "55" (now line 20) is
  // then outside any dataset.
  ExpectReadError(Variant("uff55_translation.uff", {{19, "<drop>"}}), 20,
                  {"expected '-1'", "found '55'", "dataset 55 (line 2) lose its closing '-1'"});
}

TEST(UffErrors, MissingFinalTerminator) {
  ExpectReadError(Variant("uff55_translation.uff", {}, 56), 40, {"dataset 55", "no closing '-1'"});
}

TEST(UffErrors, UnknownCoordinateSystemIsNamed) {
  ExpectReadError(Variant("testlab_geometry_151_164_18_15_82.uff",
                          {{166, "         1         0        40         8 -2.40000e+00 -9.50000e-01  0.00000e+00"}}),
                  166, {"dataset 15", "node 1", "coordinate system 40", "no dataset 18 or 2420"});
}

TEST(UffErrors, UnknownDatasetIsSkippedWithANote) {
  std::vector<std::string> lines = Lines(Sample("uff55_translation.uff"));
  lines.insert(lines.begin(), {"    -1", "  9999", "whatever this holds", "    -1"});
  const TestData d = read_test_data(WriteTempFile("unknown.uff", Join(lines)));
  ASSERT_EQ(d.datasets.size(), 4u);
  EXPECT_EQ(d.datasets[0].number, 9999);
  EXPECT_EQ(d.datasets[0].line, 2);
  EXPECT_FALSE(d.datasets[0].read);
  EXPECT_NE(d.datasets[0].note.find("unknown to this reader"), std::string::npos);
  EXPECT_EQ(d.modes.size(), 3u);
  EXPECT_EQ(d.modes[0].line, 6);
}

TEST(UffErrors, EmptyFileIsNoUniversalFile) { ExpectReadError(WriteTempFile("empty.uff", "\n\n"), 0, {"no datasets"}); }

// ---------------------------------------------------------------------------- rotation, units

// Coordinate system 5: origin (1, 2, 3), local x = global +Y, local y = global -X, z = +Z
// (90° about z). Node 1 sits at local (1, 0, 0) and reports its shape in system 5; node 2 is
// global. Mode values: node 1 local (1, 2, 3 | 0.1, 0.2, 0.3), node 2 global (4, 5, 6 | 0, 0, 0).
const char* const kNodesAndMode = R"(    -1
    15
         1         5         5         8  1.00000e+00  0.00000e+00  0.00000e+00
         2         0         0         8  0.00000e+00  0.00000e+00  0.00000e+00
    -1
    -1
    55
NONE
NONE
NONE
NONE
NONE
         1         2         3         8         2         6
         2         4         1         1
  5.00000e+00  0.00000e+00  0.00000e+00  0.00000e+00
         1
  1.00000e+00  2.00000e+00  3.00000e+00  1.00000e-01  2.00000e-01  3.00000e-01
         2
  4.00000e+00  5.00000e+00  6.00000e+00  0.00000e+00  0.00000e+00  0.00000e+00
    -1
)";

void ExpectRotatedBy90DegreesAboutZ(const TestData& d) {
  ASSERT_EQ(d.coordinate_systems.size(), 1u);
  EXPECT_EQ(d.coordinate_systems[0].id, 5);
  EXPECT_LT((d.find_node(1)->coordinates - Vec3(1, 3, 3)).norm(), 1e-15);
  EXPECT_EQ(d.find_node(2)->coordinates, Vec3(0, 0, 0));
  const TestMode& m = d.modes.at(0);
  // v_global = -2 X + 1 Y + 3 Z for local (1, 2, 3); rotations alike.
  const double expected[] = {-2, 1, 3, -0.2, 0.1, 0.3};
  for (int c = 0; c < 6; ++c) EXPECT_NEAR(*m.value(1, c), expected[c], 1e-15) << "component " << c;
  for (int c = 0; c < 3; ++c) EXPECT_EQ(*m.value(2, c), 4.0 + c);
}

TEST(UffRotation, Dataset18SystemRotatesCoordinatesAndShapes) {
  const std::string file = std::string(R"(    -1
    18
         5         0         0         8         1
TURNED
  1.00000e+00  2.00000e+00  3.00000e+00  1.00000e+00  3.00000e+00  3.00000e+00
  1.00000e+00  2.00000e+00  4.00000e+00
    -1
)") + kNodesAndMode;
  ExpectRotatedBy90DegreesAboutZ(read_test_data(WriteTempFile("sys18.uff", file)));
}

TEST(UffRotation, Dataset2420SystemRotatesCoordinatesAndShapes) {
  // Rows 1-3: the local axes in global coordinates; row 4: the origin.
  const std::string file = std::string(R"(    -1
  2420
         1
PART
         5         0         8
TURNED
   0.0000000000000000D+00   1.0000000000000000D+00   0.0000000000000000D+00
  -1.0000000000000000D+00   0.0000000000000000D+00   0.0000000000000000D+00
   0.0000000000000000D+00   0.0000000000000000D+00   1.0000000000000000D+00
   1.0000000000000000D+00   2.0000000000000000D+00   3.0000000000000000D+00
    -1
)") + kNodesAndMode;
  ExpectRotatedBy90DegreesAboutZ(read_test_data(WriteTempFile("sys2420.uff", file)));
}

TEST(UffRotation, Dataset18RelativeToAnotherSystemComposes) {
  // System 6 is system 5's frame shifted by its local x: origin global (1, 3, 3), same axes.
  const std::string file = std::string(R"(    -1
    18
         6         0         5         8         1
CHILD
  1.00000e+00  0.00000e+00  0.00000e+00  2.00000e+00  0.00000e+00  0.00000e+00
  1.00000e+00  0.00000e+00  1.00000e+00
         5         0         0         8         1
TURNED
  1.00000e+00  2.00000e+00  3.00000e+00  1.00000e+00  3.00000e+00  3.00000e+00
  1.00000e+00  2.00000e+00  4.00000e+00
    -1
)");
  const TestData d = read_test_data(WriteTempFile("chain.uff", file));
  ASSERT_EQ(d.coordinate_systems.size(), 2u);
  const CoordinateSystem& child = d.coordinate_systems[1];
  EXPECT_EQ(child.id, 6);
  EXPECT_LT((child.origin - Vec3(1, 3, 3)).norm(), 1e-15);
  EXPECT_LT((child.axes - d.coordinate_systems[0].axes).norm(), 1e-15);
}

TEST(UffRotation, CylindricalSystemInUseIsRefused) {
  const std::string file = std::string(R"(    -1
    18
         5         1         0         8         1
CYL
  1.00000e+00  2.00000e+00  3.00000e+00  1.00000e+00  3.00000e+00  3.00000e+00
  1.00000e+00  2.00000e+00  4.00000e+00
    -1
)") + kNodesAndMode;
  ExpectReadError(WriteTempFile("cyl.uff", file), 10,
                  {"dataset 15", "node 1", "'CYL'", "cylindrical", "only Cartesian"});
}

TEST(UffUnits, MillimetreFileConvertsToTheModelUnit) {
  const std::string file = R"(    -1
   164
         5mm (milli newton)            2
  1.00000000000000000D+03  1.00000000000000000D+03  1.00000000000000000D+00
  2.73149999999999977D+02
    -1
    -1
    15
         1         0         0         8  2.54000e+01  5.08000e+02  0.00000e+00
    -1
    -1
    55
NONE
NONE
NONE
NONE
NONE
         1         2         3         8         2         6
         2         4         1         1
  5.00000e+00  0.00000e+00  0.00000e+00  0.00000e+00
         1
  2.54000e+01  0.00000e+00  0.00000e+00  1.00000e-01  0.00000e+00  0.00000e+00
    -1
)";
  TestData d = read_test_data(WriteTempFile("mm.uff", file));
  ASSERT_TRUE(d.units);
  EXPECT_EQ(d.units->code, 5);
  EXPECT_EQ(d.units->description, "mm (milli newton)");
  EXPECT_EQ(d.units->temperature_mode, 2);
  EXPECT_EQ(d.units->length_factor, 1000.0);
  EXPECT_CLOSE(length_factor_to(d, "m"), 1e-3, 1e-15);
  EXPECT_CLOSE(length_factor_to(d, "mm"), 1.0, 1e-15);
  EXPECT_CLOSE(length_factor_to(d, "in"), 1.0 / 25.4, 1e-15);
  EXPECT_THROW(length_factor_to(d, "furlong"), std::invalid_argument);

  // The problem's units name inches first: 25.4 mm -> 1 in, 508 mm -> 20 in; rotations stay.
  const std::string done = convert_lengths(&d, {}, "in, lbf, s");
  EXPECT_NE(done.find("converted to in"), std::string::npos) << done;
  EXPECT_LT((d.find_node(1)->coordinates - Vec3(1, 20, 0)).norm(), 1e-12);
  EXPECT_CLOSE(*d.modes[0].value(1, 0), 1.0, 1e-12);
  EXPECT_EQ(*d.modes[0].value(1, 3), 0.1);
  EXPECT_CLOSE(d.length_scale, 1 / 25.4, 1e-15);

  // An explicit factor wins over everything.
  TestData e = read_test_data(WriteTempFile("mm.uff", file));
  convert_lengths(&e, {"m", 2.0}, "in");
  EXPECT_EQ(e.find_node(1)->coordinates, Vec3(50.8, 1016, 0));
}

TEST(UffUnits, FileWithoutUnitsIsOnlyConvertedWhenTold) {
  TestData d = read_test_data(Sample("uff55_translation.uff"));
  EXPECT_EQ(convert_lengths(&d, {}, "mm, N, s"), "");  // no dataset 164: nothing to convert from
  EXPECT_EQ(*d.modes[0].value(1, 0), -1.46518);
  const std::string done = convert_lengths(&d, {"mm", 0}, "");
  EXPECT_NE(done.find("taken as metres"), std::string::npos) << done;
  EXPECT_CLOSE(*d.modes[0].value(1, 0), -1465.18, 1e-12);
}

TEST(UffComplex, BestRealShapeOfARotatedRealShapeIsItself) {
  Eigen::VectorXcd phi(3);
  const Vector psi = (Vector(3) << 1.0, -2.0, 0.5).finished();
  phi = psi.cast<std::complex<double>>() * std::polar(1.0, 0.7);
  const RealShape r = best_real_shape(phi);
  EXPECT_CLOSE(r.collinearity, 1.0, 1e-12);
  EXPECT_LT((r.values - psi).norm() * (r.values - -psi).norm(), 1e-20);  // ± psi
  // A circular (90° out of phase, equal norm) shape has MPC 0.
  Eigen::VectorXcd circle(2);
  circle << std::complex<double>(1, 0), std::complex<double>(0, 1);
  EXPECT_NEAR(best_real_shape(circle).collinearity, 0.0, 1e-15);
}

// ---------------------------------------------------------------------------- node mapping

Model FourNodeModel() {
  Model model;
  model.add_node(1, Vec3(0, 0, 0));
  model.add_node(2, Vec3(1, 0, 0));
  model.add_node(3, Vec3(1, 1, 0));
  model.add_node(4, Vec3(0, 1, 0));
  return model;
}

TestData TestNodes(const std::vector<std::pair<long, Vec3>>& nodes) {
  TestData d;
  TestMode m;
  for (const auto& [id, x] : nodes) {
    TestNode n;
    n.id = id;
    n.coordinates = x;
    d.nodes.push_back(n);
    m.values.push_back({id, 0, 1.0});
  }
  d.modes.push_back(m);
  return d;
}

TEST(UffMapping, ById) {
  const TestData d = TestNodes({{1, Vec3(0, 0, 0.1)}, {3, Vec3(1, 1, 0)}, {17, Vec3(5, 5, 5)}});
  const NodeMapping map = map_test_nodes(d, FourNodeModel(), {});
  ASSERT_EQ(map.matches.size(), 3u);
  EXPECT_EQ(map.matches[0].model_node, 0);
  EXPECT_CLOSE(map.matches[0].distance, 0.1, 1e-15);
  EXPECT_EQ(map.matches[1].model_node, 2);
  EXPECT_EQ(map.matches[2].model_node, -1);
  EXPECT_EQ(map.num_matched(), 2);
  const std::string report = map.report();
  EXPECT_NE(report.find("2 of 3 test nodes matched a model node by id"), std::string::npos) << report;
  EXPECT_NE(report.find("unmatched test node 17: no model node has id 17"), std::string::npos) << report;
}

TEST(UffMapping, ByCoordinatesWithUnmatchedAndContestedPoints) {
  // 101 is near model node 2; 102 and 103 both nearest to model node 3 (103 nearer); 104 is far.
  const TestData d = TestNodes(
      {{101, Vec3(1.001, 0, 0)}, {102, Vec3(1, 1.004, 0)}, {103, Vec3(1, 1.002, 0)}, {104, Vec3(0.5, 0.5, 0)}});
  NodeMapOptions options;
  options.by = NodeMatchBy::Coordinates;
  options.tolerance = 0.01;
  const NodeMapping map = map_test_nodes(d, FourNodeModel(), options);
  ASSERT_EQ(map.matches.size(), 4u);
  EXPECT_EQ(map.matches[0].model_node, 1);
  EXPECT_EQ(map.matches[1].model_node, -1);
  EXPECT_NE(map.matches[1].reason.find("taken by test node 103, which is nearer"), std::string::npos)
      << map.matches[1].reason;
  EXPECT_EQ(map.matches[2].model_node, 2);
  EXPECT_EQ(map.matches[3].model_node, -1);
  EXPECT_CLOSE(map.matches[3].distance, std::sqrt(0.5), 1e-12);
  const std::string report = map.report();
  EXPECT_NE(report.find("2 of 4 test nodes matched a model node by coordinates within 0.01"), std::string::npos)
      << report;
  EXPECT_NE(report.find("unmatched test node 104: the nearest model node, 1, is 0.7071 away (tolerance 0.01)"),
            std::string::npos)
      << report;
}

TEST(UffMapping, GeometryOnlyFileMapsItsNodesByCoordinates) {
  // The Test.Lab geometry has 36 nodes and no modes; a model holding the first 30 (other ids).
  const TestData d = read_test_data(Sample("testlab_geometry_151_164_18_15_82.uff"));
  Model model;
  for (long id = 1; id <= 30; ++id) model.add_node(1000 + id, d.find_node(id)->coordinates);
  NodeMapOptions options;
  options.by = NodeMatchBy::Coordinates;
  const NodeMapping map = map_test_nodes(d, model, options);
  ASSERT_EQ(map.matches.size(), 36u);
  EXPECT_EQ(map.num_matched(), 30);
  for (int k = 0; k < 30; ++k) EXPECT_EQ(model.node_ids[map.matches[k].model_node], 1001 + k);
  // Node 31 at (-2.4, -0.9, 0) is 0.05 from node 1 at (-2.4, -0.95, 0).
  EXPECT_EQ(map.matches[30].test_node, 31);
  EXPECT_NE(map.matches[30].reason.find("the nearest model node, 1001, is 0.05 away"), std::string::npos)
      << map.matches[30].reason;
}

TEST(UffMapping, DefaultToleranceTakesCoincidentNodesOnly) {
  const TestData d = TestNodes({{7, Vec3(1, 1, 0)}, {8, Vec3(1, 1, 1e-3)}});
  NodeMapOptions options;
  options.by = NodeMatchBy::Coordinates;
  const NodeMapping map = map_test_nodes(d, FourNodeModel(), options);
  EXPECT_EQ(map.matches[0].model_node, 2);
  EXPECT_EQ(map.matches[1].model_node, -1);
  EXPECT_CLOSE(map.tolerance, 1e-6 * std::sqrt(2.0), 1e-12);
}

TEST(UffMapping, InvalidToleranceIsNamed) {
  NodeMapOptions options;
  options.tolerance = -1;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("NodeMapOptions::tolerance = -1"), std::string::npos) << error;
  EXPECT_THROW(map_test_nodes(TestData{}, FourNodeModel(), options), std::invalid_argument);
}

// ---------------------------------------------------------------------------- CSV

TEST(UffCsv, RoundTripKeepsEveryValueExactly) {
  const TestData d = read_test_data(Sample("uff55_translation_rotation.uff"));
  const std::string path = WriteTempFile("modes.csv", "");
  write_test_csv(d, path);
  const TestData back = read_test_data(path);
  EXPECT_EQ(back.format, TestData::Format::Csv);
  ASSERT_EQ(back.modes.size(), d.modes.size());
  EXPECT_EQ(back.modes[0].frequency_hz, d.modes[0].frequency_hz);
  EXPECT_EQ(back.modes[0].values_per_node, 6);
  ASSERT_EQ(back.modes[0].values.size(), d.modes[0].values.size());
  for (size_t k = 0; k < d.modes[0].values.size(); ++k) {
    EXPECT_EQ(back.modes[0].values[k].node, d.modes[0].values[k].node);
    EXPECT_EQ(back.modes[0].values[k].component, d.modes[0].values[k].component);
    EXPECT_EQ(back.modes[0].values[k].value, d.modes[0].values[k].value);
  }
  EXPECT_EQ(Lines(path).at(0), "mode,frequency_hz,node,direction,value");
  EXPECT_EQ(Lines(path).at(1), "0,97.013,1,x,0.053569");
  EXPECT_THROW(write_test_csv(d, Sample("uff55_translation_rotation.uff"), {Sample("uff55_translation_rotation.uff")}),
               std::invalid_argument);
}

TEST(UffCsv, HandWrittenFileWithCommentsAndSomeDirections) {
  const TestData d = read_test_data(WriteTempFile("hand.csv", R"(# measured by hand
Mode, Frequency_Hz, Node, Direction, Value

1,12.5,3,z,1.0
1,12.5,4,z,-0.5
2,30,3,Z,0.25
)"));
  ASSERT_EQ(d.modes.size(), 2u);
  EXPECT_EQ(d.modes[0].frequency_hz, 12.5);
  EXPECT_EQ(d.modes[0].line, 4);
  EXPECT_EQ(*d.modes[0].value(4, 2), -0.5);
  EXPECT_FALSE(d.modes[0].value(4, 0));
  EXPECT_EQ(*d.modes[1].value(3, 2), 0.25);
  EXPECT_TRUE(d.nodes.empty());
}

TEST(UffCsv, BadRowsAreNamedByLine) {
  const std::string header = "mode,frequency_hz,node,direction,value\n";
  ExpectReadError(WriteTempFile("a.csv", "mode,freq,node\n1,2,3\n"), 1, {"expected the header line"});
  ExpectReadError(WriteTempFile("b.csv", header + "1,10,3,q,1.0\n"), 2, {"direction 'q'"});
  ExpectReadError(WriteTempFile("c.csv", header + "1,10,3,x,abc\n"), 2, {"value 'abc' is not a finite number"});
  ExpectReadError(WriteTempFile("d.csv", header + "1,10,3,x,1\n1,11,4,x,1\n"), 3,
                  {"mode 1 has frequency 11 Hz here but 10 Hz at line 2"});
  ExpectReadError(WriteTempFile("e.csv", header + "1,10,3,x,1\n1,10,3,x,2\n"), 3, {"given twice (first at line 2)"});
  ExpectReadError(WriteTempFile("f.csv", header + "1,10,3,x\n"), 2, {"expected 5 comma-separated fields"});
  ExpectReadError(WriteTempFile("g.csv", header), 1, {"no data rows"});
}

// ---------------------------------------------------------------------------- problem files

// A 3 × 1 × 1 bar of unit hex8 elements: nodes on the integer grid.
const char* const kBar = R"(mesh:
  element_size: 1
  boxes:
    - {block: bar, min: [0, 0, 0], max: [3, 1, 1]}
blocks:
  bar: {E: 1000, nu: 0.3, density: 1.0}
)";

// Test nodes 11, 12, 13 at model nodes (3, 0, 0), (3, 1, 1), (1, 0, 1) given in mm, and 14 off
// the model; two modes.
const char* const kTestFile = R"(    -1
   164
         5mm (milli newton)            2
  1.00000000000000000D+03  1.00000000000000000D+03  1.00000000000000000D+00
  2.73149999999999977D+02
    -1
    -1
    15
        11         0         0         8  3.00000e+03  0.00000e+00  0.00000e+00
        12         0         0         8  3.00000e+03  1.00000e+03  1.00000e+03
        13         0         0         8  1.00000e+03  0.00000e+00  1.00000e+03
        14         0         0         8  9.00000e+03  9.00000e+03  9.00000e+03
    -1
    -1
    55
NONE
NONE
NONE
NONE
NONE
         1         2         2         8         2         3
         2         4         1         1
  4.20000e+01  0.00000e+00  1.00000e-02  0.00000e+00
        11
  1.00000e-01  2.00000e-01  3.00000e-01
        12
  4.00000e-01  5.00000e-01  6.00000e-01
        13
  7.00000e-01  8.00000e-01  9.00000e-01
        14
  1.00000e+00  1.00000e+00  1.00000e+00
    -1
    -1
    55
NONE
NONE
NONE
NONE
NONE
         1         2         2         8         2         3
         2         4         1         2
  8.40000e+01  0.00000e+00  0.00000e+00  0.00000e+00
        11
 -1.00000e-01  2.00000e-01 -3.00000e-01
        12
 -4.00000e-01  5.00000e-01 -6.00000e-01
        13
 -7.00000e-01  8.00000e-01 -9.00000e-01
        14
  1.00000e+00  1.00000e+00  1.00000e+00
    -1
)";

TEST(UffProblem, MeasuredModesComeFromAUniversalFile) {
  WriteTempFile("bar_test.uff", kTestFile);
  const std::string text = std::string("units: m, N, s\n") + kBar + R"(measured:
  test_data: {file: bar_test.uff, modes: [2, 1], map: coordinates, tolerance: 1.0e-6, directions: [y, z]}
)";
  const Problem p = LoadProblem(WriteTempFile("bar.yaml", text));
  ASSERT_EQ(p.sensors.size(), 6u);  // 3 matched nodes × (y, z)
  const Vec3 at[] = {Vec3(3, 0, 0), Vec3(3, 1, 1), Vec3(1, 0, 1)};
  for (int k = 0; k < 3; ++k)
    for (int c = 0; c < 2; ++c) {
      const Sensor& s = p.sensors[static_cast<size_t>(2 * k + c)];
      EXPECT_EQ(p.model.coordinates[s.node], at[k]) << s.label;
      EXPECT_EQ(s.component, c + 1);
    }
  EXPECT_NE(p.sensors[0].label.find("+y (test node 11)"), std::string::npos) << p.sensors[0].label;
  ASSERT_EQ(p.measured.size(), 2u);
  EXPECT_EQ(p.measured[0].frequency_hz, 84.0);  // mode 2 first, as listed
  EXPECT_EQ(p.measured[1].frequency_hz, 42.0);
  EXPECT_EQ(p.measured[0].label, "test mode 2");
  EXPECT_EQ(p.measured[0].pairing.kind, PairingRule::Kind::Mac);
  const Vector mode2 = (Vector(6) << 0.2, -0.3, 0.5, -0.6, 0.8, -0.9).finished();
  EXPECT_EQ(p.measured[0].shape, mode2 * 1e-3);  // mm -> m
  EXPECT_TRUE(HasWarning(p.warnings, "unmatched test node 14"));
  EXPECT_TRUE(HasWarning(p.warnings, "lengths converted to m"));
}

TEST(UffProblem, AnExplicitScaleAndMappingById) {
  WriteTempFile("bar_test.uff", kTestFile);
  // The bar's node ids are 1..16; test nodes 11..14 map by id onto model nodes 11..14.
  const std::string text = std::string(kBar) + R"(measured:
  test_data: {file: bar_test.uff, scale_length: 2, directions: [x]}
)";
  const Problem p = LoadProblem(WriteTempFile("bar.yaml", text));
  ASSERT_EQ(p.sensors.size(), 4u);
  for (size_t k = 0; k < 4; ++k) EXPECT_EQ(p.model.node_ids[p.sensors[k].node], 11 + static_cast<long>(k));
  ASSERT_EQ(p.measured.size(), 2u);
  EXPECT_EQ(p.measured[0].shape, (Vector(4) << 0.2, 0.8, 1.4, 2.0).finished());
}

TEST(UffProblem, SyntheticModesWrittenAsCsvComeBackThroughAProblemFile) {
  const std::string model = testing::kEveryParameterKindModel;
  const Problem truth = LoadProblem(WriteTempFile("every.yaml", model));
  TestData csv;
  for (size_t k = 0; k < truth.measured.size(); ++k) {
    TestMode m;
    m.number = static_cast<int>(k + 1);
    m.frequency_hz = truth.measured[k].frequency_hz;
    for (size_t i = 0; i < truth.sensors.size(); ++i)
      m.values.push_back({truth.model.node_ids[truth.sensors[i].node], truth.sensors[i].component,
                          truth.measured[k].shape[static_cast<Eigen::Index>(i)]});
    csv.modes.push_back(m);
  }
  write_test_csv(csv, WriteTempFile("synthetic.csv", ""));
  // The same model, its sensors and measured modes replaced by the CSV.
  const size_t from = model.find("sensors:"), to = model.find("options:");
  const std::string text = model.substr(0, from) + "measured:\n  test_data: {file: synthetic.csv}\n" + model.substr(to);
  const Problem p = LoadProblem(WriteTempFile("from_csv.yaml", text));
  ASSERT_EQ(p.measured.size(), truth.measured.size());
  ASSERT_EQ(p.sensors.size(), truth.sensors.size());
  for (size_t k = 0; k < p.measured.size(); ++k) {
    EXPECT_EQ(p.measured[k].frequency_hz, truth.measured[k].frequency_hz);
    for (size_t i = 0; i < p.sensors.size(); ++i) {
      const auto same = std::find_if(truth.sensors.begin(), truth.sensors.end(), [&](const Sensor& s) {
        return s.node == p.sensors[i].node && s.component == p.sensors[i].component;
      });
      ASSERT_NE(same, truth.sensors.end()) << p.sensors[i].label;
      EXPECT_EQ(p.measured[k].shape[static_cast<Eigen::Index>(i)],
                truth.measured[k].shape[same - truth.sensors.begin()]);
    }
  }
  // The 'at' sensor measured y and z only: its x is not in the file.
  EXPECT_TRUE(HasWarning(p.warnings, "1 sensor DOF(s) dropped"));
}

TEST(UffProblem, PermasShellModesOnASolidPlateMappedByCoordinates) {
  // The Permas nodes are a 21 × 21 grid on the unit square at z = 0: the bottom face of a
  // 20 × 20 × 1 hex plate.
  const std::string text = R"(units: m, N, s
mesh:
  element_size: 0.05
  boxes:
    - {block: plate, min: [0, 0, 0], max: [1, 1, 0.02]}
blocks:
  plate: {E: 2.1e11, nu: 0.3, density: 7850}
measured:
  test_data: {file: )" + Sample("nodes2411_results2414.uff") +
                           R"(, modes: [1, 2, 3], map: coordinates, directions: [z]}
)";
  const Problem p = LoadProblem(WriteTempFile("plate.yaml", text));
  ASSERT_EQ(p.sensors.size(), 441u);
  for (const Sensor& s : p.sensors) EXPECT_EQ(p.model.coordinates[s.node].z(), 0.0) << s.label;
  ASSERT_EQ(p.measured.size(), 3u);
  EXPECT_EQ(p.measured[1].frequency_hz, 2.34163);
  EXPECT_EQ(p.measured[0].shape[0], -7.08571e-01);  // node 1, z, the first sensor
  EXPECT_TRUE(p.warnings.empty()) << p.warnings.front();
}

TEST(UffProblem, ErrorsNameTheRightFileAndLine) {
  WriteTempFile("bar_test.uff", kTestFile);
  const std::string dir = std::filesystem::path(WriteTempFile("bar_test.uff", kTestFile)).parent_path().string();
  auto expect_error = [](const std::string& path, const std::string& file, int line,
                         const std::vector<std::string>& fragments) {
    try {
      LoadProblem(path);
      ADD_FAILURE() << "expected a ProblemError";
    } catch (const ProblemError& e) {
      EXPECT_EQ(e.file(), file) << e.what();
      EXPECT_EQ(e.line(), line) << e.what();
      for (const std::string& f : fragments)
        EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << "'" << f << "' not in: " << e.what();
    }
  };
  // A mode the file does not have: the problem file, at the list item.
  const std::string missing_mode = WriteTempFile("a.yaml", std::string(kBar) + R"(measured:
  test_data:
    file: bar_test.uff
    modes: [1, 7]
)");
  expect_error(missing_mode, missing_mode, 10, {"mode 7 is not in", "its modes: 1, 2"});
  // A broken test file: the test file, its line and dataset, and where it was asked for.
  std::string broken = kTestFile;
  broken.replace(broken.find("4.00000e-01  5.00000e-01"), 11, "4.0000xe-01");
  WriteTempFile("broken.uff", broken);
  const std::string bad_file = WriteTempFile("b.yaml", std::string(kBar) + R"(measured:
  test_data: {file: broken.uff}
)");
  expect_error(bad_file, dir + "/broken.uff", 27, {"dataset 55", "'4.0000xe-01' is not a number", "b.yaml:8"});
  // No such file: the problem file, at 'file'.
  const std::string no_file = WriteTempFile("c.yaml", std::string(kBar) + R"(measured:
  test_data: {file: nowhere.uff}
)");
  expect_error(no_file, no_file, 8, {"cannot open the test-data file", "nowhere.uff"});
  // Sensors come from the file; a 'sensors' section as well is ambiguous.
  const std::string both = WriteTempFile("d.yaml", std::string(kBar) + R"(sensors:
  - {node: 1, directions: [x]}
measured:
  test_data: {file: bar_test.uff}
)");
  expect_error(both, both, 10, {"remove the 'sensors' section"});
  // Nothing matched.
  const std::string none = WriteTempFile("e.yaml", std::string(kBar) + R"(measured:
  test_data: {file: bar_test.uff, map: coordinates}
)");
  expect_error(none, none, 8, {"no sensor", "0 of 4 test nodes matched"});
}

}  // namespace
}  // namespace modalcal
