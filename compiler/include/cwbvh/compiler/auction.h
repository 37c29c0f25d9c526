// Octant-aware child slot assignment (Ylitie et al. 2017, section 3.2) solved
// with the auction algorithm (Bertsekas 1992, "Auction algorithms for network
// flow problems: a tutorial introduction").
#pragma once

#include <array>
#include <cstdint>

#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

struct Progress;

/// Permutes the children of every wide node so that slot s holds the child
/// for which a ray of octant s (bit 2 = x<0, bit 1 = y<0, bit 0 = z<0) is
/// most likely to be traversed first: minimises sum_c cost(c, slot(c)) with
///   cost(c, s) = dot(centre(c) - centre(parent), d_s),
///   d_s[a] = -1 if bit (2-a) of s is set, else +1.
/// Deterministic. `progress` (optional) advances by one per wide node, by
/// exactly wide.nodes.size() in all; it never influences the slots.
void assign_slots(WideBvh& wide, Progress* progress = nullptr);

/// Exact maximum-benefit assignment of 8 persons to 8 objects for integer
/// benefits |b| <= 2^40: forward auction, Gauss–Seidel bidding (lowest
/// unassigned person first, ties to the lowest object), epsilon scaling down
/// to eps = 1 on benefits scaled by 9 (> n = 8), which makes the result
/// optimal (Bertsekas 1992, prop. 1). object_of[i] = object of person i.
void auction_assign(const std::array<std::array<int64_t, 8>, 8>& benefit, std::array<int, 8>& object_of);

/// Maximum-benefit assignment of the persons not in `empty` (bit i: person
/// i does not count) to distinct objects, by shortest augmenting paths with
/// potentials (Kuhn-Munkres in the form of Jonker and Volgenant 1987), exact
/// in integers, for |b| <= 2^40. Returns true when that assignment is the
/// ONLY maximum-benefit one, with it in object_of and the persons in `empty`
/// on the objects left over (lowest first); false when another one exists
/// (object_of is then unspecified). Uniqueness is read off the final
/// potentials: every optimal assignment uses only edges of reduced cost 0;
/// another one exists iff those edges hold an alternating cycle, or an
/// alternating path onto an unassigned object that releases an object of
/// potential 0.
bool unique_max_benefit(const std::array<std::array<int64_t, 8>, 8>& benefit, uint8_t empty,
                        std::array<int, 8>& object_of);

/// auction_assign's assignment for every person not in `empty`, faster; the
/// rows of the persons in `empty` must be zero (empty child slots: where they
/// go changes nothing), and they take the other objects. When the others'
/// maximum-benefit assignment is unique (unique_max_benefit), it is the one
/// the auction ends with: the auction's assignment is optimal, and zero rows
/// add nothing wherever they go. Otherwise auction_assign itself.
void slot_assign(const std::array<std::array<int64_t, 8>, 8>& benefit, uint8_t empty, std::array<int, 8>& object_of);

/// The slot cost table of one wide node of `wide`: cost[i][s] for child slot i
/// (empty slots: 0 for every s).
std::array<std::array<double, 8>, 8> slot_cost_table(const WideBvh& wide, const WideNode& node);

/// Minimum-cost assignment for a real cost table: costs are mapped to integers
/// (scaled so that max |cost| -> 2^30, rounded to nearest) and solved exactly
/// with slot_assign (the auction's assignment; `empty`: the empty slots,
/// whose rows are zero). The result is optimal up to 8 rounding steps of
/// max|cost| * 2^-30.
void assign_min_cost(const std::array<std::array<double, 8>, 8>& cost, uint8_t empty, std::array<int, 8>& slot_of);

}  // namespace cwbvh::compiler
