#pragma once
// Material instances: a plugin model plus a created instance, and the validation of a scene's
// parameters against the model's schema. The host services plugins receive live here too.

#include <algorithm>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "color/color_config.h"
#include "core/log.h"
#include "geometry/triangle_mesh.h"
#include "scene/components.h"
#include "shading/plugin_call.h"
#include "shading/plugin_loader.h"
#include "shading/texture.h"

namespace spangle {

/** What the host offers plugins (SpangleHost_v3) and the state behind it. Not copyable: the C
 *  table points at this object. */
class HostServices {
public:
    HostServices(const ColorConfig& color, const Logger& log, TextureSettings textures = {});
    HostServices(const HostServices&) = delete;
    HostServices& operator=(const HostServices&) = delete;

    const SpangleHost_v3* api() const { return &api_; }
    const ColorConfig& color() const { return color_; }
    const Logger& log() const { return log_; }
    /** Image textures of material inputs (opened while materials are made). */
    TextureService& textures() const { return textures_; }
    /** What a plugin's warnings and errors are about while a material is made ("FILE:LINE:COL:
     *  material 'paint'"): host_log puts it before them. Empty: nothing. */
    void set_subject(std::string subject) const { subject_ = std::move(subject); }
    const std::string& subject() const { return subject_; }
    /** The plugin warnings already said (each is said once). */
    WarningsSaid& said() const { return said_; }
    /** Different messages a plugin's kernels may log before the rest are dropped. */
    static constexpr int kMaxKernelMessages = 20;
    /** Counts one more different message from the kernels of `label`; returns the count. */
    int count_kernel_message(const std::string& label) const {
        std::lock_guard<std::mutex> lock(kernel_messages_mutex_);
        return ++kernel_messages_[label];
    }

private:
    const ColorConfig& color_;
    const Logger& log_;
    mutable TextureService textures_;
    std::string working_;  ///< keeps api_.working_space alive
    mutable std::string subject_;
    mutable WarningsSaid said_;
    mutable std::mutex kernel_messages_mutex_;
    mutable std::map<std::string, int> kernel_messages_;
    SpangleHost_v3 api_{};
};

/** The product of a colour-managed texture's value (working space) with a factor given in
 *  linear Rec.709, as glTF's factors, Blender's and vertex colours are: taken in Rec.709 (the
 *  working value carried there, multiplied, carried back), not channel by channel in the
 *  working space, whose primaries are not Rec.709's (an orange factor over a white image came
 *  out red in ACEScg). A grey factor is the same either way and keeps the plain product. */
struct Rec709Factor {
    float to_working[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};    ///< linear Rec.709 -> working
    float from_working[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< its inverse
    /** Sets the matrices from the colour config. */
    void init(const ColorConfig& color);
    /** `working` times `factor` (Rec.709), in the working space. */
    Vec3 apply(Vec3 working, Vec3 factor) const {
        const float* b = from_working;
        const Vec3 r(b[0] * working.x + b[1] * working.y + b[2] * working.z,
                     b[3] * working.x + b[4] * working.y + b[5] * working.z,
                     b[6] * working.x + b[7] * working.y + b[8] * working.z);
        const Vec3 c(r.x * factor.x, r.y * factor.y, r.z * factor.z);
        const float* m = to_working;
        return {m[0] * c.x + m[1] * c.y + m[2] * c.z, m[3] * c.x + m[4] * c.y + m[5] * c.z,
                m[6] * c.x + m[7] * c.y + m[8] * c.z};
    }
    /** Whether a factor is grey (the plain product is the same). */
    static bool grey(const float f[3]) { return f[0] == f[1] && f[1] == f[2]; }
};

/** A texture bound to a plugin parameter, or to one of the host's normal and bump maps. */
struct TextureBinding {
    uint32_t param = 0;    ///< schema index of the parameter (parameters only)
    int channels = 1;      ///< values per point: 1 (FLOAT), 3 (COLOR or a normal map)
    float lo = 0, hi = 1;  ///< the parameter's range: looked-up values are clamped into it
    TextureRef ref;        ///< as written: file, uv transform, scale, wrap, strength/height
    std::shared_ptr<const Texture> texture;  ///< null for vertex colours alone (ref.vertex_color)
    /** ref.vertex_color: the meshes' colours (linear Rec.709) to the working space, row-major. */
    float vertex_to_working[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    /** A colour image times a factor that is not grey, or times vertex colours: the product is
     *  taken in linear Rec.709 (`rec709`); else channel by channel. */
    bool rec709_product = false;
    Rec709Factor rec709;
    /** A number parameter read from a colour image's channel or luminance (ref.channel): the
     *  value is pick . (r, g, b) of the looked-up colour. */
    bool picks = false;
    float pick[3] = {1, 0, 0};
    /** ref.vertex_color: a vertex colour times ref.scale (both linear Rec.709), in the working
     *  space: what multiplies the image's value (1 without an image). */
    Vec3 vertex_factor(Vec3 color) const {
        const Vec3 c(color.x * ref.scale[0], color.y * ref.scale[1], color.z * ref.scale[2]);
        const float* m = vertex_to_working;
        return {m[0] * c.x + m[1] * c.y + m[2] * c.z, m[3] * c.x + m[4] * c.y + m[5] * c.z,
                m[6] * c.x + m[7] * c.y + m[8] * c.z};
    }
};

/** An alpha texture's channel at full resolution in memory, 16 bits per texel: the ray tracer
 *  tests it at every triangle a ray crosses, where a texture system's lookup cost as much as
 *  the rest of the traversal. */
struct AlphaTexels {
    int width = 0, height = 0;
    std::vector<uint16_t> texels;  ///< row 0 at the image's top, value x 65535
    /** The value at (s, t) (s right, t down, in [0, 1] over the image), wrapped as TextureRef
     *  says (periodic, clamp, black, mirror); bilinear between texel centres, or the texel
     *  itself (`closest`). */
    float at(float s, float t, int wrap, bool closest) const;
};

/** A material's `alpha`: how much of its surfaces stops rays (a cut-out where it is 0). */
struct AlphaMap {
    bool active = false;  ///< the material has an alpha (else every surface is opaque)
    float value = 1.0f;   ///< the constant alpha, or the factor on the texture's value
    /** >= 0: a hit counts where alpha >= cutoff; < 0: with probability alpha. */
    float cutoff = -1.0f;
    /** The texture as written (its path watched, its uv transform and wrap applied); empty
     *  path: the constant alone. */
    TextureRef ref;
    /** Its channel in memory (null with the constant alone, or where the image had no alpha
     *  channel to read). */
    std::shared_ptr<const AlphaTexels> texels;
};

/** `channel` of the texture's converted file (its values as looked up) at full resolution.
 *  Throws SpangleError at `loc`. */
std::shared_ptr<const AlphaTexels> alpha_texels(const Texture& tex, int channel,
                                                const FileLoc& loc);

/** The alpha of `a` at barycentrics (b1, b2) of triangle `prim` of `mesh` (its uvs; without
 *  uvs the triangle's corners take (0, 0), (1, 0), (0, 1)), in [0, 1]: the texture's value at
 *  full resolution, bilinear, times the factor. Thread-safe, and throws nothing (it runs inside
 *  the ray tracer). */
float alpha_at(const AlphaMap& a, const TriangleMesh& mesh, uint32_t prim, float b1, float b2);

/** What a material's maps do to the shading frame. */
enum class MapKind { None, Normal, Bump };

/** "plugin 'NAME' (PATH), material 'MATERIAL'". */
std::string plugin_label(const LoadedPlugin& plugin, const std::string& material);

/** One created material: owns the plugin instance and keeps its library open. */
class MaterialInstance {
public:
    MaterialInstance(std::shared_ptr<LoadedPlugin> plugin, const SpangleMaterialModel_v3* model,
                     void* instance, std::string name)
        : plugin_(std::move(plugin)),
          model_(model),
          instance_(instance),
          name_(std::move(name)),
          label_(plugin_label(*plugin_, name_)) {}
    ~MaterialInstance() {
        if (!instance_) return;
        try {
            call_plugin(label_, "destroy", [&] { model_->destroy(instance_); });
        } catch (...) {  // nothing to do about it while tearing down
        }
    }
    MaterialInstance(const MaterialInstance&) = delete;
    MaterialInstance& operator=(const MaterialInstance&) = delete;

    const SpangleMaterialModel_v3& model() const { return *model_; }
    const void* instance() const { return instance_; }
    const std::string& name() const { return name_; }
    const LoadedPlugin& plugin() const { return *plugin_; }
    /** "plugin 'smooth' (PATH), material 'paint'": who a message about a plugin call names. */
    const std::string& label() const { return label_; }
    /** Outputs of this material's eval() and sample() the host could not use (render/stage_*). */
    BadOutputCounts& bad_output() const { return bad_output_; }

    /** Textures of plugin parameters, in schema order. */
    const std::vector<TextureBinding>& textures() const { return textures_; }
    /** The normal or bump map (map_kind() None: neither). */
    MapKind map_kind() const { return map_kind_; }
    const TextureBinding& map() const { return map_; }
    void bind(std::vector<TextureBinding> textures, MapKind kind, TextureBinding map,
              AlphaMap alpha = {}) {
        textures_ = std::move(textures);
        map_kind_ = kind;
        map_ = std::move(map);
        alpha_ = std::move(alpha);
    }
    /** Its alpha (alpha().active false: opaque). */
    const AlphaMap& alpha() const { return alpha_; }
    /** Whether shading it reads the hit's footprint: its textures and normal or bump map are
     *  filtered over it, and its model reads it unless requirements() says
     *  SPANGLE_IGNORES_FOOTPRINT. */
    bool reads_footprints() const {
        const bool textured =
            map_kind_ != MapKind::None ||
            std::any_of(textures_.begin(), textures_.end(),
                        [](const TextureBinding& t) { return t.texture != nullptr; });
        return textured || !model_->requirements ||
               !(model_->requirements(instance_) & SPANGLE_IGNORES_FOOTPRINT);
    }

private:
    AlphaMap alpha_;
    std::vector<TextureBinding> textures_;
    MapKind map_kind_ = MapKind::None;
    TextureBinding map_;
    std::shared_ptr<LoadedPlugin> plugin_;  ///< declared first: destroyed after the instance
    const SpangleMaterialModel_v3* model_;
    void* instance_;
    std::string name_;
    std::string label_;
    mutable BadOutputCounts bad_output_;
};

/** A complete parameter set in schema order, with storage for its strings. */
struct ValidatedParams {
    std::vector<SpangleParamValue_v3> values;  ///< one per schema entry
    std::vector<std::string> strings;          ///< backing text for STRING values
    /** Parameters given as textures: (schema index, the entry); create_material() gives
     *  create() their images' averages. */
    std::vector<std::pair<uint32_t, const ParamEntry*>> textured;
    /** What the conversion changed, to be said: a colour outside the working space's gamut
     *  ("FILE:LINE:COL: material 'm': ..."). */
    std::vector<std::string> notes;
    SpangleParams_v3 view() const { return {values.data(), static_cast<uint32_t>(values.size())}; }
};

/** Checks `m.params` against `model`'s schema: unknown names, types, ranges, choices. Colours are
 *  converted to the working space. Throws SpangleError at the offending value's location. */
ValidatedParams validate_params(const SpangleMaterialModel_v3& model, const Material& m,
                                const ColorConfig& color);

/** Opens m's plugin (once), picks the model, validates, creates the instance and opens the
 *  textures of its parameters and maps. */
std::unique_ptr<MaterialInstance> create_material(PluginLoader& loader, const Material& m,
                                                  const HostServices& host);

/** One line describing a parameter for `spangle plugins`. */
std::string describe_param(const SpangleParamDesc_v3& p);

}  // namespace spangle
