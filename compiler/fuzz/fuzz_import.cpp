// libFuzzer target for the import stage (glTF, GLB, OBJ, PLY, Draco).
// The first input byte picks the file extension (its low bits) and, with bit 7
// set, the two-level import (import_scene_instanced, then every placement's
// instance record); the rest is the file.
// Build: see CMakeLists.txt here (clang, -fsanitize=fuzzer,address,undefined).
// Run:   ./fuzz_import -max_len=65536 corpus/   (seed with tiny .gltf/.obj files)
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "cwbvh/compiler/emit.h"
#include "cwbvh/compiler/import.h"
#include "cwbvh/compiler/two_level.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size < 1) return 0;
    static const char* kExt[] = {".gltf", ".glb", ".obj", ".ply", ".off", ".stl", ".drc"};
    const std::string path = "/tmp/cwbvh_fuzz_import_" + std::to_string(getpid()) +
                             kExt[data[0] % (sizeof kExt / sizeof kExt[0])];
    if (FILE* f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data + 1, 1, size - 1, f);
        std::fclose(f);
    } else {
        return 0;
    }
    cwbvh::compiler::Scene scene;
    std::vector<std::string> warnings;
    if (data[0] & 0x80) {
        cwbvh::compiler::InstancedScene instanced;
        bool two_level = false;
        if (cwbvh::compiler::import_scene_instanced({path}, {}, scene, instanced, two_level, warnings).ok() &&
            two_level) {
            for (const cwbvh::compiler::Placement& p : instanced.placements) {
                const cwbvh::compiler::Aabb box = cwbvh::compiler::scene_box(instanced.meshes.at(p.mesh));
                cwbvh::MeshRecord mesh{};
                for (int a = 0; a < 3; ++a) {
                    mesh.lo[a] = box.lo[a];
                    mesh.hi[a] = box.hi[a];
                }
                cwbvh::InstanceRecord record;
                (void)cwbvh::compiler::make_instance_record(p, mesh, record);
            }
        }
    } else {
        (void)cwbvh::compiler::import_scene({path}, {}, scene, warnings);
    }
    std::remove(path.c_str());
    return 0;
}
