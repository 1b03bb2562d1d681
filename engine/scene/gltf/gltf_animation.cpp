// Node transforms and their animations (glTF 2.0, 3.5 and 3.11): every node's world matrix,
// sampled at the union of the key times of the channels that move it or any of its parents.
// Between those times the builder interpolates the matrices by their decomposition, which for
// LINEAR channels of one node gives back glTF's own interpolation (translation and scale along
// straight lines, rotation along the shorter arc); a node carried by a rotating ancestor moves
// along arcs, so it is sampled every 3 degrees of that rotation. STEP channels get a key just
// before each step; CUBICSPLINE channels are evaluated exactly at their keys and at three points
// between (a note says so).

#include <algorithm>
#include <cmath>
#include <numbers>

#include "scene/gltf/gltf_accessors.h"
#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {
namespace {

constexpr std::size_t kMaxKeys = 4'000'000;   ///< matrix keys of all nodes together
constexpr std::size_t kMaxWork = 40'000'000;  ///< local matrices composed for them (keys x depth)
constexpr float kMinScale = 1e-6f;            ///< an animated scale of 0 becomes this (invertible)

/** One animation channel: what it moves and its keys. */
struct Channel {
    int node = -1;              ///< the node it moves
    int path = 0;               ///< 0 translation, 1 rotation, 2 scale
    int interp = 0;             ///< 0 LINEAR, 1 STEP, 2 CUBICSPLINE
    std::vector<float> times;   ///< seconds, increasing
    std::vector<float> values;  ///< 3 or 4 per key (CUBICSPLINE: in-tangent, value, out-tangent)
};

/** A node's local transform as parts. */
struct Trs {
    Vec3 t{0, 0, 0};
    float r[4] = {0, 0, 0, 1};  ///< quaternion x, y, z, w
    Vec3 s{1, 1, 1};
};

/** T R S as one matrix (the quaternion normalised; a zero one is no rotation). */
Affine to_affine(const Trs& p) {
    float x = p.r[0], y = p.r[1], z = p.r[2], w = p.r[3];
    const float n = std::sqrt(x * x + y * y + z * z + w * w);
    if (n > 0.0f) {
        x /= n, y /= n, z /= n, w /= n;
    } else {
        x = y = z = 0.0f, w = 1.0f;
    }
    Affine a;
    const float rot[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                             {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                             {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    const float s[3] = {p.s.x, p.s.y, p.s.z};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) a.m[r][c] = rot[r][c] * s[c];
    a.t = p.t;
    return a;
}

/** A node's own translation, rotation and scale (non-finite numbers read as 0). */
Trs node_trs(const tinygltf::Node& node) {
    Trs p;
    const auto f = [](double v) { return std::isfinite(narrow(v)) ? narrow(v) : 0.0f; };
    if (node.translation.size() == 3)
        p.t = {f(node.translation[0]), f(node.translation[1]), f(node.translation[2])};
    if (node.rotation.size() == 4)
        for (int k = 0; k < 4; ++k) p.r[k] = f(node.rotation[static_cast<std::size_t>(k)]);
    if (node.scale.size() == 3) p.s = {f(node.scale[0]), f(node.scale[1]), f(node.scale[2])};
    return p;
}

/** 0, 1, 2 for translation, rotation, scale; -1 for any other target path. */
int path_index(const std::string& p) {
    return p == "translation" ? 0 : p == "rotation" ? 1 : p == "scale" ? 2 : -1;
}

/** A sampler's interpolation (0 LINEAR, 1 STEP, 2 CUBICSPLINE), the sampler at JSON path `sp`;
 *  throws there for another. */
int sampler_interpolation(Context& ctx, const tinygltf::AnimationSampler& s,
                          const std::string& sp) {
    if (s.interpolation != "LINEAR" && s.interpolation != "STEP" &&
        s.interpolation != "CUBICSPLINE")
        throw_error(ctx.at(sp + "/interpolation"),
                    "interpolation '{}' must be LINEAR, STEP or CUBICSPLINE", s.interpolation);
    return s.interpolation == "STEP" ? 1 : s.interpolation == "CUBICSPLINE" ? 2 : 0;
}
/** A sampler's key times; throws where they do not increase. */
std::vector<float> sampler_times(Context& ctx, const tinygltf::AnimationSampler& s,
                                 const std::string& sp) {
    std::vector<float> t = read_floats(ctx, s.input, 1, "animation input", sp + "/input");
    for (std::size_t i = 1; i < t.size(); ++i)
        if (!(t[i] > t[i - 1]))
            throw_error(ctx.at(sp + "/input"), "key times must increase ({} s follows {} s)", t[i],
                        t[i - 1]);
    return t;
}

/** The channels of every animation; a node's path driven twice keeps the first channel. */
std::vector<Channel> read_channels(Context& ctx) {
    std::vector<Channel> out;
    std::set<std::pair<int, int>> driven;
    for (std::size_t a = 0; a < ctx.model.animations.size(); ++a) {
        const tinygltf::Animation& anim = ctx.model.animations[a];
        for (std::size_t c = 0; c < anim.channels.size(); ++c) {
            const tinygltf::AnimationChannel& ch = anim.channels[c];
            const std::string cp = fmt::format("animations/{}/channels/{}", a, c);
            const int path = path_index(ch.target_path);
            if (ch.target_path == "weights" && ch.target_node >= 0) continue;  // weight_tracks()
            if (path < 0 && ch.target_path != "weights") {
                ctx.note("animation path " + ch.target_path, ctx.at(cp + "/target"),
                         fmt::format("animations of '{}' are dropped (Spangle animates node "
                                     "transforms)",
                                     ch.target_path));
                continue;
            }
            if (ch.target_node < 0) {  // glTF allows a target without a node: it animates none
                ctx.note("animation without node", ctx.at(cp + "/target"),
                         "an animation channel without a target node animates nothing: dropped");
                continue;
            }
            check_index(ctx, cp + "/target/node", ch.target_node, ctx.model.nodes.size(), "node");
            check_index(ctx, cp + "/sampler", ch.sampler, anim.samplers.size(), "sampler");
            if (!driven.insert({ch.target_node, path}).second) {
                ctx.note("animation twice", ctx.at(cp),
                         fmt::format("node {}'s {} is animated twice: the first channel is kept",
                                     ch.target_node, ch.target_path));
                continue;
            }
            const tinygltf::AnimationSampler& s =
                anim.samplers[static_cast<std::size_t>(ch.sampler)];
            const std::string sp = fmt::format("animations/{}/samplers/{}", a, ch.sampler);
            Channel k;
            k.node = ch.target_node;
            k.path = path;
            k.interp = sampler_interpolation(ctx, s, sp);
            k.times = sampler_times(ctx, s, sp);
            k.values =
                read_floats(ctx, s.output, path == 1 ? 4 : 3, "animation output", sp + "/output");
            const std::size_t per = (path == 1 ? 4u : 3u) * (k.interp == 2 ? 3u : 1u);
            if (k.times.empty() || k.values.size() != k.times.size() * per)
                throw_error(ctx.at(sp),
                            "the sampler has {} key times and {} output values; "
                            "expected {} values per key",
                            k.times.size(), k.values.size(), per);
            if (k.interp == 2)
                ctx.note("CUBICSPLINE", ctx.at(sp + "/interpolation"),
                         "CUBICSPLINE animation is approximated: evaluated at its keys and three "
                         "points between each, interpolated linearly in between");
            out.push_back(std::move(k));
        }
    }
    return out;
}

/** The value of `n` numbers at time t of keys at `times` with `values` (n per key; CUBICSPLINE:
 *  in-tangents, values, out-tangents), held constant outside them; `rotation`: a quaternion
 *  (LINEAR along the shorter arc). */
void evaluate_keys(const std::vector<float>& times, const std::vector<float>& values, std::size_t n,
                   int interp, bool rotation, float t, float* out) {
    const std::size_t per = interp == 2 ? 3 * n : n;
    const std::size_t value =
        interp == 2 ? n : 0;  // a CUBICSPLINE key's value follows its in-tangent
    const std::size_t last = times.size() - 1;
    std::size_t i = 0;
    if (t >= times[last]) {
        i = last;
    } else if (t > times[0]) {
        i = static_cast<std::size_t>(std::upper_bound(times.begin(), times.end(), t) -
                                     times.begin()) -
            1;
    }
    const float* a = &values[i * per + value];
    if (i == last || t <= times[0] || interp == 1) {
        std::copy(a, a + n, out);
        return;
    }
    const float* b = &values[(i + 1) * per + value];
    const float dt = times[i + 1] - times[i], s = (t - times[i]) / dt;
    if (interp == 2) {
        // Hermite spline (glTF 2.0, Appendix C): a's out-tangent and b's in-tangent, times dt.
        const float* ta = &values[i * per + 2 * n];
        const float* tb = &values[(i + 1) * per];
        const float s2 = s * s, s3 = s2 * s;
        for (std::size_t c = 0; c < n; ++c)
            out[c] = (2 * s3 - 3 * s2 + 1) * a[c] + (s3 - 2 * s2 + s) * dt * ta[c] +
                     (-2 * s3 + 3 * s2) * b[c] + (s3 - s2) * dt * tb[c];
    } else if (rotation) {
        float d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
        const float sign = d < 0.0f ? -1.0f : 1.0f;  // the shorter arc
        d = std::min(1.0f, std::fabs(d));
        const float theta = std::acos(d);
        float wa = 1.0f - s, wb = s;
        if (theta > 1e-4f) {
            wa = std::sin((1.0f - s) * theta) / std::sin(theta);
            wb = std::sin(s * theta) / std::sin(theta);
        }
        for (std::size_t c = 0; c < 4; ++c) out[c] = wa * a[c] + sign * wb * b[c];
    } else {
        for (std::size_t c = 0; c < n; ++c) out[c] = a[c] + s * (b[c] - a[c]);
    }
}

/** Channel k's value (3 or 4 numbers) at time t, held constant outside its keys. */
void evaluate(const Channel& k, float t, float out[4]) {
    evaluate_keys(k.times, k.values, k.path == 1 ? 4 : 3, k.interp, k.path == 1, t, out);
}

/** The times at which a node moved by `channels` is sampled. */
std::vector<double> sample_times(const std::vector<const Channel*>& channels) {
    std::vector<double> t;
    for (const Channel* k : channels) {
        for (std::size_t i = 0; i < k->times.size(); ++i) {
            t.push_back(k->times[i]);
            if (i + 1 == k->times.size()) break;
            const double a = k->times[i], b = k->times[i + 1];
            if (k->interp == 1) t.push_back(b - std::min(1e-4, (b - a) / 100.0));
            if (k->interp == 2)
                for (double s : {0.25, 0.5, 0.75}) t.push_back(a + s * (b - a));
        }
    }
    std::sort(t.begin(), t.end());
    t.erase(std::unique(t.begin(), t.end()), t.end());
    return t;
}

/** Most a parent's rotation may turn between two samples of a child it carries: the child
 *  travels an arc, and the matrices, interpolated by their decomposition, move it along the
 *  chord; at 3 degrees the chord is within 0.035% of the arc's radius. */
constexpr double kMaxCarriedTurn = 3.0 * std::numbers::pi / 180.0;

/** `times` with samples added wherever a rotation in `carried` (channels of the node's
 *  ancestors) turns by more than kMaxCarriedTurn between two of them. */
std::vector<double> refine_for_arcs(const std::vector<double>& times,
                                    const std::vector<const Channel*>& carried) {
    if (carried.empty() || times.size() < 2) return times;
    std::vector<double> out{times.front()};
    for (std::size_t i = 0; i + 1 < times.size(); ++i) {
        const double a = times[i], b = times[i + 1];
        double turn = 0.0;
        for (const Channel* k : carried) {
            float qa[4], qb[4];
            evaluate(*k, static_cast<float>(a), qa);
            evaluate(*k, static_cast<float>(b), qb);
            double dot = 0.0, na = 0.0, nb = 0.0;
            for (int c = 0; c < 4; ++c) {
                dot += static_cast<double>(qa[c]) * static_cast<double>(qb[c]);
                na += static_cast<double>(qa[c]) * static_cast<double>(qa[c]);
                nb += static_cast<double>(qb[c]) * static_cast<double>(qb[c]);
            }
            if (!(na > 0.0 && nb > 0.0)) continue;
            const double d = std::fabs(dot) / std::sqrt(na * nb);
            turn = std::max(turn, 2.0 * std::acos(std::min(1.0, d)));
        }
        const int pieces = std::clamp(static_cast<int>(std::ceil(turn / kMaxCarriedTurn)), 1, 120);
        for (int j = 1; j < pieces; ++j) out.push_back(a + (b - a) * j / pieces);
        out.push_back(b);
    }
    return out;
}

}  // namespace

Affine trs_matrix(Vec3 t, const float r[4], Vec3 s) {
    Trs p;
    p.t = t;
    for (int k = 0; k < 4; ++k) p.r[k] = r[k];
    p.s = s;
    return to_affine(p);
}

std::map<int, WeightTrack> weight_tracks(Context& ctx) {
    std::map<int, WeightTrack> out;
    for (std::size_t a = 0; a < ctx.model.animations.size(); ++a) {
        const tinygltf::Animation& anim = ctx.model.animations[a];
        for (std::size_t c = 0; c < anim.channels.size(); ++c) {
            const tinygltf::AnimationChannel& ch = anim.channels[c];
            if (ch.target_path != "weights" || ch.target_node < 0) continue;  // (noted above)
            const std::string cp = fmt::format("animations/{}/channels/{}", a, c);
            check_index(ctx, cp + "/target/node", ch.target_node, ctx.model.nodes.size(), "node");
            check_index(ctx, cp + "/sampler", ch.sampler, anim.samplers.size(), "sampler");
            if (out.count(ch.target_node)) {
                ctx.note("animation twice", ctx.at(cp),
                         fmt::format("node {}'s weights are animated twice: the first channel "
                                     "is kept",
                                     ch.target_node));
                continue;
            }
            const tinygltf::AnimationSampler& s =
                anim.samplers[static_cast<std::size_t>(ch.sampler)];
            const std::string sp = fmt::format("animations/{}/samplers/{}", a, ch.sampler);
            WeightTrack w;
            w.loc = ctx.at(sp);
            w.interp = sampler_interpolation(ctx, s, sp);
            check_index(ctx, sp + "/output", s.output, ctx.model.accessors.size(), "accessor");
            if (ctx.model.accessors[static_cast<std::size_t>(s.output)].type !=
                TINYGLTF_TYPE_SCALAR) {
                ctx.note("weights not scalar", ctx.at(sp + "/output"),
                         "an animation of morph weights whose output is not SCALAR is dropped");
                continue;
            }
            w.times = sampler_times(ctx, s, sp);
            w.values = read_floats(ctx, s.output, 1, "animation output", sp + "/output");
            const std::size_t per_key = w.interp == 2 ? 3 : 1;
            if (w.times.empty() || w.values.empty() ||
                w.values.size() % (w.times.size() * per_key) != 0)
                throw_error(ctx.at(sp),
                            "the sampler has {} key times and {} output values: not the same "
                            "number of weights per key",
                            w.times.size(), w.values.size());
            w.count = w.values.size() / (w.times.size() * per_key);
            out.emplace(ch.target_node, std::move(w));
        }
    }
    return out;
}

void evaluate_weights(const WeightTrack& w, double t, float* out) {
    evaluate_keys(w.times, w.values, w.count, w.interp, false, static_cast<float>(t), out);
}

Affine local_matrix(const Context& ctx, int n) {
    const tinygltf::Node& node = ctx.model.nodes[static_cast<std::size_t>(n)];
    if (node.matrix.size() != 16) return to_affine(node_trs(node));
    for (double v : node.matrix)
        if (!std::isfinite(narrow(v)))
            throw_error(ctx.at(fmt::format("nodes/{}/matrix", n)),
                        "node {}'s matrix holds a number that is not a finite float ({})", n, v);
    float m[16];
    for (std::size_t i = 0; i < 16; ++i) m[i] = narrow(node.matrix[i]);
    return column_major_affine(m);
}

Affine column_major_affine(const float* m) {
    Affine a;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) a.m[r][c] = m[4 * c + r];
    a.t = {m[12], m[13], m[14]};
    return a;
}

std::vector<NodeMotion> node_motions(Context& ctx, const std::vector<int>& parent) {
    const std::size_t count = ctx.model.nodes.size();
    // A number beyond a float (1e39) read as 0 moved a node to the origin without a word.
    for (std::size_t n = 0; n < count; ++n) {
        const tinygltf::Node& node = ctx.model.nodes[n];
        for (const auto& [name, values] :
             {std::pair<const char*, const std::vector<double>*>{"translation", &node.translation},
              {"rotation", &node.rotation},
              {"scale", &node.scale}})
            for (double v : *values)
                if (!std::isfinite(narrow(v)))
                    throw_error(ctx.at(fmt::format("nodes/{}/{}", n, name)),
                                "node {}'s {} holds a number that is not a finite float ({})", n,
                                name, v);
    }
    const std::vector<Channel> channels = read_channels(ctx);
    std::vector<std::vector<const Channel*>> own(count), moving(count);
    for (const Channel& k : channels) own[static_cast<std::size_t>(k.node)].push_back(&k);
    for (std::size_t n = 0; n < count; ++n)
        if (!own[n].empty() && ctx.model.nodes[n].matrix.size() == 16)
            ctx.note("animated matrix", ctx.at(fmt::format("nodes/{}/matrix", n)),
                     "an animated node is given by a matrix: its animation's translation, "
                     "rotation and scale stand in for the matrix");
    const auto local_at = [&](int n, double t) {
        const auto un = static_cast<std::size_t>(n);
        if (own[un].empty()) return local_matrix(ctx, n);
        Trs p = ctx.model.nodes[un].matrix.size() == 16 ? Trs{} : node_trs(ctx.model.nodes[un]);
        for (const Channel* k : own[un]) {
            float v[4];
            evaluate(*k, static_cast<float>(t), v);
            if (k->path == 0) p.t = {v[0], v[1], v[2]};
            if (k->path == 1) std::copy(v, v + 4, p.r);
            if (k->path == 2) p.s = {v[0], v[1], v[2]};
        }
        for (float* s : {&p.s.x, &p.s.y, &p.s.z})
            if (std::fabs(*s) < kMinScale) *s = std::copysign(kMinScale, *s);
        return to_affine(p);
    };
    const auto world_at = [&](int n, double t) {
        Affine w = local_at(n, t);
        for (int a = parent[static_cast<std::size_t>(n)]; a >= 0;
             a = parent[static_cast<std::size_t>(a)])
            w = local_at(a, t).compose(w);
        return w;
    };
    std::vector<NodeMotion> out(count);
    // Placements at time 0 and the channels that move each node (its own and its ancestors'),
    // parents before children: each node's chain is resolved once.
    std::vector<char> done(count, 0);
    std::vector<std::size_t> depth(count, 1);
    for (std::size_t n = 0; n < count; ++n) {
        std::vector<std::size_t> chain;
        for (int a = static_cast<int>(n); a >= 0 && !done[static_cast<std::size_t>(a)];
             a = parent[static_cast<std::size_t>(a)])
            chain.push_back(static_cast<std::size_t>(a));
        for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
            const int p = parent[*it];
            const Affine local = local_at(static_cast<int>(*it), 0.0);
            out[*it].rest = p < 0 ? local : out[static_cast<std::size_t>(p)].rest.compose(local);
            depth[*it] = p < 0 ? 1 : depth[static_cast<std::size_t>(p)] + 1;
            if (p >= 0) moving[*it] = moving[static_cast<std::size_t>(p)];
            moving[*it].insert(moving[*it].end(), own[*it].begin(), own[*it].end());
            done[*it] = 1;
        }
    }
    // A product of finite matrices can overflow: a placement must stay finite.
    const auto finite = [](const Affine& m) {
        float sum = m.t.x + m.t.y + m.t.z;
        for (const auto& row : m.m) sum += row[0] + row[1] + row[2];
        return std::isfinite(sum);
    };
    for (std::size_t n = 0; n < count; ++n)
        if (!finite(out[n].rest))
            throw_error(ctx.at(fmt::format("nodes/{}", n)),
                        "node {}'s world transform overflows a float", n);
    std::size_t keys = 0, work = 0;
    for (std::size_t n = 0; n < count; ++n) {
        NodeMotion& m = out[n];
        if (moving[n].empty()) continue;
        m.times = sample_times(moving[n]);
        // A node carried by a rotating ancestor travels arcs, not chords: sampled densely
        // enough (a turntable's camera under a keyed pivot came 30% too close between keys).
        std::vector<const Channel*> carried;
        for (const Channel* k : moving[n])
            if (k->path == 1 && k->node != static_cast<int>(n)) carried.push_back(k);
        m.times = refine_for_arcs(m.times, carried);
        keys += m.times.size();
        work += m.times.size() * depth[n];
        if (keys > kMaxKeys || work > kMaxWork)
            throw_error(ctx.at("animations"),
                        "the animations give more than {} node keys (or {} transforms to "
                        "compose) in all",
                        kMaxKeys, kMaxWork);
        for (const Channel* k : moving[n]) m.cubic = m.cubic || k->interp == 2;
        m.matrices.reserve(m.times.size());
        for (double t : m.times) {
            m.matrices.push_back(world_at(static_cast<int>(n), t));
            if (!finite(m.matrices.back()))
                throw_error(ctx.at(fmt::format("nodes/{}", n)),
                            "node {}'s animated transform overflows a float at {} s", n, t);
        }
    }
    return out;
}

}  // namespace spangle::gltf
