#include "scene/scene_import.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "scene/keyed_motion.h"
#include "scene/object_placement.h"

namespace spangle {
namespace {

bool is_identity(const Affine& m) {
    return m == Affine{};
}

/** Gives every bare colour of `d` the space it was bare in (its [render] color_space), so that
 *  it keeps its meaning in another scene. */
void explicit_colours(SceneDescription& d) {
    const std::string space = d.render.color_space.value_or("lin_rec709");
    const FileLoc at = d.render.color_space ? d.render.color_space_loc : d.render.loc;
    const auto fix = [&](ColorDesc& c) {
        if (c.space) return;
        c.space = space;
        c.space_loc = at;
    };
    for (MaterialDesc& m : d.materials)
        for (ParamDesc& p : m.params)
            if (p.kind == ParamDesc::Kind::Color) fix(p.color);
    for (ObjectDesc& o : d.objects)
        if (o.emission) fix(o.emission->color);
    for (LightDesc& l : d.lights)
        if (l.color) fix(*l.color);
    if (d.environment && d.environment->color) fix(*d.environment->color);
}

/** Turns keys given as frames of `d`'s own frame range into seconds. */
void explicit_key_times(SceneDescription& d) {
    const auto fix = [&](KeyTime& t) {
        if (!t.frame) return;
        t.seconds = key_seconds(t, d.render.frame_start, d.render.fps);
        t.frame.reset();
    };
    for (CameraKey& k : d.camera.keys.keys) fix(k.time);
    for (ObjectDesc& o : d.objects) {
        for (ObjectKey& k : o.keys.keys) fix(k.time);
        for (MatrixKey& k : o.matrix_keys.keys) fix(k.time);
    }
}

/** The camera placed by m (the eye and the point looked at moved, up turned). */
void place_camera(CameraDesc& c, const Affine& m) {
    c.position = m.apply_point(c.position);
    c.look_at = m.apply_point(c.look_at);
    c.up = m.apply_vector(c.up);
    for (CameraKey& k : c.keys.keys) {
        if (k.position) k.position = m.apply_point(*k.position);
        if (k.look_at) k.look_at = m.apply_point(*k.look_at);
        if (k.up) k.up = m.apply_vector(*k.up);
    }
}

/** A light placed by m; a sphere's radius follows m's mean scale (cube root of the volume). */
struct PlaceLight {
    const Affine& m;
    void operator()(QuadLightDesc& q) const {
        q.corner = m.apply_point(q.corner);
        q.edge1 = m.apply_vector(q.edge1);
        q.edge2 = m.apply_vector(q.edge2);
    }
    void operator()(SphereLightDesc& s) const {
        s.center = m.apply_point(s.center);
        s.radius *= std::cbrt(std::fabs(static_cast<double>(m.determinant())));
    }
    void operator()(PointLightDesc& p) const { p.position = m.apply_point(p.position); }
    void operator()(SpotLightDesc& s) const {
        s.position = m.apply_point(s.position);
        s.look_at = m.apply_point(s.look_at);
    }
    void operator()(DistantLightDesc& d) const { d.direction = m.apply_vector(d.direction); }
};

/** Takes each [render] setting the importing file did not write from the import. */
void fill_render(RenderDesc& into, const RenderDesc& from) {
    const RenderDesc mine = into;
    into = from;
    into.written = mine.written;
    into.loc = mine.loc;
    const auto keep = [&](const char* key, auto member) {
        if (mine.wrote(key)) into.*member = mine.*member;
    };
    keep("width", &RenderDesc::width);
    keep("height", &RenderDesc::height);
    keep("spp", &RenderDesc::spp);
    // Where each setting is written follows the file it is taken from.
    keep("spp", &RenderDesc::spp_loc);
    if (mine.wrote("width") || mine.wrote("height")) into.size_loc = mine.size_loc;
    keep("max_depth", &RenderDesc::max_depth);
    keep("rr_depth", &RenderDesc::rr_depth);
    keep("seed", &RenderDesc::seed);
    keep("filter", &RenderDesc::filter);
    // A radius goes with its filter: the importing file's filter without a radius of its own
    // takes that filter's own radius, not the imported file's.
    if (mine.wrote("filter") && !mine.wrote("filter_radius")) into.filter_radius = 0.0f;
    keep("filter_radius", &RenderDesc::filter_radius);
    keep("filter_samples", &RenderDesc::filter_shared);
    keep("clamp_indirect", &RenderDesc::clamp_indirect);
    keep("filter_glossy", &RenderDesc::filter_glossy);
    keep("noise_threshold", &RenderDesc::noise_threshold);
    keep("noise_threshold", &RenderDesc::noise_threshold_loc);
    keep("min_spp", &RenderDesc::min_spp);
    keep("max_spp", &RenderDesc::max_spp);
    keep("transparent_background", &RenderDesc::transparent_background);
    keep("frame_start", &RenderDesc::frame_start);
    keep("frame_end", &RenderDesc::frame_end);
    keep("fps", &RenderDesc::fps);
    keep("shutter", &RenderDesc::shutter_open);
    keep("shutter", &RenderDesc::shutter_close);
    keep("output", &RenderDesc::output);
    keep("output", &RenderDesc::output_loc);
    // The colour spaces: the importing file's, written or not (its bare colours are bare in its
    // space; the import's were made explicit).
    into.working_space = mine.working_space;
    into.working_space_loc = mine.working_space_loc;
    into.color_space = mine.color_space;
    into.color_space_loc = mine.color_space_loc;
    if (!mine.wrote("working_space") && !mine.working_space) {
        into.working_space = from.working_space;
        into.working_space_loc = from.working_space_loc;
    }
}

/** What merging the imports has taken so far. */
struct Merge {
    std::vector<ObjectDesc> objects;              ///< imported objects, in import order
    std::vector<std::string> own_materials;       ///< names the importing file defines
    std::vector<std::string> imported_materials;  ///< names taken from imports
    bool camera = false, environment = false, render = false;
};

/** Merges one import's description into `scene` (see the header). */
void merge(SceneDescription& scene, SceneDescription in, const ImportDesc& how, Merge& m) {
    explicit_colours(in);
    explicit_key_times(in);
    const Affine place = matrix_of(how.placement);
    const bool placed = !is_identity(place);
    const auto listed = [](const std::vector<std::string>& names, const std::string& name) {
        return std::find(names.begin(), names.end(), name) != names.end();
    };
    // A material the importing file replaces takes its emission with it (a glTF material's
    // emissiveFactor): the replaced paint still glowed, and the glow kept the file's studio
    // light out.
    std::vector<std::string> unlit;
    for (ObjectDesc& o : in.objects)
        if (o.emission && o.emission->of_material && listed(m.own_materials, o.material)) {
            o.emission.reset();
            if (!listed(unlit, o.material)) unlit.push_back(o.material);
        }
    // Its only light gone with them: the studio light it would have had stands in.
    const bool dark = !unlit.empty() && in.studio_light &&
                      std::none_of(in.objects.begin(), in.objects.end(),
                                   [](const ObjectDesc& o) { return o.emission.has_value(); });
    if (dark) {
        in.environment = in.studio_light->environment;
        in.lights = in.studio_light->lights;
        scene.notes.push_back(fmt::format(
            "{}: {} has no light left: the default studio light stands in (a grey sky and a key "
            "light)",
            how.loc.str(), in.path));
    }
    for (const std::string& name : unlit)
        scene.notes.push_back(fmt::format(
            "{}: material '{}' of {} emitted light: the importing file's material of that name "
            "replaces it, emission included (give the replacing material's objects an "
            "`emission` to keep a glow)",
            how.loc.str(), name, in.path));
    for (ObjectDesc& o : in.objects) {
        if (placed) o.parent = o.parent ? place.compose(*o.parent) : place;
        m.objects.push_back(std::move(o));
    }
    for (MaterialDesc& mat : in.materials) {
        if (listed(m.own_materials, mat.name)) continue;  // the importing file's own replaces it
        if (listed(m.imported_materials, mat.name)) {
            scene.notes.push_back(fmt::format(
                "{}: material '{}' of {} is also in an earlier import: the earlier one is used",
                how.loc.str(), mat.name, in.path));
            continue;
        }
        m.imported_materials.push_back(mat.name);
        scene.materials.push_back(std::move(mat));
    }
    if (how.lights)
        for (LightDesc& l : in.lights) {
            if (placed) std::visit(PlaceLight{place}, l.shape);
            scene.lights.push_back(std::move(l));
        }
    bool took_camera = false;
    if (!scene.has_camera && !m.camera && how.camera && in.has_camera) {
        took_camera = true;
        scene.camera = in.camera;
        scene.camera_by_name = in.camera_by_name;
        if (placed) place_camera(scene.camera, place);
        m.camera = true;
    }
    if (!scene.environment && !m.environment && how.environment && in.environment) {
        scene.environment = in.environment;
        m.environment = true;
    }
    if (!m.render) {
        fill_render(scene.render, in.render);
        m.render = true;
    }
    scene.files.push_back(in.path);
    scene.files.insert(scene.files.end(), in.files.begin(), in.files.end());
    for (const std::string& note : in.notes) {
        // The import's default framing, when its camera is not the one taken, stands in for
        // nothing (the note said it did, under the importing file's own camera).
        if (in.camera_is_default && !took_camera &&
            note.find(kDefaultCameraNote) != std::string::npos)
            continue;
        scene.notes.push_back(note);
    }
}

}  // namespace

void resolve_imports(SceneDescription& scene, const ReadImport& read) {
    if (scene.imports.empty()) return;
    Merge m;
    for (const MaterialDesc& mat : scene.materials) m.own_materials.push_back(mat.name);
    const std::vector<ImportDesc> imports = std::move(scene.imports);
    scene.imports.clear();
    for (const ImportDesc& how : imports) merge(scene, read(how.path, how.loc), how, m);
    if (!scene.has_camera && !m.camera)
        throw_error(FileLoc{scene.path, 0, 0},
                    "the scene is missing required key 'camera' (and none of its imports gives "
                    "a camera)");
    scene.has_camera = true;
    // Imported objects come first: the importing file's own follow them.
    m.objects.insert(m.objects.end(), std::make_move_iterator(scene.objects.begin()),
                     std::make_move_iterator(scene.objects.end()));
    scene.objects = std::move(m.objects);
}

}  // namespace spangle
