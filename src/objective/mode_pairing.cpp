#include "objective/mode_pairing.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "modalcal/objective.hpp"
#include "objective/assignment.hpp"

namespace modalcal::detail {

namespace {

class Pairing {
 public:
  Pairing(const Problem& problem, const ModalResult& modal, ModePairing* out)
      : problem_(problem), modal_(modal), out_(*out) {}

  bool by_rules(std::vector<bool>* taken, const std::function<std::vector<ModeDescription>()>& describe);
  void by_mac(const std::vector<bool>& taken);
  void in_frequency_order();

 private:
  int num_measured() const { return static_cast<int>(problem_.measured.size()); }
  int num_model() const { return static_cast<int>(modal_.eigenvalues.size()); }
  const Vector& lambda() const { return modal_.eigenvalues; }

  const Problem& problem_;
  const ModalResult& modal_;
  ModePairing& out_;
};

bool Pairing::by_rules(std::vector<bool>* taken, const std::function<std::vector<ModeDescription>()>& describe) {
  std::vector<ModeDescription> described;
  for (int i = 0; i < num_measured(); ++i) {
    const PairingRule& rule = problem_.measured[i].pairing;
    int k = -1;
    if (rule.kind == PairingRule::Kind::ModelIndex) {
      k = rule.model_index - 1;
    } else if (rule.kind == PairingRule::Kind::Family) {
      if (described.empty()) described = describe();
      k = find_family_mode(described, rule.family, rule.family_index) - 1;
      if (k < 0) {
        out_.message = describe_measured(problem_.measured[i], i) + ": the lowest " + std::to_string(num_model()) +
                       " model modes have fewer than " + std::to_string(rule.family_index) + " '" + rule.family +
                       "' modes; raise options.num_modes or check the model";
        return false;
      }
    } else {
      continue;
    }
    if (k >= num_model() || (*taken)[k]) {
      out_.message = describe_measured(problem_.measured[i], i) + ": model mode " + std::to_string(k + 1) +
                     ((*taken)[k] ? " is already paired with another measured mode" : " was not computed");
      return false;
    }
    out_.model_of[i] = k;
    (*taken)[k] = true;
  }
  return true;
}

// The assignment with the largest total MAC among the modes left free.
void Pairing::by_mac(const std::vector<bool>& taken) {
  std::vector<int>& rows = out_.mac_rows;
  std::vector<int> free_columns;
  for (int i = 0; i < num_measured(); ++i)
    if (out_.model_of[i] < 0 && problem_.measured[i].pairing.kind == PairingRule::Kind::Mac) rows.push_back(i);
  for (int k = 0; k < num_model(); ++k)
    if (!taken[k]) free_columns.push_back(k);
  if (rows.empty() || rows.size() > free_columns.size()) return;
  // Sparse sensors can see two modes alike (on a test model, MAC 0.99999 with modes at 1.7 and
  // 3.2 Hz): rounding must not decide between them, or J jumps wherever the tie flips and a line
  // search stalls there. Each score loses kMacTieWeight |ln(lambda_k / lambda_m)|, so a tie
  // goes to the nearer eigenvalue while a MAC difference of more than ~1e-3 still decides.
  constexpr double kMacTieWeight = 1e-3;
  Matrix score(rows.size(), free_columns.size());
  for (size_t a = 0; a < rows.size(); ++a) {
    const double target = eigenvalue_of_hz(problem_.measured[rows[a]].frequency_hz);
    for (size_t b = 0; b < free_columns.size(); ++b) {
      const double ratio = std::abs(lambda()[free_columns[b]]) / target;
      score(a, b) = out_.mac_table(rows[a], free_columns[b]) - kMacTieWeight * std::abs(std::log(std::max(ratio, 1e-300)));
    }
  }
  const std::vector<int> assigned = maximize_assignment(score);
  for (size_t a = 0; a < rows.size(); ++a) out_.model_of[rows[a]] = free_columns[assigned[a]];
}

// The shapes chose the MAC-paired set; frequency order assigns it (ObjectiveOptions::
// eigenvalues_in_frequency_order).
void Pairing::in_frequency_order() {
  if (out_.mac_rows.size() < 2) return;
  std::vector<int> set;
  for (int i : out_.mac_rows) set.push_back(out_.model_of[i]);
  std::sort(set.begin(), set.end(), [&](int a, int b) { return lambda()[a] < lambda()[b]; });
  std::vector<int> rows = out_.mac_rows;
  std::stable_sort(rows.begin(), rows.end(), [&](int a, int b) {
    return problem_.measured[a].frequency_hz < problem_.measured[b].frequency_hz;
  });
  for (size_t a = 0; a < rows.size(); ++a) out_.model_of[rows[a]] = set[a];
}

}  // namespace

ModePairing pair_modes(const Problem& problem, const ModalResult& modal, const SparseMatrix& sensors,
                       bool frequency_order, const std::function<std::vector<ModeDescription>()>& describe) {
  const int num_measured = static_cast<int>(problem.measured.size());
  const int num_model = static_cast<int>(modal.eigenvalues.size());
  ModePairing out;
  out.model_of.assign(num_measured, -1);
  Pairing pairing(problem, modal, &out);
  std::vector<bool> taken(num_model, false);
  if (!pairing.by_rules(&taken, describe)) return out;
  out.mac_table = Matrix::Constant(num_measured, num_model, -1.0);
  for (int i = 0; i < num_measured; ++i) {
    const MeasuredMode& m = problem.measured[i];
    if (m.shape.size() == 0) continue;
    for (int k = 0; k < num_model; ++k) out.mac_table(i, k) = mac(sensors * modal.modes.col(k), m.shape);
  }
  pairing.by_mac(taken);
  for (int i = 0; i < num_measured; ++i)
    if (out.model_of[i] < 0) {
      out.message = describe_measured(problem.measured[i], i) + ": no model mode left to pair with";
      return out;
    }
  if (frequency_order) pairing.in_frequency_order();
  return out;
}

std::vector<PairedMode> paired_modes(const Problem& problem, const ModalResult& modal, const std::vector<int>& model_of,
                                     const Matrix& mac_table) {
  std::vector<PairedMode> pairs;
  for (size_t i = 0; i < problem.measured.size(); ++i) {
    const MeasuredMode& m = problem.measured[i];
    const int k = model_of[i];
    const double lambda = modal.eigenvalues[k], target = eigenvalue_of_hz(m.frequency_hz);
    PairedMode pair;
    pair.measured = static_cast<int>(i);
    pair.model = k;
    pair.measured_hz = m.frequency_hz;
    pair.model_hz = frequency_hz(lambda);
    pair.relative_error = (lambda - target) / target;
    pair.mac = m.shape.size() ? mac_table(static_cast<Eigen::Index>(i), k) : -1;
    pairs.push_back(pair);
  }
  return pairs;
}

std::vector<std::string> close_eigenvalue_warnings(const Problem& problem, const ModalResult& modal,
                                                   const std::vector<int>& model_of, double tolerance) {
  const Vector& lambda = modal.eigenvalues;
  std::vector<std::string> warnings;
  for (size_t i = 0; i < problem.measured.size(); ++i) {
    const int k = model_of[i];
    for (int n : {k - 1, k + 1})
      if (n >= 0 && n < lambda.size() && std::abs(lambda[n] - lambda[k]) < tolerance * lambda[k])
        warnings.push_back(describe_measured(problem.measured[i], static_cast<int>(i)) + " is paired with model mode " +
                           std::to_string(k + 1) + ", whose eigenvalue nearly repeats that of mode " +
                           std::to_string(n + 1));
  }
  return warnings;
}

int modes_to_compute(const Problem& problem, int extra_modes, int num_dofs) {
  int highest = problem.options.num_modes;
  for (const MeasuredMode& m : problem.measured)
    if (m.pairing.kind == PairingRule::Kind::ModelIndex) highest = std::max(highest, m.pairing.model_index);
  return std::max(highest, std::min(highest + extra_modes, num_dofs - problem.expected_rigid_modes()));
}

std::string describe_measured(const MeasuredMode& m, int index) {
  std::ostringstream s;
  s << "measured mode " << index + 1;
  if (!m.label.empty()) s << " ('" << m.label << "')";
  return s.str();
}

}  // namespace modalcal::detail
