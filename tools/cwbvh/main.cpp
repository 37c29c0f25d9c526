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
    const char* usage;
};

constexpr Verb kVerbs[] = {
    {"info", run_info, "info FILE [--json]          sections, bounds and build info"},
    {"validate", run_validate, "validate FILE... [--no-checksums]   check a file against the spec"},
    {"rays", run_rays, "rays FILE --primary|--diffuse [--bounce N] [--width W --height H] [--seed S] [--view NAME|N] [--camera e,e,e,t,t,t,fov] -o RAYS"},
    {"trace", run_trace, "trace FILE --rays RAYS [--hits HITS] [--any] [--fast] [--bvh2] [--cpu|--gpu] [--threads N]"},
    {"model", run_model, "model FILE --rays RAYS [--bvh2|--bvh2-2009] [--any] [--fast] [--no-postpone] [--nd N --nw N] [--check]"},
    {"render", run_render, "render FILE -o IMAGE.png [--heatmap] [--width W --height H] [--camera e,e,e,t,t,t,fov] [--ao N]"},
};

void print_usage(FILE* out) {
    std::fprintf(out, "usage: cwbvh <verb> [args]\nverbs:\n");
    for (const Verb& v : kVerbs) std::fprintf(out, "  cwbvh %s\n", v.usage);
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
    if (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0 || std::strcmp(argv[1], "help") == 0) {
        print_usage(stdout);
        return kExitOk;
    }
    for (const Verb& v : kVerbs) {
        if (std::strcmp(argv[1], v.name) != 0) continue;
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
