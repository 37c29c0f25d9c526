// cwbvh.open and the Scene's file side: info (counts, bounds, build statistics), zero-copy views
// of the stored mesh (VERT/INDX), the view catalog and the ray helpers (camera rays from a
// catalog view, diffuse bounces) over the same functions `cwbvh rays` calls (ray_gen.h,
// view_catalog.h), so the rays are the tool's to the bit.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cstring>
#include <optional>
#include <span>
#include <vector>

#include "common.h"
#include "cwbvh/format/deep_check.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/two_level_file.h"
#include "cwbvh/kernels/view_catalog.h"
#include "scene.h"

namespace cwbvh::python {

std::shared_ptr<const File> SceneHandle::file() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!file_) throw py::value_error(path_ + ": the Scene is closed");
    return file_;
}

std::shared_ptr<const DeviceScene> SceneHandle::device() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return device_;
}

void SceneHandle::set_device(std::shared_ptr<const DeviceScene> device) {
    const std::lock_guard<std::mutex> lock(mutex_);
    device_ = std::move(device);
}

void SceneHandle::close() {
    const std::lock_guard<std::mutex> lock(mutex_);
    file_.reset();
    device_.reset();
}

bool SceneHandle::closed() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return !file_;
}

namespace {

/// Read-only numpy array over rows x cols T's inside the mapping; its base (a capsule holding a
/// reference to the File) keeps the mapping alive after the Scene is closed or collected.
template <class T>
py::array file_view(const std::shared_ptr<const File>& file, const T* data, size_t rows, size_t cols) {
    auto* keep = new std::shared_ptr<const File>(file);
    py::capsule base(keep, [](void* p) { delete static_cast<std::shared_ptr<const File>*>(p); });
    py::array a(py::dtype::of<T>(), {rows, cols}, {cols * sizeof(T), sizeof(T)}, data, base);
    a.attr("setflags")(py::arg("write") = false);
    return a;
}

py::tuple vec3(const float v[3]) { return py::make_tuple(v[0], v[1], v[2]); }

py::dict info(const SceneHandle& h) {
    const std::shared_ptr<const File> f = h.file();
    py::dict d;
    d["path"] = f->path();
    d["version"] = py::make_tuple(f->header().version_major, f->header().version_minor);
    d["file_bytes"] = f->bytes().size();
    d["nodes"] = f->nodes().size();
    d["triangle_records"] = f->triangles().size();
    d["triangles"] = f->stored_triangle_count();
    d["bvh2_nodes"] = f->bvh2().size();
    d["has_mesh"] = !f->vertices().empty() && !f->indices().empty();
    if (const SceneBounds* b = f->bounds()) d["bounds"] = py::make_tuple(vec3(b->lo), vec3(b->hi));
    if (const BuildInfo* b = f->build_info()) {
        py::dict bi;
        bi["builder"] = b->builder == kBuilderEmbree ? "embree" : "sbvh";
        bi["collapse"] = b->collapse == kCollapseGreedy ? "greedy" : "optimal";
        bi["split_alpha"] = b->split_alpha;
        bi["cost_node"] = b->cost_node;
        bi["cost_prim"] = b->cost_prim;
        bi["max_leaf_triangles"] = b->max_leaf_triangles;
        bi["input_triangles"] = b->input_triangles;
        bi["dropped_nonfinite"] = b->dropped_nonfinite;
        bi["dropped_degenerate"] = b->dropped_degenerate;
        bi["skipped_primitives"] = b->skipped_primitives;
        bi["triangles"] = b->triangles;
        bi["references"] = b->references;
        bi["binary_nodes"] = b->binary_nodes;
        bi["wide_nodes"] = b->wide_nodes;
        bi["sah_binary"] = b->sah_binary;
        bi["sah_wide"] = b->sah_wide;
        bi["avg_children"] = b->avg_children;
        d["build"] = bi;
    }
    py::list sections;
    for (const SectionEntry& s : f->layout().table) {
        char tag[5] = {};
        std::memcpy(tag, &s.type, 4);
        sections.append(py::make_tuple(std::string(tag), s.size));
    }
    d["sections"] = sections;
    // Two-level files (format 1.2): the counts of `cwbvh info --json`'s "two_level" object;
    // None for a single-level file.
    d["is_two_level"] = f->is_two_level();
    if (f->is_two_level()) {
        py::dict t;
        t["meshes"] = f->meshes().size();
        t["instances"] = f->instances().size();
        t["top_nodes"] = f->top_nodes().size();
        t["distinct_triangles"] = f->stored_triangle_count();
        t["instanced_triangles"] = f->instanced_triangle_count();
        d["two_level"] = t;
    } else {
        d["two_level"] = py::none();
    }
    return d;
}

/// Read-only (count, record size) uint8 view of a section's records (Python views it with the
/// record's numpy dtype).
template <class T>
py::array record_bytes(const std::shared_ptr<const File>& file, std::span<const T> records) {
    return file_view(file, reinterpret_cast<const uint8_t*>(records.data()), records.size(), sizeof(T));
}

/// PMAP's source of each stored triangle id: (N, 4) uint32 (input, mesh, primitive, triangle);
/// a row of kInvalidIndex for MISS or an id no range holds.
py::array sources(const SceneHandle& h, py::array_t<uint32_t, py::array::c_style | py::array::forcecast> prims) {
    const auto f = h.file();
    if (prims.ndim() != 1) throw py::value_error("sources: prim must be a 1-D array of stored triangle ids");
    const size_t n = size_t(prims.shape(0));
    py::array_t<uint32_t> out({py::ssize_t(n), py::ssize_t(4)});
    const uint32_t* in = prims.data();
    uint32_t* o = out.mutable_data();
    {
        py::gil_scoped_release release;
        for (size_t i = 0; i < n; ++i) {
            const std::optional<SourceRef> s = in[i] == kInvalidIndex ? std::nullopt : f->source_of(in[i]);
            o[4 * i + 0] = s ? s->input : kInvalidIndex;
            o[4 * i + 1] = s ? s->mesh : kInvalidIndex;
            o[4 * i + 2] = s ? s->primitive : kInvalidIndex;
            o[4 * i + 3] = s ? s->triangle : kInvalidIndex;
        }
    }
    return out;
}

std::shared_ptr<SceneHandle> open_scene(const std::string& path, bool deep, bool verify_checksums) {
    std::shared_ptr<SceneHandle> h;
    {
        py::gil_scoped_release release;  // checksums and the deep check read the whole file
        OpenOptions o;
        o.verify_checksums = verify_checksums;
        Expected<File> f = File::open(path, o);
        if (!f.ok()) {
            Result r = f.error();
            r.message = r.describe();  // what `cwbvh validate` prints: the message and [rule N]
            throw ResultError(std::move(r));
        }
        if (deep) {
            // `cwbvh validate --deep`: D1-D4 (per mesh in a two-level file), then D7 over the
            // top level (mesh boxes, instance world boxes, TLAS boxes, BNDS).
            DeepCheckStats st;
            Result r = deep_check(f->nodes(), f->triangles(), f->stored_triangle_count(), &st);
            if (r.ok() && f->is_two_level())
                r = deep_check_two_level(f->triangles(),
                                         TwoLevelView{f->meshes(), f->instances(), f->top_nodes(), f->bounds()}, &st);
            if (!r.ok()) {
                r.message = path + ": " + r.describe();
                throw ResultError(std::move(r));
            }
        }
        h = std::make_shared<SceneHandle>(std::move(*f));
    }
    h->set_path(path);
    return h;
}

/// The catalog `catalog` names (a path), else the default one (view_catalog.h).
ViewCatalog load_catalog(const std::string& catalog, CatalogLoad& loaded) {
    ViewCatalog c;
    const Result r = load_view_catalog(catalog, c, loaded);
    if (loaded == CatalogLoad::kError) throw ResultError(r);
    return c;
}

py::dict view_dict(const View& v) {
    py::dict d;
    d["scene"] = v.scene;
    d["name"] = v.name;
    d["eye"] = vec3(v.camera.eye);
    d["target"] = vec3(v.camera.target);
    d["fov"] = v.camera.fov_deg;
    d["line"] = v.line;
    d["camera"] = format_camera(v.camera);
    return d;
}

/// The view `which` (a name, a 1-based index, or "" for the first) among views() of `scene`: a
/// scene of the catalog has the catalog's views, found as `cwbvh rays --view` finds them; a scene
/// the catalog does not list (or any scene without a catalog) has one view, "default" (index 1).
View pick_view(const File& f, const std::string& scene, const std::string& which, const std::string& catalog) {
    CatalogLoad loaded = CatalogLoad::kError;
    const ViewCatalog c = load_catalog(catalog, loaded);
    const std::vector<View> views = benchmark_views(c, scene, *f.bounds());
    if (which.empty()) return views.front();
    if (c.has_scene(scene)) {
        View v;
        const Result r = c.find(scene, which, v);
        if (!r.ok()) throw py::value_error(r.message);
        return v;
    }
    if (names_default_view(which)) return views.front();
    const bool index = which.find_first_not_of("0123456789") == std::string::npos;
    const std::string where = loaded == CatalogLoad::kLoaded ? "in " + c.source()
                                                             : "(no view catalog at " + default_view_catalog_path() + ")";
    throw py::value_error((index ? "view " + which + " out of range" : "no view '" + which + "'") + ": scene '" +
                          scene + "' has no views " + where + "; its one view is 1 " + views.front().name +
                          " (the default camera)");
}

/// parse_camera's message, which names the tool's option ("--camera: ..."), as camera_rays' own.
std::string camera_message(std::string message) {
    const std::string option = "--camera: ";
    if (message.rfind(option, 0) == 0) message.erase(0, option.size());
    return "camera_rays: camera: " + message;
}

Camera camera_from(py::handle camera) {
    Camera c;
    if (py::isinstance<py::str>(camera)) {
        const Result r = parse_camera(camera.cast<std::string>(), c);
        if (!r.ok()) throw py::value_error(camera_message(r.message));
        return c;
    }
    const auto v = camera.cast<std::vector<float>>();
    if (v.size() != 7) throw py::value_error("camera_rays: camera: give eye (3), target (3) and fov: 7 numbers");
    std::copy(v.begin(), v.begin() + 3, c.eye);
    std::copy(v.begin() + 3, v.begin() + 6, c.target);
    c.fov_deg = v[6];
    Camera check;  // parse_camera's rules (finite, 0 < fov < 180, eye != target) on the numbers
    if (const Result r = parse_camera(format_camera(c), check); !r.ok()) throw py::value_error(camera_message(r.message));
    return c;
}

py::array rays_array(std::vector<Ray>&& rays) {
    auto* keep = new std::vector<Ray>(std::move(rays));
    py::capsule base(keep, [](void* p) { delete static_cast<std::vector<Ray>*>(p); });
    return py::array(py::dtype::of<float>(), {keep->size(), size_t(8)}, {sizeof(Ray), sizeof(float)},
                     reinterpret_cast<const float*>(keep->data()), base);
}

}  // namespace

void bind_scene(py::module_& m) {
    py::class_<SceneHandle, std::shared_ptr<SceneHandle>>(m, "SceneHandle")
        .def_property_readonly("path", &SceneHandle::path)
        .def_property_readonly("closed", &SceneHandle::closed)
        .def("close", &SceneHandle::close)
        .def("info", &info)
        .def("vertices", [](const SceneHandle& h) {
            const auto f = h.file();
            return file_view(f, f->vertices().data(), f->vertices().size() / 3, 3);
        })
        .def("indices", [](const SceneHandle& h) {
            const auto f = h.file();
            return file_view(f, f->indices().data(), f->indices().size() / 3, 3);
        })
        .def_property_readonly("is_two_level", [](const SceneHandle& h) { return h.file()->is_two_level(); })
        .def("meshes", [](const SceneHandle& h) {
            const auto f = h.file();
            return record_bytes(f, f->meshes());
        })
        .def("instances", [](const SceneHandle& h) {
            const auto f = h.file();
            return record_bytes(f, f->instances());
        })
        .def("sources", &sources, py::arg("prim"))
        .def("views", [](const SceneHandle& h, const std::string& scene, const std::string& catalog) {
            const auto f = h.file();
            CatalogLoad loaded = CatalogLoad::kError;
            const ViewCatalog c = load_catalog(catalog, loaded);
            py::list out;
            for (const View& v : benchmark_views(c, scene, *f->bounds())) out.append(view_dict(v));
            return out;
        })
        .def("view", [](const SceneHandle& h, const std::string& scene, const std::string& which,
                        const std::string& catalog) { return view_dict(pick_view(*h.file(), scene, which, catalog)); })
        .def("camera_rays",
             [](const SceneHandle& h, py::handle camera, uint32_t width, uint32_t height) {
                 if (width == 0 || height == 0 || width > 16384 || height > 16384)
                     throw py::value_error("camera_rays: width and height must be in [1, 16384]");
                 const Camera c = camera_from(camera);
                 (void)h.file();
                 std::vector<Ray> rays;
                 {
                     py::gil_scoped_release release;
                     rays = camera_rays(c, width, height);
                 }
                 return rays_array(std::move(rays));
             })
        .def("diffuse_rays",
             [](const SceneHandle& h, py::array_t<float, py::array::c_style | py::array::forcecast> primary,
                uint32_t bounce, uint32_t seed, unsigned threads) {
                 if (primary.ndim() != 2 || primary.shape(1) != 8)
                     throw py::value_error("diffuse_rays: primary must have shape (N, 8) (the ray-file layout)");
                 if (bounce < 1 || bounce > 64) throw py::value_error("diffuse_rays: bounce must be in [1, 64]");
                 const auto f = h.file();
                 const auto n = f->nodes();
                 const auto t = f->triangles();
                 std::vector<Ray> in(size_t(primary.shape(0)));
                 std::memcpy(in.data(), primary.data(), in.size() * sizeof(Ray));
                 DiffuseRays d;
                 {
                     py::gil_scoped_release release;
                     // A two-level scene bounces off the world-space triangle of each hit, as
                     // `cwbvh rays --diffuse` does.
                     TwoLevelScene two;
                     d = two_level_scene(*f, two) ? diffuse_rays(two, in, bounce, seed, threads)
                                                  : diffuse_rays(n.data(), n.size(), t.data(), t.size(), in, bounce,
                                                                 seed, threads);
                 }
                 py::array_t<uint32_t> path(py::ssize_t(d.path.size()));
                 std::memcpy(path.mutable_data(), d.path.data(), d.path.size() * sizeof(uint32_t));
                 return py::make_tuple(rays_array(std::move(d.rays)), path);
             });
    m.def("open", &open_scene, py::arg("path"), py::arg("deep") = false, py::arg("verify_checksums") = true);
    m.def("default_view_catalog", &default_view_catalog_path);
    m.def("scene_key", &scene_key);
}

}  // namespace cwbvh::python
