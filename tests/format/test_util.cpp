#include "format/test_util.h"

#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace cwbvh::test {

std::string temp_dir() {
    static const std::string dir = [] {
        auto d = std::filesystem::temp_directory_path() / ("cwbvh_format_tests_" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        return d.string();
    }();
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
