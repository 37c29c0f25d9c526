// cwbvhc: compile meshes into a .cwbvh file. Argument parsing and exit codes only;
// the pipeline lives in compiler/src/compile.cpp (compile.h).
//   exit 0: success   exit 1: bad input (one line on stderr)   exit 2: usage error
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/import.h"
#include "cwbvh/compiler/phase_line.h"
#include "cwbvh/compiler/progress.h"
#include "cwbvh/format/file_io.h"

namespace {

constexpr const char* kUsage =
    "usage: cwbvhc INPUT... -o OUT.cwbvh [options]\n"
    "\n"
    "Compiles triangle meshes (glTF/GLB incl. Draco, OBJ, PLY, OFF, STL, DRC) into one .cwbvh file.\n"
    "\n"
    "options:\n"
    "  -o, --output PATH      output file (required)\n"
    "  --threads N            worker threads (default: all cores; output is identical for any N)\n"
    "  --builder sbvh|embree  binary builder (default sbvh)\n"
    "  --collapse optimal|greedy  binary->8-wide collapse (default optimal: Ylitie et al. 2017 DP)\n"
    "  --split-alpha A        SBVH spatial-split overlap threshold (default 3e-5)\n"
    "  --max-reference-growth G  SBVH reference budget in [0, 1]: at most (1+G) x triangles references\n"
    "                         (default 0.15; 1 for the best SAH on scenes of large triangles, ~10% larger files)\n"
    "  --collapse-cost-prim C triangle cost of the collapse DP, node cost 1 (default 0.3)\n"
    "  --keep-sbvh            also store the binary SBVH cut at the wide leaves (BV2L section:\n"
    "                         leaves of 1-3 triangles, for the BVH2 baseline kernel)\n"
    "  --keep-mesh            also store the source mesh (VERT/INDX sections)\n"
    "  --allow-parent-uris    glTF: let buffer URIs with '..' read outside the input's folder\n"
    "  --stats-json PATH      write build statistics as JSON\n"
    "  --no-verify            skip the decode-and-check pass over the encoded nodes\n"
    "  --flatten              always write a single-level file (default: a glTF input whose\n"
    "                         meshes are placed by several nodes keeps them as instances:\n"
    "                         a two-level file, format 1.2; --builder embree, --keep-sbvh\n"
    "                         and --keep-mesh imply --flatten)\n"
    "  --quiet                no progress, no summary\n"
    "  -h, --help             this text\n";

int usage_error(const std::string& message) {
    std::fprintf(stderr, "cwbvhc: %s\n(run 'cwbvhc --help' for usage)\n", message.c_str());
    return 2;
}

bool parse_int(const std::string& s, int& out) {
    char* end = nullptr;
    const long v = std::strtol(s.c_str(), &end, 10);
    if (s.empty() || *end != '\0' || v < 0 || v > 4096) return false;
    out = int(v);
    return true;
}

bool parse_float(const std::string& s, float& out) {
    char* end = nullptr;
    const float v = std::strtof(s.c_str(), &end);
    if (s.empty() || *end != '\0' || !(v >= 0.0f) || !(v <= 1.0f)) return false;
    out = v;
    return true;
}

/// Prints the import's warnings to stderr, at most kMaxWarnings of them and then how many more
/// there were; on failure as on success, since they often say why nothing was left to compile.
void print_warnings(const std::vector<std::string>& warnings) {
    constexpr size_t kMaxWarnings = 20;
    for (size_t i = 0; i < warnings.size() && i < kMaxWarnings; ++i)
        std::fprintf(stderr, "cwbvhc: warning: %s\n", warnings[i].c_str());
    if (warnings.size() > kMaxWarnings)
        std::fprintf(stderr, "cwbvhc: warning: ... %zu more (%zu warnings in all)\n", warnings.size() - kMaxWarnings,
                     warnings.size());
}

}  // namespace

int main(int argc, char** argv) {
    using namespace cwbvh::compiler;
    CompileOptions options;
    std::string stats_json;
    bool quiet = false;

    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        auto value = [&](std::string& out) {
            if (i + 1 >= argc) return false;
            out = argv[++i];
            return true;
        };
        std::string v;
        if (arg == "-h" || arg == "--help") {
            std::fputs(kUsage, stdout);
            return 0;
        } else if (arg == "-o" || arg == "--output") {
            if (!value(options.output)) return usage_error("-o needs a path");
        } else if (arg == "--threads") {
            if (!value(v) || !parse_int(v, options.threads) || options.threads == 0)
                return usage_error("--threads needs a positive integer");
        } else if (arg == "--builder") {
            if (!value(v)) return usage_error("--builder needs sbvh or embree");
            if (v == "sbvh") options.builder = cwbvh::kBuilderSbvh;
            else if (v == "embree") options.builder = cwbvh::kBuilderEmbree;
            else return usage_error("unknown builder '" + v + "' (expected sbvh or embree)");
        } else if (arg == "--collapse") {
            if (!value(v)) return usage_error("--collapse needs optimal or greedy");
            if (v == "optimal") options.collapse = cwbvh::kCollapseOptimal;
            else if (v == "greedy") options.collapse = cwbvh::kCollapseGreedy;
            else return usage_error("unknown collapse '" + v + "' (expected optimal or greedy)");
        } else if (arg == "--split-alpha") {
            if (!value(v) || !parse_float(v, options.split_alpha))
                return usage_error("--split-alpha needs a number in [0, 1]");
        } else if (arg == "--max-reference-growth") {
            if (!value(v) || !parse_float(v, options.max_reference_growth))
                return usage_error("--max-reference-growth needs a number in [0, 1]");
        } else if (arg == "--collapse-cost-prim") {
            if (!value(v) || !parse_float(v, options.collapse_cost_prim) || options.collapse_cost_prim <= 0.0f)
                return usage_error("--collapse-cost-prim needs a number in (0, 1]");
        } else if (arg == "--keep-sbvh") {
            options.keep_sbvh = true;
        } else if (arg == "--keep-mesh") {
            options.keep_mesh = true;
        } else if (arg == "--allow-parent-uris") {
            options.allow_parent_uris = true;
        } else if (arg == "--stats-json") {
            if (!value(stats_json)) return usage_error("--stats-json needs a path");
        } else if (arg == "--flatten") {
            options.flatten = true;
        } else if (arg == "--no-verify") {
            options.verify = false;
        } else if (arg == "--quiet" || arg == "-q") {
            quiet = true;
        } else if (!arg.empty() && arg[0] == '-' && arg != "-") {
            return usage_error("unknown option '" + arg + "'");
        } else {
            options.inputs.push_back(arg);
        }
    }
    if (options.inputs.empty()) return usage_error("no input files");
    if (options.output.empty()) return usage_error("no output file (-o OUT.cwbvh)");

    // Bad input rather than usage (exit 1): the arguments are well formed; what is wrong is the
    // files they name, which is often only visible on disk (a symlink, a hard link).
    // compile() checks the .cwbvh against the files the inputs name (a glTF's buffers and
    // images, an OBJ's materials); the statistics file is checked here the same way.
    std::vector<std::string> named = options.inputs;
    cwbvh::Result output_check = cwbvh::check_output_path(options.output, named);
    if (output_check.ok() && !stats_json.empty()) {
        named.push_back(options.output);
        output_check = cwbvh::check_output_path(stats_json, named);
        if (output_check.ok())
            output_check = cwbvh::check_output_not_referenced(stats_json,
                                                              cwbvh::compiler::referenced_files(options.inputs));
    }
    if (!output_check.ok()) {
        std::fprintf(stderr, "cwbvhc: error: %s\n", output_check.message.c_str());
        return 1;
    }

    const bool tty = !quiet && isatty(STDERR_FILENO);
    Progress progress;
    std::optional<PhaseLine> line;
    PhaseCallback on_phase;
    if (tty) {
        line.emplace(progress, [](const std::string& s) { std::fputs(s.c_str(), stderr); });
        on_phase = [&line](const std::string& phase, bool done, double seconds) {
            line->on_phase(phase, done, seconds);
        };
    }

    CompileStats stats;
    cwbvh::Result result;
    try {
        // All phases in a task arena of --threads; the progress channel only for the phase line.
        result = compile(options, stats, on_phase, tty ? &progress : nullptr);
    } catch (const std::bad_alloc&) {
        result = cwbvh::Result::fail(cwbvh::Status::kBadInput, 0,
                                     options.inputs.front() + ": out of memory while compiling");
    }
    if (line) line->stop();  // no phase-line output after this, whatever happened
    if (!result.ok()) {
        if (tty) std::fputs("\n", stderr);
        print_warnings(stats.warnings);  // the reasons, before the one error line
        std::fprintf(stderr, "cwbvhc: error: %s\n", result.message.c_str());
        return 1;
    }
    if (!quiet) {
        print_warnings(stats.warnings);
        std::fputs(stats_to_table(stats).c_str(), stdout);
    }
    if (!stats_json.empty()) {
        // Its folder was checked before the compile; what fails now (a full disk) leaves no
        // partial JSON, and says that the .cwbvh itself is complete.
        const std::string json = stats_to_json(stats);
        if (const cwbvh::Result w = cwbvh::write_file_atomic(stats_json, json.data(), json.size()); !w.ok()) {
            std::fprintf(stderr, "cwbvhc: error: %s (cannot write the statistics; %s was written)\n",
                         w.message.c_str(), options.output.c_str());
            return 1;
        }
    }
    return 0;
}
