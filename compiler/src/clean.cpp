// Cleaning and merging of imported primitives into the Scene (see import.h).
#include <algorithm>
#include <cmath>
#include <limits>

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

Result clean_and_append(const RawInput& input, uint32_t input_index, Scene& scene) {
    for (const auto& [kind, n] : input.skipped_primitives) scene.skipped_primitives[kind] += n;
    if (input.rejected_by_reader > 0) {
        scene.input_triangles += input.rejected_by_reader;
        scene.dropped["rejected_by_reader"] += input.rejected_by_reader;
    }

    std::vector<uint32_t> remap;
    for (const RawPrimitive& prim : input.primitives) {
        const size_t nv = prim.vertices.size();
        std::vector<uint8_t> vertex_finite(nv);
        for (size_t i = 0; i < nv; ++i) {
            const Vec3& v = prim.vertices[i];
            vertex_finite[i] = std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
        }
        remap.assign(nv, kInvalidIndex);
        std::vector<uint32_t> kept;  // triangle numbers in the primitive
        kept.reserve(prim.triangles.size());
        for (size_t t = 0; t < prim.triangles.size(); ++t) {
            const auto& tri = prim.triangles[t];
            ++scene.input_triangles;
            // Importers guarantee indices < nv; re-check (programmer contract
            // turned into a clean error rather than UB).
            if (tri[0] >= nv || tri[1] >= nv || tri[2] >= nv) {
                return Result::fail(Status::kBadInput, 0, "mesh " + std::to_string(prim.mesh) + " primitive " +
                        std::to_string(prim.primitive) + ": triangle " + std::to_string(t) +
                        " has a vertex index out of range");
            }
            if (!vertex_finite[tri[0]] || !vertex_finite[tri[1]] || !vertex_finite[tri[2]]) {
                ++scene.dropped["nonfinite"];
                continue;
            }
            for (int k = 0; k < 3; ++k) {
                const Vec3& v = prim.vertices[tri[k]];
                for (int a = 0; a < 3; ++a) {
                    if (std::fabs(v[a]) > kMaxCoordinate) {
                        return Result::fail(Status::kBadInput, 0, "mesh " + std::to_string(prim.mesh) + " primitive " +
                                std::to_string(prim.primitive) + ": coordinate " +
                                std::to_string(v[a]) +
                                " exceeds 2^125 (about 4.25e37), which the node quantization "
                                "cannot encode");
                    }
                }
            }
            if (is_degenerate(prim.vertices[tri[0]], prim.vertices[tri[1]],
                              prim.vertices[tri[2]])) {
                ++scene.dropped["degenerate"];
                continue;
            }
            kept.push_back(uint32_t(t));
            for (int k = 0; k < 3; ++k) remap[tri[k]] = 0;  // mark used
        }
        // Used vertices keep their relative source order.
        const uint64_t base = scene.vertices.size();
        uint64_t next = base;
        for (size_t i = 0; i < nv; ++i)
            if (remap[i] == 0) remap[i] = uint32_t(std::min<uint64_t>(next++, kInvalidIndex));
        if (next >= kInvalidIndex || scene.indices.size() + kept.size() >= kInvalidIndex) {
            return Result::fail(Status::kBadInput, 0, "the merged scene exceeds 2^32-1 vertices or triangles");
        }
        for (size_t i = 0; i < nv; ++i)
            if (remap[i] != kInvalidIndex) scene.vertices.push_back(prim.vertices[i]);
        // No exact reserve() here: with many primitives it would defeat the
        // vector's geometric growth and make merging quadratic.
        for (uint32_t t : kept) {
            const auto& tri = prim.triangles[t];
            scene.indices.push_back({remap[tri[0]], remap[tri[1]], remap[tri[2]]});
            scene.sources.push_back(SourceRef{input_index, prim.mesh, prim.primitive, t});
        }
    }
    return Result::success();
}

}  // namespace cwbvh::compiler
