#include "smooth_lobe.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <tuple>

namespace spangle::flake {

/** The blur table: n_o view angles x n_x x n_y compactified slopes, four floats per node (R and
 *  the blurred Fresnel's ratio to F(wo.h) per channel). A view angle's slice is computed the first
 *  time it is needed; call_once makes that safe from any number of shading threads. */
struct BlurTable {
    float alpha = 0.15f, kappa = 0.0f, sigma = 0.0f;
    double sin2_half = 0.0;
    FresnelTable fresnel;  ///< a copy: the table may outlive the material that made it
    int n_o = 0, n_x = 0, n_y = 0;
    std::vector<float> data;
    std::unique_ptr<std::once_flag[]> built;
    /** Mass corrections at kPerNode view angles per node interval (index kPerNode k is node k):
     *  interpolating two nodes' R at an angle between them does not keep the exact mass. */
    std::vector<float> correction;
    std::unique_ptr<std::once_flag[]> corrected;
    const float* node(int k) const;
    float mass_correction(float fk) const;
};

namespace {

/** View nodes: uniform in theta_o (4 degrees apart) down to cos = 0.5, then geometric in cos
 *  (ratio 1.2) down to 0.005: near grazing the blur stretches the lobe by 1 / cos(theta_o), so
 *  its shape changes with the cosine's ratio, not its difference. */
constexpr int kThetaNodes = 16;    ///< theta_o = 0, 4, ..., 60 degrees
constexpr int kGrazingNodes = 26;  ///< cos = 0.5 / 1.2^j, j = 1..26 (down to 0.0046)
constexpr int kViewNodes = kThetaNodes + kGrazingNodes;
constexpr float kThetaStep = 4.0f * 3.14159265f / 180.0f;
const float kLogRatio = std::log(1.2f);
/** Mass corrections per view-node interval (see BlurTable::correction). */
constexpr int kPerNode = 2;
constexpr int kVndfGrid = 256;  ///< stratified VNDF samples per side for the normalisation

/** wo's azimuth as (cos, sin); (1, 0) at normal incidence. */
void azimuth(V3 wo, float& c, float& s) {
    const float r = std::sqrt(wo.x * wo.x + wo.y * wo.y);
    if (r > 1e-12f) {
        c = wo.x / r;
        s = wo.y / r;
    } else {
        c = 1.0f;
        s = 0.0f;
    }
}

/** v turned into wo's azimuthal frame (wo in the xz-plane, x >= 0). */
V3 to_frame(V3 v, float c, float s) {
    return {c * v.x + s * v.y, -s * v.x + c * v.y, v.z};
}
V3 from_frame(V3 v, float c, float s) {
    return {c * v.x - s * v.y, s * v.x + c * v.y, v.z};
}

/** Slope scales of the table at a view angle: the cone reaches kappa in half-vector slope along
 *  wo's plane and kappa / cos(theta_d) across it (reflection halves angles in the plane and
 *  divides by 2 cos(theta_d) across it). */
float scale_x(float kappa) {
    return 1.0f + kappa;
}
/** 1 / cos(theta_o), smoothly limited to 20 at grazing views: the cone's reach across wo's plane
 *  grows as 1 / cos, and a kink (a hard clamp) would be a kink in every table entry between two
 *  view nodes, which linear interpolation cannot follow. */
float grazing_stretch(float cos_o) {
    return 1.0f / std::hypot(cos_o, 0.05f);
}
float scale_y(float kappa, float cos_o) {
    return 1.0f + kappa * grazing_stretch(cos_o);
}

/** The widened roughness of the proposal (along and across wo's plane). */
void proposal_alpha_of(float alpha, float kappa, float cos_o, float& ax, float& ay) {
    ax = alpha * (1.0f + 0.5f * kappa);
    ay = alpha * (1.0f + 0.5f * kappa * grazing_stretch(cos_o));
}

/** Compactified coordinate of a slope: x / (s + |x|) in (-1, 1). */
float squash(float x, float s) {
    return x / (s + std::fabs(x));
}
/** Its inverse. */
double unsquash(double w, double s) {
    return s * w / (1.0 - std::fabs(w));
}

/** Bilinear lookup of view node k at compactified slopes (wx in [-1, 1], wy in [0, 1]). */
void lookup_node(const BlurTable& t, const float* slice, float wx, float wy, float out[4]) {
    const float fx = (wx + 1.0f) * 0.5f * static_cast<float>(t.n_x - 1);
    const float fy = wy * static_cast<float>(t.n_y - 1);
    const int ix = std::clamp(static_cast<int>(fx), 0, t.n_x - 2);
    const int iy = std::clamp(static_cast<int>(fy), 0, t.n_y - 2);
    const float ax = std::clamp(fx - static_cast<float>(ix), 0.0f, 1.0f),
                ay = std::clamp(fy - static_cast<float>(iy), 0.0f, 1.0f);
    const std::size_t row = static_cast<std::size_t>(t.n_x) * 4;
    const float* p = slice + static_cast<std::size_t>(iy) * row + 4 * ix;
    for (int c = 0; c < 4; ++c) {
        const float top = p[c] + ax * (p[4 + c] - p[c]);
        const float bottom = p[row + c] + ax * (p[row + 4 + c] - p[row + c]);
        out[c] = top + ay * (bottom - top);
    }
}

/** The compactified slopes of h at view node k. */
void node_coords(const BlurTable& t, float cos_k, V3 h, float& wx, float& wy) {
    const float inv = 1.0f / (t.alpha * std::max(h.z, 1e-20f));
    wx = squash(h.x * inv, scale_x(t.kappa));
    wy = squash(std::fabs(h.y) * inv, scale_y(t.kappa, cos_k));
}

float node_cos(int k) {
    if (k < kThetaNodes) return std::cos(kThetaStep * static_cast<float>(k));
    return 0.5f * std::exp(-kLogRatio * static_cast<float>(k - kThetaNodes + 1));
}

/** Fractional node index of a view cosine (inverse of node_cos, clamped to the nodes). */
float node_index(float cos_o) {
    if (cos_o >= 0.5f) return std::acos(std::min(cos_o, 1.0f)) / kThetaStep;
    const float j = std::log(0.5f / std::max(cos_o, 1e-30f)) / kLogRatio;
    return std::min(static_cast<float>(kThetaNodes - 1) + j, static_cast<float>(kViewNodes - 1));
}

/** The view cosine at a fractional node index (inverse of node_index). */
float fractional_node_cos(float fk) {
    if (fk <= static_cast<float>(kThetaNodes - 1)) return std::cos(kThetaStep * fk);
    return 0.5f * std::exp(-kLogRatio * (fk - static_cast<float>(kThetaNodes - 1)));
}

/** R (and the Fresnel ratios) at fractional view node fk: the two nodes around it, linearly. */
void interpolate_nodes(const BlurTable& bt, float fk, V3 h, float out[4]) {
    const int k = std::min(static_cast<int>(fk), bt.n_o - 2);
    const float t = fk - static_cast<float>(k);
    float a[4], b[4], wx, wy;
    node_coords(bt, node_cos(k), h, wx, wy);
    lookup_node(bt, bt.node(k), wx, wy, a);
    node_coords(bt, node_cos(k + 1), h, wx, wy);
    lookup_node(bt, bt.node(k + 1), wx, wy, b);
    for (int c = 0; c < 4; ++c) out[c] = a[c] + t * (b[c] - a[c]);
}

/** Fills node k of the blur table from the exact integral. */
void build_node(BlurTable& t, int k) {
    const float cos_k = node_cos(k);
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_k * cos_k)), 0.0f, cos_k};
    const CapParams cp{t.alpha, t.sin2_half, &t.fresnel};
    const double sx = scale_x(t.kappa), sy = scale_y(t.kappa, cos_k);
    float ax, ay;
    proposal_alpha_of(t.alpha, t.kappa, cos_k, ax, ay);
    const float g1 = mf::ggx_g1(wo, ax, ay);
    for (int j = 0; j < t.n_y; ++j)
        for (int i = 0; i < t.n_x; ++i) {
            float* out = &t.data[((static_cast<std::size_t>(k) * t.n_y + j) * t.n_x + i) * 4];
            const double wx = -1.0 + 2.0 * i / (t.n_x - 1),
                         wy = static_cast<double>(j) / (t.n_y - 1);
            out[0] = out[1] = out[2] = out[3] = 1.0f;  // at infinite slope the blur is nothing
            out[0] = -1.0f;                            // not yet known
            // The last nodes stand for infinite slopes: take them just short of it.
            const double x = unsquash(std::clamp(wx, -0.999, 0.999), sx),
                         y = unsquash(std::min(wy, 0.999), sy);
            const V3 h = mf::normalize(
                {t.alpha * static_cast<float>(x), t.alpha * static_cast<float>(y), 1.0f});
            const V3 wi = mf::reflect(wo, h);
            if (!(wi.z > 1e-5f)) continue;
            float i_f[3], i_1;
            cap_integral(cp, wo, wi, i_f, i_1, 1e-4);
            // The share of wi's cone above the horizon is geometry, applied exactly at eval time.
            const auto above = static_cast<float>(cone_fraction_above(wi.z, t.sin2_half));
            const float p = g1 * mf::ggx_d(h, ax, ay) / (4.0f * wo.z) * above;
            if (!(p > 0.0f)) continue;
            out[0] = (i_1 / t.sigma) / p;
            float f[3];
            t.fresnel.eval(mf::dot(wo, h), f);
            for (int c = 0; c < 3; ++c)
                out[1 + c] = i_1 > 0.0f && f[c] > 0.0f ? i_f[c] / (i_1 * f[c]) : 1.0f;
        }
    // Directions under the horizon were skipped: continue each row from its nearest known node.
    for (int j = 0; j < t.n_y; ++j) {
        float* row = &t.data[(static_cast<std::size_t>(k) * t.n_y + j) * t.n_x * 4];
        int known = -1;
        for (int i = 0; i < t.n_x; ++i)
            if (row[4 * i] >= 0.0f) known = i;
        for (int i = t.n_x - 1; i >= 0; --i) {
            if (row[4 * i] >= 0.0f) {
                known = i;
            } else if (known >= 0) {
                std::copy(row + 4 * known, row + 4 * known + 4, row + 4 * i);
            } else {
                row[4 * i] = row[4 * i + 1] = row[4 * i + 2] = row[4 * i + 3] = 1.0f;
            }
        }
    }
}

/** The exact mass of the blurred lobe over wi against the table's, at view cosine cos_e (wo in the
 *  xz-plane), for `lookup(h, v)` giving R and the Fresnel ratios at half vector h. Exact:
 *  E[A 1_valid] over the visible normals (r their mirror direction, A the share of its cone above
 *  the horizon). Table: the eval'd lobe is q A R, so its mass is E[A R] over the proposal's own
 *  directions; R is bounded there (the proposal is wider than the blurred lobe), where an estimate
 *  over the unblurred normals would weight the blur's tails by rho / p and need far more samples
 *  once the cone is wider than the flake lobe. Both on stratified grids. */
template <class Lookup>
double mass_ratio(const BlurTable& t, float cos_e, int grid, Lookup&& lookup) {
    const V3 wo{std::sqrt(std::max(0.0f, 1.0f - cos_e * cos_e)), 0.0f, cos_e};
    float ax, ay;
    proposal_alpha_of(t.alpha, t.kappa, cos_e, ax, ay);
    double exact = 0.0, tabled = 0.0;
    const auto g = static_cast<float>(grid);
    for (int a = 0; a < grid; ++a)
        for (int b = 0; b < grid; ++b) {
            const float u0 = (static_cast<float>(a) + 0.5f) / g,
                        u1 = (static_cast<float>(b) + 0.5f) / g;
            const V3 r = mf::reflect(wo, mf::ggx_sample_visible(wo, t.alpha, t.alpha, u0, u1));
            if (r.z > 0.0f) exact += cone_fraction_above(r.z, t.sin2_half);
            const V3 h = mf::ggx_sample_visible(wo, ax, ay, u0, u1);
            const V3 wi = mf::reflect(wo, h);
            if (!(wi.z > 0.0f)) continue;
            float v[4];
            lookup(h, v);
            tabled += static_cast<double>(v[0]) * cone_fraction_above(wi.z, t.sin2_half);
        }
    return tabled > 0.0 ? exact / tabled : 1.0;
}

/** Scales node k's R so that the table's mass over wi equals the exact one (mass_ratio). */
void normalise_node(BlurTable& t, int k) {
    const float cos_k = node_cos(k);
    const float* slice = &t.data[static_cast<std::size_t>(k) * t.n_x * t.n_y * 4];
    const auto scale = static_cast<float>(mass_ratio(t, cos_k, kVndfGrid, [&](V3 h, float v[4]) {
        float wx, wy;
        node_coords(t, cos_k, h, wx, wy);
        lookup_node(t, slice, wx, wy, v);
    }));
    for (std::size_t n = 0; n < static_cast<std::size_t>(t.n_x * t.n_y); ++n)
        t.data[(static_cast<std::size_t>(k) * t.n_x * t.n_y + n) * 4] *= scale;
}

}  // namespace

double cone_fraction_above(double r_z, double sin2_half) {
    // The cone (a spherical cap of radius gamma around r) against the lower hemisphere (a cap of
    // radius pi/2 around -z, at angular distance pi - theta_r): the area of two intersecting caps
    // of radii r1, r2 at distance d is 2 pi - 2 cos(r1) acos((cos r2 - cos d cos r1) / (sin d sin
    // r1)) - 2 cos(r2) acos(...) - 2 acos((cos d - cos r1 cos r2) / (sin r1 sin r2)); with
    // r2 = pi/2 the middle term vanishes.
    const double sin_g = 2.0 * std::sqrt(sin2_half * (1.0 - sin2_half));  // sin(gamma)
    const double cos_g = 1.0 - 2.0 * sin2_half;
    if (r_z >= sin_g) return 1.0;  // the whole cone is above the horizon
    if (r_z <= -sin_g) return 0.0;
    const double sin_r = std::sqrt(std::max(0.0, 1.0 - r_z * r_z));  // sin(theta_r)
    const double a1 = std::acos(std::clamp(r_z * cos_g / (sin_r * sin_g), -1.0, 1.0));
    const double a2 = std::acos(std::clamp(-r_z / sin_g, -1.0, 1.0));
    const double below = 2.0 * 3.14159265358979 - 2.0 * cos_g * a1 - 2.0 * a2;
    const double cap = 4.0 * 3.14159265358979 * sin2_half;  // 2 pi (1 - cos gamma)
    return std::clamp(1.0 - below / cap, 0.0, 1.0);
}

const float* BlurTable::node(int k) const {
    std::call_once(built[k], [&] {
        auto& self = const_cast<BlurTable&>(*this);
        build_node(self, k);
        normalise_node(self, k);
    });
    return &data[static_cast<std::size_t>(k) * n_x * n_y * 4];
}

float BlurTable::mass_correction(float fk) const {
    const float e = std::clamp(kPerNode * fk, 0.0f, static_cast<float>(correction.size() - 1));
    const int e0 = std::min(static_cast<int>(e), static_cast<int>(correction.size()) - 2);
    for (int i = e0; i <= e0 + 1; ++i) {
        std::call_once(corrected[static_cast<std::size_t>(i)], [&] {
            // The table between nodes, as interpolated, against the exact mass (as in
            // normalise_node).
            const float fi = static_cast<float>(i) / kPerNode;
            auto& self = const_cast<BlurTable&>(*this);
            self.correction[static_cast<std::size_t>(i)] = static_cast<float>(
                mass_ratio(*this, fractional_node_cos(fi), kVndfGrid,
                           [&](V3 h, float v[4]) { interpolate_nodes(*this, fi, h, v); }));
        });
    }
    const float t = e - static_cast<float>(e0);
    return correction[static_cast<std::size_t>(e0)] +
           t * (correction[static_cast<std::size_t>(e0) + 1] -
                correction[static_cast<std::size_t>(e0)]);
}

namespace {

/** Tables by (alpha, gamma, Fresnel), shared within the process: scenes and tests often create
 *  the same material many times. Entries live as long as some material holds them. */
std::shared_ptr<BlurTable> shared_table(float alpha, double sin2_half, float kappa, float sigma,
                                        const FresnelTable& fresnel) {
    using Key = std::tuple<float, double, std::vector<float>>;
    static std::mutex mutex;
    static std::map<Key, std::weak_ptr<BlurTable>> cache;
    Key key{alpha, sin2_half,
            std::vector<float>(&fresnel.rgb[0][0], &fresnel.rgb[0][0] + 3 * FresnelTable::kNodes)};
    std::lock_guard<std::mutex> lock(mutex);
    if (auto hit = cache[key].lock()) return hit;
    auto t = std::make_shared<BlurTable>();
    t->alpha = alpha;
    t->kappa = kappa;
    t->sigma = sigma;
    t->sin2_half = sin2_half;
    t->fresnel = fresnel;
    // The rim of a wide cone over near-mirror flakes is about one slope unit wide at a distance
    // kappa: resolve it with a few nodes.
    const int refine = std::clamp(static_cast<int>(std::ceil(kappa / 1.5f)), 1, 4);
    t->n_o = kViewNodes;
    t->n_x = 48 * refine + 1;
    t->n_y = 24 * refine + 1;
    t->data.assign(static_cast<std::size_t>(t->n_o) * t->n_x * t->n_y * 4, 1.0f);
    t->built = std::make_unique<std::once_flag[]>(static_cast<std::size_t>(t->n_o));
    t->correction.assign(static_cast<std::size_t>(kPerNode * (t->n_o - 1) + 1), 1.0f);
    t->corrected = std::make_unique<std::once_flag[]>(t->correction.size());
    cache[key] = t;
    return t;
}

}  // namespace

void SmoothLobe::init(float alpha_, float gamma_rad, const FresnelTable* fresnel_) {
    alpha = alpha_;
    const double s = std::sin(0.5 * static_cast<double>(gamma_rad));
    sin2_half = s * s;
    sigma = static_cast<float>(4.0 * 3.14159265358979 * sin2_half);
    kappa = std::tan(0.5f * gamma_rad) / alpha;
    // The blur changes the lobe by O(kappa^2): below kappa = 0.01 it is under 1e-4.
    blur_negligible = kappa < 0.01f;
    fresnel = fresnel_;
    for (int i = 0; i < kValidNodes; ++i) {
        const float mu = std::max(1e-7f, static_cast<float>(i) / (kValidNodes - 1));
        const V3 wo{std::sqrt(std::max(0.0f, 1.0f - mu * mu)), 0.0f, mu};
        valid[i] = static_cast<float>(valid_fraction_exact(alpha, wo, 1e-9));
    }
    table = blur_negligible ? nullptr : shared_table(alpha, sin2_half, kappa, sigma, *fresnel);
}

float SmoothLobe::valid_fraction(float cos_o) const {
    const float x = std::clamp(cos_o, 0.0f, 1.0f) * static_cast<float>(kValidNodes - 1);
    const int i = std::min(static_cast<int>(x), kValidNodes - 2);
    const float f = x - static_cast<float>(i);
    return valid[i] + f * (valid[i + 1] - valid[i]);
}

void SmoothLobe::blur(float cos_o, V3 h, float out[4]) const {
    if (!table) {
        out[0] = out[1] = out[2] = out[3] = 1.0f;
        return;
    }
    const float fk = node_index(cos_o);
    interpolate_nodes(*table, fk, h, out);
    out[0] *= table->mass_correction(fk);
}

void SmoothLobe::proposal_alpha(float cos_o, float& ax, float& ay) const {
    if (blur_negligible) {
        ax = ay = alpha;  // the lobe is the unblurred one: sample it exactly
        return;
    }
    proposal_alpha_of(alpha, kappa, cos_o, ax, ay);
}

void eval_smooth(const SmoothLobe& lobe, V3 wo, float v_o, V3 wi, float f[3], float& pdf) {
    f[0] = f[1] = f[2] = pdf = 0.0f;
    if (!(wo.z > 0.0f) || !(wi.z > 0.0f) || !(v_o > 0.0f)) return;
    float c, s;
    azimuth(wo, c, s);
    const V3 wo_a = to_frame(wo, c, s), wi_a = to_frame(wi, c, s);
    V3 h = wo_a + wi_a;
    if (!(h.z > 0.0f)) return;
    h = mf::normalize(h);
    // The proposal's density of mirror directions, exact for sample_smooth().
    float ax, ay;
    lobe.proposal_alpha(wo.z, ax, ay);
    pdf = mf::ggx_g1(wo_a, ax, ay) * mf::ggx_d(h, ax, ay) / (4.0f * wo.z);
    float blur[4];
    lobe.blur(wo.z, h, blur);
    float fr[3];
    lobe.fresnel->eval(mf::dot(wo_a, h), fr);
    const auto above = static_cast<float>(cone_fraction_above(wi.z, lobe.sin2_half));
    const float k = pdf * blur[0] * above / (wi.z * v_o);
    for (int ch = 0; ch < 3; ++ch) f[ch] = fr[ch] * blur[1 + ch] * k;
    if (!std::isfinite(pdf + f[0] + f[1] + f[2])) f[0] = f[1] = f[2] = pdf = 0.0f;
}

bool sample_smooth(const SmoothLobe& lobe, V3 wo, float u0, float u1, V3& wi) {
    if (!(wo.z > 0.0f)) return false;
    float c, s, ax, ay;
    azimuth(wo, c, s);
    lobe.proposal_alpha(wo.z, ax, ay);
    const V3 wo_a = to_frame(wo, c, s);
    const V3 h = mf::ggx_sample_visible(wo_a, ax, ay, u0, u1);
    const V3 wi_a = mf::reflect(wo_a, h);
    if (!(wi_a.z > 0.0f)) return false;
    wi = from_frame(wi_a, c, s);
    return true;
}

}  // namespace spangle::flake
