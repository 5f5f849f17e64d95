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
  if (p1 < 1e-15) {
    // 1 - (1 - p1)^k = k p1 to rounding; past the doubles' range, log p1 from the tail's
    // asymptote erfc(z) ~ exp(-z^2) / (z sqrt(pi)), z^2 = best / 2.
    const double log10_p1 = p1 > 1e-300 ? std::log10(p1) : (-0.5 * best - 0.5 * std::log(M_PI * best / 2)) / std::log(10.0);
    return -(std::log10(static_cast<double>(count)) + log10_p1);
  }
  return -std::log10(-std::expm1(count * std::log1p(-p1)));
}

/// The node a single-node addition acts on, or -1.
int single_node(const Model& model, const ModelChange& change) {
  if ((change.kind != ModelChange::Kind::AddPointMass && change.kind != ModelChange::Kind::AddSpring) ||
      change.places.size() != 1 || change.places[0].kind != NodePlace::Kind::NodeId)
    return -1;
  return model.find_node(change.places[0].node_id);
}

/// The map under construction: per-place bests and counts, turned into scores at the end.
class MapBuilder {
 public:
  /// `unit`: what a unit of chi-square is in the predictions' units (1 with a stated noise).
  MapBuilder(const Model& model, double unit) : model_(model), unit_(unit) {
    const int nn = model.num_nodes(), ne = model.num_elements();
    for (const ElementBlock& b : model.blocks) first_element_.push_back(first_element_.back() + b.num_elements());
    map_.node_mass = Vector::Constant(nn, kNaN);
    map_.node_spring = Matrix::Constant(nn, 3, kNaN);
    map_.element_stiffness = map_.element_mass = Vector::Constant(ne, kNaN);
    node_best_ = Vector::Constant(nn, kNaN);
    element_best_ = Vector::Constant(ne, kNaN);
    node_count_.assign(nn, 0);
    element_count_.assign(ne, 0);
  }

  void add(const RankedEffect& r) {
    const EffectCandidate& c = r.candidate;
    const ModelChange& change = c.change;
    const double x = r.predicted_reduction;
    const bool scale = change.property == "stiffness_scale" || change.property == "mass_scale";
    if (const int v = single_node(model_, change); v >= 0) {
      const int axis = component_from_name(change.property.substr(1));
      if (change.kind == ModelChange::Kind::AddPointMass && change.property == "mass")
        map_.node_mass[v] = larger(map_.node_mass[v], x);
      else if (change.kind == ModelChange::Kind::AddSpring && axis >= 0 && axis < 3)
        map_.node_spring(v, axis) = larger(map_.node_spring(v, axis), x);
      at_node(v, x);
      ++map_.node_candidates;
    } else if (change.kind == ModelChange::Kind::AddRegion) {
      const auto [b, elements] = region_elements(model_, change);
      on_elements(b, elements, change.property == "stiffness_scale", x);
      place("region " + c.name, c.location.value_or(Vec3::Zero()), x);
      ++map_.region_candidates;
    } else if (const int b = block_index(change); b >= 0 && scale) {
      std::vector<int> all(model_.blocks[b].num_elements());
      for (size_t e = 0; e < all.size(); ++e) all[e] = static_cast<int>(e);
      on_elements(b, all, change.property == "stiffness_scale", x);
      place("block " + c.name, block_centroid(b), x);
    } else if (c.location) {  // a joint's or node set's component, a support: at the nearest node
      at_node(nearest_node(*c.location), x);
      place(c.name, *c.location, x);
    }
  }

  ScreenMap finish() {
    const int nn = model_.num_nodes(), ne = model_.num_elements();
    map_.node_score = Vector::Zero(nn);
    for (int v = 0; v < nn; ++v) {
      map_.node_score[v] = score(node_best_[v] / unit_, node_count_[v]);
      if (std::isnan(map_.node_mass[v]) && map_.node_spring.row(v).array().isNaN().all()) continue;
      std::string kind = "added mass";  // name the node's best addition
      for (int c = 0; c < 3; ++c)
        if (map_.node_spring(v, c) == node_best_[v]) kind = std::string("spring along ") + "xyz"[c];
      if (map_.node_mass[v] == node_best_[v]) kind = "added mass";
      map_.places.push_back({"node " + std::to_string(model_.node_ids[v]) + " (" + kind + ")", model_.coordinates[v],
                             map_.node_score[v]});
    }
    map_.element_score = Vector::Zero(ne);
    for (int k = 0; k < ne; ++k) map_.element_score[k] = score(element_best_[k] / unit_, element_count_[k]);
    std::stable_sort(map_.places.begin(), map_.places.end(),
                     [](const ScreenMap::Place& a, const ScreenMap::Place& b) { return a.score > b.score; });
    return std::move(map_);
  }

 private:
  void at_node(int v, double x) {
    ++node_count_[v];
    node_best_[v] = larger(node_best_[v], x);
  }
  void on_elements(int b, const std::vector<int>& elements, bool stiffness, double x) {
    Vector& field = stiffness ? map_.element_stiffness : map_.element_mass;
    for (int e : elements) {
      const int k = first_element_[b] + e;
      field[k] = larger(field[k], x);
      ++element_count_[k];
      element_best_[k] = larger(element_best_[k], x);
    }
  }
  void place(const std::string& what, const Vec3& where, double x) {
    map_.places.push_back({what, where, score(x / unit_, 1)});
  }
  int block_index(const ModelChange& change) const {
    if (change.kind != ModelChange::Kind::SetProperty) return -1;
    for (size_t b = 0; b < model_.blocks.size(); ++b)
      if (model_.blocks[b].name == change.entity) return static_cast<int>(b);
    return -1;
  }
  Vec3 block_centroid(int b) const {
    Vec3 sum = Vec3::Zero();
    for (int v : model_.blocks[b].connectivity) sum += model_.coordinates[v];
    return sum / std::max<double>(1, model_.blocks[b].connectivity.size());
  }
  int nearest_node(const Vec3& x) const {
    int best = 0;
    for (int v = 1; v < model_.num_nodes(); ++v)
      if ((model_.coordinates[v] - x).squaredNorm() < (model_.coordinates[best] - x).squaredNorm()) best = v;
    return best;
  }

  const Model& model_;
  const double unit_;
  std::vector<int> first_element_{0};  // of each block, in the model-wide numbering
  ScreenMap map_;
  Vector node_best_, element_best_;
  std::vector<int> node_count_, element_count_;
};

}  // namespace

ScreenMap screen_map(const Model& model, const EffectRanking& ranking) {
  // Without a stated noise the predictions are in 2J: scaled by the noise the residual itself
  // estimates (never below the data's resolution), as the F test does.
  const double unit = ranking.noise_known ? 1.0
                                          : std::max(ranking.chi2_before / std::max(1, ranking.dof_before),
                                                     ranking.resolution_variance);
  MapBuilder builder(model, unit > 0 ? unit : 1.0);
  for (const RankedEffect& r : ranking.effects) builder.add(r);
  return builder.finish();
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
