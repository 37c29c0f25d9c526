// `cwbvh`: dispatch to one verb. To add a verb, add its run_* to commands.h
// and one row to kVerbs.
#include <cstdio>
#include <cstring>
#include <new>
#include <stdexcept>
#include <string>

#include "commands.h"

namespace cwbvh::tool {
namespace {

struct Verb {
    const char* name;
    int (*run)(int argc, char** argv);
    const char* usage;  ///< one line for `cwbvh --help`
    const char* help;   ///< the options, for `cwbvh VERB --help`
};

constexpr Verb kVerbs[] = {
    {"info", run_info, "info FILE [--json]",
     "  sections, counts, bounds and build statistics of a compiled file\n"
     "  --json            the same as JSON\n"},
    {"validate", run_validate, "validate FILE... [--deep] [--no-checksums]",
     "  checks each file against spec/cwbvh-format.md: exit 0 valid, 1 with one line naming the file,\n"
     "  the section and the rule otherwise\n"
     "  --deep            also proves the geometry is inside every box on its path (spec section 7a;\n"
     "                    two-level files: every mesh and the top level)\n"
     "  --no-checksums    skip the section checksums (structure only)\n"},
    {"rays", run_rays,
     "rays FILE --primary|--diffuse [--bounce N] [--width W --height H] [--seed S] [--view NAME|N] "
     "[--views CATALOG] [--scene KEY] [--camera e,e,e,t,t,t,fov] [--threads N] -o RAYS",
     "  writes a ray file (spec/rays.md) of camera rays or of diffuse bounce N\n"
     "  --primary | --diffuse   camera rays, or the diffuse rays of bounce N (default 1)\n"
     "  --width W --height H    image size (default 1024 x 1024)\n"
     "  --seed S                diffuse directions' seed (default 1)\n"
     "  --view NAME|N           a view of the scene in the view catalog (default its first; for a scene\n"
     "                          not in the catalog, a camera framing the scene's bounds)\n"
     "  --views CATALOG         the catalog (default $CWBVH_VIEWS, else views/catalog.txt)\n"
     "  --scene KEY             the catalog's scene key (default FILE's stem)\n"
     "  --camera ex,ey,ez,tx,ty,tz,fov   a camera by hand (eye, target, vertical fov in degrees)\n"
     "  --threads N             CPU threads of the diffuse bounces' reference traces (default all)\n"
     "  -o, --output RAYS       the ray file to write\n"},
    {"trace", run_trace,
     "trace FILE --rays RAYS [--hits HITS] [--any] [--fast] [--bvh2] [--cpu|--gpu] [--threads N] [--repeat K] "
     "[--no-defer-hits] [--reference-node-test] [--postpone-percent P]",
     "  traces a ray file and prints Mrays/s, nodes and triangles per ray\n"
     "  --rays RAYS       the ray file (cwbvh rays)\n"
     "  --hits HITS       write the hit file (spec/rays.md; two-level files: hit file 1.1 with instances)\n"
     "  --any             any hit (occlusion) instead of closest hit\n"
     "  --fast            the fast triangle test instead of the watertight one\n"
     "  --bvh2            the BVH2 baseline over the file's BV2L section (cwbvhc --keep-sbvh)\n"
     "  --cpu | --gpu     the CPU reference (default) or the CUDA kernels\n"
     "  --threads N       CPU threads (default all)\n"
     "  --repeat K        timed runs, the median is printed (default 1)\n"
     "  --no-defer-hits, --reference-node-test, --postpone-percent P   with --gpu, the CWBVH kernel of a\n"
     "                    single-level file without deferred hit distances, with the reference node test for\n"
     "                    every ray, or postponing triangles below P % of active lanes (default 20): A/B runs,\n"
     "                    the same hits\n"},
    {"model", run_model,
     "model FILE --rays RAYS [--bvh2|--bvh2-2009] [--any] [--fast] [--warps N] [--no-postpone] "
     "[--postpone-percent P] [--postpone-with-node-work] [--no-dynamic-fetch] [--nd N --nw N] "
     "[--shared-entries N] [--node-instructions N] [--tri-instructions N] [--no-defer-hits] [--reference-node-test] "
     "[--check]",
     "  runs the GPU kernels' lock-step warp model on the CPU (warp_model.h): active lanes per node step\n"
     "  and triangle round, steps per ray, spills and refills; not a timing\n"
     "  --bvh2 | --bvh2-2009        the BVH2 kernel's model (2012 dynamic fetch, or 2009 persistent)\n"
     "  --any, --fast               any hit; the fast triangle test\n"
     "  --warps N                   warps modelled together\n"
     "  --no-postpone, --postpone-percent P, --postpone-with-node-work   triangle postponing\n"
     "  --no-dynamic-fetch, --nd N --nw N   dynamic ray fetch and its thresholds\n"
     "  --shared-entries N          stack entries in shared memory before spilling\n"
     "  --node-instructions N, --tri-instructions N   weights of the instruction estimate\n"
     "  --no-defer-hits             the watertight kernel without deferred hit distances (TraceOptions::defer_hits)\n"
     "  --reference-node-test       the reference node test for every ray (TraceOptions::fast_node_test = false)\n"
     "  --check                     also trace with the CPU reference and count disagreements\n"},
    {"render", run_render,
     "render FILE -o IMAGE.png [--heatmap] [--width W --height H] [--view NAME|N] [--views CATALOG] "
     "[--scene KEY] [--camera e,e,e,t,t,t,fov] [--ao N] [--fast] [--threads N]",
     "  renders the scene with the CPU reference traversal\n"
     "  -o, --output IMAGE.png  the image to write\n"
     "  --heatmap               wide nodes visited per camera ray, from the minimum count (blue) to the\n"
     "                          maximum (red), both printed\n"
     "  --width W --height H    image size (default 800 x 800)\n"
     "  --view, --views, --scene, --camera   the camera, as for `cwbvh rays` (default: the scene's first\n"
     "                          catalog view, else one framing the scene's bounds)\n"
     "  --ao N                  N ambient-occlusion rays per pixel\n"
     "  --fast                  the fast triangle test\n"
     "  --threads N             CPU threads (default all)\n"},
};

void print_usage(FILE* out) {
    std::fprintf(out, "usage: cwbvh <verb> [args]   (cwbvh <verb> --help: the verb's options)\nverbs:\n");
    for (const Verb& v : kVerbs) std::fprintf(out, "  cwbvh %s\n", v.usage);
}

bool is_help(const char* a) {
    return std::strcmp(a, "--help") == 0 || std::strcmp(a, "-h") == 0;
}

}  // namespace

int error(int code, const char* message) {
    std::fprintf(stderr, "cwbvh: error: %s\n", message);
    return code;
}

}  // namespace cwbvh::tool

int main(int argc, char** argv) {
    using namespace cwbvh::tool;
    if (argc < 2) {
        print_usage(stderr);
        return kExitUsage;
    }
    if (is_help(argv[1]) || std::strcmp(argv[1], "help") == 0) {
        print_usage(stdout);
        return kExitOk;
    }
    for (const Verb& v : kVerbs) {
        if (std::strcmp(argv[1], v.name) != 0) continue;
        if (argc == 3 && is_help(argv[2])) {
            std::printf("usage: cwbvh %s\n%s", v.usage, v.help);
            return kExitOk;
        }
        // The tool's edge: an allocation a hostile input still gets past the readers' bounds
        // ends as one line and exit 1, never as an uncaught std::bad_alloc (abort, exit 134).
        try {
            return v.run(argc - 1, argv + 1);
        } catch (const std::bad_alloc&) {
            return error(kExitBadInput, (std::string(v.name) + ": out of memory").c_str());
        } catch (const std::length_error&) {
            return error(kExitBadInput, (std::string(v.name) + ": out of memory (a size beyond what a container holds)").c_str());
        }
    }
    return error(kExitUsage, ("unknown verb '" + std::string(argv[1]) + "' (try cwbvh --help)").c_str());
}
