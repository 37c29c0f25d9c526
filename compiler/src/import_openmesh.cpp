// OpenMesh adapter: OBJ, PLY, OFF, STL -> RawInput (the only file that
// includes OpenMesh). Read into a PolyMesh (positions only), then
// fan-triangulate each polygon ourselves so the triangle order is ours:
// polygon (v0 v1 ... vn-1) -> (v0 v1 v2), (v0 v2 v3), ...
//
// OpenMesh's ImporterT silently drops faces with repeated or invalid vertex
// indices (printing to omerr()) and re-adds non-manifold faces with duplicated
// vertices. We capture omerr()/omlog()/omout() (and std::cerr / std::clog, which some of
// its readers write to directly) during the read, and compare the face
// count read with the count the file announces (PLY/OFF header, binary STL
// header) or that a cheap scan finds (OBJ `f` lines, ASCII STL facets),
// reporting any difference as a warning. Dropped faces are not in
// Scene::input_triangles (they never reach us).
//
// Each OBJ, PLY, OFF and STL file is scanned once by our own code before OpenMesh reads it:
// the pre-check that refuses what the reader would misread (check_obj, check_ply,
// check_off, check_stl) also takes the counts of that warning (DeclaredCounts): the faces
// the reader will try to add, as it splits lines and words, so a file it reads whole gives
// no warning and one whose faces it drops does (tests/import/openmesh_test.cpp,
// DeclaredFaceCounts). A PLY header is read twice (OpenMesh's token replay, then our lines).
#include <strings.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iostream>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

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

/// A stream buffer in front of std::cerr's (or std::clog's) own: what one thread writes
/// while it captures goes to the capture buffer, everything else (other threads, and the
/// capturing thread outside read_mesh) to the original buffer, unchanged and unbuffered.
class ThreadRoute final : public std::streambuf {
public:
    explicit ThreadRoute(std::streambuf* original) : original_(original) {}
    void capture(std::streambuf* sink) {
        sink_ = sink;  // before owner_: a thread that sees its own id sees this sink
        owner_.store(std::this_thread::get_id());
    }
    void release() { owner_.store(std::thread::id()); }

protected:
    int_type overflow(int_type c) override {
        if (traits_type::eq_int_type(c, traits_type::eof())) return traits_type::not_eof(c);
        std::streambuf* to = target();
        return to ? to->sputc(traits_type::to_char_type(c)) : c;
    }
    std::streamsize xsputn(const char* s, std::streamsize n) override {
        std::streambuf* to = target();
        return to ? to->sputn(s, n) : n;
    }
    int sync() override {
        std::streambuf* to = target();
        return to ? to->pubsync() : 0;
    }

private:
    std::streambuf* target() const { return owner_.load() == std::this_thread::get_id() ? sink_ : original_; }
    std::streambuf* const original_;
    std::streambuf* sink_ = nullptr;
    std::atomic<std::thread::id> owner_{};
};

/// Captures OpenMesh's messages for one read. OpenMesh's mostream::disconnect() leaks the
/// target wrapper that connect() allocated, so omerr()/omlog()/omout() are redirected ONCE
/// per process into a buffer owned here (never back to std::cerr; nothing else in cwbvhc
/// uses OpenMesh, see CONTRIBUTING's adapter rule) and each read starts by clearing it.
/// One read at a time per process (a mutex held while this object lives): the buffer and
/// OpenMesh's streams are process-wide, and two imports can run at once (Python threads
/// each calling cwbvh.compile, which releases the GIL).
///
/// omlog() is connected to std::clog (not std::cerr), and enabled in Debian's build (no
/// NDEBUG): its lines ("Unsupported keyword : foo" from the PLY header parser) reached
/// stderr raw as well as the buffer, so std::clog is disconnected too. Some readers write
/// to std::cerr directly ("Error in file format (colorType = 7)" in OFFReader.cc, the PLY
/// reader's "unsupported type" ones): std::cerr and std::clog get a ThreadRoute in front of
/// their buffers, once per process, which sends the importing thread's writes to the same
/// buffer while this object lives (one read_mesh; released by the destructor, also when the
/// read throws). Other threads' writes pass through: swapping std::cerr's buffer for the
/// read had put them into the import's warnings (a review found 9,230 such lines in 2,000
/// imports beside a writing thread). cwbvhc's own messages go through C stdio (stderr).
class OmCapture {
public:
    OmCapture() : lock_(mutex()) {
        static const bool redirected = [] {
            for (OpenMesh::mostream* s : {&omerr(), &omlog(), &omout()}) {
                s->disconnect(std::cerr);
                s->disconnect(std::clog);
                s->disconnect(std::cout);
                s->connect(buffer());
            }
            cerr_route() = new ThreadRoute(std::cerr.rdbuf());  // process lifetime, as the streams
            clog_route() = new ThreadRoute(std::clog.rdbuf());
            std::cerr.rdbuf(cerr_route());
            std::clog.rdbuf(clog_route());
            return true;
        }();
        (void)redirected;
        buffer().str(std::string());
        cerr_route()->capture(buffer().rdbuf());
        clog_route()->capture(buffer().rdbuf());
    }
    ~OmCapture() {
        cerr_route()->release();
        clog_route()->release();
    }
    OmCapture(const OmCapture&) = delete;
    OmCapture& operator=(const OmCapture&) = delete;
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
    static std::mutex& mutex() {
        static std::mutex m;
        return m;
    }
    static ThreadRoute*& cerr_route() {
        static ThreadRoute* r = nullptr;
        return r;
    }
    static ThreadRoute*& clog_route() {
        static ThreadRoute* r = nullptr;
        return r;
    }
    std::lock_guard<std::mutex> lock_;  // held from before the capture until after its release
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

/// What the pre-checks find for the comparison after the read (import_openmesh): the faces
/// the file declares, -1 when unknown, and the OBJ line and point elements, which OpenMesh
/// ignores. Applied only once the read has succeeded.
struct DeclaredCounts {
    int64_t faces = -1;
    uint64_t lines = 0, points = 0;
};

/// `t` for an error message: a control character (a NUL would end the printed line) as '?'.
std::string printable(std::string t) {
    for (char& c : t)
        if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7f) c = '?';
    return t;
}

/// A piece of the file for a message: blanks trimmed at both ends, cut at 48 characters,
/// made printable, in single quotes.
std::string excerpt(const std::string& t) {
    const size_t b = t.find_first_not_of(" \t\r\n"), e = t.find_last_not_of(" \t\r\n");
    const std::string s = b == std::string::npos ? std::string() : t.substr(b, e - b + 1);
    return "'" + printable(s.size() > 48 ? s.substr(0, 48) + "..." : s) + "'";
}

/// Opens `path` for one of the header checks below (binary mode, so sizes
/// and offsets are bytes); `size` gets the file's size. False: cannot open.
bool open_for_check(const std::string& path, std::ifstream& f, uint64_t& size, std::string& error) {
    f.open(path, std::ios::binary);
    if (!f) {
        error = "cannot open file";
        return false;
    }
    f.seekg(0, std::ios::end);
    size = uint64_t(f.tellg());
    f.seekg(0);
    return true;
}

/// OpenMesh 9.0's PLY header parser (_PLYReader_::can_u_read) reads the
/// header as whitespace-separated tokens, not lines: it calls
/// elements_.back() for a "property" before any "element" (a crash on an
/// empty vector, e.g. when "1.0\x1a" glues the version to "element"), and
/// loops forever on `while (keyword != "end_header")` once its stream has
/// failed (a non-numeric version or count, or end of file). Replay its
/// token reads from the start of `f` and reject the header where either would happen.
/// `file_type`: the word OpenMesh takes for the format (the second word after the "ply"
/// line, whatever the first is: "foo ascii 1.0" reads as ASCII).
bool check_ply_tokens(std::istream& f, std::string& error, std::string& file_type) {
    std::string line, keyword, a, b, c;
    std::getline(f, line);  // "ply" (OpenMesh refuses anything else before parsing on)
    float version = 0;
    f >> keyword >> file_type >> version;
    if (!f) {
        error = "PLY header has no valid 'format <type> <version>' line";
        return false;
    }
    bool element_seen = false;
    unsigned int count = 0;
    while (f >> keyword && keyword != "end_header") {
        if (keyword == "comment") {
            std::getline(f, line);
        } else if (keyword == "element") {
            f >> a >> count;
            element_seen = true;
        } else if (keyword == "property") {
            if (!element_seen) {
                error = "PLY header has a property before any element";
                return false;
            }
            f >> a;
            if (a == "list") f >> a >> b >> c;
            else f >> b;
        }
    }
    if (!f) {
        error = "PLY header is malformed or has no end_header";
        return false;
    }
    return true;
}

/// Most vertices of one polygon (OBJ, OFF and PLY faces). OpenMesh's ImporterT::add_face
/// compares a face's vertices pairwise: time grows with the square of the polygon (1.2 s
/// for 50k vertices, 45 s for 300k), so a hostile file of one huge face would import for
/// minutes. Real meshes' polygons have a handful of vertices.
constexpr uint64_t kMaxFaceVertices = 65536;

std::string face_too_large(uint64_t k) {
    return "a face of " + std::to_string(k) + " vertices (at most " + std::to_string(kMaxFaceVertices) +
           " per polygon)";
}

/// OpenMesh 9.0's OBJ reader, replayed where it goes wrong without saying so.
/// Tokenisation mirrors OBJReader.cc: getline, trim " \t\r\n", skip empty,
/// '#' and whitespace-led lines, keyword by >>, then the keyword's values by >>.
///  - `v`: it reads x, y, z with >> and, when the stream fails (nan, inf, a value beyond
///    float, fewer than three numbers, "1,0"), DROPS the vertex: every later index
///    then names the next vertex, and the file compiles to wrong geometry with no
///    message. Reject such a line.
///  - `f`: a face vertex with a texture index but no position index ("f /1 2 3") trips
///    `assert(!vhandles.empty())` (Debian builds it with assertions on): reject it;
///    a face of more than kMaxFaceVertices vertices: reject it (quadratic import).
///    OpenMesh does not end a face's data at '#': it reads every block of the line and
///    skips only those that are not numbers, so "f 1 2 3 # f 2 3 4" became the quad 1 2 3 4
///    (with no message). A comment after the vertices is accepted where OpenMesh skips all
///    of it: no block of it starts with an integer ([+-]digit) and none holds a '/' (whose
///    parts it reads as indices); otherwise the line is rejected. `v` lines need no such
///    rule: x y z stop at a '#' ("v 1 2 # 3" fails above), and what follows them is unread.
///  - A carriage return (CR) inside a line: OpenMesh ends lines only at LF and trims CRs at
///    a line's ends, so a CR-only line end joined two lines into one: "f 1 2 3\rf 2 4 3"
///    became the quad 1 2 3 4, "v 5 5 5\rv 0 0 0" or "# comment\rv 0 0 0" lost a vertex and
///    shifted every later index, a whole CR-only file was one line ("no triangles"), all
///    without a message. Reject a line whose trimmed text holds a CR, unless all that follows
///    each CR is a '#' comment (which OpenMesh skips as a CR-aware reader would: a face's
///    comment then falls under the rule above). CRLF and stray CRs at a line's ends pass.
/// The same pass counts `declared` by OpenMesh's keyword rule: the lines it reads as an `f`
/// (each is one face it adds or drops), `l` or `p` (elements it ignores), so the face
/// warning fires exactly when the reader dropped a face line ("f 1 1 2", "f 1 2 99", "f 1 2",
/// an empty "f"): CRLF or CR-led lines and "f\v1 2 3" no longer miscount.
bool check_obj(const std::string& path, std::string& error, DeclaredCounts& declared) {
    std::ifstream f;
    uint64_t size = 0;
    if (!open_for_check(path, f, size, error)) return false;
    declared = DeclaredCounts{};
    declared.faces = 0;
    std::string line, keyword, block;
    auto quote = [](std::string t) { return t.size() > 48 ? t.substr(0, 48) + "..." : t; };
    // One stream for every line, refilled and its state cleared: the same reads with the same
    // results (no format flag or width is ever set), without constructing a stream per line
    // (0.02 s of bunny.obj's 0.18 s import).
    std::istringstream in;
    // UTF-16 text (a byte order mark FE FF or FF FE, every other byte a NUL): said so, rather
    // than the CR rule below naming its first line end ("\r\0\n").
    char bom[2] = {};
    if (f.read(bom, 2) && ((bom[0] == '\xfe' && bom[1] == '\xff') || (bom[0] == '\xff' && bom[1] == '\xfe'))) {
        error = "OBJ file is UTF-16 text (it starts with a UTF-16 byte order mark); OpenMesh's reader reads 8-bit "
                "text (ASCII or UTF-8): convert it";
        return false;
    }
    f.clear();
    f.seekg(0);
    for (uint64_t number = 1; std::getline(f, line); ++number) {
        // A UTF-8 byte order mark (EF BB BF): OpenMesh reads it as part of the first line's
        // keyword, so a first line 'v ...' was dropped (every later index then named the next
        // vertex: wrong geometry, no message). Refused unless that line is a comment or blank.
        if (number == 1 && line.compare(0, 3, "\xef\xbb\xbf") == 0) {
            const size_t start = line.find_first_not_of(" \t\r\n", 3);
            if (start != std::string::npos && line[start] != '#') {
                error = "OBJ file starts with a UTF-8 byte order mark, which OpenMesh's reader takes as part of line "
                        "1's keyword (it would drop that line and shift every later vertex index): remove the mark";
                return false;
            }
        }
        const size_t start = line.find_first_not_of(" \t\r\n");
        if (start != std::string::npos) {
            const size_t end = line.find_last_not_of(" \t\r\n");  // a CR before `end` is inside the line
            for (size_t cr = line.find('\r', start); cr < end; cr = line.find('\r', cr + 1)) {
                const size_t next = line.find_first_not_of(" \t\r", cr + 1);  // <= end
                if (line[next] == '#') continue;
                error = "OBJ line " + std::to_string(number) + ": a carriage return (CR) inside the line, before '" +
                        printable(quote(line.substr(next, end - next + 1))) + "': OpenMesh's reader ends lines only at "
                        "LF, so it would read this as part of line " + std::to_string(number) +
                        " (CR-only line ends: convert them to LF or CRLF)";
                return false;
            }
        }
        if (start == std::string::npos || line[start] == '#' ||
            std::isspace(static_cast<unsigned char>(line[start])))
            continue;
        in.str(line.substr(start));
        in.clear();
        if (!(in >> keyword)) continue;
        if (keyword == "v") {
            float x = 0, y = 0, z = 0;
            in >> x >> y >> z;
            if (in.fail()) {
                const size_t end = line.find_last_not_of(" \t\r\n");
                error = "OBJ line " + std::to_string(number) + ": vertex '" +
                        quote(line.substr(start, end - start + 1)) +
                        "' is not three finite float numbers (the reader would drop it and shift every later "
                        "vertex index)";
                return false;
            }
        } else if (keyword == "l") {
            ++declared.lines;
        } else if (keyword == "p") {
            ++declared.points;
        } else if (keyword == "f") {
            ++declared.faces;
            uint64_t k = 0;
            bool comment = false;  // a '#' was seen: the rest of the line is a comment
            while (in >> block) {
                if (block[0] == '/') {
                    error = "OBJ line " + std::to_string(number) + ": face vertex '" + quote(block) +
                            "' has no position index";
                    return false;
                }
                if (++k > kMaxFaceVertices) {
                    error = "OBJ line " + std::to_string(number) + ": " + face_too_large(k) + " or more";
                    return false;
                }
                // The block holding the '#' ("3#x" is read as 3: only a '/' after its '#' counts),
                // then every block after it.
                const size_t hash = comment ? 0 : block.find('#');
                if (hash == std::string::npos) {
                    // OpenMesh reads a position index with >> into an int: "1.5" or "2e1" is read
                    // as its leading integer, another vertex than the file names. (Words that do
                    // not start like a number it skips, as before: the face counts say so.)
                    const std::string position = block.substr(0, block.find('/'));
                    const size_t first = position[0] == '+' || position[0] == '-' ? 1 : 0;
                    if (position.size() > first && std::isdigit(static_cast<unsigned char>(position[first])) &&
                        position.find_first_not_of("0123456789", first) != std::string::npos) {
                        error = "OBJ line " + std::to_string(number) + ": face vertex '" + printable(quote(block)) +
                                "' is not an integer index (the reader would take its leading digits, another "
                                "vertex)";
                        return false;
                    }
                    continue;
                }
                const size_t digit = block[0] == '+' || block[0] == '-' ? 1 : 0;
                const bool integer = (comment || hash == 0) && block.size() > digit &&
                                     std::isdigit(static_cast<unsigned char>(block[digit]));
                if (integer || block.find('/', hash) != std::string::npos) {
                    error = "OBJ line " + std::to_string(number) + ": the comment after the face's vertices holds '" +
                            printable(quote(block)) + "', which OpenMesh's reader would read as face data (it does not stop "
                            "at '#'; the face would change): put the comment on a line of its own";
                    return false;
                }
                comment = true;
            }
        }
    }
    return true;
}

/// PLY, after check_ply_tokens on the same stream: the header again, now as lines (up to
/// the first line whose first word is end_header), then an ASCII body.
///  - OpenMesh's PLY reader loops (practically) forever on element counts that the file
///    cannot hold, e.g. 10^11 elements or elements without properties. Every element
///    takes at least one byte in ASCII and binary PLY, so require a property per element
///    and sum(counts) <= body size.
///  - 'end_header' alone on its line: OpenMesh's token header ends at the word, and its body
///    read starts right after it, so "end_header x" had it read 'x' as data (uninitialised
///    values in _PLYReader_::read_ascii: an error, or a hang, by what memory held).
///  - One 'format' line: OpenMesh takes the type from the first and ignores later ones
///    ("Unsupported keyword"), so "format ascii 1.0" then "format binary_little_endian 1.0"
///    is an ambiguous header: refused. The ASCII test below takes the type OpenMesh takes
///    (check_ply_tokens), not our line reading's.
///  - ASCII (format ascii 1.0): OpenMesh reads the body with >> and keeps going after the
///    stream has failed, so a body shorter than its header (a truncated file) repeats the
///    last face it read (a duplicate triangle, exit 0), and a value it cannot read leaves
///    its variable uninitialised. Replay the reads: every element and property the header
///    declares must be there, each value OpenMesh reads as a number must be one, whole, in
///    its reading (below); a list of more than kMaxFaceVertices entries is refused
///    (quadratic import). Binary PLY is checked by OpenMesh itself.
///  - Both: a list property other than the faces' vertex_indices, in an element OpenMesh
///    reads, and face properties before vertex_indices, are refused (OpenMesh reads such a
///    list as one value and drops those properties: the faces come out wrong); so is a
///    second face element.
///  - declared.faces: the count of the "element face" line, -1 without one.
/// A PLY scalar type OpenMesh 9 knows (PLYReader.cc get_property_type).
bool is_ply_type(const std::string& t) {
    static const char* const kTypes[] = {"float32", "float64", "float", "double", "int8",   "uint8",
                                         "char",    "uchar",   "int32", "uint32", "int",    "uint",
                                         "int16",   "uint16",  "short", "ushort"};
    for (const char* k : kTypes)
        if (t == k) return true;
    return false;
}

bool check_ply(const std::string& path, std::string& error, DeclaredCounts& declared) {
    std::ifstream f;
    uint64_t size = 0;
    if (!open_for_check(path, f, size, error)) return false;
    std::string file_type;
    if (!check_ply_tokens(f, error, file_type)) return false;
    f.clear();
    f.seekg(0);
    declared = DeclaredCounts{};
    struct Property {
        std::string name, type;  // type: the scalar type, or a list's entry type
        bool list = false;
        int line = 0;
    };
    struct Element {
        std::string name;
        uint64_t count = 0;
        std::vector<Property> properties;
    };
    std::vector<Element> elements;
    const bool ascii = file_type == "ascii";
    bool face_seen = false;
    int format_line = 0;  // the line number of the first 'format' line
    std::string line;
    uint64_t total = 0;
    bool in_element = false, element_has_property = true, end_header = false;
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
                std::string after;
                if (in >> after) {
                    error = "PLY header line " + std::to_string(n + 1) + ": 'end_header' is followed by " +
                            excerpt(after) + " (OpenMesh reads the body from right after the word end_header, so it would "
                            "read this as data)";
                    return false;
                }
                end_header = true;
                break;
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
            // count_text is a whole strtoull number no larger than the file, so it reads as
            // the same value with >> into uint64_t or long long ("+5": 5, "-0": 0).
            elements.push_back(Element{name, count, {}});
            if (name == "face") {
                if (face_seen) {
                    // OpenMesh reads the first face element with the LAST one's count.
                    error = "PLY header line " + std::to_string(n + 1) + ": a second 'face' element (OpenMesh's "
                            "reader would read the first with this one's count)";
                    return false;
                }
                face_seen = true;
                declared.faces = int64_t(count);
            }
        } else if (word == "property") {
            element_has_property = true;
            Property prop;
            prop.line = n + 1;
            std::string a, b;
            in >> a;
            if (a == "list") {
                prop.list = true;
                in >> b >> prop.type >> prop.name;  // count type, entry type, name
            } else {
                in >> b;
                // OpenMesh takes "type name" in either order (get_property_name); neither a type:
                // an unknown type, named "Unsupported" (kept in `type` for the check below).
                if (is_ply_type(a)) prop.type = a, prop.name = b;
                else if (is_ply_type(b)) prop.type = b, prop.name = a;
                else prop.type = a, prop.name = b;
            }
            if (!elements.empty()) elements.back().properties.push_back(prop);
        } else if (word == "format") {
            if (format_line > 0) {
                error = "PLY header has more than one 'format' line (lines " + std::to_string(format_line) + " and " +
                        std::to_string(n + 1) + "): OpenMesh reads the first, so the file's format is ambiguous";
                return false;
            }
            format_line = n + 1;
        }
    }
    if (!end_header) {
        error = "PLY header has no end_header";
        return false;
    }
    // The elements OpenMesh reads (every one up to the first face element; it stops after the
    // faces) and how (_PLYReader_::can_u_read, read_ascii, read_binary): it reads the face
    // element's vertex_indices (or vertex_index) list as a list, but any other list property
    // as ONE value (ASCII: one word; binary: one entry's bytes), and it drops the face
    // properties declared before vertex_indices while the file still holds their values. Both
    // shift every later read: a face 'texcoord' list lost faces and made others from texture
    // coordinates; a face 'flags' property before vertex_indices had the flags read as vertex
    // counts. Refused, naming the line.
    size_t read_elements = elements.size();
    for (size_t e = 0; e < elements.size(); ++e)
        if (elements[e].name == "face") {
            read_elements = e + 1;
            break;
        }
    auto is_vertex_indices = [](const Element& e, const Property& p) {
        return e.name == "face" && p.list && (p.name == "vertex_indices" || p.name == "vertex_index");
    };
    for (size_t e = 0; e < read_elements; ++e) {
        const Element& el = elements[e];
        if (el.count == 0) continue;  // nothing of it is read
        for (size_t i = 0; i < el.properties.size(); ++i) {
            const Property& p = el.properties[i];
            const std::string at = "PLY header line " + std::to_string(p.line) + ": ";
            // Binary: a type OpenMesh does not know takes no bytes in its reading (and in a
            // vertex_indices list, no index), so every later value shifts. (ASCII reads such a
            // value as a word, which is right.)
            if (!ascii && !is_ply_type(p.type)) {
                error = at + "property '" + printable(p.name) + "' of element '" + printable(el.name) + "' has the "
                        "type '" + printable(p.type) + "', which OpenMesh's reader does not know (it would read every "
                        "later value of a binary file from the wrong bytes)";
                return false;
            }
            if (is_vertex_indices(el, p)) {
                if (i > 0) {
                    error = at + "the face element's vertex index list comes after " + std::to_string(i) +
                            " other face properties ('" + printable(el.properties[0].name) + "' first); OpenMesh's "
                            "reader drops those properties but the file holds their values, so it would read the "
                            "faces wrong (declare vertex_indices first)";
                    return false;
                }
                continue;
            }
            if (p.list) {
                error = at + "list property '" + printable(p.name) + "' of element '" + printable(el.name) +
                        "': OpenMesh's reader reads a list other than the faces' vertex_indices as a single value, "
                        "so it would read every later " + printable(el.name) + " wrong (remove the property)";
                return false;
            }
        }
    }
    if (!ascii) return true;
    // ASCII: replay OpenMesh's reads, each with the type it reads into (read_ascii: vertex
    // coordinates, normals and texture coordinates with >> float, colours with >> float or
    // >> int by their declared type, the face's vertex count and indices with >> unsigned,
    // every other property as one word; elements after the faces are not read), on the
    // file's words: each read must succeed and take its whole word. A read that fails left
    // OpenMesh's variable as it was, uninitialised at first (a fuzzed file had it reserve 2
    // GiB for one face), and one that takes part of a word ("1.5" for an index, "1.5.2" for
    // a coordinate) shifts the rest. Every element the header declares must be there.
    enum class Read { kWord, kFloat, kInt, kUnsigned };
    auto read_as = [](const Element& el, const Property& p) {
        const bool is_float_type = p.type == "float" || p.type == "float32";
        const std::string& n = p.name;
        if (el.name == "vertex") {
            if (n == "x" || n == "y" || n == "z" || n == "nx" || n == "ny" || n == "nz" || n == "u" || n == "s" ||
                n == "v" || n == "t")
                return Read::kFloat;
            if (n == "red" || n == "green" || n == "blue" || n == "diffuse_red" || n == "diffuse_green" ||
                n == "diffuse_blue" || n == "alpha")
                return is_float_type ? Read::kFloat : Read::kInt;
        } else if (el.name == "face") {
            if (n == "red" || n == "green" || n == "blue" || n == "alpha") return is_float_type ? Read::kFloat : Read::kInt;
        }
        return Read::kWord;
    };
    std::istringstream value;
    auto whole = [&value](const std::string& word, auto& x) {  // >> x takes all of `word`
        value.str(word);
        value.clear();
        value >> x;
        return !value.fail() && value.peek() == std::char_traits<char>::eof();
    };
    // What >> certainly reads whole, decided without a stream (most words; about a third of a
    // large ASCII file's import time otherwise): [+-] and at most 9 digits for the integers;
    // [+-], digits with at most one '.', an optional exponent of at most two digits, and a
    // value below 10^38 (FLT_MAX is 3.4e38) for a float. Anything else goes through the stream.
    auto plainly = [](const std::string& word, Read how) {
        size_t i = word.size() > 0 && (word[0] == '+' || word[0] == '-') ? 1 : 0;
        size_t digits = 0, before_point = 0;
        bool point = false;
        for (; i < word.size(); ++i) {
            const char c = word[i];
            if (c >= '0' && c <= '9') {
                ++digits;
                before_point += point ? 0 : 1;
            } else if (c == '.' && how == Read::kFloat && !point) {
                point = true;
            } else {
                break;
            }
        }
        if (digits == 0) return false;
        if (how != Read::kFloat) return i == word.size() && digits <= 9;
        // A float: then an exponent [eE][+-]d{1,2}, if any. >> float fails only on overflow
        // (underflow gives a subnormal or 0), so require before_point + exponent <= 38.
        int exponent = 0;
        if (i < word.size()) {
            if (word[i] != 'e' && word[i] != 'E') return false;
            ++i;
            const bool negative = i < word.size() && word[i] == '-';
            i += i < word.size() && (word[i] == '+' || word[i] == '-') ? 1 : 0;
            const size_t first = i;
            for (; i < word.size() && word[i] >= '0' && word[i] <= '9' && i - first < 2; ++i)
                exponent = 10 * exponent + (word[i] - '0');
            if (i == first || i != word.size()) return false;
            exponent = negative ? -exponent : exponent;
        }
        return int(before_point) + exponent <= 38;
    };
    auto word_fits = [&](const std::string& word, Read how) {
        if (how == Read::kWord || plainly(word, how)) return true;
        float x = 0;
        int i = 0;
        unsigned int u = 0;
        switch (how) {
            case Read::kFloat: return whole(word, x);
            case Read::kInt: return whole(word, i);
            case Read::kUnsigned: return whole(word, u);
            case Read::kWord: break;
        }
        return true;
    };
    auto unreadable = [&](const Element& el, uint64_t i, const Property& p, const std::string& word, Read how) {
        error = "PLY " + el.name + " " + std::to_string(i) + ": " + excerpt(word) + " for property '" +
                printable(p.name) + "' is not " +
                (how == Read::kFloat ? "a float number" : how == Read::kInt ? "an integer" : "an unsigned integer") +
                " as OpenMesh's reader reads it (it would read this and every later value wrong)";
        return false;
    };
    std::string token;
    for (size_t e = 0; e < elements.size(); ++e) {
        const Element& el = elements[e];
        // How OpenMesh reads each property's values (a list's entries), decided once per element.
        std::vector<Read> hows;
        for (const Property& p : el.properties)
            hows.push_back(e >= read_elements ? Read::kWord
                           : p.list           ? (is_vertex_indices(el, p) ? Read::kUnsigned : Read::kWord)
                                              : read_as(el, p));
        for (uint64_t i = 0; i < el.count; ++i) {
            for (size_t q = 0; q < el.properties.size(); ++q) {
                const Property& p = el.properties[q];
                const Read how = hows[q];
                if (!p.list) {
                    if (!(f >> token)) {
                        error = "PLY file is truncated at " + el.name + " " + std::to_string(i) + " of " +
                                std::to_string(el.count);
                        return false;
                    }
                    if (!word_fits(token, how)) return unreadable(el, i, p, token, how);
                    continue;
                }
                // The list's length: a decimal integer (">> uint64_t" would take "-1" as 2^64 - 1
                // and "7.9" as 7).
                uint64_t k = 0;
                char* end = nullptr;
                if (!(f >> token) || token[0] < '0' || token[0] > '9' ||
                    (k = std::strtoull(token.c_str(), &end, 10), *end != '\0')) {
                    error = "PLY file is truncated or unparsable at " + el.name + " " + std::to_string(i) + " of " +
                            std::to_string(el.count);
                    return false;
                }
                if (k > kMaxFaceVertices) {
                    error = "PLY " + el.name + " " + std::to_string(i) + ": " + face_too_large(k);
                    return false;
                }
                for (uint64_t j = 0; j < k; ++j) {
                    if (!(f >> token)) {
                        error = "PLY file is truncated at " + el.name + " " + std::to_string(i) + " of " +
                                std::to_string(el.count);
                        return false;
                    }
                    if (!word_fits(token, how)) return unreadable(el, i, p, token, how);
                }
            }
        }
    }
    return true;
}

/// STL. Binary: 80 bytes, a triangle count n, then n 50-byte records; a file whose size is
/// not 84 + 50 n is read by OpenMesh as ASCII and gives "no triangles" without saying why,
/// so a file that does not start with "solid" and whose size disagrees with its count is
/// refused with both numbers.
///
/// ASCII is read twice, line by line, in one pass:
///  - as words (the file's own meaning, keywords in any case): every `facet` must be complete
///    (three `vertex x y z` and `endfacet`); a file cut inside one is refused instead of read
///    in part ("truncated or malformed").
///  - as OpenMesh 9.0's _STLReader_::read_stla does, which is line-based: getline, and at any
///    line containing "outer" or "OUTER" (anywhere: "solid router" too; "Outer" is not seen)
///    it takes the NEXT THREE lines as `<word> x y z` with >>, whatever they hold. A vertex
///    whose x y z do not all parse keeps what the previous vertex left, and the first one
///    is uninitialised memory: "facet ... outer loop vertex 0 0 0 vertex ..." on one line
///    compiled to a triangle whose coordinates changed from run to run (exit 0).
///  Both readings must give the same vertices on the same lines (bit for bit), every line
///  OpenMesh reads as a vertex must be `vertex x y z`, and no 'outer' line may be left
///  without its three lines. So every layout OpenMesh reads correctly is accepted (keywords
///  in either of its cases, 'solid name' lines, blank lines between facets, leading blanks,
///  CRLF, 'endloop endfacet' on one line) and any other is refused naming the line. As the
///  words are the file's words, the float reads stop where >> stops ("1-2" is 1 then -2),
///  in both readings.
/// declared.faces: binary, the header's count; ASCII, the complete facets of the word reading
/// (keywords in any case, the words of a 'solid' / 'endsolid' name not counted), which in an
/// accepted file are the triangles OpenMesh reads, one per 'outer' line; it drops those whose
/// three vertices are not distinct, and the warning says so. (It was the words "facet" as
/// written, those of a solid's name too: "solid my facet model" declared one face too many,
/// "FACET" none, both false alarms.)
bool check_stl(const std::string& path, std::string& error, DeclaredCounts& declared) {
    std::ifstream f;
    uint64_t size = 0;
    if (!open_for_check(path, f, size, error)) return false;
    declared = DeclaredCounts{};
    char head[84] = {};
    f.read(head, 84);
    // "solid" in any case, after any white space (what an ASCII STL starts with).
    const std::streamsize got = f.gcount();
    std::streamsize k = 0;
    while (k < got && std::isspace(static_cast<unsigned char>(head[k]))) ++k;
    const bool solid = got - k >= 5 && strncasecmp(head + k, "solid", 5) == 0;
    if (got == 84) {
        uint32_t n = 0;
        std::memcpy(&n, head + 80, 4);
        if (84 + 50 * uint64_t(n) == size) {  // binary, consistent
            declared.faces = n;
            return true;
        }
        if (!solid) {
            error = "binary STL declares " + std::to_string(n) + " triangles (84 + 50 x " + std::to_string(n) +
                    " = " + std::to_string(84 + 50 * uint64_t(n)) + " bytes) but the file has " +
                    std::to_string(size) + " bytes";
            return false;
        }
    } else if (!solid) {
        error = "STL file of " + std::to_string(size) + " bytes: neither a binary header (84 bytes) nor ASCII 'solid'";
        return false;
    }
    f.clear();
    f.seekg(0);
    auto lower = [](std::string& w) {
        for (char& c : w) c = char(std::tolower(static_cast<unsigned char>(c)));  // FACET, Vertex, ...
    };
    const auto quote = excerpt;
    struct Vertex {
        float x[3];
        bool operator==(const Vertex& o) const { return std::memcmp(x, o.x, sizeof x) == 0; }
    };
    // The word reading (a vertex's x y z may run over lines, as with >> on the file).
    std::string line, word;
    std::istringstream in, om;
    uint64_t facets = 0, vertices = 0, complete = 0;
    bool open = false, broken = false;
    int pending = 0;  // coordinates still to read of the current vertex
    Vertex v{};
    std::vector<Vertex> on_line;  // the vertices the word reading completed on this line
    // OpenMesh's reading.
    int om_left = 0;  // lines it still takes as vertices after its last 'outer' line
    uint64_t om_outer = 0, number = 0, solid_line = 0;  // solid_line: the last 'solid' / 'endsolid' line
    std::string mismatch;  // the first line where the two readings differ
    while (!broken && std::getline(f, line)) {
        ++number;
        const bool om_line = om_left > 0;  // OpenMesh reads this line as a vertex
        if (om_line) {
            --om_left;
        } else if (line.find("outer") != std::string::npos || line.find("OUTER") != std::string::npos) {
            om_left = 3;
            om_outer = number;
        }

        on_line.clear();
        in.str(line);
        in.clear();
        // The line's first word is 'vertex' and its x y z (read from the same stream state as
        // OpenMesh's >> would) complete here: on_line[0] is OpenMesh's reading too.
        bool lead_vertex = false;
        const bool fresh = pending == 0;
        for (bool first = true;; first = false) {
            if (pending > 0) {
                in >> std::ws;
                if (in.eof()) break;  // the next coordinate is on a later line
                if (!(in >> v.x[3 - pending])) {
                    broken = true;
                    break;
                }
                if (--pending == 0) {
                    ++vertices;
                    on_line.push_back(v);
                }
                continue;
            }
            if (!(in >> word)) break;
            lower(word);
            if (word == "solid" || word == "endsolid") {  // the name may hold any word ("my facet model")
                solid_line = number;
                break;
            }
            if (word == "facet") {
                if (open) {  // the previous facet never ended
                    broken = true;
                    break;
                }
                open = true;
                vertices = 0;
                ++facets;
            } else if (word == "vertex" && open) {
                pending = 3;
                lead_vertex = first && fresh;
            } else if (word == "endfacet" && open) {
                if (vertices != 3) {
                    broken = true;
                    break;
                }
                open = false;
                ++complete;
            }
        }
        if (broken || !mismatch.empty()) continue;

        bool om_vertex = false;
        Vertex w{};
        if (om_line && lead_vertex && !on_line.empty()) {
            om_vertex = true;
            w = on_line[0];
        } else if (om_line) {  // OpenMesh: getline, trim, >> word >> x >> y >> z
            om.str(line);
            om.clear();
            std::string first;
            om >> first >> w.x[0] >> w.x[1] >> w.x[2];
            lower(first);
            om_vertex = !om.fail() && first == "vertex";
            if (!om_vertex) {
                mismatch = "ASCII STL line " + std::to_string(number) + ": " + quote(line) +
                           " is not 'vertex x y z', but OpenMesh's line-based reader takes the three lines after "
                           "line " + std::to_string(om_outer) + " (a line containing 'outer') for the triangle's "
                           "vertices ('outer loop' and each 'vertex x y z' must be on a line of their own)";
                continue;
            }
        }
        if (on_line.size() == (om_vertex ? 1u : 0u) && (!om_vertex || on_line[0] == w)) continue;
        const std::string at = "ASCII STL line " + std::to_string(number) + ": ";
        if (on_line.size() > 1 || (on_line.size() == 1 && !om_vertex))
            mismatch = at + quote(line) + " holds a vertex that OpenMesh's line-based reader does not read (it reads " +
                       "a triangle only from the three lines right after a line containing 'outer' or 'OUTER'; " +
                       "'outer loop' and each 'vertex x y z' must be on a line of their own)";
        else if (on_line.empty())
            mismatch = at + "OpenMesh's line-based reader takes " + quote(line) + " for a vertex (the three lines " +
                       "after line " + std::to_string(om_outer) + ", which contains 'outer') but it is not a " +
                       "vertex of a facet" +
                       (om_outer == solid_line ? " (line " + std::to_string(om_outer) + " is a 'solid' line: its name " +
                                                     "runs to the end of the line, so no facet starts on it)"
                                               : std::string());
        else
            mismatch = at + "OpenMesh's line-based reader reads another vertex from " + quote(line) +
                       " than the file holds (a vertex's x y z must be on its 'vertex' line)";
    }
    if (pending > 0) broken = true;  // the file ends inside a vertex
    if (broken || complete != facets || open) {
        error = "ASCII STL is truncated or malformed at facet " + std::to_string(complete) + " (" +
                std::to_string(complete) + " complete facets: each needs three 'vertex x y z' lines and "
                "'endfacet')";
        return false;
    }
    if (mismatch.empty() && om_left > 0)
        mismatch = "ASCII STL line " + std::to_string(om_outer) + " contains 'outer', but the file ends before "
                   "the three 'vertex x y z' lines OpenMesh's line-based reader takes after it";
    if (!mismatch.empty()) {
        error = mismatch;
        return false;
    }
    declared.faces = int64_t(complete);
    return true;
}

/// OpenMesh 9.0's OFF reader trusts the header: it reserves nV/3*nV/nF
/// elements up front (a corrupt count allocates gigabytes), keeps looping
/// over nF faces (and over a face's vertex count) after the stream has
/// failed or ended (practically forever for a huge count), and a missing
/// count is read as an uninitialised value. So replay its reads here (same
/// stream operations, same order, from its OFFReader.cc) and reject the file
/// where they would fail: every element the header announces must be there.
/// Its header rules, where it reads wrong or refuses without saying why (each refused
/// here, naming the line):
///  - line 1 must be [ST][C][N]OFF [BINARY], from its first byte (no comment or blank
///    before it); a 4 or n flag (4OFF, nOFF: vertices of other than 3 coordinates) it refuses.
///  - ASCII: it ignores the rest of line 1 and reads the counts with >> from the line after,
///    so "OFF 4 2 0" on one line had it take the first vertex for the counts ("no
///    triangles", or other counts and wrong geometry); a first word after OFF that starts
///    like a number is refused. Blank lines before the counts it skips; a comment it does
///    not (it read no counts), nor text after the three counts on their line, which it read
///    as the first vertex ("4 2 0 7" made vertex 0 (7, 0, 0); "4 2" took the edge count
///    from the first vertex and shifted every coordinate).
/// Body (ASCII): without C in the header it reads each face's count and indices with >> and
/// nothing else, so more on a face line (a face colour, which Geomview allows in any OFF; a
/// comment) became the next face: refused, naming the line.
/// declared.faces: the header's face count (ASCII and binary), which OpenMesh reads.
bool check_off(const std::string& path, std::string& error, DeclaredCounts& declared) {
    std::ifstream f;
    uint64_t size = 0;
    if (!open_for_check(path, f, size, error)) return false;
    declared = DeclaredCounts{};
    const auto quote = excerpt;
    // Header flags as in _OFFReader_::can_u_read: [ST][C][N][4][n]OFF [BINARY].
    std::string first;
    std::getline(f, first);
    const char* p = first.c_str();
    size_t left = std::min<size_t>(first.size(), 4095) + (f.eof() ? 0 : 1);
    bool texcoord = false, color = false, normal = false;
    if (left > 1 && p[0] == 'S' && p[1] == 'T') { texcoord = true; p += 2; left -= 2; }
    if (left > 0 && p[0] == 'C') { color = true; ++p; --left; }
    if (left > 0 && p[0] == 'N') { normal = true; ++p; --left; }
    if (left > 0 && (p[0] == '4' || p[0] == 'n')) {
        error = "OFF line 1: the header " + quote(first) + " announces vertices of 4 or n coordinates (4OFF, nOFF), "
                "which OpenMesh's reader does not read (3 coordinates only)";
        return false;
    }
    if (left < 3 || std::strncmp(p, "OFF", 3) != 0) {
        error = size == 0 ? std::string("OFF file is empty")
                : first.compare(0, 3, "\xef\xbb\xbf") == 0
                    ? std::string("OFF line 1: the file starts with a UTF-8 byte order mark, before the OFF header "
                                  "(OpenMesh's reader reads the header from the very first byte): remove the mark")
                          : "OFF line 1: " + quote(first) + " is not an OFF header ([ST][C][N]OFF, at the very start of "
                            "the file: OpenMesh's reader skips no comment or blank before it)";
        return false;
    }
    left = left >= 4 ? left - 4 : 0;
    const bool binary = left >= 6 && std::strncmp(p + 4, "BINARY", 6) == 0;
    if (!binary) {
        // Counts on the header line: its rest starts with two or more whole integers ("OFF 4 2 0",
        // "OFF4 2 0", "OFF 4 2"); other words there ("OFF 3D mesh", "OFF # comment") OpenMesh
        // ignores, and so does this check.
        const std::string after = first.substr(size_t(p + 3 - first.c_str()));
        std::istringstream words(after);
        std::string word;
        int integers = 0;
        while (integers < 2 && words >> word) {
            const size_t sign = word[0] == '+' || word[0] == '-' ? 1 : 0;
            if (word.size() == sign || word.find_first_not_of("0123456789", sign) != std::string::npos) break;
            ++integers;
        }
        if (integers == 2) {
            error = "OFF line 1: the counts are on the header line (" + quote(first) + "), but OpenMesh's reader "
                    "ignores the rest of that line and reads the counts from the next one: put " + quote(after) +
                    " on a line of its own";
            return false;
        }
    }

    auto short_file = [&](const char* what, uint64_t i, uint64_t n) {
        error = std::string("OFF file is truncated or unparsable at ") + what + " " +
                std::to_string(i) + " of " + std::to_string(n);
        return false;
    };
    unsigned int nv = 0, nf = 0, ne = 0;
    if (binary) {
        auto read_u32 = [&](unsigned int& v) {
            uint32_t t = 0;
            f.read(reinterpret_cast<char*>(&t), 4);
            v = t;
            return f.gcount() == 4;
        };
        if (!read_u32(nv) || !read_u32(nf) || !read_u32(ne)) {
            error = "OFF header has missing or invalid vertex/face/edge counts";
            return false;
        }
        if (nv > size || nf > size) {
            error = "OFF header declares " + std::to_string(nv) + " vertices and " +
                    std::to_string(nf) + " faces in a file of " + std::to_string(size) + " bytes";
            return false;
        }
        declared.faces = nf;
        const std::streamoff record = 12 + (normal ? 12 : 0) + (color ? 12 : 0) + (texcoord ? 8 : 0);
        const uint64_t body = size - std::min<uint64_t>(size, uint64_t(f.tellg()));
        if (uint64_t(nv) * uint64_t(record) > body) return short_file("vertex", body / record, nv);
        f.seekg(std::streamoff(nv) * record, std::ios::cur);
        for (unsigned int i = 0; i < nf; ++i) {
            unsigned int k = 0;
            if (!read_u32(k)) return short_file("face", i, nf);
            if (k > kMaxFaceVertices) {
                error = "OFF face " + std::to_string(i) + ": " + face_too_large(k);
                return false;
            }
            const uint64_t rest = size - std::min<uint64_t>(size, uint64_t(f.tellg()));
            if (uint64_t(k) * 4 > rest) return short_file("face", i, nf);
            f.seekg(std::streamoff(k) * 4, std::ios::cur);
        }
        return true;
    }
    // ASCII (_OFFReader_::read_ascii). The counts: >> from the line after the header, over
    // blank lines. `number`: the line they start on, at `start`.
    const char* blanks = " \t\r\v\f";
    std::string line;
    uint64_t number = 1;
    std::streamoff start = f.tellg();
    bool found = false;
    while (!found && std::getline(f, line)) {
        ++number;
        found = line.find_first_not_of(blanks) != std::string::npos;
        if (!found) start = f.tellg();
    }
    if (!found) {
        error = "OFF header has missing or invalid vertex/face/edge counts (the file ends at line " +
                std::to_string(number) + ")";
        return false;
    }
    if (line[line.find_first_not_of(blanks)] == '#') {
        error = "OFF line " + std::to_string(number) + ": a comment (" + quote(line) + ") where the vertex/face/edge "
                "counts belong: OpenMesh's reader reads the counts from the first words after the header line and "
                "skips no comment";
        return false;
    }
    f.clear();
    f.seekg(start);
    if (!(f >> nv >> nf >> ne)) {
        error = "OFF header has missing or invalid vertex/face/edge counts (line " + std::to_string(number) + ")";
        return false;
    }
    // The rest of the line that ends the counts: OpenMesh reads whatever is there as the first vertex.
    if (!f.eof()) {
        const std::streamoff counts_end = f.tellg();
        std::string tail;
        std::getline(f, tail);
        const std::streamoff vertices_start = f.tellg();
        std::string counts(size_t(counts_end - start), '\0');
        f.clear();
        f.seekg(start);
        f.read(&counts[0], std::streamsize(counts.size()));
        number += uint64_t(std::count(counts.begin(), counts.end(), '\n'));  // the line the counts end on
        f.clear();
        if (vertices_start >= 0) f.seekg(vertices_start);
        else f.seekg(0, std::ios::end), f.get();  // the counts' line ended the file
        if (tail.find_first_not_of(blanks) != std::string::npos) {
            error = "OFF line " + std::to_string(number) + ": " + quote(tail) + " after the vertex/face/edge counts " +
                    std::to_string(nv) + " " + std::to_string(nf) + " " + std::to_string(ne) + ": OpenMesh's reader "
                    "would read it as the first vertex (the counts must be three numbers alone on their line)";
            return false;
        }
    }
    if (nv > size || nf > size) {
        error = "OFF header declares " + std::to_string(nv) + " vertices and " +
                std::to_string(nf) + " faces in a file of " + std::to_string(size) + " bytes";
        return false;
    }
    declared.faces = nf;
    // Vertices: OpenMesh reads 3 numbers (6 with normals) with >>, over line ends and blank
    // lines, then skips the rest of the line the last one was on. A vertex spread over lines
    // ("0 0" then "0") therefore reads right, unless the line it ends on holds more: OpenMesh
    // drops that rest, so that vertex takes numbers of the next one and every later vertex
    // shifts, without a message ("1 0" then "1 1 0"). Refused, naming the line; so is a word
    // that is not a number, where OpenMesh's >> fails.
    float x = 0;
    std::string rest, word;
    std::istringstream numbers;  // one stream for every line that needs it
    const int need = normal ? 6 : 3;
    // Counts the plain decimal words of `line` (sign, digits, at most one point, no exponent,
    // under 39 integer digits: words >> reads into a float without fail) into `read` until it
    // reaches `need`; `more`: a word follows the last one needed. False when a word before
    // that is not plain: the stream decides then, as OpenMesh's >> does.
    auto scan_plain = [&](int& read, bool& more) {
        size_t at = 0;
        while (read < need && (at = line.find_first_not_of(blanks, at)) != std::string::npos) {
            size_t k = at + (line[at] == '+' || line[at] == '-' ? 1 : 0), digits = 0, whole = 0;
            bool point = false;
            for (; k < line.size() && std::strchr(blanks, line[k]) == nullptr; ++k) {
                const char c = line[k];
                if (c >= '0' && c <= '9') {
                    ++digits;
                    whole += point ? 0 : 1;
                } else if (c == '.' && !point) {
                    point = true;
                } else {
                    return false;
                }
            }
            if (digits == 0 || whole >= 39) return false;
            ++read;
            at = k;
        }
        more = read == need && line.find_first_not_of(blanks, at) != std::string::npos;
        return true;
    };
    for (unsigned int i = 0; i < nv; ++i) {
        int read = 0;
        uint64_t begun = 0;  // the line the vertex starts on
        while (read < need) {
            if (!std::getline(f, line)) return short_file("vertex", i, nv);
            ++number;
            if (line.find_first_not_of(blanks) == std::string::npos) continue;
            if (begun == 0) begun = number;
            auto where = [&] {
                return "OFF line " + std::to_string(number) + ": vertex " + std::to_string(i) + " (" + quote(line) + ") ";
            };
            const int before = read;
            bool more = false;
            if (!scan_plain(read, more)) {
                read = before;
                numbers.clear();
                numbers.str(line);
                std::streampos word_at = 0;  // where the word >> stopped at begins (it consumes "1e39")
                while (read < need && (word_at = numbers.tellg(), numbers >> x)) ++read;
                numbers.clear();
                if (read < need) numbers.seekg(word_at);
                const bool word_left = bool(numbers >> word);
                if (read < need && word_left) {
                    error = where() + "has " + quote(word) + " where OpenMesh's reader reads number " +
                            std::to_string(read + 1) + " of its " + std::to_string(need);
                    return false;
                }
                more = read == need && word_left;
            }
            if (more && begun != number) {
                // The word after the last number, for the message.
                std::istringstream rest_of(line);
                for (int w = 0; w < need - before && rest_of >> word;) ++w;
                rest_of >> word;
                error = where() + "ends the vertex begun on line " + std::to_string(begun) + " and holds more (" +
                        quote(word) + "...), which OpenMesh's reader drops: that vertex and every later one would "
                        "be read shifted (one vertex a line)";
                return false;
            }
        }
    }
    for (unsigned int i = 0; i < nf; ++i) {
        unsigned int k = 0, idx = 0;
        if (!(f >> k)) return short_file("face", i, nf);
        if (k > kMaxFaceVertices) {
            error = "OFF face " + std::to_string(i) + ": " + face_too_large(k);
            return false;
        }
        for (unsigned int j = 0; j < k; ++j)
            if (!(f >> idx)) return short_file("face", i, nf);
        if (color) {
            std::getline(f, rest);
            continue;
        }
        // Without C in the header OpenMesh reads on after the k indices with >>: anything
        // more on the face's line (a face colour, which Geomview allows in any OFF file; a
        // comment) becomes the next face's vertex count and indices. Refused, naming the line.
        if (f.eof()) break;  // the last index ended the file: nothing follows on its line
        rest.clear();
        std::getline(f, rest);
        if (rest.find_first_not_of(blanks) != std::string::npos) {
            // Where the rest began, for the line number: found here, not by a tellg per face
            // (which was two thirds of a 700k-face OFF import).
            const bool newline = !f.eof();
            f.clear();
            const std::streamoff end = newline ? std::streamoff(f.tellg()) : std::streamoff(size);
            const std::streamoff at = std::max<std::streamoff>(0, end - std::streamoff(rest.size()) - (newline ? 1 : 0));
            f.seekg(0);
            std::string before(size_t(at), '\0');
            f.read(&before[0], std::streamsize(before.size()));
            const uint64_t line_no = 1 + uint64_t(std::count(before.begin(), before.end(), '\n'));
            error = "OFF line " + std::to_string(line_no) + ": face " + std::to_string(i) + " has " + quote(rest) +
                    " after its " + std::to_string(k) + " vertex indices (a face colour, a comment, or a second "
                    "face on the line?), which OpenMesh's reader would read as the next face and Geomview as a "
                    "colour (OpenMesh skips the rest of a face line only when the header is COFF): one face a line";
            return false;
        }
    }
    return true;
}

}  // namespace

std::vector<std::string> obj_referenced_files(const std::string& path) {
    // OpenMesh's OBJ reader opens the trimmed rest of an `mtllib` line as ONE name, joined to
    // the OBJ's folder (OBJReader.cc: getline, trimString, path_ + matFile). The names split
    // at blanks are kept as well (other readers take several libraries per line).
    std::vector<std::string> out;
    std::ifstream f(path, std::ios::binary);
    if (!f) return out;
    const size_t slash = path.find_last_of('/');
    const std::string dir = slash == std::string::npos ? "" : path.substr(0, slash + 1);
    std::string line, keyword, name;
    while (out.size() < kMaxReferencedFiles && std::getline(f, line)) {
        std::istringstream in(line);
        if (!(in >> keyword) || keyword != "mtllib") continue;
        std::string rest;
        std::getline(in, rest);
        const size_t b = rest.find_first_not_of(" \t\r\n"), e = rest.find_last_not_of(" \t\r\n");
        if (b == std::string::npos) continue;
        out.push_back(dir + rest.substr(b, e - b + 1));
        std::istringstream names(rest);
        while (out.size() < kMaxReferencedFiles && names >> name) out.push_back(dir + name);
    }
    return out;
}

Result import_openmesh(const std::string& path, const ImportOptions& options, RawInput& out,
                       std::vector<std::string>& warnings) {
    (void)options;
    out = RawInput{};
    auto bad = [](std::string what) { return Result::fail(Status::kBadInput, 0, std::move(what)); };
    const std::string ext = lower_extension(path);
    std::string error;
    DeclaredCounts declared;  // the face count for the comparison after the read
    if (ext == "ply" && !check_ply(path, error, declared)) return bad(error);
    if (ext == "obj" && !check_obj(path, error, declared)) return bad(error);
    if (ext == "stl" && !check_stl(path, error, declared)) return bad(error);
    if (ext == "off" && !check_off(path, error, declared)) return bad(error);
    Mesh mesh;
    bool ok = false;
    std::vector<std::string> om_lines;
    try {
        OmCapture capture;
        OpenMesh::IO::Options opt;  // positions only
        ok = OpenMesh::IO::read_mesh(mesh, path, opt);
        om_lines = capture.error_lines();
    } catch (const std::bad_alloc&) {
        return bad("out of memory while reading (corrupt element counts?)");
    } catch (const std::exception& e) {
        return bad(std::string("OpenMesh failed: ") + e.what());
    }
    if (!ok) {
        error = "OpenMesh could not read the file as " + ext;
        if (!om_lines.empty()) error += " (" + om_lines.back() + ")";  // its last word: the reason
        return bad(error);
    }
    // OpenMesh's PLY reader parses the header twice (once to decide it can read the file), so
    // each of its header messages comes twice: a message is reported once, where it first came.
    std::set<std::string> seen;
    om_lines.erase(std::remove_if(om_lines.begin(), om_lines.end(),
                                  [&](const std::string& m) { return !seen.insert(m).second; }),
                   om_lines.end());
    constexpr size_t kMaxReaderLines = 5;
    for (size_t i = 0; i < om_lines.size() && i < kMaxReaderLines; ++i)
        warnings.push_back("OpenMesh: " + om_lines[i]);
    if (om_lines.size() > kMaxReaderLines)
        warnings.push_back("OpenMesh: ... " + std::to_string(om_lines.size() - kMaxReaderLines) +
                           " more messages");

    if (declared.lines > 0) out.skipped_primitives["lines"] = declared.lines;
    if (declared.points > 0) out.skipped_primitives["points"] = declared.points;
    const int64_t expected = declared.faces;
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
    if (prim.triangles.empty() && out.rejected_by_reader > 0)
        return bad("no triangles: the reader rejected all " + std::to_string(out.rejected_by_reader) +
                   " faces the file declares (repeated, invalid or unparsable vertex indices; the warnings "
                   "above give the reader's messages)");
    if (prim.triangles.empty() && !out.skipped_primitives.empty()) {
        std::string what = "no triangles (only";
        for (const auto& [kind, n] : out.skipped_primitives) what += " " + std::to_string(n) + " " + kind;
        return bad(what + " elements, which are not traced)");
    }
    if (prim.triangles.empty()) return bad("no triangles");
    out.primitives.push_back(std::move(prim));
    return Result::success();
}

}  // namespace cwbvh::compiler
