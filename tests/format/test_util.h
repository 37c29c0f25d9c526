// Helpers shared by the format tests: a small valid file in memory, and
// "reseal" to recompute checksums after a deliberate edit, so a test reaches
// the rule it targets instead of stopping at the checksum.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/format/checksum.h"
#include "cwbvh/format/format.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/scene_data.h"
#include "cwbvh/format/validate.h"
#include "cwbvh/format/writer.h"

namespace cwbvh::test {

inline std::vector<uint8_t> file_bytes(const SceneData& scene) {
    Writer w;
    add_scene_sections(w, scene);
    std::vector<uint8_t> out;
    const Result r = w.to_bytes(out);
    if (!r.ok()) throw std::runtime_error(r.describe());
    return out;
}

inline std::vector<uint8_t> synthetic_file(uint32_t triangles = 40) {
    SyntheticOptions o;
    o.triangles = triangles;
    return file_bytes(make_synthetic_scene(o));
}

inline FileHeader header_of(const std::vector<uint8_t>& f) {
    FileHeader h;
    std::memcpy(&h, f.data(), sizeof h);
    return h;
}
inline void set_header(std::vector<uint8_t>& f, const FileHeader& h) { std::memcpy(f.data(), &h, sizeof h); }

inline size_t entry_offset(const std::vector<uint8_t>& f, uint32_t index) {
    return header_of(f).section_table_offset + index * sizeof(SectionEntry);
}
inline SectionEntry entry(const std::vector<uint8_t>& f, uint32_t index) {
    SectionEntry e;
    std::memcpy(&e, f.data() + entry_offset(f, index), sizeof e);
    return e;
}
inline void set_entry(std::vector<uint8_t>& f, uint32_t index, const SectionEntry& e) {
    std::memcpy(f.data() + entry_offset(f, index), &e, sizeof e);
}
/// Index in the table of a section type (the file must have it).
inline uint32_t find_entry(const std::vector<uint8_t>& f, uint32_t type) {
    for (uint32_t i = 0; i < header_of(f).section_count; ++i)
        if (entry(f, i).type == type) return i;
    throw std::runtime_error("section not found");
}

/// Recomputes every in-range payload checksum and the meta checksum.
inline void reseal(std::vector<uint8_t>& f) {
    FileHeader h = header_of(f);
    const uint64_t table = h.section_table_offset;
    if (table > f.size() || uint64_t(h.section_count) * sizeof(SectionEntry) > f.size() - table) return;
    for (uint32_t i = 0; i < h.section_count; ++i) {
        SectionEntry e = entry(f, i);
        if (e.offset <= f.size() && e.size <= f.size() - e.offset) {
            e.checksum = payload_checksum(f.data() + e.offset, e.size);
            set_entry(f, i, e);
        }
    }
    h.meta_checksum = meta_checksum(h, f.data() + h.section_table_offset, h.section_count * sizeof(SectionEntry));
    set_header(f, h);
}

/// Reads element `i` of a section, lets `edit` change it, writes it back, reseals.
template <class T, class F>
void edit_element(std::vector<uint8_t>& f, uint32_t type, uint64_t i, F edit) {
    const SectionEntry e = entry(f, find_entry(f, type));
    T v;
    std::memcpy(&v, f.data() + e.offset + i * sizeof(T), sizeof v);
    edit(v);
    std::memcpy(f.data() + e.offset + i * sizeof(T), &v, sizeof v);
    reseal(f);
}

// Hand-built trees of unit boxes (depth_test, cycle_test): every node at scale 1 and origin
// 0, every box [0,1]^3 in plane bytes, every triangle (0,0,0) (1,0,0) (0,1,0).

/// A node whose slot `leaf_slot` is a leaf of one triangle, TRIS record `tri`.
inline CwbvhNode unit_leaf_node(uint32_t tri, int leaf_slot) {
    CwbvhNode n{};
    for (int a = 0; a < 3; ++a) n.e[a] = 127;  // scale 1
    n.tri_base = tri;
    n.meta[leaf_slot] = make_meta_leaf(1, 0);
    for (int a = 0; a < 3; ++a) n.q_hi[a][leaf_slot] = 1;
    return n;
}
/// Makes slot `slot` of `n` an internal child (child_base is the caller's).
inline void set_unit_internal(CwbvhNode& n, int slot) {
    n.imask = uint8_t(n.imask | (1u << slot));
    n.meta[slot] = make_meta_internal(slot);
    for (int a = 0; a < 3; ++a) n.q_hi[a][slot] = 1;
}
/// Appends the unit triangle as TRIS record `prim`.
inline void add_unit_triangle(SceneData& s, uint32_t prim) {
    TriangleRecord t{};
    t.v1[0] = 1.0f;
    t.v2[1] = 1.0f;
    t.prim = prim;
    s.triangles.push_back(t);
}
/// One PMAP range over every TRIS record, and the unit triangles' bounds.
inline void close_unit_scene(SceneData& s) {
    s.source_ranges.push_back(SourceRange{0, uint32_t(s.triangles.size()), 0, 0, 0, 0});
    s.bounds = {{0, 0, 0}, {1, 1, 0}};
}

inline Result check(const std::vector<uint8_t>& f, bool checksums = true) {
    ValidateOptions o;
    o.verify_checksums = checksums;
    return validate(f, o);
}

/// Writes bytes to a file under the test temp dir; returns the path.
std::string write_temp(const std::string& name, const std::vector<uint8_t>& bytes);
std::string temp_dir();

/// Exit code and output (stdout + stderr) of one `cwbvh` command of this build.
struct ToolRun {
    int code;
    std::string out;
};

/// Runs `cwbvh ARGS` from the build's bin folder, with CWBVH_VIEWS unset so the
/// compiled-in view catalog applies, under `timeout`: a command that hangs (a FIFO
/// input, issue 21) ends with exit 124 instead of stopping the suite. `shell_before`
/// runs first in the same shell (e.g. "ulimit -v 1000000; ").
inline ToolRun run_cwbvh(const std::string& args, const std::string& shell_before = "") {
    const std::string cmd = shell_before + "env -u CWBVH_VIEWS timeout 120 " + std::string(CWBVH_BIN_DIR) +
                            "/cwbvh " + args + " 2>&1";
    FILE* p = popen(cmd.c_str(), "r");
    if (p == nullptr) return {-1, ""};
    std::string out;
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    const int status = pclose(p);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

inline size_t count_lines(const std::string& s) { return size_t(std::count(s.begin(), s.end(), '\n')); }

}  // namespace cwbvh::test

/// Expects `result` to fail with rule `id` and a one-line message.
#define EXPECT_RULE(result, id)                                                   \
    do {                                                                          \
        const Result r_ = (result);                                               \
        EXPECT_EQ(r_.rule, uint32_t(id)) << r_.describe();                        \
        EXPECT_FALSE(r_.message.empty());                                         \
        EXPECT_EQ(r_.message.find('\n'), std::string::npos) << "one line";        \
    } while (0)
