#include "render/distribution.h"

#include <algorithm>

namespace spangle {

Distribution1D::Distribution1D(const std::vector<double>& weights) {
    for (double w : weights) total_ += w;
    if (!(total_ > 0.0)) {
        total_ = 0.0;
        return;
    }
    cdf_.resize(weights.size());
    pmf_.resize(weights.size());
    double run = 0.0;
    for (std::size_t i = 0; i < weights.size(); ++i) {
        run += weights[i];
        cdf_[i] = run / total_;
        pmf_[i] = static_cast<float>(weights[i] / total_);
    }
    cdf_.back() = 1.0;
}

uint32_t Distribution1D::sample(float u, float* remapped) const {
    // First index whose cdf exceeds u; zero-weight entries have equal cdf to their predecessor
    // and are never chosen because upper_bound skips them.
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), static_cast<double>(u));
    const std::size_t i = std::min(static_cast<std::size_t>(it - cdf_.begin()), cdf_.size() - 1);
    if (remapped) {
        const double lo = i == 0 ? 0.0 : cdf_[i - 1], hi = cdf_[i];
        const double t = hi > lo ? (static_cast<double>(u) - lo) / (hi - lo) : 0.5;
        *remapped = std::min(static_cast<float>(std::clamp(t, 0.0, 1.0)), 0x1.fffffep-1f);
    }
    return static_cast<uint32_t>(i);
}

}  // namespace spangle
