#pragma once
/// \file mode_description.hpp
/// What a mode looks like, in the terms test engineers use: its frequency, the share of its
/// kinetic energy in each global direction, its effective-mass fractions, its dominant
/// direction and the name of its mode family.
///
/// Kinetic-energy fraction of direction d:
/// \f$ e_d = \sum_{f \in d} u_f (M u)_f \,/\, u^T M u \f$ (sums over the free DOFs of that
/// translational component; the rest is rotational).
/// Effective mass fraction: \f$ (r_d^T M u)^2 / m_{total} \f$ with \f$r_d\f$ the unit rigid
/// translation along d (zero for every elastic mode of a free-free model).
/// Part-translation fraction: the share of kinetic energy in the mean translation of each part
/// (element block), \f$ t_d = \sum_b (r_{b,d}^T M u)^2 / (r_{b,d}^T M r_{b,d}) \,/\, u^T M u \f$,
/// with \f$r_{b,d}\f$ the unit translation of part b alone. It is near 1 along x for parts
/// moving against each other along x (an axial mode, supported or free-free) and small for
/// rocking or bending, whose kinetic energy may still be mostly along x. A mode joins the
/// family of direction d when \f$t_d \ge 0.5\f$.

#include <array>
#include <string>
#include <vector>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/export.hpp"

namespace modalcal {

struct MODALCAL_EXPORT ModeDescription {
  int index = 0;                              ///< 1-based elastic mode index
  double frequency_hz = 0;
  std::array<double, 3> energy_fraction{};    ///< kinetic energy share along x, y, z
  double rotational_fraction = 0;             ///< share in rotational DOFs
  std::array<double, 3> effective_mass_fraction{};
  std::array<double, 3> part_translation_fraction{};
  int dominant_direction = 0;                 ///< 0..2, the largest energy_fraction
  std::string label;                          ///< family name, or empty
};

/// Describes the elastic modes of `result`. `model.mode_families` names the labels.
MODALCAL_EXPORT std::vector<ModeDescription> describe_modes(const ParametricSystem& system, const Vector& p,
                                                            const SparseMatrix& M, const ModalResult& result);

/// 1-based index (within `modes`) of the `k`-th (1-based) mode whose label is `family`, or 0.
MODALCAL_EXPORT int find_family_mode(const std::vector<ModeDescription>& modes, const std::string& family, int k);

}  // namespace modalcal
