// OpenMesh adapter: OBJ, PLY, OFF, STL -> RawInput (the only file that
// includes OpenMesh). Read into a PolyMesh (positions only), then
// fan-triangulate each polygon ourselves so the triangle order is ours:
// polygon (v0 v1 ... vn-1) -> (v0 v1 v2), (v0 v2 v3), ...
//
// OpenMesh's ImporterT silently drops faces with repeated or invalid vertex
// indices (printing to omerr()) and re-adds non-manifold faces with duplicated
// vertices. We capture omerr()/omlog()/omout() during the read, and compare the face
// count read with the count the file announces (PLY/OFF header, binary STL
// header) or that a cheap line scan finds (OBJ `f` lines, ASCII STL `facet`
// lines), reporting any difference as a warning. Dropped faces are not in
// Scene::input_triangles (they never reach us).
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>

#include "cwbvh/compiler/import.h"

namespace cwbvh::compiler {
namespace {

struct MeshTraits : public OpenMesh::DefaultTraits {
    using Point = OpenMesh::Vec3f;
    VertexAttributes(OpenMesh::Attributes::None);
    FaceAttributes(OpenMesh::Attributes::None);
    EdgeAttributes(OpenMesh::Attributes::None);
    HalfedgeAttributes(OpenMesh::Attributes::None);
};
using Mesh = OpenMesh::PolyMesh_ArrayKernelT<MeshTraits>;

/// Captures OpenMesh's omerr()/omlog()/omout() for one read. OpenMesh's
/// mostream::disconnect() leaks the target wrapper that connect() allocated,
/// so the streams are redirected ONCE per process into a buffer owned here
/// (never back to std::cerr; nothing else in cwbvhc uses OpenMesh, see
/// CONTRIBUTING's adapter rule) and each read starts by clearing it. The
/// import is single-threaded.
class OmCapture {
public:
    OmCapture() {
        static const bool redirected = [] {
            for (OpenMesh::mostream* s : {&omerr(), &omlog(), &omout()}) {
                s->disconnect(std::cerr);
                s->disconnect(std::cout);
                s->connect(buffer());
            }
            return true;
        }();
        (void)redirected;
        buffer().str(std::string());
    }
    std::vector<std::string> error_lines() {
        for (OpenMesh::mostream* s : {&omerr(), &omlog(), &omout()}) s->flush();
        std::vector<std::string> lines;
        std::istringstream in(buffer().str());
        std::string line;
        while (std::getline(in, line))
            if (!line.empty()) lines.push_back(line);
        buffer().str(std::string());
        return lines;
    }

private:
    static std::ostringstream& buffer() {
        static std::ostringstream* text = new std::ostringstream;  // outlives OpenMesh's statics
        return *text;
    }
};

std::string lower_extension(const std::string& path) {
    const size_t dot = path.find_last_of('.');
    if (dot == std::string::npos) return "";
    std::string ext = path.substr(dot + 1);
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

/// Faces (polygons) the file says it holds, or -1 when unknown. Also counts
/// OBJ line/point elements, which OpenMesh ignores.
int64_t expected_faces(const std::string& path, const std::string& ext, RawInput& out) {
    std::ifstream f(path, std::ios::binary);
    if (!f) return -1;
    std::string line;
    if (ext == "obj") {
        int64_t faces = 0;
        while (std::getline(f, line)) {
            size_t i = line.find_first_not_of(" \t");
            if (i == std::string::npos || i + 1 >= line.size()) continue;
            const char c = line[i], d = line[i + 1];
            if (d != ' ' && d != '\t') continue;
            if (c == 'f') ++faces;
            else if (c == 'l') ++out.skipped_primitives["lines"];
            else if (c == 'p') ++out.skipped_primitives["points"];
        }
        return faces;
    }
    if (ext == "ply") {
        while (std::getline(f, line)) {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            std::istringstream in(line);
            std::string a, b;
            long long n = -1;
            in >> a >> b >> n;
            if (a == "element" && b == "face") return n;
            if (a == "end_header") break;
        }
        return -1;
    }
    if (ext == "off") {
        // "OFF" then "nv nf ne" (comments start with '#'); ASCII only.
        std::string word;
        while (f >> word) {
            if (word[0] == '#') { std::getline(f, line); continue; }
            if (word.find("OFF") != std::string::npos) {
                long long nv = -1, nf = -1;
                if (f >> nv >> nf) return nf;
            }
            return -1;
        }
        return -1;
    }
    if (ext == "stl") {
        char head[84] = {};
        f.read(head, 84);
        const std::streamsize got = f.gcount();
        f.clear();
        f.seekg(0, std::ios::end);
        const std::streamoff size = f.tellg();
        if (got == 84) {
            uint32_t n = 0;
            std::memcpy(&n, head + 80, 4);
            if (std::streamoff(84 + 50 * uint64_t(n)) == size) return n;  // binary
        }
        f.seekg(0);
        int64_t facets = 0;
        std::string word;
        while (f >> word)
            if (word == "facet") ++facets;
        return facets;
    }
    return -1;
}

/// OpenMesh's PLY reader loops (practically) forever on element counts
/// that the file cannot hold, e.g. 10^11 elements or elements without
/// properties. Every element takes at least one byte in ASCII and binary
/// PLY, so require a property per element and sum(counts) <= body size.
bool check_ply_header(const std::string& path, std::string& error) {
    std::ifstream f(path, std::ios::binary);
    if (!f) {
        error = "cannot open file";
        return false;
    }
    f.seekg(0, std::ios::end);
    const uint64_t size = uint64_t(f.tellg());
    f.seekg(0);
    std::string line;
    uint64_t total = 0;
    bool in_element = false, element_has_property = true;
    constexpr int kMaxHeaderLines = 10000;
    for (int n = 0; n < kMaxHeaderLines && std::getline(f, line); ++n) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream in(line);
        std::string word;
        in >> word;
        if (word == "element" || word == "end_header") {
            if (in_element && !element_has_property) {
                error = "PLY element without properties";
                return false;
            }
            if (word == "end_header") {
                const uint64_t body = size - std::min<uint64_t>(size, uint64_t(f.tellg()));
                if (total > body) {
                    error = "PLY header declares " + std::to_string(total) +
                            " elements but only " + std::to_string(body) + " bytes follow";
                    return false;
                }
                return true;
            }
            std::string name, count_text;
            in >> name >> count_text;
            char* end = nullptr;
            const unsigned long long count = std::strtoull(count_text.c_str(), &end, 10);
            if (count_text.empty() || *end != '\0' || count > size) {
                error = "PLY element " + name + " has invalid count '" + count_text + "'";
                return false;
            }
            total += count;
            in_element = count > 0;
            element_has_property = false;
        } else if (word == "property") {
            element_has_property = true;
        }
    }
    error = "PLY header has no end_header";
    return false;
}

}  // namespace

bool import_openmesh(const std::string& path, const ImportOptions& options, RawInput& out,
                     std::string& error, std::vector<std::string>& warnings) {
    (void)options;
    out = RawInput{};
    const std::string ext = lower_extension(path);
    if (ext == "ply" && !check_ply_header(path, error)) return false;
    Mesh mesh;
    bool ok = false;
    std::vector<std::string> om_lines;
    try {
        OmCapture capture;
        OpenMesh::IO::Options opt;  // positions only
        ok = OpenMesh::IO::read_mesh(mesh, path, opt);
        om_lines = capture.error_lines();
    } catch (const std::bad_alloc&) {
        error = "out of memory while reading (corrupt element counts?)";
        return false;
    } catch (const std::exception& e) {
        error = std::string("OpenMesh failed: ") + e.what();
        return false;
    }
    if (!ok) {
        error = "OpenMesh could not read the file as " + ext;
        if (!om_lines.empty()) error += " (" + om_lines.front() + ")";
        return false;
    }
    constexpr size_t kMaxReaderLines = 5;
    for (size_t i = 0; i < om_lines.size() && i < kMaxReaderLines; ++i)
        warnings.push_back("OpenMesh: " + om_lines[i]);
    if (om_lines.size() > kMaxReaderLines)
        warnings.push_back("OpenMesh: ... " + std::to_string(om_lines.size() - kMaxReaderLines) +
                           " more messages");

    const int64_t expected = expected_faces(path, ext, out);
    if (expected >= 0 && uint64_t(expected) != mesh.n_faces()) {
        warnings.push_back("the file declares " + std::to_string(expected) +
                           " faces but OpenMesh read " + std::to_string(mesh.n_faces()) +
                           " (faces with repeated, invalid or unparsable vertices are dropped by the "
                           "reader; counted as dropped 'rejected_by_reader')");
        if (uint64_t(expected) > mesh.n_faces()) out.rejected_by_reader += uint64_t(expected) - mesh.n_faces();
    }

    RawPrimitive prim;
    prim.vertices.resize(mesh.n_vertices());
    for (const auto vh : mesh.vertices()) {
        const auto& p = mesh.point(vh);
        prim.vertices[size_t(vh.idx())] = {p[0], p[1], p[2]};
    }
    std::vector<uint32_t> poly;
    for (const auto fh : mesh.faces()) {
        poly.clear();
        for (const auto vh : mesh.fv_range(fh)) poly.push_back(uint32_t(vh.idx()));
        for (size_t k = 2; k < poly.size(); ++k)
            prim.triangles.push_back({poly[0], poly[k - 1], poly[k]});
    }
    if (prim.triangles.empty()) {
        error = "no triangles";
        return false;
    }
    out.primitives.push_back(std::move(prim));
    return true;
}

}  // namespace cwbvh::compiler
