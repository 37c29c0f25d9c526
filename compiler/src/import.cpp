// import_scene: dispatch each input by magic/extension, then clean + merge.
#include <algorithm>
#include <cctype>
#include <cstring>
#include <exception>
#include <map>
#include <cstdint>

#include "cwbvh/compiler/import.h"
#include "cwbvh/format/file_io.h"

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

/// `r` with the "<path>: " prefix of file_io.h's messages removed (import_scene adds the path).
Result without_path(Result r, const std::string& path) {
    if (r.message.compare(0, path.size() + 2, path + ": ") == 0) r.message.erase(0, path.size() + 2);
    return r;
}

/// Magic first (a .glb or .drc under another name still loads), then the
/// extension. Returns kUnknown with `error` set when the file cannot be read.
Format detect(const std::string& path, Result& error) {
    // A regular file only: a FIFO would block the readers and a device such as /dev/zero
    // named .stl would be read without end. The readers that open the path again (OpenMesh)
    // come after this check.
    Expected<RegularFile> f = RegularFile::open(path, false);
    if (!f.ok()) {
        error = without_path(f.error(), path);
        return Format::kUnknown;
    }
    char magic[5] = {};
    const uint64_t got = std::min<uint64_t>(f->size(), sizeof magic);
    if (Result r = f->read_exact(magic, got); !r.ok()) {
        error = without_path(r, path);
        return Format::kUnknown;
    }
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

std::vector<std::string> referenced_files(const std::vector<std::string>& inputs) {
    std::vector<std::string> all;
    for (const std::string& input : inputs)
        for (std::string& f : referenced_files(input))
            if (all.size() < kMaxReferencedFiles) all.push_back(std::move(f));
    return all;
}

std::vector<std::string> referenced_files(const std::string& input) {
    Result error;
    switch (detect(input, error)) {
        case Format::kGltf:
        case Format::kGlb: return gltf_referenced_files(input);
        case Format::kOpenMesh:
            return lower_extension(input) == "obj" ? obj_referenced_files(input) : std::vector<std::string>{};
        case Format::kDraco:
        case Format::kUnknown: break;
    }
    return {};
}

Result read_file_bytes(const std::string& path, std::vector<uint8_t>& bytes) {
    // Bounded by the size fstat reported; a FIFO or device is refused (file_io.h).
    return without_path(read_regular_file(path, UINT64_MAX, bytes), path);
}

namespace {

/// The "<path>: no triangles (all N dropped: ...)" message when `scene` gained no triangle.
Result no_triangles(const std::string& path, uint64_t read, const std::map<std::string, uint64_t>& dropped,
                    const std::map<std::string, uint64_t>& dropped_before,
                    const std::map<std::string, uint64_t>& skipped) {
    std::string error = path + ": no triangles";
    if (read == 0 && !skipped.empty()) {  // points or lines only: say so
        error += " (only";
        for (const auto& [kind, n] : skipped) error += " " + std::to_string(n) + " " + kind;
        error += " primitives, which are not traced)";
    } else if (read > 0) {
        error += " (all " + std::to_string(read) + " dropped:";
        for (const auto& [reason, n] : dropped) {
            const auto it = dropped_before.find(reason);
            const uint64_t d = n - (it == dropped_before.end() ? 0 : it->second);
            if (d > 0) error += " " + std::to_string(d) + " " + reason;
        }
        error += ")";
    }
    return Result::fail(Status::kBadInput, 0, error);
}

/// clean_and_append of input `i` with import_scene's errors.
Result append_input(const std::string& path, uint32_t i, const RawInput& raw, Scene& out) {
    const uint64_t before = out.triangle_count(), read_before = out.input_triangles;
    const auto dropped_before = out.dropped;
    if (const Result c = clean_and_append(raw, i, out); !c.ok()) return Result::fail(c.status, 0, path + ": " + c.message);
    out.input_names.push_back(path);
    if (out.triangle_count() == before)
        return no_triangles(path, out.input_triangles - read_before, out.dropped, dropped_before,
                            raw.skipped_primitives);
    return Result::success();
}

/// The bottom levels of a glTF file kept instanced: each cleaned on its own
/// (input 0); bottom levels left without triangles are dropped with their placements.
Result clean_instanced(const std::string& path, const RawInstanced& raw, InstancedScene& out) {
    std::vector<uint32_t> index(raw.meshes.size(), kInvalidIndex);
    for (size_t k = 0; k < raw.meshes.size(); ++k) {
        Scene s;
        if (const Result c = clean_and_append(raw.meshes[k], 0, s); !c.ok())
            return Result::fail(c.status, 0, path + ": " + c.message);
        out.input_triangles += s.input_triangles;
        for (const auto& [reason, n] : s.dropped) out.dropped[reason] += n;
        for (const auto& [kind, n] : s.skipped_primitives) out.skipped_primitives[kind] += n;
        if (s.triangle_count() == 0) continue;
        s.input_names.push_back(path);
        index[k] = uint32_t(out.meshes.size());
        out.meshes.push_back(std::move(s));
        out.source_mesh.push_back(raw.source_mesh[k]);
    }
    for (const RawPlacement& p : raw.placements) {
        if (index[p.mesh] == kInvalidIndex) continue;
        out.placements.push_back(Placement{index[p.mesh], p.node, p.object_to_world});
    }
    out.input_names.push_back(path);
    if (out.meshes.empty()) return no_triangles(path, out.input_triangles, out.dropped, {}, {});
    return Result::success();
}

}  // namespace

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
            if (const Result a = append_input(path, uint32_t(i), raw, out); !a.ok()) return fail(a.status, a.message);
        }
    } catch (const std::bad_alloc&) {
        return fail(Status::kBadInput, "out of memory while importing");
    } catch (const std::exception& e) {
        return fail(Status::kBadInput, std::string("unexpected error while importing: ") + e.what());
    }
    return Result::success();
}

Result import_scene_instanced(const std::vector<std::string>& paths, const ImportOptions& options, Scene& flat,
                              InstancedScene& instanced, bool& is_instanced, std::vector<std::string>& warnings) {
    is_instanced = false;
    instanced = InstancedScene{};
    if (paths.size() != 1) return import_scene(paths, options, flat, warnings);
    const std::string& path = paths.front();
    Result detect_error;
    const Format format = detect(path, detect_error);
    if (format != Format::kGltf && format != Format::kGlb) return import_scene(paths, options, flat, warnings);
    flat = Scene{};
    try {
        RawInput raw;
        RawInstanced raw_instanced;
        std::vector<std::string> file_warnings;
        const Result r = import_gltf(path, options, raw, file_warnings, &raw_instanced, &is_instanced);
        for (const std::string& w : file_warnings) warnings.push_back(path + ": " + w);
        if (!r.ok()) {
            const Status status = r.status == Status::kOk ? Status::kBadInput : r.status;
            return Result::fail(status, 0, path + ": " + (r.message.empty() ? "cannot be read" : r.message));
        }
        if (!is_instanced) {
            if (Result a = append_input(path, 0, raw, flat); !a.ok()) {
                flat = Scene{};
                return a;
            }
            return Result::success();
        }
        if (Result c = clean_instanced(path, raw_instanced, instanced); !c.ok()) {
            instanced = InstancedScene{};
            return c;
        }
        // Every mesh placed twice lost all its triangles (points, lines,
        // degenerate): nothing is instanced after all; the single-level file,
        // read again exactly as import_scene reads it (its warnings already given).
        bool placed_twice = false;
        for (const Placement& p : instanced.placements) placed_twice = placed_twice || p.source_node != kInvalidIndex;
        if (!placed_twice) {
            is_instanced = false;
            instanced = InstancedScene{};
            std::vector<std::string> again;
            return import_scene(paths, options, flat, again);
        }
    } catch (const std::bad_alloc&) {
        return Result::fail(Status::kBadInput, 0, path + ": out of memory while importing");
    } catch (const std::exception& e) {
        return Result::fail(Status::kBadInput, 0, path + ": unexpected error while importing: " + e.what());
    }
    return Result::success();
}

}  // namespace cwbvh::compiler
