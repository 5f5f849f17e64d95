#pragma once
/// \file localization.hpp
/// Model-form diagnosis, "where does the model fail": a spatial error indicator from the
/// residual forces of the measured modes.
///
/// 1. **Expansion.** Each measured shape \f$\phi_s\f$ (at the sensors) is first scaled to its
///    paired model mode \f$u_k\f$ by the modal scale factor
///    \f$a = (P u_k)^T \phi_s / \phi_s^T \phi_s\f$ (test shapes have arbitrary sign and units),
///    then expanded to all DOFs on a basis \f$\Phi\f$ of model modes (the rigid-body modes of a
///    free-free model and the lowest elastic ones):
///    \f[ \phi = \Phi c,\qquad c = \arg\min_c \|P\Phi c - a\phi_s\|^2 + \alpha^2 \sigma_1^2 \|c - e_k\|^2, \f]
///    P the sensor selection, \f$\sigma_1\f$ the largest singular value of \f$P\Phi\f$, \f$e_k\f$
///    the coordinates of the paired mode (regularizing toward it, not toward zero, keeps a
///    shape the model reproduces free of residual). With
///    \f$\alpha = 0\f$ and no more basis modes than sensor readings this is SEREP (O'Callahan,
///    Avitabile & Riemer 1989). The expanded shape is normalized to \f$\phi^T M \phi = 1\f$.
/// 2. **Residual forces** with the *measured* eigenvalue,
///    \f[ r_i = (K - \lambda_{m,i} M)\,\phi_i , \f]
///    zero when the model reproduces the test mode and, for a model whose K or M is wrong by
///    \f$\Delta K, \Delta M\f$ somewhere, \f$r_i \approx -(\Delta K - \lambda_{m,i}\Delta M)\phi_i\f$:
///    nonzero exactly there.
/// 3. **Indicator.** The energy of a free DOF d is
///    \f[ e_d = \sum_i \frac{r_{i,d}^2}{\lambda_{m,i}^2\, M_{dd}} , \f]
///    the diagonal form of the residual's norm dual to the mass norm in which \f$\phi_i\f$ is
///    normalized, \f$r^T M^{-1} r/\lambda^2\f$: \f$r_d/(\lambda M_{dd})\f$ is the shape error the
///    residual force implies when read as a missing inertial force, and \f$M_{dd}\f$ times its
///    square is that error's share of the mode's kinetic energy (\f$\phi^T M \phi = 1\f$). So
///    each mode contributes a dimensionless number, independent of the shape's scale and of the
///    unit system, and translations and rotations add up in the same unit. The expanded residual
///    is \f$M\Phi(\Lambda - \lambda_m)c\f$, and \f$M_{dd}\f$ undoes that mass weighting
///    (dividing by \f$K_{dd}\f$ would rank heavy lumped masses first whatever the change;
///    docs/design.md). A node's energy is the sum over its free DOFs. For the mesh view, the
///    energy of a rigid coupling's reference node that belongs to no element is passed on
///    equally to the nodes it couples; an element gets the sum of its nodes' energies, each
///    divided by the number of elements sharing that node.
/// 4. **Regions and ranking.** Element block (sum of its elements), joint (its two nodes),
///    spring to ground and point mass (their nodes), node set (its nodes, mesh view). The share
///    of a region is its energy over the total energy of all nodes; regions overlap (a node set
///    lies inside blocks), so shares do not add up to one. Regions are ranked by share.
///
/// Caveat: an expansion on model modes can only express shapes the model can produce, so the
/// residual \f$r_i\f$ lies in the span of \f$M\Phi\f$: it is the projection
/// \f$-M\Phi\Phi^T\Delta K\phi_i\f$ of the localized force onto the basis, sharp with many basis
/// modes and smeared with few. Too many basis modes fail the other way: when the sensors cannot
/// tell them apart (\f$P\Phi\f$ ill conditioned) their coefficients fit the error itself and the
/// indicator is noise. The automatic basis therefore takes the largest one whose condition
/// number at the sensors stays below LocalizationOptions::max_condition, and no higher in frequency
/// than LocalizationOptions::max_frequency_ratio times the highest measured mode, because noise
/// in a basis coefficient enters the residual multiplied by the basis mode's eigenvalue. The
/// indicator needs accurate shapes (measured noise limits: docs/studies.md). It points at
/// regions (a changed joint shows in the blocks it connects), not at single elements; more
/// sensors, which allow more basis modes, sharpen it. A model whose measured shapes match
/// exactly has a total energy at rounding level, and then the ranking means nothing
/// (Localization::total_energy says so).
///
/// \code
/// modalcal::Problem problem = modalcal::load_problem("problems/portal-frame/synthetic.yaml");
/// modalcal::Localization result =
///     modalcal::localize_model_error(problem, problem.truth_values(), modalcal::LocalizationOptions{});
/// if (result.ok) std::cout << modalcal::format_ranking(result, 10);
/// \endcode

#include <string>
#include <vector>

#include "modalcal/eigen.hpp"
#include "modalcal/export.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

struct MODALCAL_EXPORT LocalizationOptions {
  /// Number of elastic model modes in the expansion basis (the lowest ones; the rigid-body modes
  /// of a free-free model are added to them). It must include every paired mode, and without
  /// regularization it may not have more columns than there are sensor readings. 0 chooses
  /// automatically: every mode up to `max_frequency_ratio` times the highest measured frequency,
  /// and at least up to the highest paired mode, as long as the condition number at the sensors
  /// stays at most `max_condition` and there are no more columns than readings. Range: >= 0.
  int basis_modes = 0;
  /// Frequency cutoff of the automatic basis, relative to the highest measured frequency with a
  /// shape. Noise in a basis coefficient c_j enters the residual multiplied by
  /// \f$\lambda_j - \lambda_m\f$, so high basis modes amplify noise (the measured trade-off
  /// behind the default: docs/studies.md, "Where the model fails"). Range: >= 1.
  double max_frequency_ratio = 1.5;
  /// Largest \f$\sigma_{max}/\sigma_{min}\f$ of \f$P\Phi\f$ the automatic basis accepts: beyond
  /// it the coefficients fit the error itself (docs/design.md, "Localization"). Range: > 1.
  double max_condition = 10.0;
  /// Most elastic modes the automatic choice computes. Range: >= 1.
  int max_automatic_basis = 40;
  /// Tikhonov weight alpha of the expansion, relative to the largest singular value of
  /// \f$P\Phi\f$ (0: plain least squares, SEREP). Damps the coefficients of modes the sensors
  /// barely see and allows a basis with more modes than readings (what it did on the portal
  /// frame: docs/design.md, "Localization"). Range: [0, 1).
  double regularization = 0.0;
  /// Singular values of \f$P\Phi\f$ below this fraction of the largest are dropped from the
  /// least-squares solution (a basis mode the sensors cannot see is then left out rather than
  /// amplified). Range: (0, 1e-2].
  double rank_tolerance = 1e-10;
  /// Returns false and names the field, its value and the violated condition.
  bool IsValid(std::string* error) const;
};

/// One measured mode, expanded to all DOFs, and its residual force.
struct MODALCAL_EXPORT ExpandedMode {
  int measured = 0;           ///< 0-based index into Problem::measured
  int model_mode = 0;         ///< 0-based elastic model mode it is paired with
  double measured_hz = 0, model_hz = 0;
  double mac = 0;             ///< MAC of the measured and the paired model shape at the sensors
  double scale_factor = 0;    ///< modal scale factor a applied to the measured shape
  /// \f$\|P\phi - a\phi_s\| / \|a\phi_s\|\f$ before M-normalization: how much of the measured
  /// shape the basis cannot express (0 when it can).
  double sensor_misfit = 0;
  /// This mode's part of the total energy, \f$\sum_d r_{i,d}^2/(\lambda_{m,i}^2 M_{dd})\f$.
  double energy = 0;
  Vector shape;               ///< \f$\phi_i\f$ on the free DOFs, \f$\phi^T M \phi = 1\f$
  Vector residual;            ///< \f$r_i = (K - \lambda_{m,i} M)\phi_i\f$ on the free DOFs
};

/// A region of the model and its share of the error indicator.
struct MODALCAL_EXPORT RegionShare {
  std::string name;
  std::string kind;           ///< "block", "joint", "spring", "point mass" or "node set"
  double energy = 0;
  double share = 0;           ///< energy / Localization::total_energy, in [0, 1]
};

struct MODALCAL_EXPORT Localization {
  bool ok = false;
  std::string message;                 ///< why not ok (failed solve, pairing impossible)
  std::vector<ExpandedMode> modes;     ///< the measured modes that have shapes
  Vector node_energy;                  ///< per model node, summed over its free DOFs
  /// Per element (blocks in model order, elements in block order): its energy in the mesh view
  /// divided by total_energy.
  Vector element_indicator;
  std::vector<RegionShare> ranking;    ///< every region, largest share first
  /// Sum of node_energy. At rounding level (which rises where stiff parts make
  /// \f$K_{dd}/(\lambda M_{dd})\f$ large) it means no error was found and the ranking is noise.
  double total_energy = 0;
  int basis_size = 0;                  ///< columns of \f$\Phi\f$ (rigid-body modes included)
  /// \f$\sigma_{max}/\sigma_{min}\f$ of \f$P\Phi\f$: large means the sensors barely tell some basis
  /// modes apart and the expansion amplifies noise (regularize or use fewer basis modes).
  double basis_condition = 0;
  ModalResult modal;                   ///< the model's modes at the given parameters
  std::vector<std::string> warnings;
};

/// Expands the measured shapes of `problem` (paired with the model's modes at parameters `p`
/// as the calibration objective pairs them), computes their residual forces and ranks the
/// model's regions by their share of the residual energy (see the file comment for formulas).
/// Measured modes without a shape are skipped.
/// \throws std::invalid_argument for invalid options, a parameter vector of the wrong size, no
///         measured shape, or a basis with more modes than sensor readings without regularization.
MODALCAL_EXPORT Localization localize_model_error(const Problem& problem, const Vector& p,
                                                  const LocalizationOptions& options = {});

/// The ranking as a table (rank, region, kind, share %), its first `max_rows` rows, preceded by
/// one line per expanded mode (frequencies, MAC, sensor misfit, energy).
MODALCAL_EXPORT std::string format_ranking(const Localization& result, int max_rows = 15);

}  // namespace modalcal
