// Test nodes onto model nodes, by id or by the nearest model node, with a report of the
// points that found none.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

#include "support/text_util.hpp"
#include "modalcal/test_data.hpp"

namespace modalcal {

namespace {

std::string number_text(double v) { return detail::number_text(v, 4); }

/// The nearest model node to x (ties to the lower index) and its distance.
std::pair<int, double> nearest(const Model& model, const Vec3& x) {
  std::pair<int, double> best{-1, std::numeric_limits<double>::infinity()};
  for (int v = 0; v < model.num_nodes(); ++v) {
    const double d = (model.coordinates[v] - x).norm();
    if (d < best.second) best = {v, d};
  }
  return best;
}

}  // namespace

bool NodeMapOptions::IsValid(std::string* error) const {
  if (tolerance && !(std::isfinite(*tolerance) && *tolerance > 0)) {
    if (error) *error = "NodeMapOptions::tolerance = " + number_text(*tolerance) + ": must be a finite number > 0";
    return false;
  }
  return true;
}

int NodeMapping::num_matched() const {
  int n = 0;
  for (const NodeMatch& m : matches) n += m.model_node >= 0;
  return n;
}

std::string NodeMapping::report() const {
  std::ostringstream s;
  s << num_matched() << " of " << matches.size() << " test nodes matched a model node "
    << (by == NodeMatchBy::Id ? "by id" : "by coordinates within " + number_text(tolerance));
  double largest = 0;
  for (const NodeMatch& m : matches)
    if (m.model_node >= 0 && std::isfinite(m.distance)) largest = std::max(largest, m.distance);
  if (by == NodeMatchBy::Coordinates && num_matched() > 0) s << " (largest distance " << number_text(largest) << ")";
  s << "\n";
  for (const NodeMatch& m : matches)
    if (m.model_node < 0) s << "  unmatched test node " << m.test_node << ": " << m.reason << "\n";
  return s.str();
}

NodeMapping map_test_nodes(const TestData& data, const Model& model, const NodeMapOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  NodeMapping mapping;
  mapping.by = options.by;
  mapping.tolerance = options.tolerance.value_or(1e-6 * bounding_box_diagonal(model));
  std::unordered_map<long, const TestNode*> geometry;
  for (const TestNode& n : data.nodes) geometry[n.id] = &n;
  std::unordered_map<long, int> model_index;
  for (int v = 0; v < model.num_nodes(); ++v) model_index.emplace(model.node_ids[v], v);

  for (long id : data.node_ids()) {
    NodeMatch match;
    match.test_node = id;
    const auto g = geometry.find(id);
    const bool has_coordinates = g != geometry.end();
    match.distance = std::numeric_limits<double>::quiet_NaN();
    if (options.by == NodeMatchBy::Id) {
      const auto it = model_index.find(id);
      if (it == model_index.end()) {
        match.reason = "no model node has id " + std::to_string(id);
      } else {
        match.model_node = it->second;
        if (has_coordinates) match.distance = (model.coordinates[it->second] - g->second->coordinates).norm();
      }
    } else if (!has_coordinates) {
      match.reason = "the file gives no coordinates for it (no dataset 15 or 2411 entry)";
    } else {
      const auto [v, d] = nearest(model, g->second->coordinates);
      match.distance = d;
      if (v >= 0 && d <= mapping.tolerance)
        match.model_node = v;
      else if (v >= 0)
        match.reason = "the nearest model node, " + std::to_string(model.node_ids[v]) + ", is " + number_text(d) +
                       " away (tolerance " + number_text(mapping.tolerance) + ")";
      else
        match.reason = "the model has no nodes";
    }
    mapping.matches.push_back(match);
  }

  // A model node claimed twice goes to the nearer test node (the first on a tie).
  std::unordered_map<int, size_t> owner;
  for (size_t k = 0; k < mapping.matches.size(); ++k) {
    NodeMatch& m = mapping.matches[k];
    if (m.model_node < 0) continue;
    const auto [it, inserted] = owner.try_emplace(m.model_node, k);
    if (inserted) continue;
    NodeMatch& other = mapping.matches[it->second];
    NodeMatch& loser = m.distance < other.distance ? other : m;
    const NodeMatch& winner = &loser == &m ? other : m;
    loser.reason = "model node " + std::to_string(model.node_ids[loser.model_node]) + " is taken by test node " +
                   std::to_string(winner.test_node) + ", which is nearer (" + number_text(winner.distance) +
                   " against " + number_text(loser.distance) + ")";
    loser.model_node = -1;
    it->second = &loser == &m ? it->second : k;
  }
  return mapping;
}

}  // namespace modalcal
