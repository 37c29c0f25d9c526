// The catalog of benchmark viewpoints (views/catalog.txt; format in spec/rays.md,
// "View catalog"): named pinhole cameras per scene, read by `cwbvh rays --view`,
// cwbvh_gpu_check and bench/run.py, so every benchmark looks at a scene from the
// same places (inside the enclosed scenes). A scene without catalog views uses
// default_camera (ray_gen.h). Host only. Library: cwbvh_cpu_trace.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray_gen.h"

namespace cwbvh {

/// The catalog format version this build reads ("cwbvh-views 1").
inline constexpr int kViewCatalogVersion = 1;

struct View {
    std::string scene;  ///< scene key: the stem of the input file ("sponza_dabrovic")
    std::string name;   ///< unique within its scene; starts with a letter
    Camera camera;
    uint32_t line = 0;  ///< line in the catalog; 0 for the default camera
};

class ViewCatalog {
public:
    /// Parses catalog text. On bad input returns kBadInput with one line
    /// "<source>:<line>: <what is wrong>" (`out` is left unchanged).
    static Result parse(const std::string& text, const std::string& source, ViewCatalog& out);
    /// Reads and parses `path`; kIoError "<path>: cannot read: <reason>" when it cannot be read.
    static Result load(const std::string& path, ViewCatalog& out);

    const std::string& source() const { return source_; }
    const std::vector<View>& views() const { return views_; }
    bool has_scene(const std::string& scene) const;
    /// The views of `scene` in catalog order; empty when the scene is not in the catalog.
    std::vector<View> views_of(const std::string& scene) const;
    /// `which` is a view name or a 1-based index (decimal digits) among the views of
    /// `scene`. kInvalidArgument with a one-line message naming the scene's views otherwise.
    Result find(const std::string& scene, const std::string& which, View& out) const;

private:
    std::string source_;
    std::vector<View> views_;
};

/// The catalog a tool reads by default: $CWBVH_VIEWS when set and non-empty, else
/// the path compiled in (CWBVH_VIEW_CATALOG: the source tree's views/catalog.txt).
std::string default_view_catalog_path();

enum class CatalogLoad {
    kLoaded,  ///< `out` holds the catalog
    kAbsent,  ///< the compiled-in default catalog does not exist (an installed tool without
              ///< its source tree): use default cameras; the returned Result says why
    kError,   ///< a named catalog (--views, $CWBVH_VIEWS) is unreadable, or any catalog is malformed
};

/// Loads the catalog a tool uses: `path` when non-empty (a --views option), else
/// default_view_catalog_path(). Only the compiled-in default may be absent. `loaded`
/// says which case it was; the Result is ok exactly when `loaded` is kLoaded.
Result load_view_catalog(const std::string& path, ViewCatalog& out, CatalogLoad& loaded);

/// Scene key of a path: the file name without its directories and its last
/// extension ("scenes/sponza_dabrovic.cwbvh" -> "sponza_dabrovic").
std::string scene_key(const std::string& path);

/// The views a benchmark uses for `scene`: the catalog's, or, for a scene not in the
/// catalog, one view "default" = default_camera(bounds) with line 0.
std::vector<View> benchmark_views(const ViewCatalog& catalog, const std::string& scene, const SceneBounds& bounds);

/// Whether `which` (a view name or 1-based index, as --view takes it) names the one view of a
/// scene outside the catalog: "default", or the index 1 ("1", "01"; at most 9 digits, as
/// ViewCatalog::find reads indices). `cwbvh rays|render --view` and Python's cwbvh.view agree.
bool names_default_view(const std::string& which);

/// "ex,ey,ez,tx,ty,tz,fov" with each number printed so that it reads back exactly
/// (parse_camera(format_camera(c)) == c).
std::string format_camera(const Camera& camera);

}  // namespace cwbvh
