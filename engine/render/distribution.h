#pragma once
// A piecewise-constant discrete distribution: pick index i with probability w_i / sum w.

#include <cstdint>
#include <vector>

namespace spangle {

/** Discrete distribution over weights; sums in double so that many small weights do not vanish. */
class Distribution1D {
public:
    Distribution1D() = default;
    /** Weights must be finite and >= 0; an all-zero list gives an empty distribution. */
    explicit Distribution1D(const std::vector<double>& weights);

    bool empty() const { return total_ <= 0.0; }
    std::size_t size() const { return pmf_.size(); }
    /** Index for u in [0, 1); binary search bounded by the table size. When `remapped` is
     *  given it receives u's position within the chosen bin, uniform in [0, 1). */
    uint32_t sample(float u, float* remapped = nullptr) const;
    /** Probability of index i. */
    float pmf(uint32_t i) const { return i < pmf_.size() ? pmf_[i] : 0.0f; }

private:
    std::vector<double> cdf_;  ///< cdf_[i] = sum of weights before i+1, normalised; last = 1
    std::vector<float> pmf_;   ///< normalised weights
    double total_ = 0.0;       ///< sum of weights
};

}  // namespace spangle
