#pragma once
// The render layers as a sink of the light transport. The stages (render/wave.h) are templates
// over a sink and tell it what happens to each path: light it picked up (escaping, at an
// emitter, through next-event estimation), where its camera ray landed, how it scattered. The
// sink keeps what the layers need per path -- the part of the path's throughput that went
// through a glint at the first surface, its light per light group, the first hit's geometry --
// and adds it into the layer film. NullSink, for renders without layers, does nothing, so the
// transport has no layer code of its own.
//
// The layers, per pixel (layer_channel_names): coverage A, albedo, normal N, depth Z along the
// view (a panorama's: the distance from the camera), position P, position in its object's space
// Pobj, the object's number, the glints, the light of each light group and its glint part, the
// environment seen directly (when it is kept apart from the beauty), the shadow catcher's matte and
// the Cryptomatte id/coverage pairs of objects and materials. Light groups add up to the beauty.
//
// The film holds more than is written: a shadow catcher's light sums and a fixed number of
// unranked id/coverage slots per pixel; finish_layers turns them into the written channels.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.h"
#include "render/camera.h"

namespace spangle {

/** Per-path geometry layers of the first hit: coverage, albedo, normal, depth, position, the
 *  position in its object's space and the object's number (from 1; 0 = none). */
enum Aov : uint32_t {
    kAovA = 0,
    kAovAlbedo = 1,
    kAovN = 4,
    kAovZ = 7,
    kAovP = 8,
    kAovPobj = 11,
    kAovObject = 14,
    kAovCount = 15
};

/** Id/coverage pairs a pixel gathers per Cryptomatte while rendering: ids beyond these are
 *  dropped (their coverage is then missing from the pixel's sum). */
constexpr uint32_t kCryptoSlots = 8;
/** Ranks written per Cryptomatte: the specification's suggested 6, three RGBA layers. */
constexpr uint32_t kCryptoRanks = 6;

/** Which optional layers a render writes and the names they carry. */
struct LayerPlan {
    std::vector<std::string> groups;          ///< light groups, in order of first use
    bool background = false;                  ///< the environment seen directly, apart
    bool catcher = false;                     ///< a shadow catcher's matte
    std::vector<std::string> object_names;    ///< Cryptomatte names by [[object]] number
    std::vector<std::string> material_names;  ///< Cryptomatte names by material index
};

/** Where each part of a render's layers sits in the film, in values from a pixel's first. */
struct LayerLayout {
    uint32_t groups = 0;           ///< light groups
    uint32_t glints = 0;           ///< glints RGB (kAovCount)
    uint32_t group_light = 0;      ///< light per group, RGB each
    uint32_t group_glints = 0;     ///< glint part per group, RGB each
    uint32_t background = 0;       ///< the environment seen directly, RGB
    uint32_t catcher = 0;          ///< shadow catcher: its samples, light without and with shadows
    uint32_t crypto_object = 0;    ///< kCryptoSlots (id, coverage) pairs of objects
    uint32_t crypto_material = 0;  ///< the same for materials
    uint32_t channels = 0;         ///< values per pixel in the film
};

/** The film layout of a render with `groups` light groups. */
LayerLayout layer_layout(uint32_t groups);

/** Where one render's layers go: the layer film and what its channels are measured by. */
struct LayerFilm {
    std::vector<float>* film = nullptr;  ///< layout.channels values per pixel of the image
    uint32_t groups = 0;                 ///< light groups
    uint32_t channels = 0;               ///< values per pixel (layout.channels)
    LayerLayout layout;                  ///< where each part sits
    Vec3 camera_position;                ///< depth is measured from here
    Vec3 camera_forward;                 ///< along this unit direction
    bool radial_depth = false;           ///< a panorama's depth: the distance from the camera
    std::vector<float> object_ids;       ///< Cryptomatte id per [[object]] number
    std::vector<float> material_ids;     ///< Cryptomatte id per material index
};

/** No layers: every hook does nothing. */
struct NullSink {
    void begin_wave(const LayerFilm&, std::size_t) {}
    Vec3* escape_buffer() { return nullptr; }
    void escaped(std::size_t, uint32_t, Vec3, Vec3, uint32_t, float) {}
    void emitted(std::size_t, uint32_t, Vec3, float, uint32_t, Vec3) {}
    void camera_hit(std::size_t, const RayDifferential&, float) {}
    void first_surface(std::size_t, Vec3, uint32_t, uint32_t, bool) {}
    void background(std::size_t, Vec3) {}
    void catcher_light(std::size_t, Vec3, bool) {}
    bool wants_glints(uint32_t) const { return false; }
    void glint_outputs(std::size_t, float*&, float*&, float*&) {}
    void begin_shadows() {}
    void shadow_query(uint32_t, std::size_t, std::size_t, Vec3, Vec3, Vec3, float, uint32_t) {}
    void unoccluded(std::size_t, std::size_t, Vec3, float) {}
    void shaded_normal(std::size_t, uint32_t, Vec3) {}
    void scattered(std::size_t, uint32_t, std::size_t, Vec3, Vec3, float) {}
    void survived(std::size_t, float) {}
    void accumulate(std::size_t, std::size_t, bool) {}
    Vec3 glint(std::size_t) const { return Vec3(0.0f); }
    Vec3 background_of(std::size_t) const { return Vec3(0.0f); }
};

/** The render layers of the paths of one wave (one per worker thread, reused across waves). */
class LayerSink {
public:
    /** Starts a wave of n paths writing into `film`. */
    void begin_wave(const LayerFilm& film, std::size_t n) {
        film_ = &film;
        glint_throughput_.assign(n, Vec3(0.0f));
        glint_.assign(n, Vec3(0.0f));
        group_radiance_.assign(n * film.groups, Vec3(0.0f));
        group_glint_.assign(n * film.groups, Vec3(0.0f));
        aov_.assign(n * kAovCount, 0.0f);
        escaped_by_group_.assign(film.groups, Vec3(0.0f));
        background_.assign(n, Vec3(0.0f));
        object_id_.assign(n, 0.0f);
        material_id_.assign(n, 0.0f);
        catcher_.assign(n, 0);
        catcher_free_.assign(n, 0.0f);
        catcher_lit_.assign(n, 0.0f);
    }

    /** A zeroed buffer, one entry per light group, for an escaping ray's light by group. */
    Vec3* escape_buffer() {
        std::fill(escaped_by_group_.begin(), escaped_by_group_.end(), Vec3(0.0f));
        return escaped_by_group_.data();
    }
    /** Path k escaped at `bounce` with `throughput`: the constant environment to its group, and
     *  each light at infinity (escape_buffer) to its own; kc is the indirect clamp's factor.
     *  After the first surface, the part that came through a glint goes to the glints too. */
    void escaped(std::size_t k, uint32_t bounce, Vec3 throughput, Vec3 environment,
                 uint32_t environment_group, float kc) {
        const Vec3 gt = bounce > 0 ? glint_throughput_[k] * kc : Vec3(0.0f);
        add(k, throughput * environment * kc, environment_group, gt * environment);
        for (uint32_t g = 0; g < film_->groups; ++g)
            add(k, throughput * escaped_by_group_[g] * kc, g, gt * escaped_by_group_[g]);
    }
    /** Path k met an emitter of `group`: contribution c (clamped by kc) of emitted light e. */
    void emitted(std::size_t k, uint32_t bounce, Vec3 c, float kc, uint32_t group, Vec3 e) {
        add(k, c * kc, group, bounce > 0 ? glint_throughput_[k] * e * kc : Vec3(0.0f));
    }
    /** The camera ray of path k hit something at distance t: coverage, depth, position. */
    void camera_hit(std::size_t k, const RayDifferential& ray, float t) {
        float* aov = &aov_[k * kAovCount];
        const Vec3 p = ray.o + ray.d * t;
        aov[kAovA] = 1.0f;
        aov[kAovZ] = film_->radial_depth ? length(p - film_->camera_position)
                                         : dot(p - film_->camera_position, film_->camera_forward);
        aov[kAovP] = p.x;
        aov[kAovP + 1] = p.y;
        aov[kAovP + 2] = p.z;
    }
    /** The camera ray of path k landed on object `object` (material `material`; a shadow
     *  catcher when `catcher`) at p_obj in its own space. */
    void first_surface(std::size_t k, Vec3 p_obj, uint32_t object, uint32_t material,
                       bool catcher) {
        float* aov = &aov_[k * kAovCount];
        aov[kAovPobj] = p_obj.x;
        aov[kAovPobj + 1] = p_obj.y;
        aov[kAovPobj + 2] = p_obj.z;
        aov[kAovObject] = static_cast<float>(object + 1);
        if (object < film_->object_ids.size()) object_id_[k] = film_->object_ids[object];
        if (material < film_->material_ids.size()) material_id_[k] = film_->material_ids[material];
        catcher_[k] = catcher ? 1 : 0;
    }
    /** The camera ray of path k escaped and saw c of the environment, kept out of the beauty. */
    void background(std::size_t k, Vec3 c) { background_[k] += c; }
    /** A next-event query from the shadow catcher path k's first hit would add c, and `arrived`
     *  says whether its shadow ray was unblocked: the catcher's light without and with the
     *  shadows of others (by luminance). */
    void catcher_light(std::size_t k, Vec3 c, bool arrived) {
        const float l = luminance(c);
        if (!(l > 0.0f) || !std::isfinite(l)) return;
        catcher_free_[k] += l;
        if (arrived) catcher_lit_[k] += l;
    }

    /** Whether shading at `bounce` should ask the plugins for the glint part of f (at the
     *  first surface only: later on, the glint throughput carries it). */
    bool wants_glints(uint32_t bounce) const { return bounce == 0; }
    /** Points a batch's glint outputs at buffers zeroed for `count` queries (a model without
     *  glints leaves them so). */
    void glint_outputs(std::size_t count, float*& r, float*& g, float*& b) {
        for (auto* a : {&g_r_, &g_g_, &g_b_}) {
            if (a->size() < count) a->resize(count);
            std::fill_n(a->begin(), static_cast<std::ptrdiff_t>(count), 0.0f);
        }
        r = g_r_.data();
        g = g_g_.data();
        b = g_b_.data();
    }

    /** Before a batch's next-event queries. */
    void begin_shadows() {
        shadow_group_.clear();
        shadow_glint_.clear();
    }
    /** A next-event query j of path `path` that will add throughput f radiance weight unless
     *  occluded: its group and its glint part (the glint outputs of query j at the first
     *  surface, the path's glint throughput later). */
    void shadow_query(uint32_t bounce, std::size_t j, std::size_t path, Vec3 throughput, Vec3 f,
                      Vec3 radiance, float weight, uint32_t group) {
        shadow_group_.push_back(group);
        shadow_glint_.push_back((bounce == 0 ? throughput * Vec3(g_r_[j], g_g_[j], g_b_[j])
                                             : glint_throughput_[path] * f) *
                                radiance * weight);
    }
    /** Shadow ray r (the r-th shadow_query) of `path` was not occluded: it added c (clamped by
     *  kc). */
    void unoccluded(std::size_t r, std::size_t path, Vec3 c, float kc) {
        add(path, c, shadow_group_[r], shadow_glint_[r] * kc);
    }

    /** Path i was shaded at `bounce` with shading normal n. */
    void shaded_normal(std::size_t i, uint32_t bounce, Vec3 n) {
        if (bounce != 0) return;
        float* aov = &aov_[i * kAovCount];
        aov[kAovN] = n.x;
        aov[kAovN + 1] = n.y;
        aov[kAovN + 2] = n.z;
    }
    /** Path i (shading point k of its batch) sampled f with weight cos_pdf = |cos| / pdf from
     *  `throughput`: its glint throughput goes on (and, at the first surface, the sample
     *  weight f cos / pdf estimates the albedo). */
    void scattered(std::size_t i, uint32_t bounce, std::size_t k, Vec3 throughput, Vec3 f,
                   float cos_pdf) {
        if (bounce == 0) {
            glint_throughput_[i] = throughput * Vec3(g_r_[k], g_g_[k], g_b_[k]) * cos_pdf;
            const Vec3 albedo = f * cos_pdf;
            float* aov = &aov_[i * kAovCount];
            aov[kAovAlbedo] = albedo.x;
            aov[kAovAlbedo + 1] = albedo.y;
            aov[kAovAlbedo + 2] = albedo.z;
        } else {
            glint_throughput_[i] = glint_throughput_[i] * f * cos_pdf;
        }
    }
    /** Path i survived Russian roulette: its throughput was scaled by `scale`. */
    void survived(std::size_t i, float scale) { glint_throughput_[i] *= scale; }

    /** Adds path k's layers to film pixel `at`; a path whose radiance was dropped (not
     *  finite) drops its light layers too (they add up to it). */
    void accumulate(std::size_t k, std::size_t at, bool finite) {
        float* lp = &(*film_->film)[at * film_->channels];
        const float* aov = &aov_[k * kAovCount];
        for (uint32_t c = 0; c < kAovCount; ++c)
            if (std::isfinite(aov[c])) lp[c] += aov[c];
        const LayerLayout& l = film_->layout;
        if (object_id_[k] != 0.0f) {
            add_id(lp + l.crypto_object, object_id_[k]);
            add_id(lp + l.crypto_material, material_id_[k]);
        }
        if (catcher_[k]) {
            lp[l.catcher] += 1.0f;
            lp[l.catcher + 1] += catcher_free_[k];
            lp[l.catcher + 2] += catcher_lit_[k];
        }
        if (!finite) return;
        add3(lp + l.glints, glint_[k]);
        add3(lp + l.background, background_[k]);
        for (uint32_t g = 0; g < film_->groups; ++g) {
            add3(lp + l.group_light + 3 * g, group_radiance_[k * film_->groups + g]);
            add3(lp + l.group_glints + 3 * g, group_glint_[k * film_->groups + g]);
        }
    }

    /** Path k's glint part (what accumulate adds to the glints layer when finite). */
    Vec3 glint(std::size_t k) const { return is_finite(glint_[k]) ? glint_[k] : Vec3(0.0f); }
    /** Path k's environment seen directly (what accumulate adds to the background layer). */
    Vec3 background_of(std::size_t k) const { return background_[k]; }

private:
    /** One contribution c of path k to its light group, and its glint part. */
    void add(std::size_t k, Vec3 c, uint32_t group, Vec3 glint) {
        group_radiance_[k * film_->groups + group] += c;
        group_glint_[k * film_->groups + group] += glint;
        glint_[k] += glint;
    }
    /** One sample of id `id` into a pixel's kCryptoSlots (id, weight) pairs: its own slot, else
     *  the first empty one (weight 0); dropped when every slot holds another id. */
    static void add_id(float* slots, float id) {
        for (uint32_t s = 0; s < kCryptoSlots; ++s) {
            float* slot = slots + 2 * s;
            if (slot[1] == 0.0f) slot[0] = id;
            if (slot[0] == id) {
                slot[1] += 1.0f;
                return;
            }
        }
    }
    static void add3(float* to, Vec3 v) {
        if (!is_finite(v)) return;
        to[0] += v.x;
        to[1] += v.y;
        to[2] += v.z;
    }

    const LayerFilm* film_ = nullptr;
    std::vector<Vec3> glint_throughput_;  ///< per path: its throughput's part through a glint
    std::vector<Vec3> glint_;             ///< per path: its light through a glint
    std::vector<Vec3> group_radiance_;    ///< per path and group: its light by light group
    std::vector<Vec3> group_glint_;       ///< per path and group: that light's glint part
    std::vector<Vec3> background_;        ///< per path: the environment its camera ray saw
    std::vector<float> object_id_;        ///< per path: Cryptomatte id of its first object
    std::vector<float> material_id_;      ///< per path: Cryptomatte id of its first material
    std::vector<uint8_t> catcher_;        ///< per path: its first hit is a shadow catcher
    std::vector<float> catcher_free_;     ///< per path: its catcher's light, shadows ignored
    std::vector<float> catcher_lit_;      ///< per path: its catcher's light, shadows included
    std::vector<float> aov_;              ///< per path: kAovCount values of the first hit
    std::vector<Vec3> escaped_by_group_;  ///< one escaped ray's light by group
    std::vector<float> g_r_, g_g_, g_b_;  ///< the glint part of f per query
    std::vector<uint32_t> shadow_group_;  ///< per shadow query: its light's group
    std::vector<Vec3> shadow_glint_;      ///< per shadow query: its glint part
};

/** The render layers' channel names as written (A, albedo.R/G/B, N.X/Y/Z, Z, P.X/Y/Z,
 *  Pobj.X/Y/Z, object, glints.R/G/B, lightgroup_<name>.R/G/B per light group,
 *  glints_<name>.R/G/B per light group, background.R/G/B when kept apart, shadow with a shadow
 *  catcher, then CryptoObject00..02 and CryptoMaterial00..02, R/G/B/A each). */
std::vector<std::string> layer_channel_names(const LayerPlan& plan);

/** Whether a written layer channel is data (positions, depth, normals, ids, coverages: written
 *  as 32-bit floats whatever the beauty's precision) rather than light or a matte. */
bool layer_channel_is_data(const std::string& name);

/** Turns the layer film (`layout`) holding the sums of `samples` samples per pixel (or
 *  counts[p] for pixel p, when counts is not null: adaptive sampling) into the written
 *  channels of `plan` (layer_channel_names), in place: coverage, albedo, glints, light groups
 *  and the environment averaged over all samples; depth, positions and the object number over
 *  the samples whose camera ray hit something; the normal normalised; the shadow catcher's
 *  samples turned into alpha; the Cryptomatte pairs ranked by coverage. */
void finish_layers(std::vector<float>& film, const LayerLayout& layout, const LayerPlan& plan,
                   uint32_t samples, const uint32_t* counts = nullptr);

}  // namespace spangle
