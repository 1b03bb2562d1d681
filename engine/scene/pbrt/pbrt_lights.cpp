// pbrt's lights: point, spot and distant lights placed by the current transform, the infinite
// light as Spangle's environment (a constant, or a map in pbrt's own layout and orientation),
// and the area light that the shapes after AreaLightSource emit with.

#include <cmath>

#include "core/text.h"
#include "scene/pbrt/pbrt_state.h"

namespace spangle::pbrt {

namespace {

/** A point of a light's parameters through the current transform. */
Vec3 light_point(const Reader& r, const ParamList& p, const char* name, Vec3 fallback) {
    const std::vector<double>& v = p.numbers(name, {"point3"});
    const Vec3 q = v.size() == 3 ? Vec3(static_cast<float>(v[0]), static_cast<float>(v[1]),
                                        static_cast<float>(v[2]))
                                 : fallback;
    return r.gs.ctm[0].point(q);
}

/** The rotation of a light's transform (Gram-Schmidt of its columns): where its +z points. */
Affine rotation_of(const Mat4& m) {
    Vec3 x = normalize(m.vector({1, 0, 0})), y = m.vector({0, 1, 0});
    y = normalize(y - x * dot(x, y));
    Vec3 z = cross(x, y);
    if (dot(z, m.vector({0, 0, 1})) < 0.0f) z = -z;  // a mirroring transform keeps its z
    Affine a;
    const Vec3 cols[3] = {x, y, z};
    for (int c = 0; c < 3; ++c) {
        a.m[0][c] = cols[c].x;
        a.m[1][c] = cols[c].y;
        a.m[2][c] = cols[c].z;
    }
    return a;
}

/** The environment from an infinite light. */
void infinite(Reader& r, const ParamList& p, const FileLoc& loc, ColorDesc L, double scale) {
    if (r.d.environment) {
        for (const Param& q : p.all()) q.used = true;
        r.notes.add(loc,
                    "a second infinite light: Spangle has one environment, the first is "
                    "kept");
        return;
    }
    EnvironmentDesc e;
    e.loc = loc;
    e.group.loc = loc;
    p.number("nsamples", 1);  // a sampling hint: Spangle samples the map by importance
    if (const Param* portal = p.find("portal", {"point3"}))
        r.notes.add(portal->loc,
                    "infinite light 'portal' is not supported: the whole map is "
                    "sampled");
    // pbrt-v3 names the map "mapname", pbrt-v4 "filename".
    std::string file = p.string("filename", "");
    if (const Param* v3 = p.find("mapname", {"string"})) {
        r.sign(false, v3->loc, "infinite light 'mapname'");
        if (file.empty()) file = p.string("mapname", "");
    }
    const double illuminance = p.number("illuminance", -1.0);
    if (file.empty()) {
        // pbrt-v4: a constant L with 'illuminance' E makes E at an upward surface: L = E / pi.
        if (illuminance > 0.0)
            scale *= illuminance / M_PI / static_cast<double>(std::max(1e-9f, luminance(L.rgb)));
        e.color = L;
        e.intensity = scale;
    } else {
        EnvironmentDesc::Map m;
        m.path = r.find_file(file, "infinite light filename", loc);
        m.loc = loc;
        const std::string ext = ascii_lower(std::filesystem::path(m.path).extension().string());
        if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tga" || ext == ".bmp")
            m.color_space = "srgb_texture";
        m.color_space_loc = loc;
        m.projection = MapProjection::LatLongZUp;  // made EqualArea at the end for pbrt-v4
        m.to_world = rotation_of(r.gs.ctm[0]);
        e.map = std::move(m);
        r.env_map_pending = true;
        if (illuminance > 0.0)
            r.notes.add(loc,
                        "infinite light 'illuminance' with a map is not supported: 'scale' "
                        "alone scales the map");
        const Vec3 c = L.rgb;
        if (!(c.x == c.y && c.y == c.z))
            r.notes.add(loc,
                        "an infinite light's coloured 'L' times its map: the map is scaled "
                        "by L's luminance, its tint is dropped");
        e.intensity = scale * static_cast<double>(c.x == c.y && c.y == c.z ? c.x : luminance(c));
    }
    r.d.environment = std::move(e);
}

/** pbrt-v3's light 'scale' is a spectrum ("rgb scale" [4 4 4], "color scale", "spectrum
 *  scale"): it multiplies the light's colour; white when the light has none. */
void colour_scale(Reader& r, const ParamList& p, ColorDesc& c) {
    if (const auto s = color_param(r, p, "scale", false)) {
        c.rgb = Vec3(c.rgb.x * s->rgb.x, c.rgb.y * s->rgb.y, c.rgb.z * s->rgb.z);
    }
}

}  // namespace

void read_light(Reader& r, const std::string& type, ParamList& p, const FileLoc& loc) {
    const std::string what = fmt::format("LightSource \"{}\"", type);
    LightDesc l;
    l.loc = loc;
    l.group.loc = loc;
    double scale = p.number("scale", 1.0);
    if (!(scale >= 0.0)) {
        r.notes.add(loc, fmt::format("{}: a negative 'scale' {} stands at 0", what, scale));
        scale = 0.0;
    }
    // An infinite light has no 'power' in pbrt (its 'illuminance' is): left unused, so said.
    const double power = type == "infinite" ? -1.0 : p.number("power", -1.0);
    if (type != "infinite" && p.find("power")) r.sign(true, loc, "light 'power'");
    if (type == "point" || type == "spot" || type == "goniometric" || type == "projection") {
        ColorDesc I = color_param(r, p, "I", true).value_or(r.color(Vec3(1.0f), loc));
        colour_scale(r, p, I);
        l.color = I;
        const Vec3 from = light_point(r, p, "from", Vec3(0.0f));
        if (type == "spot") {
            SpotLightDesc s;
            s.position = from;
            s.look_at = light_point(r, p, "to", Vec3(0, 0, 1));
            s.look_at_loc = s.cone_falloff_loc = loc;
            const double cone = p.number("coneangle", 30.0);
            if (cone > 90.0)
                r.notes.add(loc, fmt::format("spot 'coneangle' {} is beyond Spangle's 90 degrees: "
                                             "a hemisphere it is",
                                             cone));
            s.cone_angle = std::clamp(cone, 1e-3, 90.0);
            s.cone_falloff = std::clamp(p.number("conedeltaangle", 5.0), 0.0, s.cone_angle);
            // (pbrt-v3 fades the edge as t^4: set once the whole file says which it is.)
            if (power > 0.0) {
                // pbrt-v4: the intensity whose cone (with its smooth falloff) emits `power`.
                const double c0 = std::cos((s.cone_angle - s.cone_falloff) * M_PI / 180.0),
                             c1 = std::cos(s.cone_angle * M_PI / 180.0);
                scale *= power / (2.0 * M_PI * ((1.0 - c0) + (c0 - c1) / 2.0));
            }
            l.shape = s;
        } else {
            if (type != "point") {
                for (const Param& q : p.all()) q.used = true;
                r.notes.add(loc, fmt::format("{} is not supported: a point light of its 'I' "
                                             "stands in",
                                             what));
            }
            if (power > 0.0) scale *= power / (4.0 * M_PI);
            l.shape = PointLightDesc{from};
        }
    } else if (type == "distant") {
        l.color = color_param(r, p, "L", true).value_or(r.color(Vec3(1.0f), loc));
        colour_scale(r, p, *l.color);
        DistantLightDesc dl;
        const Vec3 from = light_point(r, p, "from", Vec3(0.0f)),
                   to = light_point(r, p, "to", Vec3(0, 0, 1));
        dl.direction = from - to;
        dl.direction_loc = loc;
        const double e = p.number("illuminance", -1.0);
        if (e > 0.0) scale *= e;
        l.shape = dl;
    } else if (type == "infinite") {
        ColorDesc L = color_param(r, p, "L", true).value_or(r.color(Vec3(1.0f), loc));
        colour_scale(r, p, L);
        infinite(r, p, loc, L, scale);
        r.notes.unused(p, what);
        return;
    } else {
        for (const Param& q : p.all()) q.used = true;
        r.notes.add(loc, fmt::format("{} is not supported: dropped", what));
        return;
    }
    l.intensity = scale;
    r.notes.unused(p, what);
    r.d.lights.push_back(std::move(l));
}

void read_area_light(Reader& r, const std::string& type, ParamList& p, const FileLoc& loc) {
    if (type == "area") r.sign(false, loc, "AreaLightSource \"area\"");
    if (type != "diffuse" && type != "area") {
        for (const Param& q : p.all()) q.used = true;
        r.notes.add(loc, fmt::format("AreaLightSource \"{}\" is not supported: its shapes do "
                                     "not emit",
                                     type));
        r.gs.area.reset();
        return;
    }
    AreaLight a;
    a.loc = loc;
    a.L = color_param(r, p, "L", true).value_or(r.color(Vec3(1.0f), loc));
    colour_scale(r, p, a.L);
    a.scale = std::max(0.0, p.number("scale", 1.0));
    a.two_sided = p.boolean("twosided", false);
    if (const Param* pw = p.find("power", {"float"});
        pw && !pw->numbers.empty() && pw->numbers[0] > 0.0) {
        r.sign(true, loc, "area light 'power'");
        a.power = pw->numbers[0];
    }
    if (const Param* f = p.find("filename", {"string"}); f && !f->strings.empty()) {
        // pbrt-v4: the image's colour at the shape's (u, 1 - v) times scale, L unused; Spangle
        // reads its textures at (u, 1 - v) too.
        TextureDesc t;
        t.path = r.find_file(f->strings[0], "area light filename", f->loc);
        t.wrap = 1;  // clamp, as pbrt's image lookups of a light
        a.image = t;
        if (p.find("L", {"rgb", "spectrum", "blackbody"}))
            r.notes.add(loc,
                        "an area light with both 'L' and 'filename' (pbrt-v4 refuses "
                        "it): the image stands, 'L' is unused");
        a.L = r.color(Vec3(1.0f), loc);
        if (a.power) {
            r.notes.add(loc, "area light 'power' with an image: 'scale' alone stands in");
            a.power.reset();
        }
    }
    r.notes.unused(p, fmt::format("AreaLightSource \"{}\"", type));
    r.gs.area = a;
}

}  // namespace spangle::pbrt
