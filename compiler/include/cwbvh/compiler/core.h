// The compiler core: the one code that turns a binary tree into file sections.
//
//   Scene --build_sbvh--> BinaryBvh          (or any binary builder: build_embree)
//         --collapse_wide--> WideBvh         (Ylitie et al. 2017, 3.1)
//         --assign_slots-->                  (octant slots: the auction's, Bertsekas 1992)
//         --encode_scene--> EmitResult       (quantize.cpp, encode.cpp, encode_bvh2.cpp)
//         --scene_sections / add_scene_sections--> Writer  (emit.cpp, format/)
//
// Library cwbvh_compiler_core: depends on format/ and oneTBB only. Front ends
// make a Scene (the importers, the synthetic scene generator, the tests' scenes)
// or a BinaryBvh (the Embree builder) and call it; cwbvhc is one of them.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/emit.h"
#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

struct Progress;

struct CoreOptions {
    SbvhConfig sbvh;          ///< compile_scene's builder settings; split_alpha is recorded in BILD either way
    CollapseConfig collapse;  ///< collapse kind and cost model (recorded in BILD)
    EmitOptions emit;         ///< optional sections, verification, builder recorded in BILD
};

/// Runs one phase of the core: its name ("collapse", "slots", "encode"), the
/// progress units it adds (0: not counted) and its body; returns what the body
/// returns. An empty runner just runs the body. cwbvhc's times and samples them.
using PhaseRunner = std::function<bool(const std::string& name, uint64_t units, const std::function<bool()>& body)>;

/// binary tree -> encoded sections: collapse, slots, encode (and verify). The
/// binary tree's nodes are released as soon as nothing needs them (once the
/// wide nodes are quantized and their boxes verified, unless a BVH2/BV2L
/// section is written). `out.build_info` holds the
/// BILD figures (sah_binary included). `progress` (optional) is advanced by the
/// collapse and the slots as in compile.h; it never changes the output.
Result compile_binary(const Scene& scene, BinaryBvh& binary, const CoreOptions& options, EmitResult& out,
                      const PhaseRunner& run = {}, Progress* progress = nullptr);

/// build_sbvh (options.sbvh) then compile_binary. A scene without triangles
/// gives the empty scene (spec 3.2: one root without used slots).
Result compile_scene(const Scene& scene, const CoreOptions& options, EmitResult& out);

}  // namespace cwbvh::compiler
