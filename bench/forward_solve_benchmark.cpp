// Forward modal solve of the LFU problem against its floor.
//
// The floor is what any sparse direct shift-invert method must pay at least once: CHOLMOD's
// symbolic analysis, one supernodal factorization of K - sigma M, and one solve. The forward
// solve (analysis + factorization + shift-invert Lanczos) is reported as a ratio to it, side by
// side in the same run. Each case runs in a forked child so that its peak memory (max RSS) is its
// own.
//
// Usage: forward_solve_benchmark [--problem FILE] [--dofs 3e4,1e5,3e5] [--modes 10,20] [--json OUT]

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "eigen/cholmod_factor.hpp"
#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/output.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

using namespace modalcal;
using modalcal::bench::parse_list;
using Clock = std::chrono::steady_clock;

namespace {

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct CaseResult {
  double refinement = 0;
  int dofs = 0, modes = 0;
  double assembly_s = 0, floor_s = 0, solve_s = 0, factor_nnz = 0;
  int factorizations = 0, solves = 0;
  double lowest_hz = 0;
  long peak_kb = 0;
  bool ok = false;
};

// Runs in the child: assembles, measures the floor, then the forward solve.
CaseResult run_case(const std::string& problem_path, double refinement, int modes) {
  CaseResult r;
  r.refinement = refinement;
  r.modes = modes;
  Problem problem = load_problem(problem_path, LoadOptions{refinement});
  synthesize_measured(&problem);
  auto t0 = Clock::now();
  ParametricSystem system(problem.model, problem.parameter_targets());
  SparseMatrix K, M;
  const Vector p = problem.has_truth() ? problem.truth_values() : problem.initial_values();
  system.assemble(p, &K, &M);
  r.assembly_s = seconds_since(t0);
  r.dofs = system.num_dofs();

  // Floor, with the shift the solver itself will use on its first solve.
  const double sigma = -1e-6 * K.diagonal().sum() / M.diagonal().sum();
  t0 = Clock::now();
  {
    detail::CholmodFactor factor(system.pattern());
    int failed = -1;
    if (!factor.factorize(K, M, sigma, &failed)) return r;
    Vector b = Vector::Ones(r.dofs), x(r.dofs);
    factor.solve(b.data(), x.data());
    r.factor_nnz = factor.factor_nonzeros();
  }
  r.floor_s = seconds_since(t0);

  ModalOptions options;
  options.num_modes = modes;
  options.max_rigid_modes = problem.expected_rigid_modes();
  t0 = Clock::now();
  ModalSolver solver(system.pattern(), options);
  const ModalResult result = solver.solve(K, M);
  r.solve_s = seconds_since(t0);
  r.ok = result.status == EigenStatus::Successful;
  r.factorizations = result.factorizations;
  r.solves = result.operator_solves;
  if (r.ok) r.lowest_hz = frequency_hz(result.eigenvalues[0]);
  return r;
}

CaseResult run_in_child(const std::string& problem_path, double refinement, int modes) {
  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    CaseResult r;
    try {
      r = run_case(problem_path, refinement, modes);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "case failed: %s\n", e.what());
    }
    if (write(fds[1], &r, sizeof(r)) != static_cast<ssize_t>(sizeof(r))) _exit(1);
    _exit(0);
  }
  close(fds[1]);
  CaseResult r;
  const bool got = read(fds[0], &r, sizeof(r)) == static_cast<ssize_t>(sizeof(r));
  close(fds[0]);
  int status = 0;
  struct rusage usage;
  wait4(pid, &status, 0, &usage);
  if (!got) r = CaseResult{};
  r.peak_kb = usage.ru_maxrss;
  return r;
}

int run(int argc, char** argv) {
  std::string problem_path = std::string(MODALCAL_SOURCE_DIR) + "/problems/lfu/lfu.yaml";
  std::vector<double> targets = {3e4, 1e5, 3e5};
  std::vector<double> mode_counts = {10, 20};
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--problem") problem_path = next();
    else if (a == "--dofs") targets = parse_list(next());
    else if (a == "--modes") mode_counts = parse_list(next());
    else if (a == "--json") json_path = next();
    else {
      std::fprintf(stderr, "usage: %s [--problem FILE] [--dofs 3e4,1e5,3e5] [--modes 10,20] [--json OUT]\n", argv[0]);
      return 2;
    }
  }
  // Grid intervals are divided into ceil(r * L / h) parts, so DOFs grow only roughly as r^3:
  // find the refinement giving the target DOF count by bisection on log r (counting DOFs needs
  // only the mesh and the DOF map, not the matrices).
  auto dofs_at = [&](double refinement) {
    Problem problem = load_problem(problem_path, LoadOptions{refinement});
    return DofMap(problem.model).num_free();
  };
  auto refinement_for = [&](double target) {
    double lo = 0.25, hi = 8.0;
    for (int k = 0; k < 14; ++k) {
      const double mid = std::sqrt(lo * hi);
      (dofs_at(mid) < target ? lo : hi) = mid;
    }
    return std::abs(dofs_at(lo) - target) < std::abs(dofs_at(hi) - target) ? lo : hi;
  };
  std::printf("Forward modal solve vs floor (analysis + 1 factorization + 1 solve), %s\n", problem_path.c_str());
  std::printf("%9s %5s %6s %10s %9s %9s %7s %6s %6s %9s %10s\n", "DOFs", "modes", "refine", "assembly s",
              "floor s", "solve s", "ratio", "facts", "solves", "peak MB", "f1 [Hz]");
  nlohmann::json json = nlohmann::json::array();
  for (double target : targets) {
    const double refinement = refinement_for(target);
    for (double modes : mode_counts) {
      const CaseResult r = run_in_child(problem_path, refinement, static_cast<int>(modes));
      const double ratio = r.floor_s > 0 ? r.solve_s / r.floor_s : NAN;
      std::printf("%9d %5d %6.3f %10.2f %9.2f %9.2f %7.2f %6d %6d %9.0f %10.2f%s\n", r.dofs, r.modes, refinement,
                  r.assembly_s, r.floor_s, r.solve_s, ratio, r.factorizations, r.solves, r.peak_kb / 1024.0,
                  r.lowest_hz, r.ok ? "" : "  FAILED");
      std::fflush(stdout);
      json.push_back({{"dofs", r.dofs}, {"modes", r.modes}, {"refinement", refinement}, {"assembly_s", r.assembly_s},
                      {"floor_s", r.floor_s}, {"solve_s", r.solve_s}, {"ratio_to_floor", ratio},
                      {"factorizations", r.factorizations}, {"operator_solves", r.solves},
                      {"factor_nonzeros", r.factor_nnz}, {"peak_memory_mb", r.peak_kb / 1024.0},
                      {"lowest_frequency_hz", r.lowest_hz}, {"ok", r.ok}});
    }
  }
  if (!json_path.empty()) write_file_atomically(json_path, json.dump(2) + "\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return modalcal::bench::run_guarded("forward_solve_benchmark", run, argc, argv); }
