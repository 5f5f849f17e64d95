#pragma once
// Internal: whether two effect candidates make one kind of change.

#include "modalcal/effects.hpp"

namespace modalcal::detail {

/// The same change to the same property: candidates of one kind, which EffectCandidate::neighbour_of
/// then tells apart by place.
inline bool same_change(const EffectCandidate& a, const EffectCandidate& b) {
  return a.change.kind == b.change.kind && a.change.property == b.change.property;
}

}  // namespace modalcal::detail
