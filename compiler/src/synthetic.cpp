// The synthetic scene: its own triangles, the core's tree.
#include "cwbvh/compiler/synthetic.h"

#include <stdexcept>
#include <string>

#include "cwbvh/compiler/core.h"

namespace cwbvh {
namespace {

uint64_t splitmix(uint64_t& s) {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

uint32_t compact_bits(uint32_t v) {  // every third bit of a Morton code
    uint32_t r = 0;
    for (int i = 0; i < 10; ++i) r |= ((v >> (3 * i)) & 1u) << i;
    return r;
}

/// Triangle i lies in the unit cell at Morton index i (consecutive ids are
/// close), its vertices jittered inside the cell; primitives of 8 triangles.
compiler::Scene synthetic_triangles(const SyntheticOptions& options) {
    compiler::Scene scene;
    const uint32_t count = options.triangles;
    uint64_t rng = options.seed;
    for (uint32_t i = 0; i < count; ++i) {
        const float cell[3] = {float(compact_bits(i)), float(compact_bits(i >> 1)), float(compact_bits(i >> 2))};
        // The outlier sits 4096 cells out on x: past any grid of up to 2^30 triangles.
        const float shift = options.outlier && i + 1 == count ? 4096.0f : 0.0f;
        for (uint32_t k = 0; k < 3; ++k) {
            compiler::Vec3 v;
            for (int a = 0; a < 3; ++a) v[a] = cell[a] + float(splitmix(rng) >> 40) / float(1u << 24);
            v[0] += shift;
            scene.vertices.push_back(v);
        }
        scene.indices.push_back({3 * i, 3 * i + 1, 3 * i + 2});
        scene.sources.push_back({0, 0, i / 8, i % 8});
    }
    scene.input_triangles = count;
    if (options.source_geometry) scene.input_names.push_back("synthetic");
    return scene;
}

}  // namespace

SceneData make_synthetic_scene(const SyntheticOptions& options) {
    const compiler::Scene scene = synthetic_triangles(options);
    compiler::CoreOptions core;
    core.emit.bvh2 = !options.bvh2 ? compiler::Bvh2Section::kNone
                     : options.bvh2_leaf_ranges ? compiler::Bvh2Section::kLeafRanges
                                                : compiler::Bvh2Section::kBvh2;
    core.emit.keep_mesh = options.source_geometry;
    compiler::EmitResult encoded;
    if (const Result r = compiler::compile_scene(scene, core, encoded); !r.ok())
        throw std::logic_error("make_synthetic_scene: " + r.message);
    SceneData out = SceneData::copy_of(compiler::scene_sections(scene, encoded));
    if (!options.build_info) out.build_info.reset();
    return out;
}

}  // namespace cwbvh
