// Child slot assignment (Ylitie, Karras, Laine 2017, section 3.2, "octant-based
// traversal order") solved with the forward auction algorithm of Bertsekas
// (1992, "Auction algorithms for network flow problems: a tutorial
// introduction", Comput. Optim. Appl. 1:7-66), with epsilon scaling. Where
// the children's optimal assignment is unique, slot_assign takes it from an
// exact shortest-augmenting-path solve instead (Jonker and Volgenant 1987,
// "A shortest augmenting path algorithm for dense and sparse linear
// assignment problems", Computing 38): the same slots, since the auction's
// result is optimal. Where optima tie, the auction's path decides.
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
        // One scaling phase: start unassigned, keep the prices. owner[j] = n
        // is no one: a ninth person whose bit is masked off, so that a bid
        // displaces without a branch (who owned the object is data).
        // object_of is read off the owners after the last phase.
        for (int j = 0; j < n; ++j) owner[j] = n;
        constexpr uint32_t kAll = (1u << n) - 1;
        uint32_t unassigned = kAll;
        while (unassigned != 0) {
            const int i = __builtin_ctz(unassigned);  // fixed bidding order: the lowest unassigned person
            // Best object (ties: the lowest), its value v1 and the best value
            // among the other objects v2 (a second object equal to the best
            // gives v2 = v1), in one pass without branches (which object wins
            // a bid is data): v2 is the running second largest value.
            const int64_t* bi = b[i];
            int best = 0;
            int64_t v1 = bi[0] - price[0];
            int64_t v2 = INT64_MIN;
            for (int j = 1; j < n; ++j) {
                const int64_t x = bi[j] - price[j];
                const int64_t lower = x < v1 ? x : v1;
                v2 = lower > v2 ? lower : v2;
                const bool gt = x > v1;
                v1 = gt ? x : v1;
                best = gt ? j : best;
            }
            price[best] += v1 - v2 + eps;  // bid increment >= eps > 0
            const int previous = owner[best];
            owner[best] = i;
            unassigned = (unassigned & ~(1u << i)) | ((1u << previous) & kAll);
        }
        if (eps == 1) {
            for (int j = 0; j < n; ++j) object_of[owner[j]] = j;  // every object is owned: a permutation
            break;
        }
        // Scaling factor 8 (Bertsekas suggests 4-10): ~11 phases over the
        // 2^34 benefit range instead of ~17 with 4; the slots phase of the
        // dragon took 0.29 s with 4.
        eps = eps / 8 > 1 ? eps / 8 : 1;
    }
}

bool unique_max_benefit(const std::array<std::array<int64_t, 8>, 8>& benefit, uint8_t empty,
                        std::array<int, 8>& object_of) {
    constexpr int n = 8;
    constexpr int64_t kInf = INT64_MAX / 4;  // |benefit| <= 2^40: potentials and path lengths stay below 2^45
    int row[n];  // the persons that count, k of them
    int k = 0;
    for (int i = 0; i < n; ++i)
        if (!(empty >> i & 1)) row[k++] = i;
    // Rows 1..k (person row[r - 1]) and objects 1..n; object 0 is the
    // search's start. Every object that a search visits is assigned from then
    // on, and only visited objects' potentials change: an unassigned object
    // keeps v = 0, an assigned one v <= 0.
    int64_t u[n + 1] = {}, v[n + 1] = {};
    int person_of[n + 1] = {}, way[n + 1] = {};
    for (int r = 1; r <= k; ++r) {
        person_of[0] = r;
        int j0 = 0;
        int64_t minv[n + 1];
        bool used[n + 1] = {};
        for (int j = 0; j <= n; ++j) minv[j] = kInf;
        do {
            used[j0] = true;
            const int r0 = person_of[j0];
            const int64_t* b = benefit[row[r0 - 1]].data();
            const int64_t ur0 = u[r0];
            int64_t delta = kInf;
            int j1 = 0;
            // Without branches (which object improves is data): a used
            // object neither improves nor wins (its values read as kInf).
            for (int j = 1; j <= n; ++j) {
                const int64_t cur = used[j] ? kInf : -b[j - 1] - ur0 - v[j];
                const bool better = cur < minv[j];
                minv[j] = better ? cur : minv[j];
                way[j] = better ? j0 : way[j];
                const int64_t m = used[j] ? kInf : minv[j];
                const bool wins = m < delta;
                delta = wins ? m : delta;
                j1 = wins ? j : j1;
            }
            for (int j = 0; j <= n; ++j) {
                const int64_t d = used[j] ? delta : 0;
                u[person_of[j]] += d;  // d = 0 for an unused j (whatever person_of[j] holds)
                v[j] -= d;
                minv[j] -= used[j] ? 0 : delta;
            }
            j0 = j1;
        } while (person_of[j0] != 0);
        do {  // augment along the path
            const int j1 = way[j0];
            person_of[j0] = person_of[j1];
            j0 = j1;
        } while (j0 != 0);
    }
    // Another optimal assignment of the k persons exists iff, on the edges of
    // reduced cost 0 (every optimal assignment uses only those), an
    // alternating cycle exists, or an alternating path that moves a person
    // onto an unassigned object and ends by releasing an object whose
    // potential is 0 (the only objects another optimum may leave unassigned).
    // Graph on rows: r -> r' when r can take r''s object; bit kFree when r
    // can take an unassigned object.
    constexpr uint32_t kFree = 1u << n;
    uint32_t reach[n] = {};
    int object_of_row[n] = {};
    for (int j = 1; j <= n; ++j)
        if (person_of[j] != 0) object_of_row[person_of[j] - 1] = j;
    for (int r = 0; r < k; ++r) {
        uint32_t m = 0;
        for (int j = 1; j <= n; ++j) {
            const bool tight = -benefit[row[r]][j - 1] - u[r + 1] - v[j] == 0;
            const int other = person_of[j] - 1;  // -1: unassigned
            m |= tight && other < 0 ? kFree : 0;
            m |= uint32_t(tight && other >= 0 && other != r) << (other & 31);
        }
        reach[r] = m;
    }
    for (int q = 0; q < k; ++q)  // transitive closure (Warshall on bit rows)
        for (int r = 0; r < k; ++r)
            if (reach[r] >> q & 1) reach[r] |= reach[q];
    for (int r = 0; r < k; ++r) {
        if (reach[r] >> r & 1) return false;                           // a cycle
        if ((reach[r] & kFree) && v[object_of_row[r]] == 0) return false;  // a path that releases r's object
    }
    // The unique optimum; the other persons take the objects left, lowest first.
    for (int r = 0; r < k; ++r) object_of[row[r]] = object_of_row[r] - 1;
    int next = 1;
    for (int i = 0; i < n; ++i) {
        if (!(empty >> i & 1)) continue;
        while (person_of[next] != 0) ++next;
        object_of[i] = next++ - 1;
    }
    return true;
}

void slot_assign(const std::array<std::array<int64_t, 8>, 8>& benefit, uint8_t empty, std::array<int, 8>& object_of) {
    if (unique_max_benefit(benefit, empty, object_of)) return;
    auction_assign(benefit, object_of);
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
/// zero (|x| <= 2^30 here). x - trunc(x) is exact for such x (and int64_t(x) is trunc(x)), so the result is
/// llround's bit for bit.
inline int64_t round_half_away(double x) {
    const int64_t t = int64_t(x);  // truncation toward zero, exact for |x| <= 2^30
    const double f = x - double(t);
    return t + int64_t(f >= 0.5) - int64_t(f <= -0.5);  // without branches: the sign is data
}
}  // namespace

void assign_min_cost(const std::array<std::array<double, 8>, 8>& cost, uint8_t empty, std::array<int, 8>& slot_of) {
    double max_abs = 0.0;
    for (const auto& row : cost)
        for (double c : row) max_abs = std::fabs(c) > max_abs ? std::fabs(c) : max_abs;
    std::array<std::array<int64_t, 8>, 8> benefit{};
    if (max_abs > 0.0 && std::isfinite(max_abs)) {
        const double scale = std::ldexp(1.0, 30) / max_abs;
        for (int i = 0; i < 8; ++i)
            for (int j = 0; j < 8; ++j) benefit[i][j] = -round_half_away(cost[i][j] * scale);  // maximise -cost
    }
    slot_assign(benefit, empty, slot_of);
}

void assign_slots(WideBvh& wide, Progress* progress) {
    // Nodes are independent: the result does not depend on the partitioning.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, wide.nodes.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            WideNode& node = wide.nodes[k];
            std::array<int, 8> slot_of{};
            uint8_t empty = 0;
            for (int i = 0; i < kWidth; ++i) empty |= uint8_t((node.slots[i].kind == WideChild::kEmpty) << i);
            assign_min_cost(slot_cost_table(wide, node), empty, slot_of);
            std::array<WideChild, 8> slots;
            for (int i = 0; i < kWidth; ++i) slots[slot_of[i]] = node.slots[i];
            node.slots = slots;
        }
        progress_add(progress, r.size());  // one relaxed atomic per chunk (>= 512 nodes)
    });
}

}  // namespace cwbvh::compiler
