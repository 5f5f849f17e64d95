// Loads a bundled problem through the installed library and prints its lowest frequency:
// proves the installed headers, library and package config are complete.
#include <cmath>
#include <cstdio>

#include <modalcal/eigen.hpp>
#include <modalcal/problem.hpp>
#include "modalcal/problem_file.hpp"
#include "modalcal/synthesis.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer PROBLEM.yaml\n");
    return 2;
  }
  modalcal::Problem problem = modalcal::load_problem(argv[1]);
  modalcal::synthesize_measured(&problem);
  std::printf("%s: %d nodes, %zu parameters, %zu measured modes, first measured %.6f Hz\n", problem.name.c_str(),
              problem.model.num_nodes(), problem.parameters.size(), problem.measured.size(),
              problem.measured.empty() ? 0.0 : problem.measured.front().frequency_hz);
  return problem.measured.empty() ? 1 : 0;
}
