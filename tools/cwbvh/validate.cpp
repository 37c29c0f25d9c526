// cwbvh validate FILE... [--no-checksums]
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "commands.h"
#include "cwbvh/loader.h"

namespace cwbvh::tool {

int run_validate(int argc, char** argv) {
    std::vector<const char*> paths;
    OpenOptions options;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--no-checksums") == 0)
            options.verify_checksums = false;
        else if (argv[i][0] == '-' && argv[i][1] != '\0')
            return error(kExitUsage, ("validate: unknown option " + std::string(argv[i])).c_str());
        else
            paths.push_back(argv[i]);
    }
    if (paths.empty()) return error(kExitUsage, "usage: cwbvh validate FILE... [--no-checksums]");
    int code = kExitOk;
    for (const char* path : paths) {
        auto file = File::open(path, options);
        if (file.ok()) {
            std::printf("%s: valid\n", path);
        } else {
            code = error(kExitBadInput, file.error().describe().c_str());
        }
    }
    return code;
}

}  // namespace cwbvh::tool
