// View catalog (see view_catalog.h; format in spec/rays.md, "View catalog").
#include "cwbvh/kernels/view_catalog.h"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "cwbvh/format/file_io.h"

#ifndef CWBVH_VIEW_CATALOG
#define CWBVH_VIEW_CATALOG "views/catalog.txt"
#endif

namespace cwbvh {
namespace {

constexpr const char* kHeaderWord = "cwbvh-views";
constexpr size_t kMaxCatalogBytes = size_t(1) << 20;  // a catalog is a few kB; refuse anything absurd

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_letter(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

std::vector<std::string> split_fields(const std::string& line) {
    std::vector<std::string> out;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && is_space(line[i])) ++i;
        const size_t b = i;
        while (i < line.size() && !is_space(line[i])) ++i;
        if (i > b) out.push_back(line.substr(b, i - b));
    }
    return out;
}

/// Scene keys are file stems: letters, digits, '_', '-', '.'.
bool valid_scene_key(const std::string& s) {
    if (s.empty()) return false;
    for (char c : s)
        if (!is_letter(c) && !is_digit(c) && c != '_' && c != '-' && c != '.') return false;
    return true;
}

/// View names start with a letter (so an all-digit --view argument is always an index).
bool valid_view_name(const std::string& s) {
    if (s.empty() || !is_letter(s[0])) return false;
    for (char c : s)
        if (!is_letter(c) && !is_digit(c) && c != '_' && c != '-') return false;
    return true;
}

std::string printable(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c >= 0x20 && c < 0x7F) {
            o += c;
        } else {
            char b[8];
            std::snprintf(b, sizeof b, "\\x%02X", unsigned(static_cast<unsigned char>(c)));
            o += b;
        }
    }
    return o;
}

std::string join_names(const std::vector<View>& v) {
    std::string s;
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(i + 1) + " " + v[i].name;
    return s;
}

}  // namespace

Result ViewCatalog::parse(const std::string& text, const std::string& source, ViewCatalog& out) {
    ViewCatalog cat;
    cat.source_ = source;
    auto fail = [&](size_t line, const std::string& what) {
        return Result::fail(Status::kBadInput, 0, source + ":" + std::to_string(line) + ": " + what);
    };
    if (text.size() > kMaxCatalogBytes)
        return fail(1, "catalog larger than " + std::to_string(kMaxCatalogBytes) + " bytes");
    size_t pos = 0, line_no = 0;
    bool header = false;
    while (pos < text.size() || (line_no == 0 && !header)) {
        size_t end = text.find('\n', pos);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(pos, end - pos);
        pos = end + 1;
        ++line_no;
        if (line.find('\0') != std::string::npos) return fail(line_no, "NUL byte in a text file");
        if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
        const std::vector<std::string> f = split_fields(line);
        if (!header) {
            // Line 1 is the version header, nothing else (a comment may follow it).
            if (f.size() != 2 || f[0] != kHeaderWord) {
                return fail(line_no, std::string("expected the header '") + kHeaderWord + " " +
                                         std::to_string(kViewCatalogVersion) + "' on line 1, got '" +
                                         printable(line) + "'");
            }
            if (f[1] != std::to_string(kViewCatalogVersion)) {
                return fail(line_no, "unsupported catalog version '" + printable(f[1]) + "' (this build reads " +
                                         kHeaderWord + " " + std::to_string(kViewCatalogVersion) + ")");
            }
            header = true;
            continue;
        }
        if (f.empty()) continue;
        if (f.size() != 3) {
            return fail(line_no, "expected 3 fields 'SCENE VIEW ex,ey,ez,tx,ty,tz,fov', got " +
                                     std::to_string(f.size()));
        }
        if (!valid_scene_key(f[0]))
            return fail(line_no, "scene key '" + printable(f[0]) + "': use letters, digits, '_', '-', '.'");
        if (!valid_view_name(f[1])) {
            return fail(line_no, "view name '" + printable(f[1]) +
                                     "': must start with a letter and use letters, digits, '_', '-'");
        }
        for (char c : f[2]) {
            if (!is_digit(c) && c != ',' && c != '.' && c != '-' && c != '+' && c != 'e' && c != 'E')
                return fail(line_no, "camera '" + printable(f[2]) + "': unexpected character");
        }
        View v;
        v.scene = f[0];
        v.name = f[1];
        v.line = uint32_t(line_no);
        if (Result cam = parse_camera(f[2], v.camera); !cam.ok()) {
            std::string& cam_error = cam.message;
            // parse_camera words its errors for the --camera option; name the field instead.
            const std::string prefix = "--camera: ";
            if (cam_error.rfind(prefix, 0) == 0) cam_error.erase(0, prefix.size());
            return fail(line_no, "camera: " + cam_error);
        }
        for (const View& o : cat.views_) {
            if (o.scene == v.scene && o.name == v.name) {
                return fail(line_no, "duplicate view '" + v.name + "' of scene '" + v.scene + "' (first on line " +
                                         std::to_string(o.line) + ")");
            }
        }
        cat.views_.push_back(std::move(v));
    }
    out = std::move(cat);
    return Result::success();
}

Result ViewCatalog::load(const std::string& path, ViewCatalog& out) {
    // A regular file only (a FIFO would block, a device never end), of at most 16 MiB.
    constexpr uint64_t kMaxCatalogBytes = uint64_t(16) << 20;
    std::vector<uint8_t> bytes;
    if (Result r = read_regular_file(path, kMaxCatalogBytes, bytes); !r.ok()) return r;
    return parse(std::string(bytes.begin(), bytes.end()), path, out);
}

bool ViewCatalog::has_scene(const std::string& scene) const {
    for (const View& v : views_)
        if (v.scene == scene) return true;
    return false;
}

std::vector<View> ViewCatalog::views_of(const std::string& scene) const {
    std::vector<View> out;
    for (const View& v : views_)
        if (v.scene == scene) out.push_back(v);
    return out;
}

Result ViewCatalog::find(const std::string& scene, const std::string& which, View& out) const {
    auto fail = [](std::string what) { return Result::fail(Status::kInvalidArgument, 0, std::move(what)); };
    const std::vector<View> vs = views_of(scene);
    if (vs.empty()) return fail("scene '" + scene + "' has no views in " + source_);
    bool digits = !which.empty();
    for (char c : which) digits = digits && is_digit(c);
    if (digits) {
        // At most 9 digits: no overflow, and any index past the list is reported as such.
        const unsigned long n = which.size() <= 9 ? std::strtoul(which.c_str(), nullptr, 10) : 0;
        if (n < 1 || n > vs.size()) {
            return fail("view " + printable(which) + " out of range: scene '" + scene + "' has " +
                        std::to_string(vs.size()) + " views in " + source_ + " (" + join_names(vs) + ")");
        }
        out = vs[n - 1];
        return Result::success();
    }
    for (const View& v : vs) {
        if (v.name == which) {
            out = v;
            return Result::success();
        }
    }
    return fail("no view '" + printable(which) + "' of scene '" + scene + "' in " + source_ + " (" + join_names(vs) +
                ")");
}

std::string default_view_catalog_path() {
    const char* env = std::getenv("CWBVH_VIEWS");
    if (env != nullptr && *env != '\0') return env;
    return CWBVH_VIEW_CATALOG;
}

Result load_view_catalog(const std::string& path, ViewCatalog& out, CatalogLoad& loaded) {
    const char* env = std::getenv("CWBVH_VIEWS");
    const bool named = !path.empty() || (env != nullptr && *env != '\0');
    const std::string p = path.empty() ? default_view_catalog_path() : path;
    Result r = ViewCatalog::load(p, out);
    if (r.ok()) {
        loaded = CatalogLoad::kLoaded;
    } else {
        loaded = !named && !std::ifstream(p) ? CatalogLoad::kAbsent : CatalogLoad::kError;
    }
    return r;
}

std::string scene_key(const std::string& path) {
    const size_t slash = path.find_last_of('/');
    std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
    const size_t dot = name.find_last_of('.');
    if (dot != std::string::npos && dot > 0) name.resize(dot);
    return name;
}

std::vector<View> benchmark_views(const ViewCatalog& catalog, const std::string& scene, const SceneBounds& bounds) {
    std::vector<View> vs = catalog.views_of(scene);
    if (vs.empty()) {
        View d;
        d.scene = scene;
        d.name = "default";
        d.camera = default_camera(bounds);
        vs.push_back(d);
    }
    return vs;
}

bool names_default_view(const std::string& which) {
    if (which == "default") return true;
    if (which.empty() || which.size() > 9 || which.find_first_not_of("0123456789") != std::string::npos) return false;
    return std::stoul(which) == 1;
}

std::string format_camera(const Camera& c) {
    const float v[7] = {c.eye[0], c.eye[1], c.eye[2], c.target[0], c.target[1], c.target[2], c.fov_deg};
    std::string s;
    for (int i = 0; i < 7; ++i) {
        // Shortest %g form from 6 digits up (no exponent below 1e6) that reads back to the
        // same float (9 digits always do).
        char buf[32];
        for (int prec = 6; prec <= 9; ++prec) {
            std::snprintf(buf, sizeof buf, "%.*g", prec, double(v[i]));
            if (float(std::strtod(buf, nullptr)) == v[i]) break;
        }
        s += (i ? "," : "") + std::string(buf);
    }
    return s;
}

}  // namespace cwbvh
