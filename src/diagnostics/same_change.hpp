#pragma once
// Internal: whether two effect candidates make one kind of change, or state one hypothesis.

#include <algorithm>

#include "modalcal/effects.hpp"

namespace modalcal::detail {

/// The same change to the same property: candidates of one kind, which EffectCandidate::neighbour_of
/// then tells apart by place.
inline bool same_change(const EffectCandidate& a, const EffectCandidate& b) {
  return a.change.kind == b.change.kind && a.change.property == b.change.property;
}

/// Mass added (or missing) at a place: a point mass or a block region's mass scale, two
/// parametrizations of one physical hypothesis (one kind in the ranking's prior).
inline bool local_mass(const EffectCandidate& c) {
  return (c.change.kind == ModelChange::Kind::AddPointMass && c.change.property == "mass") ||
         (c.change.kind == ModelChange::Kind::AddRegion && c.change.property == "mass_scale");
}

/// One hypothesis at one place: neighbours of one kind (EffectCandidate::neighbour_of), or mass
/// at a place in either parametrization within the larger of the two neighbourhoods.
inline bool one_hypothesis(const EffectCandidate& a, const EffectCandidate& b) {
  if (a.neighbour_of(b)) return true;
  return local_mass(a) && local_mass(b) && a.location && b.location &&
         (*a.location - *b.location).norm() < std::max(a.neighbourhood, b.neighbourhood);
}

}  // namespace modalcal::detail
