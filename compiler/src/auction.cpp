// Child slot assignment (Ylitie, Karras, Laine 2017, section 3.2, "octant-based
// traversal order") solved with the forward auction algorithm of Bertsekas
// (1992, "Auction algorithms for network flow problems: a tutorial
// introduction", Comput. Optim. Appl. 1:7-66), with epsilon scaling.
#include "cwbvh/compiler/auction.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cwbvh/compiler/progress.h"

namespace cwbvh::compiler {

void auction_assign(const std::array<std::array<int64_t, 8>, 8>& benefit, std::array<int, 8>& object_of) {
    constexpr int n = 8;
    // Benefits scaled by n + 1 = 9: with integer benefits, eps-complementary
    // slackness at eps = 1 (i.e. 1/9 of a unit < 1/n) implies optimality
    // (Bertsekas 1992, proposition 1). Termination is exact (integers).
    int64_t b[n][n];
    int64_t lo = 0, hi = 0;
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            b[i][j] = benefit[i][j] * (n + 1);
            if (i == 0 && j == 0) lo = hi = b[i][j];
            lo = b[i][j] < lo ? b[i][j] : lo;
            hi = b[i][j] > hi ? b[i][j] : hi;
        }
    }
    int64_t price[n] = {};
    int owner[n];
    int64_t eps = (hi - lo) / 4;
    if (eps < 1) eps = 1;
    for (;;) {
        // One scaling phase: start unassigned, keep the prices.
        for (int j = 0; j < n; ++j) owner[j] = -1;
        for (int i = 0; i < n; ++i) object_of[i] = -1;
        uint32_t unassigned = (1u << n) - 1;
        while (unassigned != 0) {
            const int i = __builtin_ctz(unassigned);  // fixed bidding order: the lowest unassigned person
            // Best object (ties: the lowest) and the best value among the
            // others, without branches (which object wins a bid is data):
            // the maximum and its lowest index, then the maximum over the
            // other objects (a second object equal to the best gives v2 = v1,
            // as the one-pass loop did).
            int64_t v[n];
            for (int j = 0; j < n; ++j) v[j] = b[i][j] - price[j];
            int best = 0;
            int64_t v1 = v[0];
            for (int j = 1; j < n; ++j) {
                const bool gt = v[j] > v1;
                v1 = gt ? v[j] : v1;
                best = gt ? j : best;
            }
            int64_t v2 = INT64_MIN;
            for (int j = 0; j < n; ++j) {
                const int64_t x = j == best ? INT64_MIN : v[j];
                v2 = x > v2 ? x : v2;
            }
            price[best] += v1 - v2 + eps;  // bid increment >= eps > 0
            const int previous = owner[best];
            if (previous >= 0) {
                object_of[previous] = -1;
                unassigned |= 1u << previous;
            }
            owner[best] = i;
            object_of[i] = best;
            unassigned &= ~(1u << i);
        }
        if (eps == 1) break;
        // Scaling factor 8 (Bertsekas suggests 4-10): ~11 phases over the
        // 2^34 benefit range instead of ~17 with 4; the slots phase of the
        // dragon took 0.29 s with 4.
        eps = eps / 8 > 1 ? eps / 8 : 1;
    }
}

std::array<std::array<double, 8>, 8> slot_cost_table(const WideBvh& wide, const WideNode& node) {
    std::array<std::array<double, 8>, 8> cost{};
    double centre[3];
    const Aabb& box = wide.box(node);
    for (int a = 0; a < 3; ++a) centre[a] = 0.5 * (double(box.lo[a]) + double(box.hi[a]));
    for (int i = 0; i < kWidth; ++i) {
        const WideChild& ch = node.slots[i];
        if (ch.kind == WideChild::kEmpty) continue;
        double rel[3];
        const Aabb& child = wide.box(ch);
        for (int a = 0; a < 3; ++a) rel[a] = 0.5 * (double(child.lo[a]) + double(child.hi[a])) - centre[a];
        for (int s = 0; s < kWidth; ++s) {
            double c = 0.0;
            // d_s: -1 on axis a where bit (2 - a) of s is set (bit 2 = x, bit 1 = y, bit 0 = z).
            for (int a = 0; a < 3; ++a) c += (s >> (2 - a) & 1) ? -rel[a] : rel[a];
            cost[i][s] = c;
        }
    }
    return cost;
}

namespace {
/// std::llround without the library call: nearest integer, halves away from
/// zero (|x| <= 2^30 here). x - trunc(x) is exact for such x, so the result is
/// llround's bit for bit.
inline int64_t round_half_away(double x) {
    const double t = std::trunc(x);
    const double f = x - t;
    return int64_t(t) + (f >= 0.5 ? 1 : (f <= -0.5 ? -1 : 0));
}
}  // namespace

void assign_min_cost(const std::array<std::array<double, 8>, 8>& cost, std::array<int, 8>& slot_of) {
    double max_abs = 0.0;
    for (const auto& row : cost)
        for (double c : row) max_abs = std::fabs(c) > max_abs ? std::fabs(c) : max_abs;
    std::array<std::array<int64_t, 8>, 8> benefit{};
    if (max_abs > 0.0 && std::isfinite(max_abs)) {
        const double scale = std::ldexp(1.0, 30) / max_abs;
        for (int i = 0; i < 8; ++i)
            for (int j = 0; j < 8; ++j) benefit[i][j] = -round_half_away(cost[i][j] * scale);  // maximise -cost
    }
    auction_assign(benefit, slot_of);
}

void assign_slots(WideBvh& wide, Progress* progress) {
    // Nodes are independent: the result does not depend on the partitioning.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, wide.nodes.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            WideNode& node = wide.nodes[k];
            std::array<int, 8> slot_of{};
            assign_min_cost(slot_cost_table(wide, node), slot_of);
            std::array<WideChild, 8> slots;
            for (int i = 0; i < kWidth; ++i) slots[slot_of[i]] = node.slots[i];
            node.slots = slots;
        }
        progress_add(progress, r.size());  // one relaxed atomic per chunk (>= 512 nodes)
    });
}

}  // namespace cwbvh::compiler
