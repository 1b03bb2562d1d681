// Adaptive sampling's plan, checkpoints and per-pixel error estimate: see adaptive.h.

#include "render/adaptive.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace spangle {

namespace {

/** Samples before a pixel may stop when neither the scene nor the options say. */
constexpr uint32_t kAutoMinSpp = 16;
/** The fewest samples after which a pixel can stop: two looks at four samples each. */
constexpr uint32_t kEarliestStop = 8;
/** The floor of dark pixels in the relative error (the relMSE metric's 0.01 = 0.1^2). */
constexpr double kDarkFloor2 = 0.01;

}  // namespace

AdaptivePlan adaptive_plan(const Film& film, const RenderOptions& options) {
    AdaptivePlan p;
    p.threshold = options.noise_threshold_override >= 0.0f ? options.noise_threshold_override
                                                           : film.noise_threshold;
    if (!(p.threshold > 0.0f)) return AdaptivePlan{};
    const uint32_t spp = options.spp_override ? options.spp_override : film.spp;
    p.max_spp =
        options.max_spp_override ? options.max_spp_override : (film.max_spp ? film.max_spp : spp);
    const uint32_t asked = options.min_spp_override ? options.min_spp_override : film.min_spp;
    if (asked > p.max_spp)
        throw_error("min_spp {} is more than the {} samples a pixel may take (max_spp, or spp)",
                    asked, p.max_spp);
    p.min_spp = asked ? asked : std::min(kAutoMinSpp, p.max_spp);
    // Four equal quarters, and two looks before a stop (at 4 and 8 samples at the soonest):
    // a pixel cannot stop before 8 whatever min_spp says, so 8 is what the header records.
    p.min_spp = std::min(p.max_spp, std::max(kEarliestStop, (p.min_spp + 3u) & ~3u));
    return p;
}

std::string spp_range_refusal(const std::string& render) {
    return "--spp-range cannot split " + render +
           ": a part cannot know which pixels stopped before its first sample without rendering "
           "those samples; split it by pixels (--crop, MPI bands), which give the whole render "
           "bit for bit";
}

bool adaptive_on(const Film& film, const RenderOptions& options) {
    return adaptive_plan(film, options).on();
}

uint32_t next_checkpoint(const AdaptivePlan& plan, uint32_t samples) {
    // A look at half of min_spp first, so that a pixel within the threshold there and at
    // min_spp stops at min_spp.
    const uint32_t half = (plan.min_spp / 2) & ~3u;
    if (half >= 4 && samples < half) return half;
    if (samples < plan.min_spp) return plan.min_spp;
    // Then steps of an eighth (at least 8); from a min_spp of 4 (no half look before it) the
    // next look is at 8, so that a lower min_spp never stops later (it stopped at 12: 4 + 8).
    uint32_t c = plan.min_spp;
    while (c <= samples) c += c < 8 ? 8 - c : std::max(8u, (c / 8) & ~3u);
    return std::min(c, plan.max_spp);
}

void AdaptiveFilm::reset(std::size_t pixels) {
    count.assign(pixels, 0);
    parts.assign(kParts * pixels, 0.0f);
    ratio.assign(pixels, 1e30f);
    strikes.assign(pixels, 0);
    active.assign(pixels, 1);
}

float adaptive_error(const AdaptivePlan& plan, const PixelSums& s) {
    if (s.samples < 4) return 1e30f;
    const double n = s.samples, q = 0.25 * n;
    double smooth = 0.0, glint_se2 = 0.0, glint_mean2 = 0.0, glint_abs = 0.0;
    for (int c = 0; c < 3; ++c) {
        const double total = static_cast<double>(s.beauty[c]) * 0x1p-40 +
                             (s.background ? static_cast<double>(s.background[c]) : 0.0);
        const double g_total = s.glints ? static_cast<double>(s.glints[c]) : 0.0;
        // The four quarters' sums of the beauty without its glints, and of the glints.
        double rest[4], glint[4];
        rest[0] = total - g_total;
        glint[0] = g_total;
        for (int k = 1; k < 4; ++k) {
            const double b = static_cast<double>(s.parts[6 * (k - 1) + c]);
            const double g = s.glints ? static_cast<double>(s.parts[6 * (k - 1) + 3 + c]) : 0.0;
            rest[k] = b - g;
            glint[k] = g;
            rest[0] -= rest[k];
            glint[0] -= g;
        }
        // The squared standard error of the mean: the quarter means' sample variance over 4.
        const auto se2 = [q](const double* sums) {
            const double mean = (sums[0] + sums[1] + sums[2] + sums[3]) / (4.0 * q);
            double v = 0.0;
            for (int k = 0; k < 4; ++k) v += (sums[k] / q - mean) * (sums[k] / q - mean);
            return v / 12.0;
        };
        const double mean = total / n;
        const double norm = mean * mean + kDarkFloor2;
        smooth += se2(rest) / norm;
        const double g2 = se2(glint);
        glint_se2 += g2;
        glint_abs += g2 / norm;
        const double g_mean = g_total / n;
        glint_mean2 += g_mean * g_mean;
    }
    const double t = static_cast<double>(plan.threshold);
    double ratio = std::sqrt(smooth / 3.0) / t;
    if (glint_mean2 > 0.0) {
        const double tolerance = std::min(0.5, 10.0 * t);
        const double relative = std::sqrt(glint_se2 / glint_mean2) / tolerance;
        const double absolute = std::sqrt(glint_abs / 3.0) / t;
        ratio = std::max(ratio, std::min(relative, absolute));
    }
    return std::isfinite(ratio) ? static_cast<float>(ratio) : 1e30f;
}

}  // namespace spangle
