#include "core/pixel_filter.h"

#include <algorithm>
#include <cmath>

namespace spangle {

bool parse_filter(const std::string& name, FilterKind& out) {
    if (name == "box")
        out = FilterKind::Box;
    else if (name == "gaussian")
        out = FilterKind::Gaussian;
    else if (name == "blackman-harris")
        out = FilterKind::BlackmanHarris;
    else
        return false;
    return true;
}

double filter_value(FilterKind kind, double x, double radius) {
    switch (kind) {
        case FilterKind::Box:
            return 1.0;
        case FilterKind::Gaussian: {
            // sigma = radius / 3 (0.5 px at the default 1.5), shifted so that it reaches 0 at
            // the radius.
            const double sigma = radius / 3.0, s2 = 2.0 * sigma * sigma;
            return std::max(0.0, std::exp(-x * x / s2) - std::exp(-radius * radius / s2));
        }
        case FilterKind::BlackmanHarris: {
            // Four-term Blackman-Harris window over [-radius, radius].
            const double t = 2.0 * M_PI * (x / (2.0 * radius) + 0.5);
            return 0.35875 - 0.48829 * std::cos(t) + 0.14128 * std::cos(2 * t) -
                   0.01168 * std::cos(3 * t);
        }
    }
    return 0.0;
}

float default_filter_radius(FilterKind kind) {
    switch (kind) {
        case FilterKind::Box:
            return 0.5f;
        case FilterKind::Gaussian:
            return 1.5f;
        case FilterKind::BlackmanHarris:
            return 2.0f;
    }
    return 0.5f;
}

namespace {

/** The filter's variance (its second moment over its integral) on [-r, r]. */
double filter_variance(FilterKind kind, double r) {
    constexpr int kSteps = 4096;
    double m0 = 0.0, m2 = 0.0;
    for (int i = 0; i < kSteps; ++i) {
        const double x = -r + (i + 0.5) * 2.0 * r / kSteps, f = filter_value(kind, x, r);
        m0 += f;
        m2 += x * x * f;
    }
    return m0 > 0.0 ? m2 / m0 : 0.0;
}

/** The filter narrowed by `narrow` (g(x narrow), reaching r / narrow), integrated over each
 *  pixel by the midpoint rule (256 points a pixel), from the centre out and mirrored (the filters
 *  are even: so are the weights, exactly, and the image is not shifted by their rounding);
 *  normalised to a sum of 1. */
std::vector<double> narrowed_weights(FilterKind kind, double r, double narrow) {
    const double h = r / narrow;
    // Offsets o whose pixel [o - 1/2, o + 1/2] meets (-h, h): |o| < h + 1/2.
    const int reach = std::max(0, static_cast<int>(std::ceil(h + 0.5)) - 1);
    std::vector<double> w(static_cast<std::size_t>(2 * reach + 1), 0.0);
    constexpr int kSteps = 256;
    double total = 0.0;
    for (int o = 0; o <= reach; ++o) {
        const double a = std::max(-h, o - 0.5), b = std::min(h, o + 0.5);
        double sum = 0.0;
        if (b > a)
            for (int i = 0; i < kSteps; ++i)
                sum += filter_value(kind, (a + (i + 0.5) * (b - a) / kSteps) * narrow, r);
        const double v = b > a ? sum * (b - a) / kSteps : 0.0;
        w[static_cast<std::size_t>(reach + o)] = w[static_cast<std::size_t>(reach - o)] = v;
        total += o == 0 ? v : 2.0 * v;
    }
    if (!(total > 0.0)) return {1.0};
    for (double& x : w) x /= total;
    return w;
}

/** The weights' variance in pixels squared (their second moment about the centre). */
double weights_variance(const std::vector<double>& w) {
    const int reach = static_cast<int>(w.size() / 2);
    double v = 0.0;
    for (int o = -reach; o <= reach; ++o) v += o * o * w[static_cast<std::size_t>(o + reach)];
    return v;
}

}  // namespace

std::vector<double> spread_weights(FilterKind kind, float radius) {
    const double r = radius > 0.0f ? radius : default_filter_radius(kind);
    // A pixel's own samples are spread over it (a box of one pixel: variance 1/12), so the
    // weights make up the rest of the filter's width: the filter narrowed until the weights'
    // variance plus 1/12 is the filter's. (Its plain integral over each pixel added the pixel's
    // width once more: Blackman-Harris 2 blurred as one of variance 0.47 pixels^2, not 0.31.)
    const double target = filter_variance(kind, r) - 1.0 / 12.0;
    if (!(target > 1e-9)) return {1.0};
    // Narrowing only lowers the variance; at narrow = 1 it is about the filter's plus 1/12.
    double wide = 1.0, narrow = 1e3;
    for (int it = 0; it < 64; ++it) {
        const double mid = std::sqrt(wide * narrow);
        (weights_variance(narrowed_weights(kind, r, mid)) > target ? wide : narrow) = mid;
    }
    return narrowed_weights(kind, r, narrow);
}

void spread_pixels(float* values, std::size_t channels, const std::vector<bool>& spread,
                   const PixelRect& have, const PixelRect& to, const std::vector<double>& weights) {
    const int reach = static_cast<int>(weights.size() / 2);
    if (reach == 0 || to.x0 >= to.x1 || to.y0 >= to.y1) return;
    const auto hw = static_cast<std::size_t>(have.x1 - have.x0);
    std::vector<std::size_t> cs;
    for (std::size_t c = 0; c < channels && c < spread.size(); ++c)
        if (spread[c]) cs.push_back(c);
    if (cs.empty()) return;
    // Along x first, for the rows of `to` and `reach` rows on either side (those in `have`),
    // the columns of `to`; then along y into `to`. Both in double, in offset order. In blocks of
    // rows, so that the passes hold a few rows, not the image (each pixel's sums are the same
    // whatever the blocks). A block's results are written once the next block's pass along x has
    // read the rows it shares with it (at most `reach` of them, fewer than a block's).
    const std::size_t tw = to.x1 - to.x0, nc = cs.size();
    const auto at = [&](uint32_t x, uint32_t y) {
        return values + ((y - have.y0) * hw + (x - have.x0)) * channels;
    };
    constexpr uint32_t kBlockRows = 32;
    std::vector<double> rows, acc(nc);
    std::vector<float> pending;
    uint32_t pending_y0 = 0, pending_y1 = 0;
    const auto flush = [&] {
        for (uint32_t y = pending_y0; y < pending_y1; ++y)
            for (uint32_t x = to.x0; x < to.x1; ++x) {
                float* v = at(x, y);
                const float* r = &pending[((y - pending_y0) * tw + (x - to.x0)) * nc];
                for (std::size_t k = 0; k < nc; ++k) v[cs[k]] = r[k];
            }
        pending_y0 = pending_y1 = 0;
    };
    for (uint32_t by0 = to.y0; by0 < to.y1; by0 += kBlockRows) {
        const uint32_t by1 = std::min(to.y1, by0 + kBlockRows);
        const auto ry0 = static_cast<uint32_t>(
                       std::max<int64_t>(have.y0, static_cast<int64_t>(by0) - reach)),
                   ry1 = std::min<uint32_t>(have.y1, by1 + static_cast<uint32_t>(reach));
        rows.assign(static_cast<std::size_t>(ry1 - ry0) * tw * nc, 0.0);
        for (uint32_t y = ry0; y < ry1; ++y)
            for (uint32_t x = to.x0; x < to.x1; ++x) {
                double* out = &rows[((y - ry0) * tw + (x - to.x0)) * nc];
                double wsum = 0.0;
                for (int o = -reach; o <= reach; ++o) {
                    const int64_t xx = static_cast<int64_t>(x) + o;
                    if (xx < have.x0 || xx >= have.x1) continue;
                    const double w = weights[static_cast<std::size_t>(o + reach)];
                    const float* v = at(static_cast<uint32_t>(xx), y);
                    for (std::size_t k = 0; k < nc; ++k)
                        out[k] += w * static_cast<double>(v[cs[k]]);
                    wsum += w;
                }
                for (std::size_t k = 0; k < nc; ++k) out[k] /= wsum;
            }
        flush();
        pending.assign(static_cast<std::size_t>(by1 - by0) * tw * nc, 0.0f);
        pending_y0 = by0;
        pending_y1 = by1;
        for (uint32_t y = by0; y < by1; ++y)
            for (uint32_t x = to.x0; x < to.x1; ++x) {
                float* v = &pending[((y - by0) * tw + (x - to.x0)) * nc];
                double wsum = 0.0;
                std::fill(acc.begin(), acc.end(), 0.0);
                for (int o = -reach; o <= reach; ++o) {
                    const int64_t yy = static_cast<int64_t>(y) + o;
                    if (yy < have.y0 || yy >= have.y1) continue;
                    const double w = weights[static_cast<std::size_t>(o + reach)];
                    const double* r =
                        &rows[((static_cast<uint32_t>(yy) - ry0) * tw + (x - to.x0)) * nc];
                    for (std::size_t k = 0; k < nc; ++k) acc[k] += w * r[k];
                    wsum += w;
                }
                for (std::size_t k = 0; k < nc; ++k) v[k] = static_cast<float>(acc[k] / wsum);
            }
    }
    flush();
}

}  // namespace spangle
