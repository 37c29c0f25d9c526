// Test-only mesh helpers for tests/build: a tiny OBJ reader (v/f lines only,
// fan triangulation, negative indices) and generated scenes. Not the importer.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "cwbvh/compiler/model.h"
#include "scene_corpus.h"

namespace cwbvh::compiler::test {

/// False when the file cannot be opened, a vertex does not parse, a face index is out of
/// range, or there is no face: a broken scene file is the test's failure, not a reason to skip.
inline bool read_obj(const std::string& path, Scene& scene) {
    std::ifstream in(path);
    if (!in) return false;
    scene = Scene{};
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream ls(line);
        std::string tag;
        ls >> tag;
        if (tag == "v") {
            Vec3 v{};
            if (!(ls >> v[0] >> v[1] >> v[2])) return false;
            scene.vertices.push_back(v);
        } else if (tag == "f") {
            std::vector<uint32_t> idx;
            std::string tok;
            while (ls >> tok) {
                long i = std::strtol(tok.c_str(), nullptr, 10);
                if (i < 0) i = long(scene.vertices.size()) + i + 1;
                if (i < 1 || i > long(scene.vertices.size())) return false;
                idx.push_back(uint32_t(i - 1));
            }
            for (size_t k = 2; k < idx.size(); ++k) {
                scene.indices.push_back({idx[0], idx[k - 1], idx[k]});
                scene.sources.push_back(SourceRef{0, 0, 0, uint32_t(scene.indices.size() - 1)});
            }
        }
    }
    scene.input_triangles = scene.indices.size();
    return !scene.indices.empty();
}

inline void add_triangle(Scene& s, const Vec3& a, const Vec3& b, const Vec3& c) {
    const uint32_t base = uint32_t(s.vertices.size());
    s.vertices.push_back(a);
    s.vertices.push_back(b);
    s.vertices.push_back(c);
    s.indices.push_back({base, base + 1, base + 2});
    s.sources.push_back(SourceRef{0, 0, 0, uint32_t(s.indices.size() - 1)});
    s.input_triangles = s.indices.size();
}

inline Scene random_soup(int n, uint64_t seed, float size = 0.05f) {
    Scene s;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f), d(-size, size);
    for (int i = 0; i < n; ++i) {
        const Vec3 a{u(rng), u(rng), u(rng)};
        add_triangle(s, a, Vec3{a[0] + d(rng), a[1] + d(rng), a[2] + d(rng)},
                     Vec3{a[0] + d(rng), a[1] + d(rng), a[2] + d(rng)});
    }
    return s;
}

/// Long thin diagonal triangles at random places: their boxes overlap
/// massively and spatial splits pay off (Stich et al. 2009, Figure 1).
inline Scene sliver_scene(int n, uint64_t seed = 9) {
    Scene s;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int i = 0; i < n; ++i) {
        const Vec3 a{u(rng), u(rng), u(rng)};
        const float len = 0.2f + 0.3f * u(rng);
        const Vec3 b{a[0] + len, a[1] + len, a[2] + len};
        add_triangle(s, a, b, Vec3{b[0], b[1] + 0.002f, b[2]});
    }
    return s;
}

/// A scene of the corpus (scene_corpus.h).
inline std::string scene_path(const char* name) { return ::cwbvh::test::corpus_scene(name); }

/// Reads corpus scene `name` into `s`: skips or fails as CWBVH_REQUIRE_SCENE says when it is
/// not there, fails when it is there but does not parse. The caller returns when
/// corpus_obj_missing_or_broken() says so afterwards.
inline void read_corpus_obj(const char* name, Scene& s) {
    const std::string path = scene_path(name);
    CWBVH_REQUIRE_SCENE(path);
    ASSERT_TRUE(read_obj(path, s)) << path << " is there but does not parse";
}
inline bool corpus_obj_missing_or_broken() {
    return ::testing::Test::IsSkipped() || ::testing::Test::HasFatalFailure();
}

/// Runs `check(scene, what)` on `soup`, then on corpus scene `name` (read_corpus_obj): the
/// generated scene is tested whether or not the corpus is there, never instead of it.
template <class Check>
void on_soup_then_corpus_obj(const Scene& soup, const char* name, Check check) {
    check(soup, std::string("random soup"));
    Scene s;
    read_corpus_obj(name, s);
    if (corpus_obj_missing_or_broken()) return;
    check(s, std::string(name));
}

}  // namespace cwbvh::compiler::test
