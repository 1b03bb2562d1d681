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
// view, position P, position in its object's space Pobj, the object's number, the glints, and
// the light of each light group. Light groups add up to the beauty.

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

/** Where one render's layers go: the layer film and what its channels are measured by. */
struct LayerFilm {
    std::vector<float>* film = nullptr;  ///< channels values per pixel of the image
    uint32_t groups = 0;                 ///< light groups
    uint32_t channels = 0;               ///< values per pixel: kAovCount + 3 + 3 * groups
    Vec3 camera_position;                ///< depth is measured from here
    Vec3 camera_forward;                 ///< along this unit direction
};

/** No layers: every hook does nothing. */
struct NullSink {
    void begin_wave(const LayerFilm&, std::size_t) {}
    Vec3* escape_buffer() { return nullptr; }
    void escaped(std::size_t, uint32_t, Vec3, Vec3, uint32_t, float) {}
    void emitted(std::size_t, uint32_t, Vec3, float, uint32_t, Vec3) {}
    void camera_hit(std::size_t, const RayDifferential&, float) {}
    void first_surface(std::size_t, Vec3, uint32_t) {}
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
        aov_.assign(n * kAovCount, 0.0f);
        escaped_by_group_.assign(film.groups, Vec3(0.0f));
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
        aov[kAovZ] = dot(p - film_->camera_position, film_->camera_forward);
        aov[kAovP] = p.x;
        aov[kAovP + 1] = p.y;
        aov[kAovP + 2] = p.z;
    }
    /** The camera ray of path k landed on object `object` at p_obj in its own space. */
    void first_surface(std::size_t k, Vec3 p_obj, uint32_t object) {
        float* aov = &aov_[k * kAovCount];
        aov[kAovPobj] = p_obj.x;
        aov[kAovPobj + 1] = p_obj.y;
        aov[kAovPobj + 2] = p_obj.z;
        aov[kAovObject] = static_cast<float>(object + 1);
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
        if (!finite) return;
        add3(lp + kAovCount, glint_[k]);
        for (uint32_t g = 0; g < film_->groups; ++g)
            add3(lp + kAovCount + 3 + 3 * g, group_radiance_[k * film_->groups + g]);
    }

    /** Path k's glint part (what accumulate adds to the glints layer when finite). */
    Vec3 glint(std::size_t k) const { return is_finite(glint_[k]) ? glint_[k] : Vec3(0.0f); }

private:
    /** One contribution c of path k to its light group, and its glint part. */
    void add(std::size_t k, Vec3 c, uint32_t group, Vec3 glint) {
        group_radiance_[k * film_->groups + group] += c;
        glint_[k] += glint;
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
    std::vector<float> aov_;              ///< per path: kAovCount values of the first hit
    std::vector<Vec3> escaped_by_group_;  ///< one escaped ray's light by group
    std::vector<float> g_r_, g_g_, g_b_;  ///< the glint part of f per query
    std::vector<uint32_t> shadow_group_;  ///< per shadow query: its light's group
    std::vector<Vec3> shadow_glint_;      ///< per shadow query: its glint part
};

/** The render layers' channel names in film order (A, albedo.R/G/B, N.X/Y/Z, Z, P.X/Y/Z,
 *  Pobj.X/Y/Z, object, glints.R/G/B, then lightgroup_<name>.R/G/B per light group). */
std::vector<std::string> layer_channel_names(const std::vector<std::string>& light_groups);

/** Turns the layer film's sums of `samples` samples per pixel (or counts[p] for pixel p,
 *  when counts is not null: adaptive sampling) into the layers: coverage, albedo, glints and
 *  light groups averaged over all samples; depth, positions and the object number over the
 *  samples whose camera ray hit something; the normal normalised. */
void finish_layers(std::vector<float>& film, std::size_t channels, uint32_t samples,
                   const uint32_t* counts = nullptr);

}  // namespace spangle
