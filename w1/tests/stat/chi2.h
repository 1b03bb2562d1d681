#pragma once
// Pearson's chi-square goodness-of-fit test with pooling of sparse cells, and the upper
// regularised incomplete gamma function for its p-value.

#include <cmath>
#include <vector>

namespace spangle::test {

/** Q(a, x) = Gamma(a, x) / Gamma(a): series for x < a + 1, continued fraction otherwise
 *  (Press et al., Numerical Recipes, section 6.2). */
inline double gamma_q(double a, double x) {
    if (x <= 0.0) return 1.0;
    const double log_prefix = -x + a * std::log(x) - std::lgamma(a);
    if (x < a + 1.0) {
        double term = 1.0 / a, sum = term;
        for (int n = 1; n < 10000 && std::fabs(term) > std::fabs(sum) * 1e-15; ++n) {
            term *= x / (a + n);
            sum += term;
        }
        return 1.0 - sum * std::exp(log_prefix);
    }
    // Lentz's method for the continued fraction.
    const double tiny = 1e-300;
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 10000; ++i) {
        const double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::fabs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::fabs(c) < tiny) c = tiny;
        d = 1.0 / d;
        const double delta = d * c;
        h *= delta;
        if (std::fabs(delta - 1.0) < 1e-15) break;
    }
    return std::exp(log_prefix) * h;
}

/** Result of a chi-square test. */
struct Chi2Result {
    double statistic = 0.0;
    int dof = 0;
    double p_value = 1.0;
    int pooled = 0;  ///< cells merged because their expected count was below 5
};

/** Compares observed with expected counts; cells expected below 5 are pooled into one cell, as
 *  the test's approximation requires. */
inline Chi2Result chi2_test(const std::vector<double>& observed,
                            const std::vector<double>& expected) {
    Chi2Result r;
    double pool_o = 0.0, pool_e = 0.0;
    int cells = 0;
    for (std::size_t i = 0; i < observed.size(); ++i) {
        if (expected[i] < 5.0) {
            pool_o += observed[i];
            pool_e += expected[i];
            ++r.pooled;
            continue;
        }
        r.statistic += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
        ++cells;
    }
    if (pool_e > 0.0) {
        r.statistic += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        ++cells;
    } else if (pool_o > 0.0) {
        r.statistic = INFINITY;  // samples where the pdf says none can be
    }
    r.dof = cells - 1;
    if (!std::isfinite(r.statistic))
        r.p_value = 0.0;
    else
        r.p_value = r.dof > 0 ? gamma_q(0.5 * r.dof, 0.5 * r.statistic) : 1.0;
    return r;
}

}  // namespace spangle::test
