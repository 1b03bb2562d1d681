// The camera and the render settings once the whole file is read: pbrt's left-handed camera
// (the image is the mirror of a right-handed camera's: CameraDesc::mirror), its fov on the
// shorter image axis, screen window, lens, shutter and motion; Film, Sampler, Integrator and
// PixelFilter with each version's defaults.

#include <cmath>

#include "color/image_io.h"
#include "scene/pbrt/pbrt_state.h"

namespace spangle::pbrt {

namespace {

/** The film's resolution, output file and crop window. */
void film(Reader& r) {
    const ParamList& p = r.film;
    RenderDesc& d = r.d.render;
    d.loc = r.film_loc;
    const auto pixels = [&](const char* name, double fallback) {
        const double v = p.number(name, fallback);
        if (!(v >= 1.0 && v <= 16384.0))
            throw_error(r.film_loc, "Film '{}' must be in 1..16384, got {}", name, v);
        return static_cast<uint32_t>(v);
    };
    d.width = pixels("xresolution", 640);
    d.height = pixels("yresolution", 480);
    if (const Param* x = p.find("xresolution"))
        d.size_loc = x->loc;
    else if (const Param* y = p.find("yresolution"))
        d.size_loc = y->loc;
    const std::string out = p.string("filename", "");
    if (!out.empty()) {
        d.output = out;
        const Param* f = p.find("filename");
        d.output_loc = f ? f->loc : r.film_loc;
    }
    if (const Param* c = p.find("cropwindow", {"float"})) {
        if (c->numbers.size() != 4)
            throw_error(c->loc, "'cropwindow' needs 4 numbers x0 x1 y0 y1, got {}",
                        c->numbers.size());
        d.crop = std::array<double, 4>{c->numbers[0], c->numbers[1], c->numbers[2], c->numbers[3]};
        d.crop_loc = c->loc;
    }
    if (!r.film_type.empty() && r.film_type != "image" && r.film_type != "rgb")
        r.notes.add(r.film_loc, fmt::format("Film \"{}\": an RGB film stands in", r.film_type));
    p.number("iso", 100.0);  // read by exposure() once the camera's shutter is known
    r.notes.unused(p, fmt::format("Film \"{}\"", r.film_type));
}

/** Samples per pixel, bounces and the pixel filter. */
void sampling(Reader& r) {
    RenderDesc& d = r.d.render;
    if (r.sampler_type == "stratified") {
        d.spp = static_cast<uint32_t>(std::max(1.0, r.sampler.number("xsamples", 2)) *
                                      std::max(1.0, r.sampler.number("ysamples", 2)));
        if (const Param* x = r.sampler.find("xsamples"))
            d.spp_loc = x->loc;
        else if (const Param* y = r.sampler.find("ysamples"))
            d.spp_loc = y->loc;
        if (!r.sampler.boolean("jitter", true))
            r.notes.add(r.sampler.find("jitter")->loc,
                        "Sampler \"stratified\": 'jitter' false is dropped (Spangle's samples "
                        "are always scrambled)");
    } else {
        const double asked = r.sampler.number("pixelsamples", 16);
        if (const Param* n = r.sampler.find("pixelsamples")) d.spp_loc = n->loc;
        d.spp = static_cast<uint32_t>(std::clamp(asked, 1.0, 1048576.0));
        if (asked != static_cast<double>(d.spp))
            r.notes.add(r.sampler.find("pixelsamples")->loc,
                        fmt::format("'pixelsamples' {} is taken as {}", asked, d.spp));
    }
    if (const Param* s = r.sampler.find("seed", {"integer"}); s && !s->numbers.empty())
        d.seed = static_cast<uint64_t>(std::fabs(s->numbers[0]));
    r.notes.unused(r.sampler, fmt::format("Sampler \"{}\"", r.sampler_type));
    const std::string& it = r.integrator_type;
    if (!it.empty() && it != "path" && it != "volpath")
        r.notes.add(r.integrator_loc, fmt::format("Integrator \"{}\": Spangle's path tracer "
                                                  "stands in",
                                                  it));
    const double depth = r.integrator.number("maxdepth", 5);
    d.max_depth = static_cast<uint32_t>(std::clamp(depth, 1.0, 1024.0));
    if (depth != static_cast<double>(d.max_depth))
        r.notes.add(r.integrator.find("maxdepth")->loc,
                    depth < 1.0 ? fmt::format("'maxdepth' {} is taken as 1: Spangle's paths "
                                              "bounce at least once (pbrt shows only the "
                                              "light seen directly)",
                                              depth)
                                : fmt::format("'maxdepth' {} is taken as {}", depth, d.max_depth));
    r.integrator.number("rrthreshold", 1);  // Spangle's roulette has its own threshold
    r.integrator.string("lightsamplestrategy", "");
    r.integrator.string("lightsampler", "");
    r.integrator.boolean("regularize", false);
    r.notes.unused(r.integrator, fmt::format("Integrator \"{}\"", it));
    // The default filter: pbrt-v3's is a box of radius 0.5, pbrt-v4's a Gaussian of sigma 0.5
    // and radius 1.5 (Spangle's Gaussian).
    std::string f = r.filter_type.empty() ? (r.v4() ? "gaussian" : "box") : r.filter_type;
    // Its reach: pbrt-v4's xradius/yradius or pbrt-v3's xwidth/ywidth (both half-widths), one
    // value for both axes here (their mean, said). A Gaussian keeps its sigma (v4's sigma, v3's
    // 1 / sqrt(2 alpha), 0.5 by default in both): Spangle's Gaussian of radius 3 sigma, or of
    // the file's radius where that is shorter (said: its sigma is then radius / 3). A stand-in
    // for another filter keeps Spangle's default Gaussian.
    const double def = f == "box" ? 0.5 : f == "gaussian" ? (r.v4() ? 1.5 : 2.0) : 2.0;
    const double xr = r.filter.number("xradius", r.filter.number("xwidth", def)),
                 yr = r.filter.number("yradius", r.filter.number("ywidth", def));
    const double reach = 0.5 * (xr + yr);
    if (xr != yr)
        r.notes.add(r.filter_loc, fmt::format("PixelFilter \"{}\": radii {} and {} (x, y): {} on "
                                              "both axes",
                                              f, xr, yr, reach));
    double radius = 0.0;  // Spangle's own
    if (f == "box") {
        d.filter = FilterKind::Box;
        radius = reach;
    } else {
        d.filter = FilterKind::Gaussian;
        if (f == "gaussian") {
            const double alpha = r.filter.number("alpha", 2.0);
            const double sigma =
                r.filter.number("sigma", 1.0 / std::sqrt(2.0 * std::max(1e-6, alpha)));
            radius = std::min(3.0 * sigma, reach);
            if (3.0 * sigma > reach + 1e-6)
                r.notes.add(r.filter_loc,
                            fmt::format("PixelFilter \"gaussian\": sigma {} cut at radius {}: "
                                        "Spangle's Gaussian of radius {} (sigma {}) stands in",
                                        sigma, reach, reach, reach / 3.0));
        } else {
            r.notes.add(r.filter_loc, fmt::format("PixelFilter \"{}\": a Gaussian (sigma 0.5, "
                                                  "radius 1.5) stands in",
                                                  f));
        }
    }
    if (radius > 0.0 && (radius > 8.0 || radius < 0.05))
        r.notes.add(r.filter_loc, fmt::format("PixelFilter \"{}\": radius {} taken as {}", f,
                                              radius, std::clamp(radius, 0.05, 8.0)));
    radius = radius > 0.0 ? std::clamp(radius, 0.05, 8.0) : 0.0;
    const double own = f == "box" ? 0.5 : 1.5;
    if (radius > 0.0 && std::fabs(radius - own) > 1e-9)
        d.filter_radius = static_cast<float>(radius);
    r.notes.unused(r.filter, fmt::format("PixelFilter \"{}\"", f));
}

/** pbrt-v4's sensor exposure: its image is the radiance times the imaging ratio
 *  (shutterclose - shutteropen) x iso / 100 (1 by default); Spangle's image is the radiance, so
 *  every light of the scene is scaled by it. pbrt-v3 has no such factor. */
void exposure(Reader& r) {
    if (!r.v4()) return;
    const double iso = r.film.number("iso", 100.0);
    const ParamList& cp = r.camera.params;
    const double open = cp.number("shutteropen", 0.0), close = cp.number("shutterclose", 1.0);
    const double ratio = std::fabs(close - open) * iso / 100.0;
    if (ratio == 1.0) return;
    if (!(ratio > 0.0 && std::isfinite(ratio))) {
        r.notes.add(r.film_loc, fmt::format("Film: the exposure (shutter {} s x iso {} / 100) is "
                                            "{}: pbrt's image would be black; 1 stands in",
                                            std::fabs(close - open), iso, ratio));
        return;
    }
    for (LightDesc& l : r.d.lights) l.intensity *= ratio;
    if (r.d.environment) r.d.environment->intensity *= ratio;
    for (ObjectDesc& o : r.d.objects)
        if (o.emission) o.emission->intensity *= ratio;
    r.notes.add(r.film_loc,
                fmt::format("Film: pbrt-v4's exposure (shutter {} s x iso {} / 100 = {}) scales "
                            "every light",
                            std::fabs(close - open), iso, ratio));
}

/** The shutter in seconds as Spangle's frames at one frame per second. */
void shutter(Reader& r) {
    RenderDesc& d = r.d.render;
    const ParamList& p = r.camera.params;
    double open = p.number("shutteropen", 0.0), close = p.number("shutterclose", 1.0);
    if (open > close) {
        r.notes.add(r.camera.loc, "Camera: 'shutteropen' comes after 'shutterclose': swapped");
        std::swap(open, close);
    }
    if (!(std::fabs(open) <= 16.0 && std::fabs(close) <= 16.0)) {
        r.notes.add(r.camera.loc, "Camera: the shutter is clamped to [-16, 16] s");
        open = std::clamp(open, -16.0, 16.0);
        close = std::clamp(close, -16.0, 16.0);
    }
    d.fps = 1.0;
    d.shutter_open = open;
    d.shutter_close = close;
}

/** Eye, look-at and up of a camera-to-world transform. pbrt's equirectangular camera (v4's
 *  `spherical` with mapping "equirectangular", v3's `environment`) puts camera space's -x at the
 *  image's centre (direction (sin t cos p, cos t, sin t sin p), t = pi v, p = 2 pi u, up +y):
 *  Spangle's panorama looking along -x. */
void view_of(const Mat4& m, Vec3& eye, Vec3& look, Vec3& up, bool equirect = false) {
    eye = m.point(Vec3(0.0f));
    look = eye + normalize(equirect ? -m.vector({1, 0, 0}) : m.vector({0, 0, 1}));
    up = normalize(m.vector({0, 1, 0}));
}

/** The camera's two keys (TransformTimes) when its transform moves between them. */
void camera_keys(Reader& r) {
    const CameraState& cs = r.camera;
    if (cs.to_world[0] == cs.to_world[1]) return;
    Keys<CameraKey>& keys = r.d.camera.keys;
    keys.smooth = false;
    keys.loc = cs.loc;
    const double times[2] = {r.time_start, r.time_end};
    for (int i = 0; i < 2; ++i) {
        CameraKey k;
        k.time.seconds = times[i];
        Vec3 e, l, u;
        view_of(cs.to_world[i], e, l, u, r.d.camera.equirect);
        k.position = e;
        k.look_at = l;
        k.up = u;
        k.loc = cs.loc;
        k.what = fmt::format("the camera at time {}", times[i]);
        keys.keys.push_back(std::move(k));
    }
}

}  // namespace

void finish_camera_and_render(Reader& r) {
    film(r);
    sampling(r);
    CameraDesc& c = r.d.camera;
    CameraState& cs = r.camera;
    c.loc = c.look_at_loc = c.up_loc = c.screen_loc = cs.loc;
    // pbrt's orthographic camera: its screen window is in camera space (by default the shorter
    // side spans 2 units), so the view's unit is 1: an ortho_height of 2.
    const bool ortho = cs.given && cs.type == "orthographic";
    // pbrt's equirectangular cameras: v4's spherical with that mapping (its default, equal-area,
    // is not Spangle's), v3's environment camera.
    const bool equirect =
        cs.given && ((cs.type == "spherical" &&
                      cs.params.string("mapping", "equalarea") == "equirectangular") ||
                     cs.type == "environment");
    if (cs.given && cs.type != "perspective" && !ortho && !equirect) {
        for (const Param& q : cs.params.all()) q.used = true;
        r.notes.add(cs.loc,
                    cs.type == "spherical"
                        ? fmt::format("Camera \"spherical\" with mapping \"{}\" is not supported "
                                      "(only \"equirectangular\" is): a perspective camera (fov "
                                      "90) stands in",
                                      cs.params.string("mapping", "equalarea"))
                        : fmt::format("Camera \"{}\" is not supported: a perspective camera (fov "
                                      "90) stands in",
                                      cs.type));
    }
    const Mat4& m = cs.to_world[0];
    c.equirect = equirect;
    view_of(m, c.position, c.look_at, c.up, equirect);
    // pbrt's camera space is left-handed: a camera-to-world transform that keeps handedness
    // (det > 0, as LookAt makes) shows the mirror image of Spangle's right-handed view. The
    // panorama's right (its azimuth's +90 degrees) is camera space's -z: mirrored when
    // Spangle's right-handed right, look x up, is not.
    c.mirror = equirect ? dot(cross(m.vector({-1, 0, 0}), m.vector({0, 1, 0})),
                              m.vector({0, 0, -1})) < 0.0f
                        : m.determinant3() > 0.0;
    const Vec3 x = m.vector({1, 0, 0}), y = m.vector({0, 1, 0}), z = m.vector({0, 0, 1});
    const float lx = length(x), ly = length(y), lz = length(z);
    if (std::fabs(dot(x, y)) > 1e-3f * lx * ly || std::fabs(dot(y, z)) > 1e-3f * ly * lz ||
        std::fabs(dot(x, z)) > 1e-3f * lx * lz || std::fabs(lx - ly) > 1e-3f * lx ||
        std::fabs(lx - lz) > 1e-3f * lx)
        r.notes.add(cs.loc,
                    "Camera: the camera transform shears or scales unevenly: only its "
                    "position and orientation are kept");
    const ParamList& p = cs.params;
    const double fov = ortho || equirect ? 90.0 : p.number("fov", 90.0);
    // A uniform scale in the camera transform scales camera space: an orthographic camera's
    // screen window (its view), and the lens of either camera, are that many world units.
    const double scale = lx > 0.0f && std::isfinite(lx) ? static_cast<double>(lx) : 1.0;
    if (ortho) c.ortho_height = 2.0 * scale;
    if (!(fov > 0.0 && fov < 180.0))
        throw_error(cs.loc, "Camera 'fov' must be in (0, 180), got {}", fov);
    const double aspect = static_cast<double>(r.d.render.width) / r.d.render.height;
    const double frame = equirect ? aspect : p.number("frameaspectratio", aspect);
    if (equirect) {
        c.fov_deg = fov;  // unused: a panorama sees every direction
    } else if (const Param* w = p.find("screenwindow", {"float"})) {
        if (w->numbers.size() != 4)
            throw_error(w->loc, "'screenwindow' needs 4 numbers x0 x1 y0 y1, got {}",
                        w->numbers.size());
        c.screen =
            std::array<double, 4>{w->numbers[0], w->numbers[1], w->numbers[2], w->numbers[3]};
        c.screen_loc = w->loc;
        c.fov_deg = fov;
    } else if (frame != aspect) {
        c.screen = frame >= 1.0 ? std::array<double, 4>{-frame, frame, -1.0, 1.0}
                                : std::array<double, 4>{-1.0, 1.0, -1.0 / frame, 1.0 / frame};
        c.fov_deg = fov;
    } else {
        // pbrt's fov spans the shorter image axis, of the size rendered (--size may turn a
        // portrait film into a landscape image): resolved by the camera model.
        c.fov_deg = fov;
        c.fov_shorter = true;
    }
    c.aperture = equirect ? 0.0 : std::max(0.0, p.number("lensradius", 0.0)) * scale;
    const double focus = equirect ? 1e6 : p.number("focaldistance", 1e6);
    const Param* focus_param = p.find("focaldistance");
    if (c.aperture > 0.0 && !(focus > 0.0))
        throw_error(focus_param ? focus_param->loc : cs.loc,
                    "Camera 'focaldistance' must be positive with a lens ('lensradius' {}), got {}",
                    c.aperture / scale, focus);
    if (c.aperture > 0.0) c.focus_distance = focus * scale;
    shutter(r);
    exposure(r);
    camera_keys(r);
    r.notes.unused(p, fmt::format("Camera \"{}\"", cs.type));
    if (r.env_map_pending && r.d.environment && r.d.environment->map && r.v4()) {
        // pbrt-v4 takes only square (equal-area octahedral) maps; a 2:1 map in a v4 file is a
        // lat-long one (pbrt-v3's layout, its z up): read so, with a note, rather than wrapped
        // onto the octahedron as garbage. A map that cannot be read is left to its loader's
        // error.
        EnvironmentDesc::Map& map = *r.d.environment->map;
        bool square = true;
        try {
            const ImageHeader h = read_image_header(map.path, "environment map");
            square = h.width == h.height;
            if (!square)
                r.notes.add(map.loc, fmt::format("infinite light: '{}' is {}x{}, not square: "
                                                 "pbrt-v4 takes only square equal-area maps; it is "
                                                 "read as a lat-long map (pbrt-v3's layout)",
                                                 map.path, h.width, h.height));
        } catch (const SpangleError&) {
        }
        if (square) map.projection = MapProjection::EqualArea;
    }
}

}  // namespace spangle::pbrt
