// The `spangle` Python module (import spangle): load any scene Spangle reads into a session, edit
// its materials, object transforms, camera and lights, render with progress and a way to stop,
// and get the beauty and every render layer as numpy arrays; write EXR/PNG through the CLI's own
// outputs. The GIL is released while rendering; errors are Python exceptions carrying the
// message's file:line.

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <filesystem>

#include <cxxabi.h>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <thread>

#include "cli/output_paths.h"
#include "cli/outputs.h"
#include "core/error.h"
#include "session.h"
#include "shading/plugin_call.h"

namespace py = pybind11;

namespace spangle::py_bind {

using spangle::python::ParamValue;
using spangle::python::PySession;
using spangle::python::RenderedImage;

namespace {

/** The renders under way, so that the interpreter's exit can stop them. Python ends a daemon
 *  thread that wants the GIL once finalisation has begun by unwinding it, and a render's
 *  callbacks run on TBB's threads, which catch that unwinding (the process aborted). An atexit
 *  hook, which runs before finalisation while daemon threads still live, stops every render and
 *  waits for it with the GIL released; renders asked for after it raise. Never destroyed (static
 *  destructors run after the interpreter is gone). */
struct ActiveRenders {
    std::mutex m;
    std::condition_variable cv;
    std::set<PySession*> sessions;  // one render at a time per session
    bool exiting = false;
};
ActiveRenders& active_renders() {
    static auto* a = new ActiveRenders;
    return *a;
}

/** Registers a render for its lifetime (throws when the interpreter is exiting). */
class RenderUnderWay {
public:
    explicit RenderUnderWay(PySession& s) : s_(s) {
        ActiveRenders& a = active_renders();
        std::lock_guard<std::mutex> l(a.m);
        if (a.exiting) throw SpangleError("render(): the interpreter is exiting");
        a.sessions.insert(&s_);
    }
    ~RenderUnderWay() {
        ActiveRenders& a = active_renders();
        std::lock_guard<std::mutex> l(a.m);
        a.sessions.erase(&s_);
        a.cv.notify_all();
    }
    RenderUnderWay(const RenderUnderWay&) = delete;
    RenderUnderWay& operator=(const RenderUnderWay&) = delete;

private:
    PySession& s_;
};

/** The atexit hook: stops the renders under way and waits for them to end. */
void stop_renders_at_exit() {
    py::gil_scoped_release release;
    ActiveRenders& a = active_renders();
    std::unique_lock<std::mutex> l(a.m);
    a.exiting = true;
    for (PySession* s : a.sessions) s->stop();
    a.cv.wait(l, [&] { return a.sessions.empty(); });
}

/** spangle.SceneError, a RuntimeError with file, line and column attributes. */
PyObject* g_scene_error = nullptr;

/** Raises SceneError from a SpangleError, with the location its message starts with. */
void raise_scene_error(const SpangleError& e) {
    const std::string msg = e.what();
    static const std::regex loc(R"(^(.+?)(?::(\d+))?(?::(\d+))?: error: )");
    py::object err = py::reinterpret_borrow<py::object>(g_scene_error)(msg);
    std::smatch m;
    if (std::regex_search(msg, m, loc)) {
        err.attr("file") = m[1].str();
        err.attr("line") = m[2].matched ? std::stoi(m[2].str()) : 0;
        err.attr("column") = m[3].matched ? std::stoi(m[3].str()) : 0;
    } else {
        err.attr("file") = py::none();
        err.attr("line") = 0;
        err.attr("column") = 0;
    }
    PyErr_SetObject(g_scene_error, err.ptr());
}

Vec3 vec3(const std::array<double, 3>& a) {
    return Vec3(static_cast<float>(a[0]), static_cast<float>(a[1]), static_cast<float>(a[2]));
}
/** Real numbers given as a number, a (nested) list or a numpy array: their shape and values,
 *  row by row. Anything else (strings, complex or boolean numbers, ragged lists) is a
 *  SceneError at `at` naming `what`. */
struct RealArray {
    std::vector<std::size_t> shape;
    std::vector<double> values;
    std::string describe() const {
        if (shape.empty()) return "one number";
        return fmt::format("an array of shape ({})", fmt::join(shape, ", "));
    }
};
RealArray real_array(const py::object& in, const FileLoc& at, const char* what) {
    const auto np = py::module_::import("numpy");
    py::array raw;
    try {
        raw = np.attr("asarray")(in);
    } catch (const py::error_already_set&) {
        throw SpangleError(at, fmt::format("{} takes real numbers", what));
    }
    const char kind = raw.dtype().kind();
    // Python objects (Decimal, Fraction) are numbers when float() takes them.
    if (kind == 'O') {
        try {
            raw = np.attr("asarray")(in, "float64");
        } catch (const py::error_already_set&) {
            throw SpangleError(at, fmt::format("{} takes real numbers", what));
        }
    } else if (kind != 'f' && kind != 'i' && kind != 'u')
        throw SpangleError(at, fmt::format("{} takes real numbers, got numpy dtype {}", what,
                                           py::str(raw.dtype()).cast<std::string>()));
    RealArray out;
    for (py::ssize_t d = 0; d < raw.ndim(); ++d)
        out.shape.push_back(static_cast<std::size_t>(raw.shape(d)));
    const py::array_t<double> flat =
        np.attr("asarray")(raw, "float64").attr("reshape")(-1).cast<py::array_t<double>>();
    out.values.assign(flat.data(), flat.data() + flat.size());
    return out;
}

std::optional<Vec3> vec3(const std::optional<std::array<double, 3>>& a) {
    return a ? std::optional<Vec3>(vec3(*a)) : std::nullopt;
}
py::tuple tuple3(Vec3 v) {
    return py::make_tuple(v.x, v.y, v.z);
}

/** An H x W x C float32 array of `channels` interleaved channels starting at `first` of
 *  `stride` per pixel. */
py::array_t<float> image_array(const std::vector<float>& data, uint32_t w, uint32_t h,
                               std::size_t stride, std::size_t first, std::size_t channels) {
    py::array_t<float> a({static_cast<py::ssize_t>(h), static_cast<py::ssize_t>(w),
                          static_cast<py::ssize_t>(channels)});
    float* out = a.mutable_data();
    const std::size_t n = static_cast<std::size_t>(w) * h;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t c = 0; c < channels; ++c)
            out[i * channels + c] = data[i * stride + first + c];
    return a;
}

/** The layers by name: channels "albedo.R", "albedo.G", "albedo.B" make "albedo" (H x W x 3);
 *  a channel without a dot is a layer of one channel. */
py::dict layer_arrays(const RenderResult& r) {
    py::dict out;
    const std::size_t stride = r.layer_names.size();
    std::size_t k = 0;
    while (k < stride) {
        const std::string& name = r.layer_names[k];
        const std::size_t dot = name.rfind('.');
        const std::string layer = dot == std::string::npos ? name : name.substr(0, dot);
        std::size_t end = k + 1;
        while (dot != std::string::npos && end < stride && r.layer_names[end].rfind('.') == dot &&
               r.layer_names[end].compare(0, dot, layer) == 0)
            ++end;
        out[py::str(layer)] = image_array(r.layers, r.width, r.height, stride, k, end - k);
        k = end;
    }
    return out;
}

/** A material parameter's value from Python: bool, int, float, str or three numbers. */
ParamValue param_value(const std::string& key, const py::handle& v) {
    if (py::isinstance<py::bool_>(v)) return v.cast<bool>();
    if (py::isinstance<py::int_>(v)) {
        // Beyond 64 bits: say which parameter, not pybind's "Unable to cast".
        try {
            return v.cast<long long>();
        } catch (const py::cast_error&) {
            throw SpangleError("python: set_material(): parameter '" + key + "' " +
                               py::str(v).cast<std::string>() + " is out of range");
        }
    }
    if (py::isinstance<py::float_>(v)) return v.cast<double>();
    // numpy scalars (np.float32(3), np.int32, np.bool_) as the Python numbers they stand for,
    // as set_camera and render take them.
    const py::object numpy_generic = []() -> py::object {
        try {
            return py::module_::import("numpy").attr("generic");
        } catch (const py::error_already_set&) {
            return py::object();
        }
    }();
    if (numpy_generic && py::isinstance(v, numpy_generic))
        return param_value(key, v.attr("item")());
    if (py::isinstance<py::str>(v)) return v.cast<std::string>();
    if (py::isinstance<py::sequence>(v) && py::len(v) == 3) return v.cast<std::array<double, 3>>();
    throw py::type_error("parameter '" + key +
                         "': expected a bool, an int, a float, a str or three numbers");
}

py::object param_to_python(const ParamDesc& p) {
    switch (p.kind) {
        case ParamDesc::Kind::Bool:
            return py::bool_(p.number != 0.0);
        case ParamDesc::Kind::Number:
            return p.is_integer ? py::object(py::int_(static_cast<long long>(p.number)))
                                : py::object(py::float_(p.number));
        case ParamDesc::Kind::String:
            return py::str(p.text);
        case ParamDesc::Kind::Color:
            return tuple3(p.color.rgb);
        case ParamDesc::Kind::Texture: {
            py::dict t;
            if (!p.texture.path.empty()) t["texture"] = p.texture.path;
            if (p.texture.vertex_color) t["vertex_color"] = true;
            return t;
        }
    }
    return py::none();
}

/** Writes a rendered image as the CLI does: the EXR (half floats unless `full_float`, with the
 *  layers when there are any) and, unless `preview` is empty, its PNG through the OCIO view. */
void write_image(const RenderedImage& img, const std::string& path, const std::string& preview,
                 bool full_float, const std::string& compression) {
    Outputs out;
    out.exr = path;
    out.preview = preview;
    out.scene = img.scene;
    out.exr_options.half = !full_float;
    out.exr_options.compression = compression;
    const auto& valid = exr_compressions();
    if (std::find(valid.begin(), valid.end(), compression) == valid.end())
        throw SpangleError(fmt::format("unknown EXR compression '{}'", compression));
    if (path.size() < 4 || path.compare(path.size() - 4, 4, ".exr") != 0)
        throw SpangleError(fmt::format("output '{}' must end in .exr", path));
    if (!img.info || !img.color) throw SpangleError("write(): this image holds no render");
    // As spangle render: never over a file the scene reads (the scene file, a mesh, a texture,
    // a map), and no compression that is lossy for the layers' 32-bit data.
    out.check_not_inputs(img.inputs, "path=", "preview=");
    if (!img.result.layer_names.empty() && lossy_for_floats(compression))
        throw SpangleError(fmt::format(
            "write(): compression '{}' is lossy for 32-bit floats and would corrupt the data "
            "layers (object and material ids, depth, positions, normals): use zip, zips, piz, "
            "rle, b44, b44a or none, or render with layers=False",
            compression));
    out.write(final_image(img.result, *img.color, *img.info));
}

}  // namespace

}  // namespace spangle::py_bind

PYBIND11_MODULE(_spangle, m) {
    using namespace spangle;
    using namespace spangle::py_bind;
    m.doc() = "Spangle, an offline renderer for glitter, from Python (see docs/python.md).";
    // A plugin that crashes takes the interpreter with it (nothing can be caught): its last
    // words name the plugin, the material and the kernel, as the command line's do (Python died
    // without a word), before the signal goes on to Python's own handler or the default.
    name_plugin_crashes();
    static py::exception<SpangleError> scene_error(m, "SceneError", PyExc_RuntimeError);
    g_scene_error = scene_error.ptr();
    // A SpangleError leaving a binding (after any released GIL is taken again) becomes SceneError.
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const SpangleError& e) {
            raise_scene_error(e);
        }
    });
    m.attr("__version__") = SPANGLE_VERSION;
    m.def("_set_module_location", &spangle::python::set_module_location);
    py::module_::import("atexit").attr("register")(py::cpp_function(&stop_renders_at_exit));
    // pybind11 imports numpy's C API on the first array made, inside a function-local static
    // that releases the GIL while numpy imports: two threads making their first arrays at once
    // (two images read, two on_pass callbacks) each waited for the other for ever. Made here,
    // at import, on one thread. Without numpy the module still imports; arrays then raise.
    try {
        const py::array_t<float> first(0);
        (void)first;
    } catch (const py::error_already_set&) {
    }

    py::class_<RenderedImage>(m, "Image", "A rendered image: the beauty, its layers, its samples.")
        .def_property_readonly(
            "beauty",
            [](const RenderedImage& i) {
                return image_array(i.result.image, i.result.width, i.result.height, 3, 0, 3);
            },
            "RGB in the scene's working space, float32, H x W x 3.")
        .def_property_readonly(
            "layers", [](const RenderedImage& i) { return layer_arrays(i.result); },
            "The render layers by name (alpha, albedo, normal, depth, position, glints, one per "
            "light group), each float32 H x W x C; empty unless rendered with layers=True.")
        .def_property_readonly(
            "glints",
            [](const RenderedImage& i) -> py::object {
                py::dict l = layer_arrays(i.result);
                return l.contains("glints") ? py::object(l["glints"]) : py::object(py::none());
            },
            "The glints alone (the part of the beauty the discrete flakes make), or None.")
        .def_property_readonly(
            "spp", [](const RenderedImage& i) { return i.result.stats.spp_reached; },
            "Samples per pixel reached.")
        .def_property_readonly(
            "spp_mean",
            [](const RenderedImage& i) {
                return i.result.stats.pixel_spp_mean > 0.0
                           ? i.result.stats.pixel_spp_mean
                           : static_cast<double>(i.result.stats.spp_reached);
            },
            "Samples per pixel on average: below spp where adaptive sampling stopped pixels.")
        .def_property_readonly(
            "denoised", [](const RenderedImage& i) { return i.result.stats.denoised; },
            "Whether the beauty was denoised (render(denoise=True); False where the image was "
            "too small to filter, with a warning).")
        .def_property_readonly(
            "stopped",
            [](const RenderedImage& i) {
                return i.result.stats.spp_reached < i.result.stats.spp_target;
            },
            "Whether stop() ended it early.")
        .def_property_readonly(
            "seconds", [](const RenderedImage& i) { return i.result.stats.seconds; },
            "Render time in seconds.")
        .def_property_readonly("width", [](const RenderedImage& i) { return i.result.width; })
        .def_property_readonly("height", [](const RenderedImage& i) { return i.result.height; });

    py::class_<PySession>(m, "Session", "A live scene to edit and render.")
        .def(py::init([](const py::object& plugin_path, const std::string& ocio, int threads,
                         bool verbose) {
                 // One folder (a str or os.PathLike) or a list of them; each must be a folder (a
                 // typo was searched silently, the plugins then found elsewhere or not at all).
                 std::vector<std::string> dirs;
                 const py::object fspath = py::module_::import("os").attr("fspath");
                 if (!plugin_path.is_none()) {
                     if (py::isinstance<py::str>(plugin_path) ||
                         py::isinstance<py::bytes>(plugin_path) ||
                         py::hasattr(plugin_path, "__fspath__"))
                         dirs.push_back(fspath(plugin_path).cast<std::string>());
                     else
                         for (const py::handle item : plugin_path)
                             dirs.push_back(fspath(item).cast<std::string>());
                 }
                 for (const std::string& d : dirs) {
                     std::error_code ec;
                     if (!std::filesystem::is_directory(d, ec))
                         throw SpangleError(fmt::format("plugin_path '{}' is not a folder", d));
                 }
                 return std::make_unique<PySession>(std::move(dirs), ocio, threads, verbose);
             }),
             py::arg("plugin_path") = py::none(), py::arg("ocio") = "", py::arg("threads") = 0,
             py::arg("verbose") = false)
        .def(
            "load",
            [](PySession& s, const py::object& path_like, double time,
               std::optional<std::pair<uint32_t, uint32_t>> size) {
                // A str or any os.PathLike (pathlib.Path).
                const std::string path =
                    py::module_::import("os").attr("fspath")(path_like).cast<std::string>();
                py::gil_scoped_release release;
                s.load(path, time, size);
            },
            py::arg("path"), py::arg("time") = 0.0, py::arg("size") = py::none(),
            "Reads a scene file (TOML, pbrt-v3/v4, glTF) into the session. `time`: seconds after "
            "its first frame; `size`: (width, height) to build it for (what depends on the "
            "image's pixels, such as automatic subdivision levels, is built for it), else the "
            "scene's own.")
        .def_property_readonly("materials", [](PySession& s) { return s.materials(); })
        .def(
            "material",
            [](PySession& s, const std::string& name) {
                return [&]() -> py::dict {
                    const SceneDescription desc = s.description();  // a copy: edits swap it
                    for (const MaterialDesc& mat : desc.materials) {
                        if (mat.name != name) continue;
                        py::dict d, params;
                        d["name"] = mat.name;
                        d["plugin"] = mat.plugin;
                        d["model"] = mat.model;
                        for (const ParamDesc& p : mat.params)
                            params[py::str(p.name)] = param_to_python(p);
                        d["params"] = params;
                        // Beside the plugin's parameters, as set_material takes them (they
                        // could be set but not read back).
                        if (mat.alpha) d["alpha"] = param_to_python(*mat.alpha);
                        if (mat.alpha_cutoff) d["alpha_cutoff"] = *mat.alpha_cutoff;
                        return d;
                    }
                    throw SpangleError(fmt::format("no material '{}'", name));
                }();
            },
            py::arg("name"), "The material as written: plugin, model and parameters.")
        .def(
            "set_material",
            [](PySession& s, const std::string& name, const py::kwargs& params) {
                std::vector<std::pair<std::string, ParamValue>> values;
                for (const auto& [k, v] : params) {
                    const std::string key = py::str(k);
                    values.emplace_back(key, param_value(key, v));
                }
                py::gil_scoped_release release;
                s.set_material(name, values);
            },
            py::arg("name"),
            "Sets parameters of a material by keyword; the plugin's schema validates them (a bad "
            "value raises SceneError and changes nothing).")
        .def_property_readonly("objects", [](PySession& s) { return s.objects(); })
        .def(
            "transform",
            [](PySession& s, const std::string& name) {
                return [&]() -> py::dict {
                    const std::vector<std::string> names = s.objects();
                    for (std::size_t i = 0; i < names.size(); ++i) {
                        if (names[i] != name) continue;
                        const SceneDescription desc = s.description();
                        const PlacementDesc& p = desc.objects[i].placement;
                        py::dict d;
                        if (p.matrix) {
                            py::list rows;
                            for (int r = 0; r < 3; ++r)
                                rows.append(py::make_tuple(p.matrix->m[r][0], p.matrix->m[r][1],
                                                           p.matrix->m[r][2], (&p.matrix->t.x)[r]));
                            d["matrix"] = rows;
                        } else {
                            d["translate"] = tuple3(p.parts.translate);
                            d["rotate"] = tuple3(p.parts.rotate);
                            d["scale"] = tuple3(p.parts.scale);
                        }
                        return d;
                    }
                    throw SpangleError(fmt::format("no object '{}'", name));
                }();
            },
            py::arg("name"), "The object's placement: translate/rotate/scale, or a 3 x 4 matrix.")
        .def(
            "set_transform",
            [](PySession& s, const std::string& name,
               std::optional<std::array<double, 3>> translate,
               std::optional<std::array<double, 3>> rotate, const py::object& scale_in,
               const py::object& matrix_in) {
                const FileLoc edit{fmt::format("python: set_transform('{}')", name), 0, 0};
                // scale: three numbers or one (uniform), as the scene file takes it.
                std::optional<std::array<double, 3>> scale;
                if (!scale_in.is_none()) {
                    // (A numpy array of three has __float__ too: it was cast as one number and
                    // failed with pybind11's bare cast error.)
                    const RealArray v = real_array(scale_in, edit, "'scale'");
                    if (v.values.size() == 1)
                        scale = std::array<double, 3>{v.values[0], v.values[0], v.values[0]};
                    else if (v.values.size() == 3 && v.shape.size() <= 1)
                        scale = std::array<double, 3>{v.values[0], v.values[1], v.values[2]};
                    else
                        throw SpangleError(edit, fmt::format("'scale' takes three numbers or one; "
                                                             "got {}",
                                                             v.describe()));
                }
                // matrix: 3 x 4 or 4 x 4 (its last row 0 0 0 1), nested or flat (12 or 16
                // numbers, row by row), a list or a numpy array, as the scene file's `matrix`.
                std::optional<Affine> a;
                if (!matrix_in.is_none()) {
                    const RealArray mat = real_array(matrix_in, edit, "matrix");
                    const auto n = mat.values.size();
                    const double* v = mat.values.data();
                    // Flat, or 3 x 4 / 4 x 4: a 4 x 3 (a transposed matrix) or 2 x 8 of twelve
                    // numbers was read row by row without a word.
                    const bool shaped =
                        mat.shape.size() == 1 || (mat.shape.size() == 2 && mat.shape[1] == 4 &&
                                                  (mat.shape[0] == 3 || mat.shape[0] == 4));
                    if ((n != 12 && n != 16) || !shaped)
                        throw SpangleError(edit, fmt::format("matrix takes 12 numbers (3 x 4) or "
                                                             "16 (4 x 4), row by row, flat or "
                                                             "nested; got {}",
                                                             mat.describe()));
                    if (n == 16 && !(v[12] == 0.0 && v[13] == 0.0 && v[14] == 0.0 && v[15] == 1.0))
                        throw SpangleError(edit,
                                           "a 4 x 4 matrix's last row must be 0 0 0 1 (an "
                                           "affine placement)");
                    Affine x;
                    for (int r = 0; r < 3; ++r) {
                        for (int c = 0; c < 3; ++c) x.m[r][c] = static_cast<float>(v[4 * r + c]);
                        (&x.t.x)[r] = static_cast<float>(v[4 * r + 3]);
                    }
                    a = x;
                }
                py::gil_scoped_release release;
                s.set_transform(name, vec3(translate), vec3(rotate), vec3(scale), a);
            },
            py::arg("name"), py::kw_only(), py::arg("translate") = py::none(),
            py::arg("rotate") = py::none(), py::arg("scale") = py::none(),
            py::arg("matrix") = py::none(),
            "Places an object: translate (world units), rotate (degrees about X, Y, Z), scale "
            "(three numbers or one), or an object-to-world matrix (3 x 4 or 4 x 4, nested or "
            "flat, row by row).")
        .def_property_readonly(
            "camera",
            [](PySession& s) {
                return [&] {
                    const SceneDescription desc = s.description();
                    const CameraDesc& c = desc.camera;
                    py::dict d;
                    d["position"] = tuple3(c.position);
                    d["look_at"] = tuple3(c.look_at);
                    d["up"] = tuple3(c.up);
                    d["fov"] = c.equirect || c.ortho_height > 0.0
                                   ? py::object(py::none())
                                   : py::object(py::float_(c.fov_deg));
                    d["projection"] = c.equirect             ? "equirectangular"
                                      : c.ortho_height > 0.0 ? "orthographic"
                                                             : "perspective";
                    d["ortho_height"] = c.ortho_height > 0.0
                                            ? py::object(py::float_(c.ortho_height))
                                            : py::object(py::none());
                    d["aperture"] = c.aperture;
                    d["focus_distance"] = c.focus_distance
                                              ? py::object(py::float_(*c.focus_distance))
                                              : py::object(py::none());
                    return d;
                }();
            },
            "The camera: position, look_at, up, projection, fov (vertical, degrees), ortho_height "
            "(an "
            "orthographic camera's view height in scene units, or None), aperture (lens radius, "
            "metres), focus_distance.")
        .def(
            "set_camera",
            [](PySession& s, std::optional<std::array<double, 3>> position,
               std::optional<std::array<double, 3>> look_at,
               std::optional<std::array<double, 3>> up, std::optional<double> fov,
               std::optional<double> aperture, std::optional<double> focus_distance,
               std::optional<double> ortho_height, std::optional<std::string> projection) {
                py::gil_scoped_release release;
                s.set_camera(vec3(position), vec3(look_at), vec3(up), fov, aperture, focus_distance,
                             ortho_height, projection);
            },
            py::kw_only(), py::arg("position") = py::none(), py::arg("look_at") = py::none(),
            py::arg("up") = py::none(), py::arg("fov") = py::none(),
            py::arg("aperture") = py::none(), py::arg("focus_distance") = py::none(),
            py::arg("ortho_height") = py::none(), py::arg("projection") = py::none(),
            "Moves or changes the camera; what is not given stays. ortho_height > 0 makes it "
            "orthographic (the view's height in scene units), 0 perspective again. projection "
            "\"perspective\", \"orthographic\" (with an ortho_height) or \"equirectangular\" "
            "(a panorama: no fov and no lens) switches it, as [camera] projection does.")
        .def_property_readonly(
            "lights",
            [](PySession& s) {
                return [&] {
                    py::list out;
                    const SceneDescription desc = s.description();
                    for (const LightDesc& l : desc.lights) {
                        py::dict d;
                        d["intensity"] = l.intensity;
                        d["color"] =
                            l.color ? py::object(tuple3(l.color->rgb)) : py::object(py::none());
                        std::visit(
                            [&](const auto& x) {
                                using S = std::decay_t<decltype(x)>;
                                if constexpr (std::is_same_v<S, QuadLightDesc>) {
                                    d["kind"] = "quad";
                                    d["position"] = tuple3(x.corner);
                                } else if constexpr (std::is_same_v<S, SphereLightDesc>) {
                                    d["kind"] = "sphere";
                                    d["position"] = tuple3(x.center);
                                    d["radius"] = x.radius;
                                } else if constexpr (std::is_same_v<S, PointLightDesc>) {
                                    d["kind"] = "point";
                                    d["position"] = tuple3(x.position);
                                } else if constexpr (std::is_same_v<S, SpotLightDesc>) {
                                    d["kind"] = "spot";
                                    d["position"] = tuple3(x.position);
                                } else {
                                    d["kind"] = "distant";
                                    d["direction"] = tuple3(x.direction);
                                }
                            },
                            l.shape);
                        out.append(d);
                    }
                    return out;
                }();
            },
            "The lights, in the order written: kind, intensity, color, position (and radius).")
        .def(
            "set_light",
            [](PySession& s, int64_t index, std::optional<double> intensity,
               std::optional<std::array<double, 3>> color,
               std::optional<std::array<double, 3>> position, std::optional<double> radius) {
                // A negative index is the edit's error, as one past the last (it was a TypeError
                // from the conversion to an unsigned index).
                if (index < 0)
                    throw SpangleError(
                        FileLoc{fmt::format("python: set_light({})", index), 0, 0},
                        fmt::format("no light {}: lights are numbered from 0", index));
                py::gil_scoped_release release;
                s.set_light(static_cast<std::size_t>(index), intensity, vec3(color), vec3(position),
                            radius);
            },
            py::arg("index"), py::kw_only(), py::arg("intensity") = py::none(),
            py::arg("color") = py::none(), py::arg("position") = py::none(),
            py::arg("radius") = py::none(), "Changes a light; what is not given stays.")
        .def(
            "render",
            [](PySession& s, std::optional<int64_t> spp_in,
               std::optional<std::pair<uint32_t, uint32_t>> size, bool layers,
               std::optional<py::function> progress, std::optional<py::function> on_pass,
               std::optional<bool> background_apart, std::optional<double> noise_threshold,
               std::optional<int64_t> min_spp_in, std::optional<int64_t> max_spp_in, bool denoise,
               std::optional<std::string> denoise_glints) {
                // Sample counts as Python ints of any size: one out of range is a SceneError
                // naming it (a negative or huge one was pybind's TypeError).
                const auto count = [](const char* name, std::optional<int64_t> v) {
                    if (v && (*v < 1 || *v > (int64_t{1} << 20)))
                        throw SpangleError(fmt::format(
                            "render(): {} {} must be 1 to 1048576 (None: the scene's)", name, *v));
                    return v ? std::optional<uint32_t>(static_cast<uint32_t>(*v)) : std::nullopt;
                };
                const std::optional<uint32_t> spp = count("spp", spp_in),
                                              min_spp = count("min_spp", min_spp_in),
                                              max_spp = count("max_spp", max_spp_in);
                // As the command line's --denoise-glints without --denoise: it names nothing.
                if (denoise_glints && !denoise)
                    throw SpangleError(fmt::format(
                        "render(): denoise_glints=\"{}\" needs denoise=True", *denoise_glints));
                spangle::python::DenoiseArgs denoise_args;
                if (denoise) denoise_args.glints = denoise_glints.value_or("keep");
                // Callbacks run on render threads: they take the GIL, and a Python exception in
                // one stops the render and is raised once it has ended.
                std::mutex failed_m;
                std::optional<py::error_already_set> failed;
                spangle::python::RenderCallbacks cb;
                if (progress)
                    cb.progress = [&](uint64_t done, uint64_t total) {
                        py::gil_scoped_acquire gil;
                        try {
                            (*progress)(done, total);
                        } catch (py::error_already_set& e) {
                            std::lock_guard<std::mutex> l(failed_m);
                            if (!failed) failed = std::move(e);
                            s.stop();
                        }
                    };
                if (on_pass)
                    cb.on_pass = [&](const PassImage& p) {
                        py::gil_scoped_acquire gil;
                        try {
                            (*on_pass)(image_array(p.image, p.width, p.height, 3, 0, 3), p.spp);
                        } catch (py::error_already_set& e) {
                            std::lock_guard<std::mutex> l(failed_m);
                            if (!failed) failed = std::move(e);
                            s.stop();
                        }
                    };
                // The render runs on a thread of its own while this one waits with the GIL
                // released, looking for signals every 50 ms: Ctrl-C stops the render and
                // raises KeyboardInterrupt (it waited for the whole render, then discarded it).
                RenderedImage img;
                std::exception_ptr error;
                std::optional<py::error_already_set> interrupted;
                const RenderUnderWay under_way(s);
                {
                    py::gil_scoped_release release;
                    std::mutex done_m;
                    std::condition_variable cv;
                    bool finished = false;
                    std::thread worker([&] {
                        try {
                            img = s.render(spp, size, layers, cb, background_apart.value_or(layers),
                                           {noise_threshold, min_spp, max_spp}, denoise_args);
                        } catch (abi::__forced_unwind&) {
                            // Python ends a thread that wants the GIL after finalisation began
                            // (a progress callback at exit) by unwinding it: let it go.
                            throw;
                        } catch (...) {
                            error = std::current_exception();
                        }
                        std::lock_guard<std::mutex> l(done_m);
                        finished = true;
                        cv.notify_all();
                    });
                    // A daemon thread rendering when the interpreter exits is unwound where it
                    // takes the GIL: the render is stopped and waited for, not left running on
                    // this frame's variables (a joinable std::thread destroyed aborts).
                    struct StopAndJoin {
                        PySession& s;
                        std::thread& worker;
                        ~StopAndJoin() {
                            if (!worker.joinable()) return;
                            s.stop();
                            worker.join();
                        }
                    } stop_and_join{s, worker};
                    std::unique_lock<std::mutex> l(done_m);
                    while (
                        !cv.wait_for(l, std::chrono::milliseconds(50), [&] { return finished; })) {
                        l.unlock();
                        {
                            py::gil_scoped_acquire gil;
                            if (!interrupted && PyErr_CheckSignals() != 0) {
                                interrupted.emplace();  // the pending exception, fetched
                                s.stop();
                            }
                        }
                        l.lock();
                    }
                    l.unlock();
                    worker.join();
                }
                if (interrupted) throw std::move(*interrupted);
                if (failed) throw std::move(*failed);
                if (error) std::rethrow_exception(error);
                return img;
            },
            py::kw_only(), py::arg("spp") = py::none(), py::arg("size") = py::none(),
            py::arg("layers") = true, py::arg("progress") = py::none(),
            py::arg("on_pass") = py::none(), py::arg("background_apart") = py::none(),
            py::arg("noise_threshold") = py::none(), py::arg("min_spp") = py::none(),
            py::arg("max_spp") = py::none(), py::arg("denoise") = false,
            py::arg("denoise_glints") = py::none(),
            "Renders the live scene (the GIL is released). spp and size=(width, height) override "
            "the scene's; progress(done, total) is told the samples done; on_pass(beauty, spp) "
            "gets each progressive pass. stop() from another thread ends it early. With layers, "
            "the environment seen directly is the 'background' layer and the beauty is "
            "premultiplied, as with `spangle render --layers`; background_apart=False keeps it "
            "in the beauty. noise_threshold, min_spp and max_spp set adaptive sampling as "
            "`spangle render --noise-threshold --min-spp --max-spp` do (None: the scene's). "
            "denoise=True denoises the final image as `--denoise` does (Intel Open Image "
            "Denoise, albedo and normal guides; needs layers): the beauty is the denoised one, "
            "the noisy one the layer 'noisy'; denoise_glints is \"keep\" (the default: glints "
            "pass through unfiltered), \"apart\" or \"filter\", as `--denoise-glints`.")
        .def(
            "parameters",
            [](PySession& s, const std::string& plugin, const std::string& model) {
                py::list out;
                for (const SpangleParamDesc_v3& p : s.parameters(plugin, model)) {
                    py::dict d;
                    d["name"] = p.name;
                    static const char* kTypes[] = {"float", "int",    "bool",
                                                   "color", "string", "vec3"};
                    const auto t = static_cast<std::size_t>(p.type);
                    d["type"] = t < 6 ? kTypes[t] : "unknown";
                    if (p.type == SPANGLE_PARAM_COLOR || p.type == SPANGLE_PARAM_VEC3)
                        d["default"] = py::make_tuple(p.default_value[0], p.default_value[1],
                                                      p.default_value[2]);
                    else if (p.type == SPANGLE_PARAM_STRING)
                        d["default"] = p.default_string ? p.default_string : "";
                    else if (p.type == SPANGLE_PARAM_BOOL)
                        d["default"] = p.default_value[0] != 0.0;
                    else if (p.type == SPANGLE_PARAM_INT)
                        d["default"] = static_cast<long long>(p.default_value[0]);
                    else
                        d["default"] = p.default_value[0];
                    d["min"] = p.min_value;
                    d["max"] = p.max_value;
                    py::list choices;
                    if (p.choices) {
                        std::string c = p.choices;
                        for (std::size_t a = 0, b; a <= c.size(); a = b + 1) {
                            b = std::min(c.find('|', a), c.size());
                            if (b > a) choices.append(c.substr(a, b - a));
                        }
                    }
                    d["choices"] = choices;
                    d["doc"] = p.doc ? p.doc : "";
                    d["texturable"] = (p.flags & SPANGLE_PARAM_TEXTURABLE) != 0;
                    out.append(d);
                }
                return out;
            },
            py::arg("plugin"), py::arg("model") = "",
            "The parameters of a plugin's model as its schema declares them: name, type (float, "
            "int, bool, color, string), default, min, max, choices, doc, texturable.")
        .def("stop", &PySession::stop,
             "Ends a render running in another thread after the waves in flight; safe to call "
             "from any thread.")
        .def(
            "write",
            [](PySession&, const RenderedImage& img, const py::object& path_in,
               const py::object& preview_in, bool full_float, const std::string& compression) {
                // Paths as str or os.PathLike (pathlib.Path was a TypeError), checked as the
                // command line checks -o and --preview.
                const auto text = [](const py::object& o, const char* what) {
                    const std::string t =
                        py::module_::import("os").attr("fspath")(o).cast<std::string>();
                    if (t.find('\0') != std::string::npos)
                        throw SpangleError(
                            fmt::format("write(): the {} path holds a NUL byte", what));
                    return t;
                };
                const std::string path = text(path_in, "image");
                // Said first: "out.png" gave "the EXR and the PNG preview are the same file".
                if (path.size() < 4 || path.compare(path.size() - 4, 4, ".exr") != 0)
                    throw SpangleError(fmt::format("output '{}' must end in .exr", path));
                std::string png = preview_in.is_none()
                                      ? (path.size() > 4 ? path.substr(0, path.size() - 4) + ".png"
                                                         : std::string())
                                      : text(preview_in, "preview");
                if (!png.empty()) {
                    if (png.size() < 4 || png.compare(png.size() - 4, 4, ".png") != 0)
                        throw SpangleError(fmt::format(
                            "write(): preview '{}' must end in .png (it is a PNG)", png));
                    if (same_file(png, path))
                        throw SpangleError(fmt::format(
                            "write(): the EXR and the PNG preview are the same file '{}'", path));
                }
                py::gil_scoped_release release;
                write_image(img, path, png, full_float, compression);
            },
            py::arg("image"), py::arg("path"), py::kw_only(), py::arg("preview") = py::none(),
            py::arg("float") = false, py::arg("compression") = "zip",
            "Writes an image as spangle render does: an EXR in the working space (its layers "
            "beside the beauty), whole or not at all, and a PNG preview through the OCIO view "
            "(preview='' for none; default: the EXR's name with .png).");
}
