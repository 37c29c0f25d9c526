// Helpers for the import tests: temp files and a one-call import.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../result_util.h"
#include "cwbvh/compiler/import.h"

namespace cwbvh::compiler::test {

/// A fresh temporary directory per test, removed afterwards.
class TempDir {
public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        path_ = std::filesystem::temp_directory_path() /
                ("cwbvh_import_" + std::string(info->test_suite_name()) + "_" + info->name() +
                 "_" + std::to_string(::getpid()));
        std::filesystem::remove_all(path_);
        std::filesystem::create_directories(path_);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path_, ec);
    }
    std::string write(const std::string& name, const std::string& bytes) const {
        const std::string p = (path_ / name).string();
        std::ofstream(p, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
        return p;
    }
    std::string path(const std::string& name) const { return (path_ / name).string(); }

private:
    std::filesystem::path path_;
};

struct Result {
    bool ok = false;
    Scene scene;
    std::string error;
    std::vector<std::string> warnings;
};

inline Result import_files(const std::vector<std::string>& paths, bool permissive = false) {
    Result r;
    ImportOptions options;
    options.permissive = permissive;
    r.ok = ::cwbvh::test::ok(import_scene(paths, options, r.scene, r.warnings), r.error);
    return r;
}

inline Aabb bounds(const Scene& s) {
    Aabb b;
    for (size_t i = 0; i < s.triangle_count(); ++i)
        for (const Vec3& v : s.triangle(i)) b.grow(v);
    return b;
}

inline bool exists(const std::string& p) { return std::filesystem::exists(p); }

}  // namespace cwbvh::compiler::test
