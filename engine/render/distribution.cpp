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

uint32_t Distribution1D::sample(float u) const {
    // First index whose cdf exceeds u; zero-weight entries have equal cdf to their predecessor
    // and are never chosen because upper_bound skips them.
    const auto it = std::upper_bound(cdf_.begin(), cdf_.end(), static_cast<double>(u));
    const auto i = static_cast<std::size_t>(it - cdf_.begin());
    return static_cast<uint32_t>(std::min(i, cdf_.size() - 1));
}

}  // namespace spangle
