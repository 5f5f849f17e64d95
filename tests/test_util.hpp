#pragma once
// Shared test helpers (in the spirit of Ceres' test_util): relative/absolute closeness with a
// message that shows both numbers, and small model builders used by several test files.

#include <string>

#include <gtest/gtest.h>

#include "modalcal/model.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/types.hpp"

namespace modalcal::testing {

/// |a - b| <= tol * max(|a|, |b|, floor); reports both values on failure.
::testing::AssertionResult IsClose(double a, double b, double rel_tol, double floor = 0.0);
#define EXPECT_CLOSE(a, b, tol) EXPECT_TRUE(::modalcal::testing::IsClose((a), (b), (tol)))

/// load_problem(), then synthesize_measured(): the problem file with its measured modes, as the
/// tool loads it.
Problem LoadProblem(const std::string& path, const LoadOptions& options = {});

/// Compares two texts that differ only in the last digits of their numbers: the parts between
/// numbers must be equal, and each pair of numbers must satisfy
/// |a - b| <= absolute + relative |b|. Returns "" when they agree, otherwise where they first
/// differ (line and both tokens). For files written from floating-point results, which are not
/// bit-identical across CPUs and BLAS thread counts.
std::string NumericTextDifference(const std::string& actual, const std::string& expected, double relative,
                                  double absolute);

/// Max-abs-entry relative difference of two matrices, scaled by max |b|.
double RelativeDifference(const Matrix& a, const Matrix& b);

/// Problem file text: a two-block cantilever with a joint to a reference node carrying a point
/// mass, springs at the root, sensors on the top edge, six measured modes with shapes
/// synthesized at the truth values, and a parameter of every kind (E, nu, K, G, densities,
/// stiffness and mass scales, joint, spring, point mass and inertia). Not every combination is
/// identifiable (E and the stiffness scale of the same block act alike): for derivative checks.
extern const char* const kEveryParameterKindModel;

/// Problem-file text of a hex8 cantilevered bar 4 x 0.5 x 0.75 (block `bar`: E 1000, nu 0.3,
/// density 1; element size 0.5, so 9 x 2 x 3 nodes and a non-square section without repeated
/// eigenvalues), clamped at x = 0 (node set `root`), with node sets `tip` (x = 4) and `top_edge`
/// (y = 0.5, z = 0.75; 9 nodes, the first at the root). `extra_node_sets` and `extra_fixed` are
/// appended to those sections (YAML lines indented by two); tests add the other sections.
std::string CantileverBar(const std::string& extra_node_sets = "", const std::string& extra_fixed = "");

/// Path of a file in the source tree.
std::string SourcePath(const std::string& relative);

/// Writes `text` to a fresh file in a per-test temporary directory and returns its path.
std::string WriteTempFile(const std::string& name, const std::string& text);

/// The whole content of a file ("" if it cannot be read).
std::string ReadFile(const std::string& path);

/// One run of the command-line program.
struct CliRun {
  int exit_code;
  std::string output;  ///< stdout and stderr
};

/// Runs `fullspace_calib ARGS` through the shell (so ARGS may quote and redirect).
CliRun RunCli(const std::string& args);
/// Runs a shell command line, its stderr joined to its stdout.
CliRun RunShell(const std::string& command);

/// CantileverBar() with one calibration parameter (the modulus E, log-scaled, start 1000),
/// triaxial sensors along the top edge and six modes: the CLI tests' small problem.
std::string SensedBar();

/// Writes SensedBar() as nominal.yaml, data measured on a truth with 50 g at its tip (modes 1-4,
/// 0.2 % frequency and 1 % shape noise, seed 3) as data.yaml, and study.yaml, the nominal model
/// reading those data, into the test's folder; returns study.yaml's path. Fails the test when
/// `synth` does.
std::string WriteTipMassStudy();

/// A spring-mass chain along x: `n` point masses `m` on nodes 1..n joined by joints of axial
/// stiffness `k` (properties "joint<i>.kx"); node 0 is fixed in x when `grounded`, otherwise
/// it is a further mass (free-free chain with one rigid-body mode). y and z are fixed
/// everywhere so only axial motion remains.
Model MakeChain(int n, double m, double k, bool grounded);

}  // namespace modalcal::testing
