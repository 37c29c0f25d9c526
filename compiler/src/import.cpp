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
Format detect(const std::string& path, Result& error) {
    std::ifstream f(path, std::ios::binary);
    if (!f) {
        error = Result::fail(Status::kIoError, 0, "cannot open file");
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
    error = Result::fail(Status::kBadInput, 0,
                         "unknown file type (expected .gltf, .glb, .obj, .ply, .off, .stl or .drc)");
    return Format::kUnknown;
}

Result import_one(const std::string& path, const ImportOptions& options, RawInput& raw,
                  std::vector<std::string>& warnings) {
    Result error;
    const Format format = detect(path, error);
    switch (format) {
        case Format::kGltf:
        case Format::kGlb: return import_gltf(path, options, raw, warnings);
        case Format::kDraco: return import_draco_file(path, raw);
        case Format::kOpenMesh: return import_openmesh(path, options, raw, warnings);
        case Format::kUnknown: break;
    }
    return error;
}

}  // namespace

Result read_file_bytes(const std::string& path, std::vector<uint8_t>& bytes) {
    bytes.clear();
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    if (!f) return Result::fail(Status::kIoError, 0, "cannot open file");
    const std::streamoff size = f.tellg();
    if (size < 0) return Result::fail(Status::kIoError, 0, "cannot read file");
    bytes.resize(size_t(size));
    f.seekg(0);
    if (size > 0 && !f.read(reinterpret_cast<char*>(bytes.data()), size)) {
        bytes.clear();
        return Result::fail(Status::kIoError, 0, "cannot read file");
    }
    return Result::success();
}

Result import_scene(const std::vector<std::string>& paths, const ImportOptions& options, Scene& out,
                    std::vector<std::string>& warnings) {
    out = Scene{};
    auto fail = [&out](Status status, std::string message) {
        out = Scene{};
        return Result::fail(status, 0, std::move(message));
    };
    if (paths.empty()) return fail(Status::kInvalidArgument, "no input files");
    try {
        for (size_t i = 0; i < paths.size(); ++i) {
            const std::string& path = paths[i];
            RawInput raw;
            std::vector<std::string> file_warnings;
            const Result r = import_one(path, options, raw, file_warnings);
            for (const std::string& w : file_warnings) warnings.push_back(path + ": " + w);
            if (!r.ok()) {
                const Status status = r.status == Status::kOk ? Status::kBadInput : r.status;
                return fail(status, path + ": " + (r.message.empty() ? "cannot be read" : r.message));
            }
            const uint64_t before = out.triangle_count(), read_before = out.input_triangles;
            const auto dropped_before = out.dropped;
            if (const Result c = clean_and_append(raw, uint32_t(i), out); !c.ok()) {
                return fail(c.status, path + ": " + c.message);
            }
            out.input_names.push_back(path);
            if (out.triangle_count() == before) {
                std::string error = path + ": no triangles";
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
                return fail(Status::kBadInput, error);
            }
        }
    } catch (const std::bad_alloc&) {
        return fail(Status::kBadInput, "out of memory while importing");
    } catch (const std::exception& e) {
        return fail(Status::kBadInput, std::string("unexpected error while importing: ") + e.what());
    }
    return Result::success();
}

}  // namespace cwbvh::compiler
