// cwbvh info FILE [--json]
#include <cstdio>
#include <cstring>
#include <string>

#include "commands.h"
#include "cwbvh/format/describe.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh::tool {

int run_info(int argc, char** argv) {
    const char* path = nullptr;
    bool json = false;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--json") == 0) {
            json = true;
        } else if (argv[i][0] == '-' && argv[i][1] != '\0') {
            return error(kExitUsage, ("info: unknown option " + std::string(argv[i])).c_str());
        } else if (path != nullptr) {
            return error(kExitUsage, "info: expects exactly one FILE");
        } else {
            path = argv[i];
        }
    }
    if (path == nullptr) return error(kExitUsage, "usage: cwbvh info FILE [--json]");
    auto file = File::open(path);
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    const std::string text = json ? describe_json(file->layout()) : describe_text(file->layout());
    std::fputs(text.c_str(), stdout);
    return kExitOk;
}

}  // namespace cwbvh::tool
