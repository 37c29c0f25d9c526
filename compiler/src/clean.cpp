// Cleaning and merging of imported primitives into the Scene (see import.h).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "cwbvh/compiler/import.h"

namespace cwbvh::compiler {
namespace {

/// a - b in double, and whether that difference is exact. Knuth's TwoSum
/// error term is zero iff the rounded difference is the exact one.
inline double exact_diff(float a, float b, bool& exact) {
    const double x = a, y = -double(b);
    const double s = x + y;
    const double bb = s - x;
    const double err = (x - (s - bb)) + (y - bb);
    if (err != 0.0) exact = false;
    return s;
}

/// Is u*v - w*z exactly zero? With p = RN(u*v) and pe = u*v - p (exact by
/// fma, no underflow for the magnitudes the cleaner admits: |products| lie in
/// [2^-298, 2^252]), u*v = p + pe exactly, and RN(p + pe) = p. So u*v == w*z
/// iff p == q and pe == qe.
inline bool product_difference_is_zero(double u, double v, double w, double z) {
    const double p = u * v, q = w * z;
    if (p != q) return false;
    return std::fma(u, v, -p) == std::fma(w, z, -q);
}

}  // namespace

bool is_degenerate(const Vec3& a, const Vec3& b, const Vec3& c) {
    bool exact = true;
    const double e1[3] = {exact_diff(b[0], a[0], exact), exact_diff(b[1], a[1], exact),
                          exact_diff(b[2], a[2], exact)};
    const double e2[3] = {exact_diff(c[0], a[0], exact), exact_diff(c[1], a[1], exact),
                          exact_diff(c[2], a[2], exact)};
    // Not provably zero: keep the triangle (see import.h).
    if (!exact) return false;
    return product_difference_is_zero(e1[1], e2[2], e1[2], e2[1]) &&
           product_difference_is_zero(e1[2], e2[0], e1[0], e2[2]) &&
           product_difference_is_zero(e1[0], e2[1], e1[1], e2[0]);
}

namespace {

/// Triangles of one primitive classified in blocks of this many, in parallel.
constexpr size_t kCleanBlock = 65536;

enum TriangleVerdict : uint8_t { kKeep, kNonfinite, kDegenerate };

/// One block of a primitive's triangles [begin, end): the verdicts and, if
/// the block holds a triangle that fails the import, the first such.
struct CleanBlock {
    size_t prim = 0, begin = 0, end = 0;
    uint64_t kept = 0, nonfinite = 0, degenerate = 0;
    uint64_t first_kept = 0;  ///< kept triangles of the primitive before this block
    bool failed = false;
    size_t bad_triangle = 0;
    bool bad_index = false;   ///< else: a coordinate beyond kMaxCoordinate
    float bad_value = 0.0f;
};

/// The checks of one triangle, in the order that decides which message a bad
/// triangle gets: vertex index range, non-finite (drop), too large (error),
/// zero area (drop).
void classify(const RawPrimitive& prim, CleanBlock& b, uint8_t* verdict) {
    const size_t nv = prim.vertices.size();
    for (size_t t = b.begin; t < b.end; ++t) {
        const auto& tri = prim.triangles[t];
        // Importers guarantee indices < nv; re-check (programmer contract
        // turned into a clean error rather than UB).
        if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv) {
            b.failed = true;
            b.bad_triangle = t;
            b.bad_index = true;
            return;
        }
        const Vec3* v[3] = {&prim.vertices[tri[0]], &prim.vertices[tri[1]], &prim.vertices[tri[2]]};
        bool finite = true;
        for (const Vec3* p : v) finite = finite && std::isfinite((*p)[0]) && std::isfinite((*p)[1]) && std::isfinite((*p)[2]);
        if (!finite) {
            verdict[t] = kNonfinite;
            ++b.nonfinite;
            continue;
        }
        for (const Vec3* p : v) {
            for (int a = 0; a < 3; ++a) {
                if (std::fabs((*p)[a]) > kMaxCoordinate) {
                    b.failed = true;
                    b.bad_triangle = t;
                    b.bad_value = (*p)[a];
                    return;
                }
            }
        }
        if (is_degenerate(*v[0], *v[1], *v[2])) {
            verdict[t] = kDegenerate;
            ++b.degenerate;
            continue;
        }
        verdict[t] = kKeep;
        ++b.kept;
    }
}

}  // namespace

Result clean_and_append(const RawInput& input, uint32_t input_index, Scene& scene) {
    for (const auto& [kind, n] : input.skipped_primitives) scene.skipped_primitives[kind] += n;
    if (input.rejected_by_reader > 0) {
        scene.input_triangles += input.rejected_by_reader;
        scene.dropped["rejected_by_reader"] += input.rejected_by_reader;
    }
    const std::vector<RawPrimitive>& prims = input.primitives;

    // 1. Every triangle's verdict, blocks in parallel (each verdict depends on
    //    its triangle alone).
    std::vector<CleanBlock> blocks;
    std::vector<size_t> verdict_base(prims.size() + 1, 0);
    for (size_t p = 0; p < prims.size(); ++p) {
        const size_t n = prims[p].triangles.size();
        for (size_t b = 0; b < n; b += kCleanBlock) blocks.push_back(CleanBlock{p, b, std::min(n, b + kCleanBlock)});
        verdict_base[p + 1] = verdict_base[p] + n;
    }
    std::vector<uint8_t> verdicts(verdict_base.back());
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t i) {
        CleanBlock& b = blocks[i];
        classify(prims[b.prim], b, verdicts.data() + verdict_base[b.prim]);
    });

    // 2. In source order: the first failing triangle reports (as a serial
    //    pass would), counts, and each block's first kept triangle.
    uint64_t nonfinite = 0, degenerate = 0;
    std::vector<uint64_t> prim_kept(prims.size(), 0);
    for (CleanBlock& b : blocks) {
        const RawPrimitive& prim = prims[b.prim];
        if (b.failed) {
            const std::string where = "mesh " + std::to_string(prim.mesh) + " primitive " + std::to_string(prim.primitive);
            if (b.bad_index) {
                return Result::fail(Status::kBadInput, 0,
                                    where + ": triangle " + std::to_string(b.bad_triangle) +
                                        " has a vertex index out of range");
            }
            return Result::fail(Status::kBadInput, 0,
                                where + ": coordinate " + std::to_string(b.bad_value) +
                                    " exceeds 2^125 (about 4.25e37), which the node quantization cannot encode");
        }
        b.first_kept = prim_kept[b.prim];
        prim_kept[b.prim] += b.kept;
        nonfinite += b.nonfinite;
        degenerate += b.degenerate;
    }

    // 3. Per primitive, in parallel: vertices used by a kept triangle, numbered
    //    in source order (remap: local number, or kInvalidIndex).
    std::vector<std::vector<uint32_t>> remap(prims.size());
    std::vector<uint64_t> prim_used(prims.size(), 0);
    tbb::parallel_for(size_t(0), prims.size(), [&](size_t p) {
        const RawPrimitive& prim = prims[p];
        std::vector<uint32_t>& r = remap[p];
        r.assign(prim.vertices.size(), kInvalidIndex);
        const uint8_t* verdict = verdicts.data() + verdict_base[p];
        for (size_t t = 0; t < prim.triangles.size(); ++t)
            if (verdict[t] == kKeep)
                for (int k = 0; k < 3; ++k) r[prim.triangles[t][k]] = 0;  // mark used
        uint32_t next = 0;
        for (uint32_t& x : r)
            if (x == 0) x = next++;
        prim_used[p] = next;
    });

    // 4. Offsets in the merged scene, checked in order.
    std::vector<uint64_t> vertex_base(prims.size()), triangle_base(prims.size());
    uint64_t vertices = scene.vertices.size(), triangles = scene.indices.size();
    for (size_t p = 0; p < prims.size(); ++p) {
        vertex_base[p] = vertices;
        triangle_base[p] = triangles;
        vertices += prim_used[p];
        triangles += prim_kept[p];
        if (vertices >= kInvalidIndex || triangles >= kInvalidIndex) {
            return Result::fail(Status::kBadInput, 0, "the merged scene exceeds 2^32-1 vertices or triangles");
        }
    }
    scene.input_triangles += verdicts.size();
    if (nonfinite > 0) scene.dropped["nonfinite"] += nonfinite;
    if (degenerate > 0) scene.dropped["degenerate"] += degenerate;
    // Geometric growth across inputs (one exact resize per input would make
    // merging many inputs quadratic).
    auto grow = [](auto& v, size_t n) {
        if (v.capacity() < n) v.reserve(std::max(n, 2 * v.capacity()));
        v.resize(n);
    };
    grow(scene.vertices, vertices);
    grow(scene.indices, triangles);
    grow(scene.sources, triangles);

    // 5. Copies, in parallel: used vertices per primitive, kept triangles per block.
    tbb::parallel_for(size_t(0), prims.size(), [&](size_t p) {
        const RawPrimitive& prim = prims[p];
        Vec3* out = scene.vertices.data() + vertex_base[p];
        for (size_t i = 0; i < prim.vertices.size(); ++i)
            if (remap[p][i] != kInvalidIndex) *out++ = prim.vertices[i];
    });
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t i) {
        const CleanBlock& b = blocks[i];
        const RawPrimitive& prim = prims[b.prim];
        const uint32_t* r = remap[b.prim].data();
        const uint32_t base = uint32_t(vertex_base[b.prim]);
        const uint8_t* verdict = verdicts.data() + verdict_base[b.prim];
        size_t out = size_t(triangle_base[b.prim] + b.first_kept);
        for (size_t t = b.begin; t < b.end; ++t) {
            if (verdict[t] != kKeep) continue;
            const auto& tri = prim.triangles[t];
            scene.indices[out] = {base + r[tri[0]], base + r[tri[1]], base + r[tri[2]]};
            scene.sources[out] = SourceRef{input_index, prim.mesh, prim.primitive, uint32_t(t)};
            ++out;
        }
    });
    return Result::success();
}

}  // namespace cwbvh::compiler
