// --stats-json and the end-of-compile summary table.
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "cwbvh/compiler/compile.h"

namespace cwbvh::compiler {

std::string stats_to_json(const CompileStats& s) {
    nlohmann::ordered_json j;
    j["input_triangles"] = s.input_triangles;
    j["dropped_triangles"] = nlohmann::ordered_json::object();
    for (const auto& [reason, n] : s.dropped_triangles) j["dropped_triangles"][reason] = n;
    j["skipped_primitives"] = nlohmann::ordered_json::object();
    for (const auto& [kind, n] : s.skipped_primitives) j["skipped_primitives"][kind] = n;
    j["triangles"] = s.triangles;
    j["two_level"] = s.two_level;
    j["meshes"] = s.meshes;
    j["instances"] = s.instances;
    j["distinct_triangles"] = s.triangles;
    j["instanced_triangles"] = s.instanced_triangles;
    j["top_nodes"] = s.top_nodes;
    j["top_depth"] = s.top_depth;
    j["references"] = s.references;
    j["spatial_splits"] = s.spatial_splits;
    j["binary_nodes"] = s.binary_nodes;
    j["wide_nodes"] = s.wide_nodes;
    j["wide_depth"] = s.wide_depth;
    j["avg_children"] = s.avg_children;
    j["max_leaf_triangles"] = s.max_leaf_triangles;
    j["sah_binary"] = s.sah_binary;
    j["sah_wide"] = s.sah_wide;
    j["bytes"] = nlohmann::ordered_json::object();
    for (const auto& [section, n] : s.bytes) j["bytes"][section] = n;
    j["file_bytes"] = s.file_bytes;
    j["seconds"] = nlohmann::ordered_json::object();
    double total = 0;
    for (const auto& [phase, t] : s.seconds) {
        j["seconds"][phase] = t;
        total += t;
    }
    j["seconds"]["total"] = total;
    j["mesh_phase_seconds"] = nlohmann::ordered_json::object();
    for (const auto& [phase, t] : s.mesh_phase_seconds) j["mesh_phase_seconds"][phase] = t;
    j["peak_rss_bytes"] = s.peak_rss_bytes;
    j["peak_rss_after"] = nlohmann::ordered_json::object();
    for (const auto& [phase, b] : s.peak_rss_after) j["peak_rss_after"][phase] = b;
    j["rss_after"] = nlohmann::ordered_json::object();
    for (const auto& [phase, b] : s.rss_after) j["rss_after"][phase] = b;
    j["warnings"] = s.warnings;
    return j.dump(2) + "\n";
}

std::string stats_to_table(const CompileStats& s) {
    std::string out;
    char line[160];
    auto row = [&](const char* name, const std::string& value) {
        std::snprintf(line, sizeof line, "  %-28s %s\n", name, value.c_str());
        out += line;
    };
    auto num = [](uint64_t v) { return std::to_string(v); };
    auto fmt = [](const char* f, double v) {
        char b[64];
        std::snprintf(b, sizeof b, f, v);
        return std::string(b);
    };
    uint64_t dropped = 0;
    for (const auto& [reason, n] : s.dropped_triangles) dropped += n;

    out += "cwbvhc summary\n";
    row("triangles in", num(s.input_triangles));
    for (const auto& [reason, n] : s.dropped_triangles) row(("  dropped (" + reason + ")").c_str(), num(n));
    for (const auto& [kind, n] : s.skipped_primitives)
        row(("  skipped " + kind + " primitives").c_str(), num(n));
    row("triangles stored", num(s.triangles));
    if (s.two_level) {
        row("two-level: meshes", num(s.meshes));
        row("two-level: instances", num(s.instances));
        row("distinct triangles", num(s.triangles));
        row("instanced triangles", num(s.instanced_triangles));
        row("top-level nodes / depth", num(s.top_nodes) + " / " + num(s.top_depth));
    }
    row("references after splits",
        num(s.references) + fmt(" (+%.2f%%)", s.triangles ? 100.0 * (double(s.references) - double(s.triangles)) /
                                                                 double(s.triangles)
                                                           : 0.0));
    row("binary nodes", num(s.binary_nodes));
    row("wide nodes", num(s.wide_nodes));
    row("wide tree depth", num(s.wide_depth));
    row("avg children per node", fmt("%.2f", s.avg_children));
    row("max triangles per leaf", num(s.max_leaf_triangles));
    row("SAH binary / wide", fmt("%.4f", s.sah_binary) + " / " + fmt("%.4f", s.sah_wide));
    for (const auto& [section, n] : s.bytes) row(("bytes " + section).c_str(), num(n));
    row("bytes file", num(s.file_bytes));
    double total = 0;
    for (const auto& [phase, t] : s.seconds) {
        row(("seconds " + phase).c_str(), fmt("%.3f", t));
        total += t;
    }
    row("seconds total", fmt("%.3f", total));
    for (const auto& [phase, t] : s.mesh_phase_seconds)
        row(("mesh cpu seconds " + phase).c_str(), fmt("%.3f", t));
    row("peak memory", fmt("%.1f MiB", double(s.peak_rss_bytes) / (1024.0 * 1024.0)));
    (void)dropped;
    return out;
}

}  // namespace cwbvh::compiler
