#pragma once
// Internal: which model mode each measured mode is compared with, from a forward solve alone, so
// that the objective and the test-analysis comparison (diagnostics/comparison.cpp) pair alike
// without the comparison building a whole Objective.

#include <functional>
#include <string>
#include <vector>

#include "modalcal/eigen.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/objective.hpp"
#include "modalcal/problem.hpp"

namespace modalcal::detail {

struct ModePairing {
  std::vector<int> model_of;  ///< the model mode paired with each measured mode (-1: none)
  std::vector<int> mac_rows;  ///< the measured modes paired by MAC
  Matrix mac_table;           ///< MAC of each measured shape with each model mode (-1: no shape)
  std::string message;        ///< why the pairing failed; empty when every measured mode has its mode
  bool ok() const { return message.empty(); }
};

/// Fixed rules first (a model index, or the n-th mode of a family: `describe` gives the modes'
/// descriptions, called only when a family rule needs them), then by MAC (largest total MAC,
/// one-to-one, near ties to the nearer eigenvalue); with `frequency_order` the MAC-paired set is
/// assigned in frequency order. `sensors` maps free DOFs to sensor readings.
ModePairing pair_modes(const Problem& problem, const ModalResult& modal, const SparseMatrix& sensors,
                       bool frequency_order, const std::function<std::vector<ModeDescription>()>& describe);

/// The pairs of `model_of` (measured mode, model mode, both frequencies, relative eigenvalue
/// error, MAC from `mac_table` or -1 without a shape), in measured order.
std::vector<PairedMode> paired_modes(const Problem& problem, const ModalResult& modal, const std::vector<int>& model_of,
                                     const Matrix& mac_table);

/// "measured mode 1 is paired with model mode 3, whose eigenvalue nearly repeats that of mode 4"
/// for each pair whose model eigenvalue lies within `tolerance` (relative) of a neighbour's.
std::vector<std::string> close_eigenvalue_warnings(const Problem& problem, const ModalResult& modal,
                                                   const std::vector<int>& model_of, double tolerance);

/// The elastic modes a forward solve computes for `problem`: the highest its pairing rules name or
/// problem.options.num_modes, plus `extra_modes` as far as a model of `num_dofs` has them.
int modes_to_compute(const Problem& problem, int extra_modes, int num_dofs);

/// "measured mode 2 ('bending 1')", for messages.
std::string describe_measured(const MeasuredMode& m, int index);

}  // namespace modalcal::detail
