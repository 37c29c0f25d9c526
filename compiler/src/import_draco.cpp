// Draco adapter (the only file that includes Draco): .drc files and the
// compressed buffer views of glTF KHR_draco_mesh_compression primitives.

#include <draco/compression/decode.h>
#include <draco/core/decoder_buffer.h>

#include "cwbvh/compiler/import.h"

namespace cwbvh::compiler {

Result decode_draco_mesh(const uint8_t* data, size_t size, int position_id,
                       std::vector<Vec3>& vertices,
                       std::vector<std::array<uint32_t, 3>>& triangles) {
    vertices.clear();
    triangles.clear();
    try {
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(data), size);
        auto type = draco::Decoder::GetEncodedGeometryType(&buffer);
        if (!type.ok()) return Result::fail(Status::kBadInput, 0, "Draco: " + type.status().error_msg_string());
        if (type.value() != draco::TRIANGULAR_MESH) {
            return Result::fail(Status::kBadInput, 0, "Draco data is a point cloud, not a triangle mesh");
        }
        draco::Decoder decoder;
        auto result = decoder.DecodeMeshFromBuffer(&buffer);
        if (!result.ok()) {
            return Result::fail(Status::kBadInput, 0, "Draco decode failed: " + result.status().error_msg_string());
        }
        const draco::Mesh& mesh = *result.value();
        const draco::PointAttribute* pos =
            position_id >= 0 ? mesh.GetAttributeByUniqueId(uint32_t(position_id))
                             : mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
        if (pos == nullptr) {
            return Result::fail(Status::kBadInput, 0, "Draco data has no position attribute" +
                    (position_id >= 0 ? " with id " + std::to_string(position_id) : std::string()));
        }
        if (pos->num_components() != 3) {
            return Result::fail(
                Status::kBadInput, 0,
                "Draco position attribute has " + std::to_string(pos->num_components()) + " components, expected 3");
        }
        const uint32_t num_points = mesh.num_points();
        if (!pos->is_mapping_identity() && pos->indices_map_size() < num_points) {
            return Result::fail(Status::kBadInput, 0, "Draco position attribute maps fewer points than the mesh has");
        }
        vertices.resize(num_points);
        for (uint32_t i = 0; i < num_points; ++i) {
            const draco::AttributeValueIndex avi = pos->mapped_index(draco::PointIndex(i));
            float v[3] = {0, 0, 0};
            // ConvertValue dequantizes (Draco's own quantization and normalized
            // integer attributes) to float.
            if (avi.value() >= pos->size() || !pos->ConvertValue<float>(avi, 3, v)) {
                return Result::fail(Status::kBadInput, 0,
                                    "Draco position of point " + std::to_string(i) + " cannot be read");
            }
            vertices[i] = {v[0], v[1], v[2]};
        }
        triangles.resize(mesh.num_faces());
        for (uint32_t f = 0; f < mesh.num_faces(); ++f) {
            const draco::Mesh::Face& face = mesh.face(draco::FaceIndex(f));
            for (int k = 0; k < 3; ++k) {
                const uint32_t v = face[k].value();
                if (v >= num_points) {
                    return Result::fail(Status::kBadInput, 0, "Draco face " + std::to_string(f) + " has vertex index " +
                            std::to_string(v) + " >= " + std::to_string(num_points));
                }
                triangles[f][k] = v;
            }
        }
    } catch (const std::bad_alloc&) {
        return Result::fail(Status::kBadInput, 0, "out of memory while decoding Draco data");
    } catch (const std::exception& e) {
        return Result::fail(Status::kBadInput, 0, std::string("Draco decode failed: ") + e.what());
    }
    return Result::success();
}

Result import_draco_file(const std::string& path, RawInput& out) {
    out = RawInput{};
    std::vector<uint8_t> bytes;
    if (Result r = read_file_bytes(path, bytes); !r.ok()) return r;
    RawPrimitive prim;
    if (Result r = decode_draco_mesh(bytes.data(), bytes.size(), -1, prim.vertices, prim.triangles); !r.ok())
        return r;
    out.primitives.push_back(std::move(prim));
    return Result::success();
}

}  // namespace cwbvh::compiler
