// The screen as a map of where the model fails: each spatial and region candidate's predicted
// chi-square reduction placed on the node or elements it acts on (effects.hpp, ScreenMap).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "modalcal/effects.hpp"

namespace modalcal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// max(a, b) where NaN means "nothing yet".
double larger(double a, double b) { return std::isnan(a) ? b : std::max(a, b); }

/// -log10 of the Šidák-corrected p-value of the best of `count` chi-square(1) statistics.
double score(double best, int count) {
  if (count == 0 || !(best > 0)) return 0;
  const double p1 = chi_square_upper_tail(best, 1);
  // 1 - (1 - p1)^k, accurate for small p1.
  const double p = -std::expm1(count * std::log1p(-std::min(p1, 1.0 - 1e-16)));
  return -std::log10(std::max(p, std::numeric_limits<double>::min()));
}

/// The node a single-node addition acts on, or -1.
int single_node(const Model& model, const ModelChange& change) {
  if ((change.kind != ModelChange::Kind::AddPointMass && change.kind != ModelChange::Kind::AddSpring) ||
      change.places.size() != 1 || change.places[0].kind != NodePlace::Kind::NodeId)
    return -1;
  return model.find_node(change.places[0].node_id);
}

}  // namespace

ScreenMap screen_map(const Model& model, const EffectRanking& ranking) {
  const int nn = model.num_nodes(), ne = model.num_elements();
  std::vector<int> first_element{0};  // of each block, in the model-wide numbering
  for (const ElementBlock& b : model.blocks) first_element.push_back(first_element.back() + b.num_elements());
  ScreenMap map;
  map.node_mass = Vector::Constant(nn, kNaN);
  map.node_spring = Matrix::Constant(nn, 3, kNaN);
  map.element_stiffness = map.element_mass = Vector::Constant(ne, kNaN);
  std::vector<int> node_count(nn, 0), element_count(ne, 0);
  Vector node_best = Vector::Constant(nn, kNaN), element_best = Vector::Constant(ne, kNaN);
  for (const RankedEffect& r : ranking.effects) {
    const ModelChange& change = r.candidate.change;
    const double x = r.predicted_reduction;
    if (const int v = single_node(model, change); v >= 0) {
      if (change.kind == ModelChange::Kind::AddPointMass && change.property == "mass") {
        map.node_mass[v] = larger(map.node_mass[v], x);
      } else if (const int c = component_from_name(change.property.substr(1)); change.kind == ModelChange::Kind::AddSpring && c >= 0 && c < 3) {
        map.node_spring(v, c) = larger(map.node_spring(v, c), x);
      } else {
        continue;
      }
      ++node_count[v];
      node_best[v] = larger(node_best[v], x);
      ++map.node_candidates;
    } else if (change.kind == ModelChange::Kind::AddRegion) {
      const auto [b, elements] = region_elements(model, change);
      const bool stiffness = change.property == "stiffness_scale";
      const std::string entity = r.candidate.name.substr(0, r.candidate.name.rfind('.'));
      map.places.push_back({"region " + entity + (stiffness ? " (stiffness)" : " (mass)"),
                            r.candidate.location.value_or(Vec3::Zero()), score(x, 1)});
      Vector& field = change.property == "stiffness_scale" ? map.element_stiffness : map.element_mass;
      for (int e : elements) {
        const int k = first_element[b] + e;
        field[k] = larger(field[k], x);
        ++element_count[k];
        element_best[k] = larger(element_best[k], x);
      }
      ++map.region_candidates;
    }
  }
  map.node_score = Vector::Zero(nn);
  for (int v = 0; v < nn; ++v) {
    map.node_score[v] = score(node_best[v], node_count[v]);
    if (node_count[v] == 0) continue;
    // Name the node's best candidate.
    std::string kind = "added mass";
    for (int c = 0; c < 3; ++c)
      if (map.node_spring(v, c) == node_best[v]) kind = std::string("spring along ") + "xyz"[c];
    if (map.node_mass[v] == node_best[v]) kind = "added mass";
    map.places.push_back({"node " + std::to_string(model.node_ids[v]) + " (" + kind + ")", model.coordinates[v],
                          map.node_score[v]});
  }
  std::stable_sort(map.places.begin(), map.places.end(),
                   [](const ScreenMap::Place& a, const ScreenMap::Place& b) { return a.score > b.score; });
  map.element_score = Vector::Zero(ne);
  for (int k = 0; k < ne; ++k) map.element_score[k] = score(element_best[k], element_count[k]);
  return map;
}

std::string format_screen_map(const ScreenMap& map, int rows) {
  std::string text;
  char line[300];
  const int n = std::min<int>(rows, static_cast<int>(map.places.size()));
  for (int k = 0; k < n; ++k) {
    const ScreenMap::Place& p = map.places[k];
    std::snprintf(line, sizeof line, "  %6.2f  %-48s at [%.4g, %.4g, %.4g]\n", p.score, p.what.c_str(), p.location[0],
                  p.location[1], p.location[2]);
    text += line;
  }
  if (n == 0) text = "  no spatial or region candidate was screened\n";
  return text;
}

}  // namespace modalcal
