// Slot assignment tests: auction (Bertsekas 1992) against brute force over all
// 8! permutations; octant cost table (Ylitie et al. 2017, 3.2).
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <numeric>
#include <random>

#include "../result_util.h"
#include "cwbvh/compiler/auction.h"
#include "cwbvh/compiler/collapse.h"
#include "wide/wide_test_util.h"

namespace cwbvh::compiler {
namespace {

template <class T>
T brute_force_max(const std::array<std::array<T, 8>, 8>& b) {
    std::array<int, 8> perm;
    std::iota(perm.begin(), perm.end(), 0);
    T best = 0;
    bool first = true;
    do {
        T sum = 0;
        for (int i = 0; i < 8; ++i) sum += b[i][perm[i]];
        if (first || sum > best) best = sum;
        first = false;
    } while (std::next_permutation(perm.begin(), perm.end()));
    return best;
}

bool is_permutation(const std::array<int, 8>& a) {
    std::array<int, 8> s = a;
    std::sort(s.begin(), s.end());
    for (int i = 0; i < 8; ++i)
        if (s[i] != i) return false;
    return true;
}

TEST(Auction, IntegerTablesAreSolvedExactly) {
    std::mt19937 rng(1);
    for (int t = 0; t < 200; ++t) {
        std::array<std::array<int64_t, 8>, 8> b{};
        const int64_t range = t % 4 == 0 ? 3 : t % 4 == 1 ? 100 : t % 4 == 2 ? 1'000'000 : (int64_t(1) << 40);
        for (auto& row : b)
            for (auto& x : row) x = int64_t(rng() % uint64_t(2 * range + 1)) - range;
        std::array<int, 8> obj{};
        auction_assign(b, obj);
        ASSERT_TRUE(is_permutation(obj));
        int64_t sum = 0;
        for (int i = 0; i < 8; ++i) sum += b[i][obj[i]];
        EXPECT_EQ(sum, brute_force_max(b)) << "table " << t;
    }
}

TEST(Auction, RealCostTablesMatchBruteForce) {
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int t = 0; t < 200; ++t) {
        std::array<std::array<double, 8>, 8> cost{}, neg{};
        const int children = 1 + t % 8;  // partially filled nodes: empty rows cost 0
        for (int i = 0; i < children; ++i)
            for (int j = 0; j < 8; ++j) cost[i][j] = u(rng) * (t % 3 == 0 ? 1e-20 : 1e6);
        for (int i = 0; i < 8; ++i)
            for (int j = 0; j < 8; ++j) neg[i][j] = -cost[i][j];
        std::array<int, 8> slot{};
        const uint8_t empty = uint8_t(0xFF << children);  // rows >= children are empty slots
        assign_min_cost(cost, empty, slot);
        ASSERT_TRUE(is_permutation(slot));
        double sum = 0, max_abs = 0;
        for (int i = 0; i < 8; ++i) sum += cost[i][slot[i]];
        for (const auto& r : cost)
            for (double c : r) max_abs = std::max(max_abs, std::fabs(c));
        EXPECT_NEAR(sum, -brute_force_max(neg), 16 * max_abs * 0x1p-30) << t;
    }
}

/// Number of distinct assignments of the persons not in `empty` that reach
/// the maximum benefit (brute force over all 8! permutations; permutations
/// that differ only in where the `empty` persons go count once).
int count_optima(const std::array<std::array<int64_t, 8>, 8>& b, uint8_t empty) {
    const int64_t best = brute_force_max(b);
    std::array<int, 8> perm;
    std::iota(perm.begin(), perm.end(), 0);
    std::vector<std::array<int, 8>> seen;
    do {
        int64_t sum = 0;
        for (int i = 0; i < 8; ++i) sum += b[i][perm[i]];
        if (sum != best) continue;
        std::array<int, 8> counted = perm;
        for (int i = 0; i < 8; ++i)
            if (empty >> i & 1) counted[i] = -1;
        if (std::find(seen.begin(), seen.end(), counted) == seen.end()) seen.push_back(counted);
    } while (std::next_permutation(perm.begin(), perm.end()));
    return int(seen.size());
}

/// Tables of the kinds the slots meet: random ranges, few distinct values
/// (many ties), rows of zeros (empty slots, marked in `empty`, and children
/// whose row happens to be zero, not marked), and octant tables
/// cost(c, s) = dot(rel_c, d_s) with coordinates on a coarse grid (a child
/// centred on its parent in an axis is indifferent to that axis' slot bit).
std::array<std::array<int64_t, 8>, 8> slot_test_table(std::mt19937& rng, int t, uint8_t& empty) {
    std::array<std::array<int64_t, 8>, 8> b{};
    const int zero_rows = t % 3 == 0 ? 0 : int(rng() % 4);
    if (t % 2 == 0) {
        const int64_t range = t % 8 == 0 ? 2 : t % 8 == 2 ? 50 : t % 8 == 4 ? 1'000'000 : (int64_t(1) << 40);
        for (auto& row : b)
            for (auto& x : row) x = int64_t(rng() % uint64_t(2 * range + 1)) - range;
    } else {
        const int64_t grid = t % 4 == 1 ? 2 : 1000;
        for (auto& row : b) {
            int64_t rel[3];
            for (auto& r : rel) r = int64_t(rng() % uint64_t(2 * grid + 1)) - grid;
            for (int s = 0; s < 8; ++s) {
                int64_t c = 0;
                for (int a = 0; a < 3; ++a) c += (s >> (2 - a) & 1) ? -rel[a] : rel[a];
                row[s] = -c;
            }
        }
    }
    empty = 0;
    for (int z = 0; z < zero_rows; ++z) {
        const int i = int(rng() % 8);
        b[size_t(i)] = {};
        if (rng() % 4 != 0) empty = uint8_t(empty | 1u << i);  // mostly empty slots, some zero children
    }
    if (t % 5 == 0) {  // nodes of few children: up to 6 empty slots
        for (int i = 8 - int(rng() % 7); i < 8; ++i) {
            b[size_t(i)] = {};
            empty = uint8_t(empty | 1u << i);
        }
    }
    return b;
}

/// The auction as auction.h states it, written plainly: benefits x 9,
/// eps from (max - min) / 4 down by 8 to 1, each phase from all unassigned
/// with the prices kept, the lowest unassigned person bids for its best
/// object (ties: the lowest) by best - second best + eps. auction_assign
/// must give exactly its assignments (its ties decide the files' slots).
std::array<int, 8> textbook_auction(const std::array<std::array<int64_t, 8>, 8>& benefit) {
    int64_t b[8][8], lo = INT64_MAX, hi = INT64_MIN;
    for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) {
            b[i][j] = benefit[i][j] * 9;
            lo = std::min(lo, b[i][j]);
            hi = std::max(hi, b[i][j]);
        }
    int64_t price[8] = {};
    std::array<int, 8> object_of{};
    int64_t eps = std::max<int64_t>(1, (hi - lo) / 4);
    for (;;) {
        int owner[8];
        std::fill(owner, owner + 8, -1);
        object_of.fill(-1);
        for (;;) {
            int i = 0;
            while (i < 8 && object_of[i] >= 0) ++i;
            if (i == 8) break;
            int best = 0;
            for (int j = 1; j < 8; ++j)
                if (b[i][j] - price[j] > b[i][best] - price[best]) best = j;
            int64_t second = INT64_MIN;
            for (int j = 0; j < 8; ++j)
                if (j != best) second = std::max(second, b[i][j] - price[j]);
            price[best] += b[i][best] - price[best] - second + eps;
            if (owner[best] >= 0) object_of[owner[best]] = -1;
            owner[best] = i;
            object_of[i] = best;
        }
        if (eps == 1) break;
        eps = std::max<int64_t>(1, eps / 8);
    }
    return object_of;
}

TEST(Auction, IsTheTextbookAuction) {
    std::mt19937 rng(4);
    for (int t = 0; t < 600; ++t) {
        uint8_t empty = 0;
        const auto b = slot_test_table(rng, t, empty);
        std::array<int, 8> fast{};
        auction_assign(b, fast);
        ASSERT_EQ(fast, textbook_auction(b)) << "table " << t;
    }
}

TEST(Auction, SlotAssignIsTheAuctionsAssignment) {
    // slot_assign takes a shortest-augmenting-path solve when the counted
    // persons' optimum is unique and the auction otherwise: every counted
    // person must get the auction's object, whether the optimum is unique or
    // not; the empty slots take the other objects.
    std::mt19937 rng(3);
    int unique = 0, tied = 0, unique_with_empties = 0;
    for (int t = 0; t < 600; ++t) {
        uint8_t empty = 0;
        const auto b = slot_test_table(rng, t, empty);
        std::array<int, 8> fast{}, auction{};
        slot_assign(b, empty, fast);
        auction_assign(b, auction);
        ASSERT_TRUE(is_permutation(fast)) << "table " << t;
        for (int i = 0; i < 8; ++i)
            if (!(empty >> i & 1)) {
                ASSERT_EQ(fast[i], auction[i]) << "table " << t << " person " << i;
            }
        // The uniqueness test agrees with brute force, and a unique optimum
        // is the auction's assignment.
        std::array<int, 8> direct{};
        const bool is_unique = count_optima(b, empty) == 1;
        ASSERT_EQ(unique_max_benefit(b, empty, direct), is_unique) << "table " << t;
        if (is_unique) {
            ASSERT_TRUE(is_permutation(direct)) << "table " << t;
            for (int i = 0; i < 8; ++i)
                if (!(empty >> i & 1)) {
                    EXPECT_EQ(direct[i], auction[i]) << "table " << t;
                }
        }
        (is_unique ? unique : tied) += 1;
        unique_with_empties += is_unique && __builtin_popcount(empty) >= 2;
    }
    // Every path is exercised.
    EXPECT_GT(unique, 100);
    EXPECT_GT(tied, 100);
    EXPECT_GT(unique_with_empties, 30);
}

TEST(Auction, Deterministic) {
    std::array<std::array<int64_t, 8>, 8> b{};  // all ties
    std::array<int, 8> a{}, c{};
    auction_assign(b, a);
    auction_assign(b, c);
    EXPECT_EQ(a, c);
    EXPECT_TRUE(is_permutation(a));
}

TEST(Auction, CornerChildrenGoToTheirOctantSlots) {
    // Children at the 8 corners of the parent: the child at the low corner
    // (-,-,-) has the smallest dot with d_0 = (+1,+1,+1) and goes to slot 0;
    // the corner with x high is traversed first by rays with x < 0 (bit 2).
    WideBvh wide;
    BinaryBvh boxes;
    wide.binary = &boxes;
    wide.nodes.resize(1);
    WideNode& n = wide.nodes[0];
    Aabb parent;
    parent.lo = {0, 0, 0};
    parent.hi = {2, 2, 2};
    n.bnode = wide_test::add_box(boxes, parent);
    for (int c = 0; c < 8; ++c) {
        const int corner = 7 - c;  // fill in reverse to force a permutation
        WideChild& ch = n.slots[c];
        ch.kind = WideChild::kLeaf;
        ch.ref_count = 1;
        ch.first_ref = uint32_t(corner);  // remember which corner
        Aabb box;
        for (int a = 0; a < 3; ++a) {
            const float lo = (corner >> (2 - a) & 1) ? 1.0f : 0.0f;
            box.lo[a] = lo;
            box.hi[a] = lo + 1.0f;
        }
        ch.bnode = wide_test::add_box(boxes, box);
    }
    assign_slots(wide);
    for (int s = 0; s < 8; ++s) EXPECT_EQ(n.slots[s].first_ref, uint32_t(s));
}

TEST(Auction, AssignSlotsKeepsChildrenAndIsDeterministic) {
    const Scene scene = wide_test::random_scene(3000, 21);
    const BinaryBvh binary = wide_test::build_binary(scene);
    WideBvh wide;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, CollapseConfig{}, wide), error)) << error;
    WideBvh a = wide, b = wide;
    assign_slots(a);
    assign_slots(b);
    double before = 0, after = 0;
    for (size_t i = 0; i < wide.nodes.size(); ++i) {
        EXPECT_EQ(a.nodes[i].child_count(), wide.nodes[i].child_count());
        const auto ct = slot_cost_table(wide, wide.nodes[i]);
        for (int s = 0; s < 8; ++s) {
            EXPECT_EQ(a.nodes[i].slots[s].kind, b.nodes[i].slots[s].kind);
            EXPECT_EQ(a.nodes[i].slots[s].node, b.nodes[i].slots[s].node);
            EXPECT_EQ(a.nodes[i].slots[s].first_ref, b.nodes[i].slots[s].first_ref);
            before += ct[s][s];
        }
        const auto ca = slot_cost_table(a, a.nodes[i]);
        for (int s = 0; s < 8; ++s) after += ca[s][s];
    }
    EXPECT_LE(after, before);
}

}  // namespace
}  // namespace cwbvh::compiler
