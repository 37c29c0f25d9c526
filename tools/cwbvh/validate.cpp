// cwbvh validate FILE... [--no-checksums] [--deep]
// --deep adds the geometric checks of deep_check.h (nesting of decoded boxes,
// triangles inside their leaves, coverage of split triangles, every stored
// triangle referenced; two-level files: D1-D4 per mesh and D7 on the top level).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "commands.h"
#include "cwbvh/format/deep_check.h"
#include "cwbvh/format/sections.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh::tool {

int run_validate(int argc, char** argv) {
    std::vector<const char*> paths;
    OpenOptions options;
    bool deep = false;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--no-checksums") == 0)
            options.verify_checksums = false;
        else if (std::strcmp(argv[i], "--deep") == 0)
            deep = true;
        else if (argv[i][0] == '-' && argv[i][1] != '\0')
            return error(kExitUsage, ("validate: unknown option " + std::string(argv[i])).c_str());
        else
            paths.push_back(argv[i]);
    }
    if (paths.empty()) return error(kExitUsage, "usage: cwbvh validate FILE... [--no-checksums] [--deep]");
    int code = kExitOk;
    for (const char* path : paths) {
        auto file = File::open(path, options);
        if (!file.ok()) {
            code = error(kExitBadInput, file.error().describe().c_str());
            continue;
        }
        if (!deep) {
            std::printf("%s: valid\n", path);
            continue;
        }
        // Stored triangle count: the PMAP total (validated: rule 5305 bounds it by the TRIS count).
        const uint64_t stored = file->stored_triangle_count();
        DeepCheckStats st;
        Result r = deep_check(file->nodes(), file->triangles(), stored, &st);
        std::string binary;
        for (const uint32_t type : {uint32_t(kSectionBvh2), uint32_t(kSectionBvh2Leaves)}) {
            const std::span<const uint8_t> bytes = file->section(type);
            if (!r.ok() || bytes.empty()) continue;
            // Sections start 64-byte aligned in the mapping; 64-byte records.
            const std::span<const Bvh2Node> nodes(reinterpret_cast<const Bvh2Node*>(bytes.data()),
                                                  bytes.size() / sizeof(Bvh2Node));
            DeepCheckStats bst;
            r = deep_check_bvh2(nodes, type == kSectionBvh2Leaves, file->triangles(), stored, &bst);
            binary += "; " + section_name(type) + ": " + std::to_string(bst.unsplit_triangles + bst.split_triangles) +
                      " triangles inside their leaf-to-root boxes";
        }
        if (r.ok() && file->is_two_level()) {
            // D7 (and D1 on TLAS): mesh boxes, instance world boxes, TLAS boxes, BNDS (spec 7a).
            r = deep_check_two_level(file->triangles(),
                                     TwoLevelView{file->meshes(), file->instances(), file->top_nodes(), file->bounds()},
                                     &st);
            binary += "; " + std::to_string(st.instances) + " instances inside their world and top-level boxes";
        }
        if (r.ok()) {
            std::printf("%s: valid (deep: %llu parent links, %llu triangles inside their leaf-to-root boxes, "
                        "%llu split triangles covered by %llu points%s)\n",
                        path, (unsigned long long)st.internal_edges, (unsigned long long)st.unsplit_triangles,
                        (unsigned long long)st.split_triangles, (unsigned long long)st.samples, binary.c_str());
        } else {
            code = error(kExitBadInput, (std::string(path) + ": " + r.describe()).c_str());
        }
    }
    return code;
}

}  // namespace cwbvh::tool
