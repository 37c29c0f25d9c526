// import_scene: dispatch each input by magic/extension, then clean + merge.
#include <algorithm>
#include <cctype>
#include <cstring>
#include <exception>
#include <fstream>

#include "cwbvh/compiler/import.h"

namespace cwbvh::compiler {
namespace {

enum class Format { kUnknown, kGltf, kGlb, kDraco, kOpenMesh };

std::string lower_extension(const std::string& path) {
    const size_t slash = path.find_last_of('/');
    const size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string ext = path.substr(dot + 1);
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

/// Magic first (a .glb or .drc under another name still loads), then the
/// extension. Returns kUnknown with `error` set when the file cannot be read.
Format detect(const std::string& path, std::string& error) {
    std::ifstream f(path, std::ios::binary);
    if (!f) {
        error = "cannot open file";
        return Format::kUnknown;
    }
    char magic[5] = {};
    f.read(magic, 5);
    const std::streamsize got = f.gcount();
    if (got >= 4 && std::memcmp(magic, "glTF", 4) == 0) return Format::kGlb;
    if (got >= 5 && std::memcmp(magic, "DRACO", 5) == 0) return Format::kDraco;
    const std::string ext = lower_extension(path);
    if (ext == "gltf") return Format::kGltf;
    if (ext == "glb") return Format::kGlb;
    if (ext == "drc") return Format::kDraco;
    if (ext == "obj" || ext == "ply" || ext == "off" || ext == "stl") return Format::kOpenMesh;
    error = "unknown file type (expected .gltf, .glb, .obj, .ply, .off, .stl or .drc)";
    return Format::kUnknown;
}

bool import_one(const std::string& path, const ImportOptions& options, RawInput& raw,
                std::string& error, std::vector<std::string>& warnings) {
    const Format format = detect(path, error);
    switch (format) {
        case Format::kGltf:
        case Format::kGlb: return import_gltf(path, options, raw, error, warnings);
        case Format::kDraco: return import_draco_file(path, raw, error);
        case Format::kOpenMesh: return import_openmesh(path, options, raw, error, warnings);
        case Format::kUnknown: break;
    }
    return false;
}

}  // namespace

bool import_scene(const std::vector<std::string>& paths, const ImportOptions& options,
                  Scene& out, std::string& error, std::vector<std::string>& warnings) {
    out = Scene{};
    error.clear();
    if (paths.empty()) {
        error = "no input files";
        return false;
    }
    try {
        for (size_t i = 0; i < paths.size(); ++i) {
            const std::string& path = paths[i];
            RawInput raw;
            std::string what;
            std::vector<std::string> file_warnings;
            const bool ok = import_one(path, options, raw, what, file_warnings);
            for (const std::string& w : file_warnings) warnings.push_back(path + ": " + w);
            if (!ok) {
                error = path + ": " + (what.empty() ? "cannot be read" : what);
                out = Scene{};
                return false;
            }
            const uint64_t before = out.triangle_count(), read_before = out.input_triangles;
            const auto dropped_before = out.dropped;
            if (!clean_and_append(raw, uint32_t(i), out, what)) {
                error = path + ": " + what;
                out = Scene{};
                return false;
            }
            out.input_names.push_back(path);
            if (out.triangle_count() == before) {
                error = path + ": no triangles";
                const uint64_t read = out.input_triangles - read_before;
                if (read > 0) {
                    error += " (all " + std::to_string(read) + " dropped:";
                    for (const auto& [reason, n] : out.dropped) {
                        const auto it = dropped_before.find(reason);
                        const uint64_t d = n - (it == dropped_before.end() ? 0 : it->second);
                        if (d > 0) error += " " + std::to_string(d) + " " + reason;
                    }
                    error += ")";
                }
                out = Scene{};
                return false;
            }
        }
    } catch (const std::bad_alloc&) {
        error = "out of memory while importing";
        out = Scene{};
        return false;
    } catch (const std::exception& e) {
        error = std::string("unexpected error while importing: ") + e.what();
        out = Scene{};
        return false;
    }
    return true;
}

}  // namespace cwbvh::compiler
