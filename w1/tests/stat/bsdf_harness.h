#pragma once
// Drives one material model of a plugin through the real ABI, one wo at a time, for the
// statistical tests: sample(), eval() and their agreement.

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "core/hash.h"
#include "core/math.h"
#include "render/arena.h"
#include "shading/material.h"
#include "shading/plugin_loader.h"
#include "test_support.h"

namespace spangle::test {

/** One created model instance and a prepared closure for a chosen wo. */
class BsdfHarness {
public:
    /** Opens `plugin`, creates `model` with the given parameters (name -> numbers), defaults for
     *  the rest. String parameters go in `strings`. */
    BsdfHarness(const std::string& plugin, const std::string& model,
                const std::vector<std::pair<std::string, std::vector<double>>>& numbers,
                const std::vector<std::pair<std::string, std::string>>& strings = {});
    ~BsdfHarness();

    /** Prepares the closure for wo (local frame); backface sets SPANGLE_SHADING_BACKFACE. */
    void prepare(Vec3 wo, bool backface = false);

    /** The shading point's surface data beyond wo, for footprint-based models. */
    struct Point {
        float u = 0.5f, v = 0.5f;                      ///< uv
        float dudx = 0, dudy = 0, dvdx = 0, dvdy = 0;  ///< footprint axes in uv
        bool has_differentials = true;
        float uv_area = 1.0f;
        bool no_uv = false;          ///< SPANGLE_SHADING_NO_UV
        Vec3 p_obj, n_obj{0, 0, 1};  ///< object-space position and normal
        Vec3 dpdx_obj, dpdy_obj;     ///< object-space footprint axes
        float roughness_floor = 0;   ///< > 0: SPANGLE_SHADING_ROUGHNESS_FLOOR with this alpha
    };
    /** Prepares the closure for wo at a given point (the scratch arena is reset first). */
    void prepare(Vec3 wo, const Point& point, bool backface = false);

    struct Sample {
        Vec3 wi, f;
        float pdf;
        uint32_t flags;
    };
    /** n samples with counter-based uniforms from `seed`. */
    std::vector<Sample> sample(uint32_t n, uint64_t seed) const;
    /** f and pdf for each wi. */
    void eval(const std::vector<Vec3>& wi, std::vector<Vec3>& f, std::vector<float>& pdf) const;
    /** f and pdf at the wi of each sample (for sample/eval agreement). */
    void eval(const std::vector<Sample>& samples, std::vector<Vec3>& f,
              std::vector<float>& pdf) const;

    /** The directional albedo of the prepared closure estimated from n of its samples: the mean
     *  of f[channel] |cos theta_i| / pdf (an invalid sample counts 0; a transmitted one is scaled
     *  by transmission_scale) and its standard error. */
    struct Albedo {
        double mean = 0.0, se = 0.0;
    };
    Albedo albedo(uint32_t n, uint64_t seed, int channel = 1,
                  double transmission_scale = 1.0) const;

    const SpangleMaterialModel_v3& model() const { return *model_; }

private:
    ColorConfig color_;
    std::unique_ptr<HostServices> host_;
    std::shared_ptr<LoadedPlugin> plugin_;
    const SpangleMaterialModel_v3* model_ = nullptr;
    void* instance_ = nullptr;
    std::vector<std::byte> closure_;
    ScratchArena arena_;
};

}  // namespace spangle::test
