// Helpers for tests that run the cwbvhc / cwbvh executables.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <array>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace cwbvh::test {

struct RunResult {
    int exit_code = -1;
    std::string out;
    std::string err;
};

inline std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

inline std::string shell_quote(const std::string& s) {
    std::string q = "'";
    for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

/// Runs bin/<tool> with arguments (in `cwd` when given); captures stdout, stderr and the exit code.
inline RunResult run_tool(const std::string& tool, const std::vector<std::string>& args,
                          const std::filesystem::path& cwd = {}) {
    static int counter = 0;
    const auto dir = std::filesystem::temp_directory_path() / ("cwbvh_cli_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const auto out = dir / ("out" + std::to_string(counter));
    const auto err = dir / ("err" + std::to_string(counter++));
    std::string cmd = cwd.empty() ? std::string() : "cd " + shell_quote(cwd.string()) + " && ";
    cmd += shell_quote(std::string(CWBVH_BIN_DIR) + "/" + tool);
    for (const auto& a : args) cmd += " " + shell_quote(a);
    cmd += " >" + shell_quote(out.string()) + " 2>" + shell_quote(err.string());
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
}

inline int count_lines(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

/// A fresh temporary directory per test.
inline std::filesystem::path temp_dir(const std::string& name) {
    const auto dir = std::filesystem::temp_directory_path() /
                     ("cwbvh_test_" + name + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

/// Writes an OBJ from float vertices and 0-based triangles.
inline void write_obj(const std::filesystem::path& path, const std::vector<std::array<double, 3>>& v,
                      const std::vector<std::array<int, 3>>& f) {
    std::ofstream out(path);
    out.precision(17);
    for (const auto& p : v) out << "v " << p[0] << " " << p[1] << " " << p[2] << "\n";
    for (const auto& t : f) out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
}

inline const char* bunny_path() { return "/usr/share/glmark2/models/bunny.obj"; }

}  // namespace cwbvh::test
