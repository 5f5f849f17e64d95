#pragma once
/// \file comparison.hpp
/// Test-analysis correlation of measured and model modes at given parameter values: the pairing
/// (the calibration objective's own, by MAC, model index or family), frequency errors, the full
/// MAC matrix, COMAC per sensor DOF and the cross-orthogonality with a SEREP test-analysis mass.
///
/// - MAC (Allemang & Brown 1982) of measured shape \f$\phi_i\f$ and model mode k at the sensors:
///   \f$\mathrm{MAC}_{ik} = (\phi_i^T P u_k)^2 / ((\phi_i^T\phi_i)(u_k^T P^T P u_k))\f$.
/// - COMAC (Lieven & Ewins 1988; Allemang 2003) of sensor DOF s over the pairs (i, k) with shapes,
///   each measured shape first scaled onto its model mode by the modal scale factor
///   \f$\mathrm{MSF}_i = (P u_k)^T \phi_i / \phi_i^T \phi_i\f$ (which also fixes its sign):
///   \f[ \mathrm{COMAC}_s = \frac{\big(\sum_i |\tilde\phi_{is}\,(P u_{k(i)})_s|\big)^2}
///       {\sum_i \tilde\phi_{is}^2 \,\sum_i (P u_{k(i)})_s^2}, \qquad \tilde\phi_i = \mathrm{MSF}_i\,\phi_i. \f]
///   1 where measured and model shapes agree at that DOF in every pair; low values localize the
///   disagreement. Undefined (NaN) where a DOF is zero in every measured or every model shape.
/// - Cross-orthogonality \f$C = \tilde\Phi_t^T M_a \Phi_a\f$ with the SEREP mass (O'Callahan,
///   Avitabile & Riemer 1989): with U the basis modes and \f$\Phi_a = P U\f$ at the sensors,
///   \f$T = U \Phi_a^+\f$, \f$M_a = T^T M T = (\Phi_a^+)^T (U^T M U) \Phi_a^+ = (\Phi_a^+)^T \Phi_a^+\f$
///   since the modes are mass-normalized; each measured shape is scaled to
///   \f$\tilde\phi^T M_a \tilde\phi = 1\f$ with the sign of its pair. The basis modes reduced this way
///   are exactly M_a-orthonormal, so C is the identity for perfect data; the usual acceptance is
///   \f$|C_{ii}| > 0.9\f$, \f$|C_{ij}| < 0.1\f$. The basis is every computed mode when there are at
///   least as many sensor DOFs and the modes are independent at the sensors (a measured shape's
///   part outside the paired modes then shows against the others), else the paired modes alone
///   (each row of C then has unit length: only the mixing among paired modes shows); when
///   neither works there is no test mass and C is left empty.
///
/// \code
/// modalcal::ModalComparison c = modalcal::compare_modes(problem, problem.initial_values());
/// for (const modalcal::ComparedPair& pair : c.pairs) std::cout << pair.error_percent << " " << pair.mac << "\n";
/// \endcode

#include <cmath>
#include <string>
#include <vector>

#include "modalcal/export.hpp"
#include "modalcal/problem.hpp"

namespace modalcal {

struct MODALCAL_EXPORT ComparisonOptions {
  /// A pair whose MAC is below this is listed as unpaired: no model mode resembles the measured
  /// shape (0.5: the shapes are closer to orthogonal than to parallel). Range: [0, 1].
  double unpaired_mac = 0.5;
  /// SEREP needs the paired modes at the sensors to be independent: the ratio of the smallest to
  /// the largest singular value of \f$\Phi_a\f$ must exceed this. Range: (0, 1).
  double serep_condition = 1e-6;
  /// Returns false and names the field, its value and the violated range.
  bool IsValid(std::string* error) const;
};

/// One measured mode and its paired model mode.
struct MODALCAL_EXPORT ComparedPair {
  int measured = 0;               ///< 0-based index into Problem::measured
  int model = 0;                  ///< 0-based elastic model mode
  double measured_hz = 0, model_hz = 0;
  double error_percent = 0;       ///< 100 (f_model / f_measured - 1)
  double mac = -1;                ///< -1 without a measured shape
  double cross_orthogonality = NAN;  ///< C_ii, NaN without a test mass or shape
};

struct MODALCAL_EXPORT ModalComparison {
  std::vector<ComparedPair> pairs;           ///< in the order of Problem::measured
  std::vector<int> unpaired_measured;        ///< indices into `pairs` with MAC < unpaired_mac
  std::vector<int> unpaired_model;           ///< 0-based model modes no measured mode pairs with
  Vector model_hz;                           ///< every computed elastic model mode
  /// measured x model modes; rows of modes without a shape are NaN.
  Matrix mac;
  /// per sensor DOF (Problem::sensors), NaN where undefined; empty without shapes.
  Vector comac;
  /// rows: the measured modes of `shape_pairs`, columns: the model modes of `serep_modes`;
  /// empty without a test mass (see `cross_orthogonality_note`).
  Matrix cross_orthogonality;
  std::vector<int> shape_pairs;              ///< indices into `pairs` of the pairs with shapes
  std::vector<int> serep_modes;              ///< 0-based model modes of the SEREP basis
  std::string cross_orthogonality_note;      ///< why there is no test mass, or empty
  std::vector<std::string> warnings;         ///< the pairing's warnings (nearly repeated eigenvalues)
};

/// Solves the model at `p` and correlates it with the problem's measured modes.
/// \throws std::invalid_argument for invalid options or a problem without measured modes,
///   std::runtime_error (with the cause) if the model solve or the pairing fails.
MODALCAL_EXPORT ModalComparison compare_modes(const Problem& problem, const Vector& p,
                                              const ComparisonOptions& options = {});

}  // namespace modalcal
