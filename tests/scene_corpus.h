// The scene corpus: real scenes in ../shared/scenes (CWBVH_SHARED_SCENES_DIR, or
// $CWBVH_SHARED_SCENES at run time; listed in SCENES.md there), not in this repository. A test that reads one starts with
// CWBVH_REQUIRE_SCENE(path):
//   - the file is there: the test goes on;
//   - the corpus folder is missing: under CI (environment CI=true) the test fails; elsewhere
//     it is skipped, and the test program prints how many such skips it had when it ends
//     ("N scene test(s) skipped: ... missing"), so a run without the corpus cannot pass
//     quietly as if it had tested the scenes;
//   - the folder is there but the file is not: the test fails (an incomplete corpus).
// A file that is there but does not load is the test's failure, never a skip.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace cwbvh::test {

/// $CWBVH_SHARED_SCENES (as bench/run.py reads it) when set, else the configured folder.
inline std::string scene_corpus_dir() {
    const char* env = std::getenv("CWBVH_SHARED_SCENES");
    return env != nullptr && *env != '\0' ? std::string(env) : std::string(CWBVH_SHARED_SCENES_DIR);
}
inline std::string corpus_scene(const std::string& name) { return scene_corpus_dir() + "/" + name; }

/// CI=true (what GitHub Actions, GitLab CI and most others set).
inline bool under_ci() {
    const char* ci = std::getenv("CI");
    return ci != nullptr && std::string(ci) == "true";
}

enum class SceneAvailability { kPresent, kCorpusMissing, kFileMissing };

inline SceneAvailability scene_availability(const std::string& path) {
    std::error_code ec;
    if (std::filesystem::exists(path, ec)) return SceneAvailability::kPresent;
    if (!std::filesystem::is_directory(scene_corpus_dir(), ec)) return SceneAvailability::kCorpusMissing;
    return SceneAvailability::kFileMissing;
}

inline int& scene_skip_count() {
    static int n = 0;
    return n;
}

/// Prints the number of scene tests this program skipped, after the last test.
class SceneSkipReport : public ::testing::Environment {
public:
    void TearDown() override {
        if (scene_skip_count() == 0) return;
        std::printf("%d scene test(s) skipped: %s missing (with CI=true they fail)\n", scene_skip_count(),
                    scene_corpus_dir().c_str());
        std::fflush(stdout);
    }
};
inline const bool kSceneSkipReportRegistered = (::testing::AddGlobalTestEnvironment(new SceneSkipReport), true);

}  // namespace cwbvh::test

/// Fails or skips the current test (returns from the calling function) unless the corpus
/// scene at `path` exists; see above.
#define CWBVH_REQUIRE_SCENE(path)                                                                             \
    do {                                                                                                      \
        const std::string cwbvh_scene_ = (path);                                                              \
        switch (::cwbvh::test::scene_availability(cwbvh_scene_)) {                                            \
            case ::cwbvh::test::SceneAvailability::kPresent:                                                  \
                break;                                                                                        \
            case ::cwbvh::test::SceneAvailability::kFileMissing:                                              \
                FAIL() << cwbvh_scene_ << " is missing from the scene corpus " << ::cwbvh::test::scene_corpus_dir(); \
            case ::cwbvh::test::SceneAvailability::kCorpusMissing:                                            \
                if (::cwbvh::test::under_ci())                                                                \
                    FAIL() << "scene corpus " << ::cwbvh::test::scene_corpus_dir()                            \
                           << " missing (CI=true: a missing corpus is a failure); needed: " << cwbvh_scene_;  \
                (void)::cwbvh::test::kSceneSkipReportRegistered;                                              \
                ++::cwbvh::test::scene_skip_count();                                                          \
                GTEST_SKIP() << "scene corpus " << ::cwbvh::test::scene_corpus_dir() << " missing: " << cwbvh_scene_; \
        }                                                                                                     \
    } while (0)
