#include "format/test_util.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <unistd.h>

namespace cwbvh::test {

namespace {
std::string& temp_dir_path() {
    static std::string dir;
    return dir;
}
void remove_temp_dir() {
    std::error_code ignored;
    std::filesystem::remove_all(temp_dir_path(), ignored);
}
}  // namespace

std::string temp_dir() {
    std::string& dir = temp_dir_path();
    if (dir.empty()) {
        auto d = std::filesystem::temp_directory_path() / ("cwbvh_format_tests_" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        dir = d.string();
        std::atexit(remove_temp_dir);  // the test binary cleans up after itself
    }
    return dir;
}

std::string write_temp(const std::string& name, const std::vector<uint8_t>& bytes) {
    const std::string path = temp_dir() + "/" + name;
    FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr) throw std::runtime_error("cannot write " + path);
    if (!bytes.empty()) std::fwrite(bytes.data(), 1, bytes.size(), f);
    std::fclose(f);
    return path;
}

}  // namespace cwbvh::test
