// tinygltf adapter: glTF 2.0 (.gltf/.glb) -> RawInput. The only file that
// includes tinygltf (and compiles its implementation).
//
// Deliberately NOT compiled with TINYGLTF_ENABLE_DRACO: tinygltf 2.7's
// ParseDracoExtension indexes bufferViews/buffers/accessors with JSON-supplied
// integers without range checks, dereferences a null attribute pointer for an
// unknown Draco attribute id, and ignores decode failures. Instead the
// KHR_draco_mesh_compression extension is left in primitive.extensions and we
// decode it ourselves (decode_draco_mesh in import_draco.cpp) after checking
// every index and range, then check the decoded counts against the accessors.
//
// tinygltf only parses: every accessor, buffer view and index is validated
// here before it is read (no out-of-bounds read for any input). Sparse
// accessors are parsed but not applied by tinygltf 2.7; we apply them.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cctype>
#include <cstring>
#include <limits>
#include <map>
#include <string_view>
#include <utility>

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#include "cwbvh/compiler/import.h"
#include "cwbvh/compiler/parallel_exact.h"
#include "cwbvh/format/file_io.h"

namespace cwbvh::compiler {
namespace {

namespace tg = tinygltf;

/// An accessor without a bufferView is all zeros (plus sparse values); its
/// count is not bounded by any buffer, so cap it to keep a hostile file from
/// allocating gigabytes.
constexpr size_t kMaxUnbackedCount = size_t(1) << 24;
constexpr size_t kMaxNodeVisits = size_t(1) << 22;

/// Geometry-neutral extensions that may appear in extensionsRequired.
bool extension_supported(const std::string& name) {
    if (name == "KHR_draco_mesh_compression" || name == "KHR_mesh_quantization") return true;
    // These change only materials, textures or lights: irrelevant to geometry.
    for (const char* prefix : {"KHR_materials_", "KHR_texture_", "EXT_texture_"})
        if (name.rfind(prefix, 0) == 0) return true;
    return name == "KHR_lights_punctual";
}

/// Image callback that never decodes anything (we need geometry only).
bool ignore_image(tg::Image*, const int, std::string*, std::string*, int, int,
                  const unsigned char*, int, void*) {
    return true;
}

int component_size(int component_type) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_BYTE:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
        case TINYGLTF_COMPONENT_TYPE_SHORT:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
        default: return 0;
    }
}

/// One component at `p` (little-endian host assumed, as everywhere in cwbvh),
/// converted to double. For normalized integers the glTF 2.0 spec
/// ("Animations"/"KHR_mesh_quantization": f = max(c / (2^(b-1)-1), -1.0) for
/// signed, f = c / (2^b - 1) for unsigned) is applied. The division is
/// rounded to nearest in double; the final float conversion rounds once more
/// to nearest, so the result is within an ulp of the exact value.
double read_component(const uint8_t* p, int component_type, bool normalized) {
    switch (component_type) {
        case TINYGLTF_COMPONENT_TYPE_BYTE: {
            int8_t v;
            std::memcpy(&v, p, 1);
            return normalized ? std::max(v / 127.0, -1.0) : double(v);
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
            uint8_t v;
            std::memcpy(&v, p, 1);
            return normalized ? v / 255.0 : double(v);
        }
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t v;
            std::memcpy(&v, p, 2);
            return normalized ? std::max(v / 32767.0, -1.0) : double(v);
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t v;
            std::memcpy(&v, p, 2);
            return normalized ? v / 65535.0 : double(v);
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
            uint32_t v;
            std::memcpy(&v, p, 4);
            return double(v);
        }
        case TINYGLTF_COMPONENT_TYPE_FLOAT: {
            float v;
            std::memcpy(&v, p, 4);
            return double(v);
        }
        default: return 0.0;
    }
}

/// The glTF's JSON text inside `bytes` (a GLB's first chunk, or the whole file); false
/// when a GLB's chunk does not fit (tinygltf then reports the malformed file).
bool json_text(const std::vector<uint8_t>& bytes, bool binary, size_t& begin, size_t& size) {
    begin = 0;
    size = bytes.size();
    if (!binary) return true;
    if (bytes.size() < 20) return false;
    uint32_t chunk0 = 0;
    std::memcpy(&chunk0, bytes.data() + 12, 4);
    if (chunk0 > bytes.size() - 20) return false;
    begin = 20;
    size = chunk0;
    return true;
}

/// Deepest nesting of JSON arrays and objects cwbvhc reads. tinygltf converts `extras` and
/// extension values recursively (ParseJsonAsValue): about 30,000 nested brackets in a
/// 100 KB file overflowed the stack (SIGSEGV). glTF itself nests about 6 deep; 512 leaves
/// user `extras` ample room.
constexpr int kMaxJsonDepth = 512;

/// Whether the JSON text nests deeper than kMaxJsonDepth: a scan of brackets outside strings
/// (backslash escapes skipped), before any parser recurses. Malformed JSON that does not nest
/// too deep passes, for tinygltf to report.
bool json_too_deep(const char* text, size_t size) {
    int depth = 0;
    bool in_string = false;
    for (size_t i = 0; i < size; ++i) {
        const char c = text[i];
        if (in_string) {
            if (c == '\\') ++i;
            else if (c == '"') in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            if (++depth > kMaxJsonDepth) return true;
        } else if ((c == ']' || c == '}') && depth > 0) {  // a stray closer does not buy depth
            --depth;
        }
    }
    return false;
}

/// (mesh, primitive) -> indices accessor of KHR_draco_mesh_compression
/// primitives (see strip_draco_indices).
using DracoIndices = std::map<std::pair<size_t, size_t>, int>;

/// tinygltf 2.7 without TINYGLTF_ENABLE_DRACO rejects a primitive whose
/// indices accessor has no bufferView ("accessor[i] invalid bufferView"),
/// which is exactly what KHR_draco_mesh_compression primitives have. So,
/// before tinygltf sees the JSON, remove "indices" from every Draco
/// primitive and remember it in `table`; the reader checks it against the
/// decoded data. Rebuilds `bytes` when something was removed; on any parse
/// problem leaves them unchanged and lets tinygltf report the error.
void strip_draco_indices(std::vector<uint8_t>& bytes, bool binary, DracoIndices& table) {
    static const std::string kExt = "KHR_draco_mesh_compression";
    size_t json_begin = 0, json_size = 0;
    if (!json_text(bytes, binary, json_begin, json_size)) return;
    const char* text = reinterpret_cast<const char*>(bytes.data()) + json_begin;
    if (std::string_view(text, json_size).find(kExt) == std::string_view::npos) return;
    nlohmann::json doc = nlohmann::json::parse(text, text + json_size, nullptr, false);
    if (doc.is_discarded() || !doc.is_object()) return;
    auto meshes = doc.find("meshes");
    if (meshes == doc.end() || !meshes->is_array()) return;
    bool changed = false;
    for (size_t m = 0; m < meshes->size(); ++m) {
        nlohmann::json& mesh = (*meshes)[m];
        if (!mesh.is_object() || !mesh.contains("primitives") || !mesh["primitives"].is_array())
            continue;
        nlohmann::json& prims = mesh["primitives"];
        for (size_t k = 0; k < prims.size(); ++k) {
            nlohmann::json& prim = prims[k];
            if (!prim.is_object() || !prim.contains("extensions") ||
                !prim["extensions"].is_object() || !prim["extensions"].contains(kExt) ||
                !prim.contains("indices") || !prim["indices"].is_number_integer())
                continue;
            const int64_t idx = prim["indices"].get<int64_t>();
            table[{m, k}] = idx >= 0 && idx <= std::numeric_limits<int>::max() ? int(idx) : -2;
            prim.erase("indices");
            changed = true;
        }
    }
    if (!changed) return;
    std::string json = doc.dump();
    if (!binary) {
        bytes.assign(json.begin(), json.end());
        return;
    }
    while (json.size() % 4 != 0) json.push_back(' ');  // GLB chunks are 4-aligned
    const size_t rest_begin = json_begin + json_size;
    std::vector<uint8_t> out(bytes.begin(), bytes.begin() + 12);
    const uint32_t chunk_len = uint32_t(json.size()), chunk_type = 0x4E4F534A;  // "JSON"
    out.insert(out.end(), reinterpret_cast<const uint8_t*>(&chunk_len),
               reinterpret_cast<const uint8_t*>(&chunk_len) + 4);
    out.insert(out.end(), reinterpret_cast<const uint8_t*>(&chunk_type),
               reinterpret_cast<const uint8_t*>(&chunk_type) + 4);
    out.insert(out.end(), json.begin(), json.end());
    out.insert(out.end(), bytes.begin() + std::ptrdiff_t(rest_begin), bytes.end());
    const uint32_t total = uint32_t(out.size());
    std::memcpy(out.data() + 8, &total, 4);
    bytes = std::move(out);
}

/// Elements per task of the importer's parallel loops (each element is
/// independent: the result does not depend on it).
constexpr size_t kImportGrain = 16384;

/// Local (untransformed) geometry of one primitive, decoded once and shared
/// by every node that instances the mesh.
struct LocalPrimitive {
    bool decoded = false;
    bool skipped = false;
    std::vector<double> positions;  ///< x, y, z per vertex
    std::vector<std::array<uint32_t, 3>> triangles;
    /// Nodes that still have to emit this mesh (counted over all nodes; the
    /// last one takes `triangles` instead of a copy).
    size_t uses_left = 0;
};

class GltfReader {
public:
    GltfReader(const tg::Model& model, const DracoIndices& draco_indices,
               const ImportOptions& options, std::vector<std::string>& warnings)
        : model_(model), draco_indices_(draco_indices), options_(options), warnings_(warnings) {}

    /// `instanced` (optional): keep instancing when some mesh is placed twice
    /// (then `*is_instanced` is set and `out` stays empty).
    bool run(RawInput& out, std::string& error, RawInstanced* instanced = nullptr, bool* is_instanced = nullptr);

private:
    /// A validated view of accessor data: element i starts at
    /// base + i * stride (base == nullptr: all zeros).
    struct View {
        const uint8_t* base = nullptr;
        size_t stride = 0;
    };

    bool byte_range(int buffer_view, size_t offset, size_t elem_size, size_t stride, size_t count,
                    const std::string& what, View& out, std::string& error) const;
    /// T: double (positions) or uint32_t (indices: every value is an
    /// unsigned integer below 2^32, exact either way).
    template <class T>
    bool read_accessor(int index, int type, int components, bool indices, size_t min_count,
                       std::vector<T>& out, size_t& count, std::string& error) const;
    bool decode_primitive(size_t mesh, size_t prim, LocalPrimitive& lp, RawInput& out,
                          std::string& error);
    bool emit_mesh(int mesh, const glm::dmat4& world, RawInput& out, std::string& error);
    bool local_matrix(size_t node, glm::dmat4& m, std::string& error) const;
    /// One node that places a mesh, found by the walk.
    struct Placed {
        size_t node;
        int mesh;
        glm::dmat4 world;
    };
    bool emit_instanced(const std::vector<Placed>& placed, RawInstanced& out, std::string& error);
    bool quantization_used() const {
        return std::find(model_.extensionsUsed.begin(), model_.extensionsUsed.end(),
                         "KHR_mesh_quantization") != model_.extensionsUsed.end();
    }

    const tg::Model& model_;
    const DracoIndices& draco_indices_;
    const ImportOptions& options_;
    std::vector<std::string>& warnings_;
    std::vector<std::vector<LocalPrimitive>> cache_;
};

bool GltfReader::byte_range(int buffer_view, size_t offset, size_t elem_size, size_t stride,
                            size_t count, const std::string& what, View& out,
                            std::string& error) const {
    if (buffer_view < 0 || size_t(buffer_view) >= model_.bufferViews.size()) {
        error = what + ": bufferView " + std::to_string(buffer_view) + " does not exist";
        return false;
    }
    const tg::BufferView& bv = model_.bufferViews[size_t(buffer_view)];
    if (bv.buffer < 0 || size_t(bv.buffer) >= model_.buffers.size()) {
        error = what + ": bufferView " + std::to_string(buffer_view) + " names buffer " +
                std::to_string(bv.buffer) + ", which does not exist";
        return false;
    }
    const size_t buffer_size = model_.buffers[size_t(bv.buffer)].data.size();
    if (bv.byteOffset > buffer_size || bv.byteLength > buffer_size - bv.byteOffset) {
        error = what + ": bufferView " + std::to_string(buffer_view) + " (offset " +
                std::to_string(bv.byteOffset) + ", length " + std::to_string(bv.byteLength) +
                ") does not fit its buffer of " + std::to_string(buffer_size) + " bytes";
        return false;
    }
    if (stride < elem_size) {
        error = what + ": byteStride " + std::to_string(stride) +
                " is smaller than the element size " + std::to_string(elem_size);
        return false;
    }
    if (count > 0) {
        // offset + (count-1)*stride + elem_size <= byteLength, overflow-safe.
        const size_t len = bv.byteLength;
        const bool fits = offset <= len && elem_size <= len - offset &&
                          (count - 1) <= (len - offset - elem_size) / stride;
        if (!fits) {
            error = what + ": " + std::to_string(count) + " elements of " +
                    std::to_string(elem_size) + " bytes (stride " + std::to_string(stride) +
                    ", offset " + std::to_string(offset) + ") overrun bufferView " +
                    std::to_string(buffer_view) + " of " + std::to_string(len) + " bytes";
            return false;
        }
    }
    out.base = model_.buffers[size_t(bv.buffer)].data.data() + bv.byteOffset + offset;
    out.stride = stride;
    return true;
}

/// Reads accessor `index` (of glTF `type` with `components` components) into
/// `out` (count * components values of type T), applying sparse substitution. For
/// indices only unsigned byte/short/int are allowed, else float or (with
/// KHR_mesh_quantization) 8/16-bit integers.
template <class T>
bool GltfReader::read_accessor(int index, int type, int components, bool indices,
                               size_t min_count, std::vector<T>& out, size_t& count,
                               std::string& error) const {
    const std::string what = "accessor " + std::to_string(index);
    if (index < 0 || size_t(index) >= model_.accessors.size()) {
        error = what + " does not exist";
        return false;
    }
    const tg::Accessor& acc = model_.accessors[size_t(index)];
    if (acc.type != type) {
        error = what + " has type " + std::to_string(acc.type) + ", expected " +
                (indices ? "SCALAR" : "VEC3");
        return false;
    }
    const int ct = acc.componentType;
    const int csize = component_size(ct);
    bool ct_ok;
    if (indices) {
        ct_ok = ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ||
                ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    } else if (ct == TINYGLTF_COMPONENT_TYPE_FLOAT) {
        ct_ok = true;
    } else {
        ct_ok = csize == 1 || csize == 2;  // (u)int8/16: KHR_mesh_quantization
        if (ct_ok && !quantization_used()) {
            if (!options_.permissive) {
                error = what + ": integer POSITION needs KHR_mesh_quantization in extensionsUsed";
                return false;
            }
            warnings_.push_back(what + ": integer POSITION without KHR_mesh_quantization");
        }
    }
    if (!ct_ok || csize == 0) {
        error = what + " has unsupported componentType " + std::to_string(ct);
        return false;
    }
    count = acc.count;
    if (count < min_count) {
        error = what + " has count " + std::to_string(count) + ", expected at least " +
                std::to_string(min_count);
        return false;
    }
    const size_t elem = size_t(csize) * size_t(components);
    View view;
    if (acc.bufferView >= 0) {
        size_t stride = elem;
        const size_t bv = size_t(acc.bufferView);
        if (bv < model_.bufferViews.size() && model_.bufferViews[bv].byteStride != 0) {
            stride = model_.bufferViews[bv].byteStride;
            if (stride % size_t(csize) != 0 || stride > 252) {
                error = what + ": bufferView " + std::to_string(bv) + " has invalid byteStride " +
                        std::to_string(stride);
                return false;
            }
        }
        if (!byte_range(acc.bufferView, acc.byteOffset, elem, stride, count, what, view, error))
            return false;
    } else if (count > kMaxUnbackedCount) {
        error = what + " has no bufferView and count " + std::to_string(count) + " (limit " +
                std::to_string(kMaxUnbackedCount) + ")";
        return false;
    }
    if (view.base == nullptr) {
        out.assign(count * size_t(components), T(0));
    } else {
        out.resize(count * size_t(components));
        // Not normalized (indices, float positions, integer positions
        // without normalization): T(c) is T(double(c)), read_component's
        // value, without its switch per component.
        auto direct = [&](auto zero) {
            using C = decltype(zero);
            // Each element on its own: in parallel, the same values.
            tbb::parallel_for(tbb::blocked_range<size_t>(0, count, kImportGrain), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i != r.end(); ++i) {
                    const uint8_t* p = view.base + i * view.stride;
                    for (int c = 0; c < components; ++c) {
                        C v;
                        std::memcpy(&v, p + size_t(c) * sizeof(C), sizeof(C));
                        out[i * size_t(components) + size_t(c)] = T(v);
                    }
                }
            });
        };
        if (acc.normalized && ct != TINYGLTF_COMPONENT_TYPE_FLOAT) {
            for (size_t i = 0; i < count; ++i) {
                const uint8_t* p = view.base + i * view.stride;
                for (int c = 0; c < components; ++c)
                    out[i * size_t(components) + size_t(c)] =
                        T(read_component(p + size_t(c) * size_t(csize), ct, true));
            }
        } else {
            switch (ct) {
                case TINYGLTF_COMPONENT_TYPE_BYTE: direct(int8_t{}); break;
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: direct(uint8_t{}); break;
                case TINYGLTF_COMPONENT_TYPE_SHORT: direct(int16_t{}); break;
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: direct(uint16_t{}); break;
                case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: direct(uint32_t{}); break;
                default: direct(float{}); break;  // FLOAT: the only other type ct_ok admits
            }
        }
    }
    if (acc.sparse.isSparse) {
        const auto& sp = acc.sparse;
        if (sp.count < 0 || size_t(sp.count) > count) {
            error = what + ": sparse count " + std::to_string(sp.count) + " exceeds count " +
                    std::to_string(count);
            return false;
        }
        const size_t n = size_t(sp.count);
        const int ict = sp.indices.componentType;
        if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
            ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
            error = what + ": sparse indices have invalid componentType " + std::to_string(ict);
            return false;
        }
        const size_t isize = size_t(component_size(ict));
        View iv, vv;
        if (sp.indices.byteOffset < 0 || sp.values.byteOffset < 0 ||
            !byte_range(sp.indices.bufferView, size_t(sp.indices.byteOffset), isize, isize, n,
                        what + " sparse indices", iv, error) ||
            !byte_range(sp.values.bufferView, size_t(sp.values.byteOffset), elem, elem, n,
                        what + " sparse values", vv, error)) {
            if (error.empty()) error = what + ": negative sparse byteOffset";
            return false;
        }
        for (size_t k = 0; k < n; ++k) {
            const double di = read_component(iv.base + k * isize, ict, false);
            if (di >= double(count)) {
                error = what + ": sparse index " + std::to_string(uint64_t(di)) +
                        " out of range (count " + std::to_string(count) + ")";
                return false;
            }
            const size_t i = size_t(di);
            for (int c = 0; c < components; ++c)
                out[i * size_t(components) + size_t(c)] =
                    T(read_component(vv.base + k * elem + size_t(c) * size_t(csize), ct,
                                     acc.normalized));
        }
    }
    return true;
}

std::string prim_name(size_t mesh, size_t prim) {
    return "mesh " + std::to_string(mesh) + " primitive " + std::to_string(prim);
}

bool GltfReader::decode_primitive(size_t mesh, size_t prim, LocalPrimitive& lp, RawInput& out,
                                  std::string& error) {
    lp.decoded = true;
    const tg::Primitive& p = model_.meshes[mesh].primitives[prim];
    const std::string name = prim_name(mesh, prim);
    switch (p.mode) {
        case TINYGLTF_MODE_POINTS: ++out.skipped_primitives["points"]; lp.skipped = true; return true;
        case TINYGLTF_MODE_LINE: ++out.skipped_primitives["lines"]; lp.skipped = true; return true;
        case TINYGLTF_MODE_LINE_LOOP: ++out.skipped_primitives["line_loop"]; lp.skipped = true; return true;
        case TINYGLTF_MODE_LINE_STRIP: ++out.skipped_primitives["line_strip"]; lp.skipped = true; return true;
        case TINYGLTF_MODE_TRIANGLES:
        case TINYGLTF_MODE_TRIANGLE_STRIP:
        case TINYGLTF_MODE_TRIANGLE_FAN: break;
        default: error = name + ": unknown mode " + std::to_string(p.mode); return false;
    }
    const auto pos_it = p.attributes.find("POSITION");
    if (pos_it == p.attributes.end()) {
        warnings_.push_back(name + ": no POSITION attribute, skipped");
        ++out.skipped_primitives["no_position"];
        lp.skipped = true;
        return true;
    }
    const int pos_acc = pos_it->second;

    const auto draco_it = p.extensions.find("KHR_draco_mesh_compression");
    if (draco_it != p.extensions.end()) {
        // KHR_draco_mesh_compression: decode the compressed bufferView; the
        // accessors only describe the decoded data (count, type).
        // (tinygltf's Value::Get(key) asserts IsObject(): check first.)
        const tg::Value& ext = draco_it->second;
        static const tg::Value kNull;
        const tg::Value& bv_value = ext.IsObject() ? ext.Get("bufferView") : kNull;
        const tg::Value& attrs = ext.IsObject() ? ext.Get("attributes") : kNull;
        if (!bv_value.IsInt() || !attrs.IsObject() || !attrs.Get("POSITION").IsInt()) {
            error = name + ": malformed KHR_draco_mesh_compression object";
            return false;
        }
        if (p.mode == TINYGLTF_MODE_TRIANGLE_FAN) {
            error = name + ": KHR_draco_mesh_compression with TRIANGLE_FAN mode";
            return false;
        }
        View view;
        const int bv = bv_value.Get<int>();
        if (bv < 0 || size_t(bv) >= model_.bufferViews.size()) {
            error = name + ": Draco bufferView " + std::to_string(bv) + " does not exist";
            return false;
        }
        const size_t length = model_.bufferViews[size_t(bv)].byteLength;
        if (!byte_range(bv, 0, 1, 1, length, name + " Draco data", view, error)) return false;
        std::vector<Vec3> verts;
        if (const Result r = decode_draco_mesh(view.base, length, attrs.Get("POSITION").Get<int>(), verts,
                                               lp.triangles);
            !r.ok()) {
            error = name + ": " + r.message;
            return false;
        }
        // Check the decoded sizes against what the accessors announce.
        if (pos_acc < 0 || size_t(pos_acc) >= model_.accessors.size()) {
            error = name + ": POSITION accessor " + std::to_string(pos_acc) + " does not exist";
            return false;
        }
        std::string mismatch;
        if (model_.accessors[size_t(pos_acc)].count != verts.size())
            mismatch = "POSITION accessor count " +
                       std::to_string(model_.accessors[size_t(pos_acc)].count) +
                       " but Draco decoded " + std::to_string(verts.size()) + " points";
        const auto di = draco_indices_.find({mesh, prim});
        const int indices = di != draco_indices_.end() ? di->second : p.indices;
        if (indices != -1) {
            if (indices < 0 || size_t(indices) >= model_.accessors.size()) {
                error = name + ": indices accessor " + std::to_string(indices) +
                        " does not exist";
                return false;
            }
            if (model_.accessors[size_t(indices)].count != 3 * lp.triangles.size())
                mismatch = "indices accessor count " +
                           std::to_string(model_.accessors[size_t(indices)].count) +
                           " but Draco decoded " + std::to_string(lp.triangles.size()) +
                           " triangles";
        }
        if (!mismatch.empty()) {
            if (!options_.permissive) {
                error = name + ": " + mismatch;
                return false;
            }
            warnings_.push_back(name + ": " + mismatch);
        }
        lp.positions.resize(3 * verts.size());
        for (size_t i = 0; i < verts.size(); ++i)
            for (int a = 0; a < 3; ++a) lp.positions[3 * i + size_t(a)] = verts[i][a];
        return true;
    }

    size_t nv = 0;
    if (!read_accessor(pos_acc, TINYGLTF_TYPE_VEC3, 3, false, 0, lp.positions, nv, error)) {
        error = name + " POSITION: " + error;
        return false;
    }
    if (nv >= kInvalidIndex) {
        error = name + ": too many vertices";
        return false;
    }

    std::vector<uint32_t> idx;
    if (p.indices >= 0) {
        size_t n = 0;
        if (!read_accessor(p.indices, TINYGLTF_TYPE_SCALAR, 1, true, 0, idx, n, error)) {
            error = name + " indices: " + error;
            return false;
        }
        const size_t i = lowest_failing(n, kImportGrain, [&](size_t k) { return idx[k] >= nv; });
        if (i < n) {  // the first out-of-range index reports, as a serial scan would
            error = name + ": index " + std::to_string(idx[i]) + " at position " + std::to_string(i) +
                    " is out of range (" + std::to_string(nv) + " vertices)";
            return false;
        }
    } else {
        idx.resize(nv);
        for (size_t i = 0; i < nv; ++i) idx[i] = uint32_t(i);
    }
    const size_t n = idx.size();
    lp.triangles.reserve(p.mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : (n >= 2 ? n - 2 : 0));
    // Triangulation exactly as the glTF 2.0 spec ("Meshes", primitive modes).
    if (p.mode == TINYGLTF_MODE_TRIANGLES) {
        if (n % 3 != 0)
            warnings_.push_back(name + ": " + std::to_string(n) +
                                " indices is not a multiple of 3; the rest is ignored");
        lp.triangles.resize(n / 3);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n / 3, kImportGrain), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t t = r.begin(); t != r.end(); ++t) lp.triangles[t] = {idx[3 * t], idx[3 * t + 1], idx[3 * t + 2]};
        });
    } else if (p.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        // p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}: alternate winding.
        for (size_t i = 0; i + 2 < n; ++i)
            lp.triangles.push_back({idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]});
    } else {
        // p_i = {v_{i+1}, v_{i+2}, v_0}.
        for (size_t i = 0; i + 2 < n; ++i) lp.triangles.push_back({idx[i + 1], idx[i + 2], idx[0]});
    }
    return true;
}

bool GltfReader::emit_mesh(int mesh, const glm::dmat4& world, RawInput& out,
                           std::string& error) {
    if (mesh < 0 || size_t(mesh) >= model_.meshes.size()) {
        error = "mesh " + std::to_string(mesh) + " does not exist";
        return false;
    }
    const size_t m = size_t(mesh);
    for (size_t k = 0; k < model_.meshes[m].primitives.size(); ++k) {
        LocalPrimitive& lp = cache_[m][k];
        if (!lp.decoded && !decode_primitive(m, k, lp, out, error)) return false;
        if (lp.skipped) continue;
        RawPrimitive rp;
        rp.mesh = uint32_t(m);
        rp.primitive = uint32_t(k);
        const size_t nv = lp.positions.size() / 3;
        rp.vertices.resize(nv);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nv, kImportGrain), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const double* q = &lp.positions[3 * i];
                const glm::dvec4 w = world * glm::dvec4(q[0], q[1], q[2], 1.0);
                // Composition and transform in double; one final round to
                // nearest float (identity transforms reproduce float input
                // exactly). Per vertex: the same bits in parallel.
                rp.vertices[i] = {float(w.x), float(w.y), float(w.z)};
            }
        });
        // The last node that names the mesh takes its triangles instead of a
        // copy; the cache entry is then reset, so that a further instance
        // (a node of several parents, permissive mode) decodes it again.
        if (--lp.uses_left == 0) {
            rp.triangles = std::move(lp.triangles);
            lp = LocalPrimitive{};
        } else {
            rp.triangles = lp.triangles;
        }
        out.primitives.push_back(std::move(rp));
    }
    return true;
}

bool GltfReader::local_matrix(size_t node, glm::dmat4& m, std::string& error) const {
    const tg::Node& n = model_.nodes[node];
    const std::string name = "node " + std::to_string(node);
    auto finite = [](const std::vector<double>& v) {
        return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
    };
    if (!finite(n.matrix) || !finite(n.translation) || !finite(n.rotation) || !finite(n.scale)) {
        error = name + " has a non-finite transform";
        return false;
    }
    if (!n.matrix.empty()) {
        if (n.matrix.size() != 16) {
            error = name + ": matrix has " + std::to_string(n.matrix.size()) + " entries";
            return false;
        }
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) m[c][r] = n.matrix[size_t(c * 4 + r)];  // column-major
        return true;
    }
    if ((!n.translation.empty() && n.translation.size() != 3) ||
        (!n.rotation.empty() && n.rotation.size() != 4) ||
        (!n.scale.empty() && n.scale.size() != 3)) {
        error = name + ": translation/rotation/scale has the wrong number of entries";
        return false;
    }
    glm::dmat4 t(1.0), r(1.0), s(1.0);
    if (!n.translation.empty())
        t[3] = glm::dvec4(n.translation[0], n.translation[1], n.translation[2], 1.0);
    if (!n.rotation.empty()) {
        // glTF stores (x, y, z, w); glm::dquat's constructor takes (w, x, y, z).
        glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);
        const double len = glm::length(q);
        if (!(len > 0.0)) {
            error = name + ": rotation quaternion is zero";
            return false;
        }
        r = glm::mat4_cast(q / len);
    }
    if (!n.scale.empty()) {
        s[0][0] = n.scale[0];
        s[1][1] = n.scale[1];
        s[2][2] = n.scale[2];
    }
    m = t * r * s;
    return true;
}

bool GltfReader::run(RawInput& out, std::string& error, RawInstanced* instanced, bool* is_instanced) {
    cache_.resize(model_.meshes.size());
    for (size_t m = 0; m < model_.meshes.size(); ++m)
        cache_[m].resize(model_.meshes[m].primitives.size());
    // How many nodes name each mesh (all nodes, reachable or not): the
    // emissions each cache entry serves before its last one.
    auto count_use = [&](size_t m) {
        for (LocalPrimitive& lp : cache_[m]) ++lp.uses_left;
    };
    if (model_.scenes.empty()) {
        for (size_t m = 0; m < model_.meshes.size(); ++m) count_use(m);
    } else {
        for (const tg::Node& node : model_.nodes)
            if (node.mesh >= 0 && size_t(node.mesh) < model_.meshes.size()) count_use(size_t(node.mesh));
    }

    if (model_.scenes.empty()) {
        // No scene: every mesh once with the identity transform.
        for (size_t m = 0; m < model_.meshes.size(); ++m)
            if (!emit_mesh(int(m), glm::dmat4(1.0), out, error)) return false;
        return true;
    }
    size_t scene = 0;
    if (model_.defaultScene >= 0) {
        if (size_t(model_.defaultScene) >= model_.scenes.size()) {
            error = "default scene " + std::to_string(model_.defaultScene) + " does not exist";
            return false;
        }
        scene = size_t(model_.defaultScene);
    }
    // Iterative depth-first walk (no recursion: depth is attacker-controlled).
    // state: 0 unvisited, 1 on the current path, 2 finished.
    std::vector<uint8_t> state(model_.nodes.size(), 0);
    struct Frame {
        size_t node;
        size_t next_child;
        glm::dmat4 world;
    };
    std::vector<Frame> stack;
    std::vector<Placed> placed;  // only with `instanced`
    size_t visits = 0;
    auto enter = [&](int node, const glm::dmat4& parent) -> bool {
        if (node < 0 || size_t(node) >= model_.nodes.size()) {
            error = "node " + std::to_string(node) + " does not exist";
            return false;
        }
        const size_t n = size_t(node);
        if (state[n] == 1) {
            error = "node " + std::to_string(n) + " is its own ancestor (recursive node graph)";
            return false;
        }
        if (state[n] == 2) {
            if (!options_.permissive) {
                error = "node " + std::to_string(n) +
                        " has more than one parent (the node graph must be a forest)";
                return false;
            }
            warnings_.push_back("node " + std::to_string(n) + " has more than one parent");
        }
        if (++visits > kMaxNodeVisits) {
            error = "more than " + std::to_string(kMaxNodeVisits) + " node instances";
            return false;
        }
        glm::dmat4 local(1.0);
        if (!local_matrix(n, local, error)) return false;
        state[n] = 1;
        stack.push_back(Frame{n, 0, parent * local});
        const int mesh = model_.nodes[n].mesh;
        if (mesh < 0) return true;
        if (instanced) {  // decided once the walk is done
            placed.push_back(Placed{n, mesh, stack.back().world});
            return true;
        }
        return emit_mesh(mesh, stack.back().world, out, error);
    };
    for (int root : model_.scenes[scene].nodes) {
        if (!enter(root, glm::dmat4(1.0))) return false;
        while (!stack.empty()) {
            Frame& f = stack.back();
            const auto& children = model_.nodes[f.node].children;
            if (f.next_child < children.size()) {
                const int child = children[f.next_child++];
                const glm::dmat4 world = f.world;  // `f` dies if the stack grows
                if (!enter(child, world)) return false;
            } else {
                state[f.node] = 2;
                stack.pop_back();
            }
        }
    }
    if (!instanced) return true;
    // Policy (issue 19): instances only when some mesh is placed twice;
    // otherwise the placements are emitted in walk order, as without `instanced`.
    std::vector<uint32_t> uses(model_.meshes.size(), 0);
    bool shared = false;
    for (const Placed& p : placed)
        if (p.mesh >= 0 && size_t(p.mesh) < uses.size()) shared = ++uses[size_t(p.mesh)] > 1 || shared;
    if (!shared) {
        for (const Placed& p : placed)
            if (!emit_mesh(p.mesh, p.world, out, error)) return false;
        return true;
    }
    *is_instanced = true;
    return emit_instanced(placed, *instanced, error);
}

bool GltfReader::emit_instanced(const std::vector<Placed>& placed, RawInstanced& out, std::string& error) {
    std::vector<uint32_t> uses(model_.meshes.size(), 0), bottom(model_.meshes.size(), kInvalidIndex);
    for (const Placed& p : placed) {
        if (p.mesh < 0 || size_t(p.mesh) >= model_.meshes.size()) {
            error = "mesh " + std::to_string(p.mesh) + " does not exist";
            return false;
        }
        ++uses[size_t(p.mesh)];
    }
    // Every mesh is emitted exactly once below: its last (only) use takes the
    // decoded triangles instead of a copy.
    for (auto& mesh : cache_)
        for (LocalPrimitive& lp : mesh) lp.uses_left = 1;
    for (size_t m = 0; m < uses.size(); ++m) {
        if (uses[m] < 2) continue;
        bottom[m] = uint32_t(out.meshes.size());
        out.meshes.emplace_back();
        out.source_mesh.push_back(uint32_t(m));
        // Object space: the identity reproduces the float input exactly.
        if (!emit_mesh(int(m), glm::dmat4(1.0), out.meshes.back(), error)) return false;
    }
    RawInput merged;
    for (const Placed& p : placed) {
        const size_t m = size_t(p.mesh);
        if (uses[m] >= 2) {
            RawPlacement rp;
            rp.node = uint32_t(p.node);
            rp.mesh = bottom[m];
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 4; ++c) rp.object_to_world[size_t(4 * r + c)] = p.world[c][r];  // glm: [column][row]
            out.placements.push_back(rp);
        } else if (!emit_mesh(p.mesh, p.world, merged, error)) {
            return false;
        }
    }
    if (!merged.primitives.empty() || !merged.skipped_primitives.empty()) {
        RawPlacement rp;
        rp.mesh = uint32_t(out.meshes.size());
        out.meshes.push_back(std::move(merged));
        out.source_mesh.push_back(kInvalidIndex);
        out.placements.push_back(rp);
    }
    return true;
}

/// tinygltf's file access for external buffers. Its defaults expand the path with wordexp() (which
/// performs $(...) substitution) and fall back to the current directory; ours take the path as
/// written and read only a URI that is relative, has no ".." component (unless the option allows
/// it) and names a regular file (read_regular_file: no FIFO, no device) in the input's folder.
struct ExternalFiles {
    std::string prefix;  ///< the base directory tinygltf joins the URI to, with its '/'
    bool allow_parent = false;
    std::string refused;  ///< why the first refused URI was refused
};

/// True when tinygltf's joined path `joined` (prefix + decoded URI) may be read.
bool uri_allowed(ExternalFiles& x, const std::string& joined) {
    if (joined.compare(0, x.prefix.size(), x.prefix) != 0) return false;  // the current-directory fallback
    const std::string uri = joined.substr(x.prefix.size());
    auto refuse = [&](const std::string& why) {
        if (x.refused.empty()) x.refused = "buffer URI '" + uri + "' " + why;
        return false;
    };
    if (!uri.empty() && uri[0] == '/') return refuse("is absolute; buffers must lie in the input's folder");
    if (!x.allow_parent) {
        size_t start = 0;
        while (start <= uri.size()) {
            size_t end = uri.find('/', start);
            if (end == std::string::npos) end = uri.size();
            if (uri.compare(start, end - start, "..") == 0 && end - start == 2)
                return refuse("leaves the input's folder ('..'); cwbvhc --allow-parent-uris allows it");
            start = end + 1;
        }
    }
    return true;
}

bool external_exists(const std::string& path, void* user) {
    if (!uri_allowed(*static_cast<ExternalFiles*>(user), path)) return false;
    return ::access(path.c_str(), F_OK) == 0;
}

std::string external_expand(const std::string& path, void*) { return path; }

bool external_read(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
    if (!uri_allowed(*static_cast<ExternalFiles*>(user), path)) return false;
    const Result r = read_regular_file(path, UINT64_MAX, *out);
    if (!r.ok() && err != nullptr) *err = r.message;
    return r.ok();
}

bool external_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err != nullptr) *err = "cwbvhc writes no glTF files";
    return false;
}

std::vector<std::string> split_lines(const std::string& text) {
    std::vector<std::string> lines;
    size_t start = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        if (end > start) lines.push_back(text.substr(start, end - start));
        start = end + 1;
    }
    return lines;
}

}  // namespace

std::vector<std::string> gltf_referenced_files(const std::string& path) {
    std::vector<std::string> out;
    std::vector<uint8_t> bytes;
    if (!read_file_bytes(path, bytes).ok()) return out;
    const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
    size_t begin = 0, size = 0;
    if (!json_text(bytes, binary, begin, size)) return out;
    const char* text = reinterpret_cast<const char*>(bytes.data()) + begin;
    if (json_too_deep(text, size)) return out;
    const nlohmann::json doc = nlohmann::json::parse(text, text + size, nullptr, false);
    if (doc.is_discarded() || !doc.is_object()) return out;
    const size_t slash = path.find_last_of('/');
    const std::string dir = slash == std::string::npos ? "" : path.substr(0, slash + 1);
    auto percent_decoded = [](const std::string& uri) {
        std::string d;
        for (size_t i = 0; i < uri.size(); ++i) {
            if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
                std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
                d.push_back(char(std::stoi(uri.substr(i + 1, 2), nullptr, 16)));
                i += 2;
            } else {
                d.push_back(uri[i]);
            }
        }
        return d;
    };
    for (const char* key : {"buffers", "images"}) {
        const auto list = doc.find(key);
        if (list == doc.end() || !list->is_array()) continue;
        for (const nlohmann::json& item : *list) {
            if (!item.is_object() || !item.contains("uri") || !item["uri"].is_string()) continue;
            const std::string uri = item["uri"].get<std::string>();
            if (uri.empty() || uri.rfind("data:", 0) == 0) continue;
            if (out.size() >= kMaxReferencedFiles) return out;
            for (const std::string& u : {uri, percent_decoded(uri)})
                out.push_back(!u.empty() && u[0] == '/' ? u : dir + u);
        }
    }
    return out;
}

Result import_gltf(const std::string& path, const ImportOptions& options, RawInput& out,
                   std::vector<std::string>& warnings, RawInstanced* instanced, bool* is_instanced) {
    auto bad = [](std::string what) { return Result::fail(Status::kBadInput, 0, std::move(what)); };
    out = RawInput{};
    bool instanced_local = false;
    if (instanced) *instanced = RawInstanced{};
    if (!is_instanced) is_instanced = &instanced_local;
    *is_instanced = false;
    try {
        std::vector<uint8_t> bytes;
        if (Result r = read_file_bytes(path, bytes); !r.ok()) return r;
        const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
        if (size_t jb = 0, js = 0;
            json_text(bytes, binary, jb, js) && json_too_deep(reinterpret_cast<const char*>(bytes.data()) + jb, js))
            return bad("JSON nests arrays or objects more than " + std::to_string(kMaxJsonDepth) + " deep");
        DracoIndices draco_indices;
        strip_draco_indices(bytes, binary, draco_indices);
        if (bytes.size() >= std::numeric_limits<unsigned int>::max())
            return bad("file of 4 GiB or more (tinygltf limit)");
        const size_t slash = path.find_last_of('/');
        const std::string base_dir = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);

        tg::TinyGLTF loader;
        loader.SetImageLoader(&ignore_image, nullptr);
        ExternalFiles external{base_dir.back() == '/' ? base_dir : base_dir + "/", options.allow_parent_uris, ""};
        loader.SetFsCallbacks({&external_exists, &external_expand, &external_read, &external_write, &external});
        tg::Model model;
        std::string err, warn;
        const bool ok =
            binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(),
                                                 unsigned(bytes.size()), base_dir)
                   : loader.LoadASCIIFromString(&model, &err, &warn,
                                                reinterpret_cast<const char*>(bytes.data()),
                                                unsigned(bytes.size()), base_dir);
        std::vector<uint8_t>().swap(bytes);  // tinygltf holds its own copy of the buffers
        for (const std::string& w : split_lines(warn)) warnings.push_back("tinygltf: " + w);
        if (!ok && !external.refused.empty()) return bad(external.refused);
        if (!ok) {
            const auto lines = split_lines(err);
            return bad("not a valid glTF 2.0 file: " + (lines.empty() ? "tinygltf failed" : lines.front()));
        }
        for (const std::string& e : split_lines(err)) warnings.push_back("tinygltf: " + e);
        // glTF 1.0 (asset.version "1.0", or no asset: 1.0 made it optional) parses far enough
        // to give "no triangles"; say what it is instead.
        if (model.asset.version.empty() || model.asset.version[0] != '2')
            return bad("glTF version '" + model.asset.version + "' is not supported (glTF 2.0 only)");

        for (const std::string& ext : model.extensionsRequired) {
            if (extension_supported(ext)) continue;
            if (!options.permissive) return bad("required extension " + ext + " is not supported");
            warnings.push_back("required extension " + ext + " is not supported; ignored");
        }
        for (const std::string& ext : model.extensionsUsed)
            if (ext == "EXT_mesh_gpu_instancing" || ext == "EXT_meshopt_compression")
                warnings.push_back("extension " + ext +
                                   " is not supported; geometry may be incomplete");

        GltfReader reader(model, draco_indices, options, warnings);
        std::string error;
        if (!reader.run(out, error, instanced, is_instanced)) return bad(error);
        return Result::success();
    } catch (const std::bad_alloc&) {
        return bad("out of memory while reading glTF");
    } catch (const std::exception& e) {
        return bad(std::string("glTF error: ") + e.what());
    }
}

}  // namespace cwbvh::compiler
