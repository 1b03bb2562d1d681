// What accuracy costs in time. The shipped spheres and beetle scenes, at a reduced resolution, are
// rendered with the settings that trade one for the other -- samples per pixel, the flake
// blending thresholds, the flake algorithm and its precision knobs, gamma, the light transport
// strategy, the indirect clamp -- and each image is compared with a converged reference of its
// scene. Writes accuracy.md (tables, definitions, the best setting per time budget) and
// accuracy.svg (error against time, log-log) into the output folder:
//
//     ./build/spangle_accuracy --out docs           # the full report (80 minutes, 2 cores)
//     ./build/spangle_accuracy --quick --out DIR    # a smoke run of a few seconds (ctest)
//
// References are rendered once and cached (build/accuracy-cache unless --cache is given, and
// build/accuracy-cache-quick for --quick, so that a smoke run keeps the full references), keyed
// by a hash of their scene text, settings and the plugin libraries' bytes. Every render uses fixed
// seeds, so the report changes between runs only in its timings. The generated accuracy.md defines
// every number.

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "accuracy_plane.h"
#include "accuracy_plot.h"
#include "accuracy_render.h"
#include "core/check.h"
#include "core/error.h"
#include "core/files.h"
#include "shading/plugin_loader.h"
#include "test_support.h"

namespace fs = std::filesystem;

namespace spangle::accuracy {
namespace {

using Clock = std::chrono::steady_clock;

/** Bump when the reference renders or their cache format change meaning. */
constexpr int kCacheVersion = 1;
/** relMSE's regulariser: keeps near-black pixels from dominating. */
constexpr double kRelMseEps = 1e-2;
/** A glitter pixel's discrete reference exceeds the smooth one by this factor of it... */
constexpr double kGlintRatio = 0.5;
/** ...and by at least this much (working-space brightness), in both halves of the reference. */
constexpr double kGlintFloor = 0.05;
/** Half-width of the box whose mean the structure error's high-pass removes (5x5 pixels). */
constexpr int kHighPassRadius = 2;
/** Passes (the last ones of a curve) the convergence slope is fitted over. */
constexpr std::size_t kSlopePasses = 3;
/** Time budgets (seconds per frame) of the recommendations. */
constexpr double kBudgets[] = {0.5, 2, 8, 30, 120, 300};

/** Command line. */
struct Args {
    bool quick = false;  ///< the smoke run: tiny images, few samples
    bool fresh = false;  ///< re-render the references even when cached
    int threads = 0;     ///< render threads; 0 = all cores
    std::string out;     ///< folder of accuracy.md and accuracy.svg
    std::string cache;   ///< folder of the cached references
};

/** FNV-1a, 64 bits: the cache key of a reference. */
uint64_t fnv1a(const std::string& s) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (unsigned char c : s) h = (h ^ c) * 0x100000001b3ull;
    return h;
}

/** Errors of an image against a reference (definitions in the report's text). */
struct Errors {
    double all = 0;        ///< relMSE over all pixels and channels
    double glitter = 0;    ///< relMSE over the glitter pixels
    double structure = 0;  ///< relative RMS of the glints' high-pass on the glitter pixels
    bool finite() const {
        return std::isfinite(all) && std::isfinite(glitter) && std::isfinite(structure);
    }
};

/** Brightness minus its mean over a (2r+1)^2 box clipped to the image: the glints. */
std::vector<double> high_pass(const Image& img) {
    const int w = static_cast<int>(img.width), h = static_cast<int>(img.height);
    std::vector<double> out(img.pixels());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double sum = 0;
            int n = 0;
            for (int v = std::max(0, y - kHighPassRadius);
                 v <= std::min(h - 1, y + kHighPassRadius); ++v)
                for (int u = std::max(0, x - kHighPassRadius);
                     u <= std::min(w - 1, x + kHighPassRadius); ++u, ++n)
                    sum += img.brightness(static_cast<std::size_t>(v * w + u));
            const auto i = static_cast<std::size_t>(y * w + x);
            out[i] = img.brightness(i) - sum / n;
        }
    return out;
}

/** A converged image of one scene variant and what the errors need from it. */
struct Reference {
    double gamma = 1.0;            ///< the scale of every flake material's gamma
    std::string label;             ///< which variant, for the report
    Image image;                   ///< the mean of the two halves
    std::vector<uint8_t> glitter;  ///< 1 for the glitter pixels
    std::size_t glitter_pixels = 0;
    std::vector<double> high;  ///< high_pass(image)
    Errors noise;              ///< its own error, estimated from its halves
    uint32_t spp = 0;          ///< both halves together
    uint32_t smooth_spp = 0;   ///< of the smooth render that defines the mask
    double seconds = 0;        ///< render time of the three images; 0 when all were cached
};

/** The errors of `img` against `ref` (same size). */
Errors measure(const Image& img, const Reference& ref) {
    SPANGLE_CHECK(img.rgb.size() == ref.image.rgb.size(), "image and reference differ in size");
    const std::vector<double> high = high_pass(img);
    double all = 0, glitter = 0, diff = 0, energy = 0;
    for (std::size_t i = 0; i < img.pixels(); ++i) {
        double rel = 0;
        for (std::size_t c = 3 * i; c < 3 * i + 3; ++c) {
            const double r = ref.image.rgb[c], d = static_cast<double>(img.rgb[c]) - r;
            rel += d * d / (r * r + kRelMseEps);
        }
        all += rel;
        if (!ref.glitter[i]) continue;
        glitter += rel;
        diff += (high[i] - ref.high[i]) * (high[i] - ref.high[i]);
        energy += ref.high[i] * ref.high[i];
    }
    return {all / (3.0 * static_cast<double>(img.pixels())),
            glitter / (3.0 * static_cast<double>(ref.glitter_pixels)), std::sqrt(diff / energy)};
}

/** Where references are kept between runs. */
class ReferenceCache {
public:
    ReferenceCache(std::string dir, bool fresh)
        : dir_(std::move(dir)), fresh_(fresh), plugins_(plugins_fingerprint()) {
        fs::create_directories(dir_);
    }

    /** The render of `text` at `spp`, from the cache when its key matches, else rendered and
     *  stored. Adds the render time to `seconds` when it renders. */
    Image get(Renderer& r, const std::string& name, const std::string& text, uint32_t spp,
              double& seconds) {
        // The plugins' bytes are part of the key: a reference rendered by an earlier build of the
        // flake material is another material's reference.
        const uint64_t key = fnv1a(fmt::format("{}\n{}\n{}{}", kCacheVersion, spp, plugins_, text));
        const std::string path = fmt::format("{}/{}-{:016x}.ref", dir_, name, key);
        if (!fresh_) {
            if (auto img = read(path, key)) return *img;
        }
        fmt::print(stderr, "  rendering reference {} ({} spp)...\n", name, spp);
        r.load(text);
        const auto t0 = Clock::now();
        Image img = r.render(spp, Strategy::Mis);
        seconds += seconds_since(t0);
        write(path, key, img);
        remove_stale(name, path);
        return img;
    }

private:
    /** Removes the cached renders of `name` under other keys than the one at `kept` (renders of
     *  an earlier scene text or plugin build: each rebuild of a plugin would otherwise leave a
     *  whole set behind). */
    void remove_stale(const std::string& name, const std::string& kept) const {
        std::error_code ec;
        for (const auto& entry : fs::directory_iterator(dir_, ec)) {
            const std::string file = entry.path().filename().string();
            // name-<16 hex digits>.ref
            const bool ours =
                file.size() == name.size() + 21 && file.starts_with(name + "-") &&
                file.ends_with(".ref") &&
                file.find_first_not_of("0123456789abcdef", name.size() + 1) == name.size() + 17;
            if (ours && file != fs::path(kept).filename().string()) fs::remove(entry.path(), ec);
        }
    }

    /** Larger headers are not the report's: such a file is ignored and rewritten. */
    static constexpr std::size_t kMaxCachedPixels = std::size_t{1} << 26;

    static std::optional<Image> read(const std::string& path, uint64_t key) {
        std::ifstream f(path, std::ios::binary);
        uint64_t k = 0;
        Image img;
        if (!f.read(reinterpret_cast<char*>(&k), sizeof k) || k != key) return std::nullopt;
        f.read(reinterpret_cast<char*>(&img.width), sizeof img.width);
        f.read(reinterpret_cast<char*>(&img.height), sizeof img.height);
        if (!f || img.pixels() > kMaxCachedPixels) return std::nullopt;
        img.rgb.resize(img.pixels() * 3);
        f.read(reinterpret_cast<char*>(img.rgb.data()),
               static_cast<std::streamsize>(img.rgb.size() * sizeof(float)));
        if (!f) return std::nullopt;
        return img;
    }
    static void write(const std::string& path, uint64_t key, const Image& img) {
        const std::string tmp = path + ".tmp";
        {
            std::ofstream f(tmp, std::ios::binary);
            f.write(reinterpret_cast<const char*>(&key), sizeof key);
            f.write(reinterpret_cast<const char*>(&img.width), sizeof img.width);
            f.write(reinterpret_cast<const char*>(&img.height), sizeof img.height);
            f.write(reinterpret_cast<const char*>(img.rgb.data()),
                    static_cast<std::streamsize>(img.rgb.size() * sizeof(float)));
            if (!f) throw_error("cannot write the reference cache file '{}'", tmp);
        }
        fs::rename(tmp, path);
    }
    std::string dir_;
    bool fresh_;
    std::string plugins_;  ///< plugins_fingerprint() when the run began
};

/** Sample counts of one run of the report. */
struct Plan {
    uint32_t default_spp;    ///< the default settings' curve goes up to this
    uint32_t curve_spp;      ///< the other curves
    uint32_t point_spp;      ///< settings shown as a single point
    uint32_t ref_spp;        ///< each half of a scene's reference, unless the scene says more
    uint32_t gamma_ref_spp;  ///< each half of the references at other gammas (shorter curves)
    uint32_t smooth_spp;     ///< the all-smooth render that defines the glitter mask
};

constexpr Plan kFullPlan{1024, 256, 64, 2048, 1024, 256};
constexpr Plan kQuickPlan{16, 4, 4, 32, 16, 16};

/** One shipped scene in the report. */
struct SceneSpec {
    std::string name;           ///< file stem under assets/scenes
    uint32_t width, height;     ///< the report's resolution
    uint32_t quick_w, quick_h;  ///< the smoke run's
    bool clamped;               ///< ships with clamp_indirect on
    bool gamma_sweep;           ///< also rendered at other gammas
    uint32_t ref_spp;           ///< each half of its reference in the full report; 0 = the plan's
};

// The spheres' glints converge slowest and cost least per sample: their reference gets more.
const SceneSpec kScenes[] = {{"spheres", 320, 100, 96, 30, false, false, 4096},
                             {"beetle", 320, 180, 96, 54, true, true, 0}};

/** One way of rendering a scene. */
struct Setting {
    std::string label;   ///< tables
    std::string legend;  ///< the plot's legend (the same for all scenes); empty = label
    SceneEdit edit;      ///< size and seed filled in per scene
    Strategy strategy = Strategy::Mis;
    uint32_t spp = 0;           ///< samples of its progressive render
    bool curve = true;          ///< false: reported at `spp` alone, as a point
    double ref_gamma = 1.0;     ///< gamma scale of the reference it is compared with
    int color = 0, marker = 0;  ///< plot style (accuracy_plot.h)
};

/** Plot style of the precision knobs' points: grey plus signs. */
constexpr int kKnobColor = 10, kKnobMarker = 6;

/** Every setting of a scene, the default one first. */
std::vector<Setting> settings_for(const SceneSpec& scene, const Plan& plan) {
    std::vector<Setting> out;
    const auto add = [&](std::string label, std::vector<std::pair<std::string, std::string>> flake,
                         uint32_t spp, bool curve = true) {
        Setting s;
        s.label = std::move(label);
        s.edit.flake = std::move(flake);
        s.spp = spp;
        s.curve = curve;
        s.color = static_cast<int>(out.size());
        s.marker = s.color % 6;
        out.push_back(s);
        return &out.back();
    };
    add("default (as shipped)", {}, plan.default_spp);
    add("all discrete (min/max_flakes 9e8/1e9)", {{"min_flakes", "9e8"}, {"max_flakes", "1e9"}},
        plan.curve_spp);
    // (To the default's count: at 256 spp both are still noise, and where the smooth look's
    // difference from the flakes shows is what a user choosing it must see.)
    add("all smooth (min/max_flakes 0/1)", {{"min_flakes", "0"}, {"max_flakes", "1"}},
        plan.default_spp);
    add("algorithm enumerate", {{"algorithm", "\"enumerate\""}}, plan.curve_spp);
    add("NEE only", {}, plan.curve_spp)->strategy = Strategy::NeeOnly;
    add("BSDF only", {}, plan.curve_spp)->strategy = Strategy::BsdfOnly;
    Setting* clamp =
        add(scene.clamped ? "clamp_indirect 0 (off)" : "clamp_indirect 20", {}, plan.curve_spp);
    clamp->edit.clamp = scene.clamped ? 0.0 : 20.0;
    clamp->legend = "clamp_indirect: beetle off, spheres 20";
    if (scene.gamma_sweep)
        for (double g : {0.5, 2.0}) {
            Setting* s = add(fmt::format("gamma x{} (own reference)", g), {}, plan.curve_spp);
            s->edit.gamma_scale = s->ref_gamma = g;
        }
    const std::pair<const char*, const char*> knobs[] = {{"leaf_size", "4"},
                                                         {"leaf_size", "64"},
                                                         {"max_depth", "10"},
                                                         {"max_depth", "16"},
                                                         {"exact_flakes", "32"},
                                                         {"exact_flakes", "4096"},
                                                         {"binomial_exact_below", "0"},
                                                         {"binomial_exact_below", "1000"}};
    for (const auto& [k, v] : knobs) {
        Setting* s = add(fmt::format("{} {}", k, v), {{k, v}}, plan.point_spp, false);
        s->color = kKnobColor;
        s->marker = kKnobMarker;
    }
    return out;
}

/** A setting's measurements: one per pass. */
struct Point {
    uint32_t spp;
    double seconds;
    Errors err;
};

/** A setting's measurements against its reference. */
struct SettingResult {
    const Setting* setting;
    const Reference* ref;
    std::vector<Point> points;     ///< in pass order
    bool same_as_default = false;  ///< a point whose image is the default's, bit for bit
};

/** Everything measured for one scene. */
struct SceneResult {
    const SceneSpec* spec;
    bool quick = false;  ///< the smoke run's sizes and samples
    uint32_t width, height;
    std::vector<std::unique_ptr<Reference>> refs;  ///< [0]: the scene's own gamma
    std::vector<Setting> settings;
    std::vector<SettingResult> results;
    double load_seconds = 0;    ///< first load: parse, subdivision, BVH
    double cold_first_spp = 0;  ///< 1 spp on a fresh load, tables built inside
    double warm_first_spp = 0;  ///< 1 spp once they exist
};

/** The reference of `scene` at gamma x`gamma`: the flake model without distance blending
 *  (every footprint discrete) and without the clamp, MIS, two halves with seeds 1 and 2; and
 *  the all-smooth render (seed 3) that the glitter mask compares it with. */
std::unique_ptr<Reference> make_reference(Renderer& r, ReferenceCache& cache,
                                          const std::string& shipped, const std::string& dir,
                                          const SceneResult& s, double gamma, const Plan& plan) {
    auto ref = std::make_unique<Reference>();
    ref->gamma = gamma;
    ref->label = gamma == 1.0 ? std::string("the scene's gamma") : fmt::format("gamma x{}", gamma);
    SceneEdit e;
    e.width = s.width;
    e.height = s.height;
    e.clamp = 0.0;
    e.gamma_scale = gamma;
    e.flake = {{"min_flakes", "9e8"}, {"max_flakes", "1e9"}};
    const std::string name = fmt::format("{}-g{}", s.spec->name, gamma);
    const uint32_t spp = gamma != 1.0                  ? plan.gamma_ref_spp
                         : s.spec->ref_spp && !s.quick ? s.spec->ref_spp
                                                       : plan.ref_spp;
    e.seed = 1;
    const Image a = cache.get(r, name + "-a", edit_scene(shipped, dir, e), spp, ref->seconds);
    e.seed = 2;
    const Image b = cache.get(r, name + "-b", edit_scene(shipped, dir, e), spp, ref->seconds);
    e.seed = 3;
    e.flake = {{"min_flakes", "0"}, {"max_flakes", "1"}};
    const Image smooth =
        cache.get(r, name + "-smooth", edit_scene(shipped, dir, e), plan.smooth_spp, ref->seconds);
    ref->spp = 2 * spp;
    ref->smooth_spp = plan.smooth_spp;
    ref->image = a;
    for (std::size_t i = 0; i < a.rgb.size(); ++i) ref->image.rgb[i] = 0.5f * (a.rgb[i] + b.rgb[i]);

    // Glitter: the discrete flakes outshine their expectation (the smooth lobe) in both halves.
    const auto n = a.pixels();
    const int w = static_cast<int>(a.width), h = static_cast<int>(a.height);
    std::vector<uint8_t> glint(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        const double sm = smooth.brightness(i);
        const double need = std::max(kGlintRatio * sm, kGlintFloor);
        glint[i] = a.brightness(i) - sm > need && b.brightness(i) - sm > need;
    }
    // ...and their neighbours, where a misplaced or blurred glint shows.
    ref->glitter.assign(n, 0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            if (!glint[static_cast<std::size_t>(y * w + x)]) continue;
            for (int v = std::max(0, y - 1); v <= std::min(h - 1, y + 1); ++v)
                for (int u = std::max(0, x - 1); u <= std::min(w - 1, x + 1); ++u)
                    ref->glitter[static_cast<std::size_t>(v * w + u)] = 1;
        }
    for (uint8_t g : ref->glitter) ref->glitter_pixels += g;
    if (ref->glitter_pixels == 0)
        throw_error("{}: the reference has no glitter pixels; the mask is empty", name);
    ref->high = high_pass(ref->image);
    // A half minus the mean is half the difference of the halves: its expected squared error is
    // the variance of the mean of both, the reference's own noise.
    ref->noise = measure(a, *ref);
    return ref;
}

/** Renders and measures every setting of one scene, with the references they need. */
SceneResult run_scene(const SceneSpec& spec, const Args& args, const Plan& plan,
                      ReferenceCache& cache) {
    SceneResult s;
    s.spec = &spec;
    s.quick = args.quick;
    s.width = args.quick ? spec.quick_w : spec.width;
    s.height = args.quick ? spec.quick_h : spec.height;
    const std::string dir = test::asset_dir() + "/scenes";
    std::ifstream in(dir + "/" + spec.name + ".toml");
    const std::string shipped{std::istreambuf_iterator<char>(in), {}};
    if (shipped.empty()) throw_error("cannot read {}/{}.toml", dir, spec.name);
    Renderer r(fmt::format("{}/{}-work.toml", args.cache, spec.name), args.threads);
    s.settings = settings_for(spec, plan);

    // What a one-shot render pays before the timed part: loading, and the first samples that
    // build the flake tables.
    SceneEdit e0;
    e0.width = s.width;
    e0.height = s.height;
    auto t0 = Clock::now();
    r.load(edit_scene(shipped, dir, e0));
    s.load_seconds = seconds_since(t0);
    t0 = Clock::now();
    r.render(1, Strategy::Mis);
    s.cold_first_spp = seconds_since(t0);
    r.render(4 * kWarmUpSpp, Strategy::Mis);  // the tables for (nearly) every view angle
    t0 = Clock::now();
    r.render(1, Strategy::Mis);
    s.warm_first_spp = seconds_since(t0);

    std::vector<float> default_at_point;
    for (const Setting& st : s.settings) {
        const Reference* ref = nullptr;
        for (const auto& rf : s.refs)
            if (rf->gamma == st.ref_gamma) ref = rf.get();
        if (!ref) {
            s.refs.push_back(make_reference(r, cache, shipped, dir, s, st.ref_gamma, plan));
            ref = s.refs.back().get();
        }
        SceneEdit e = st.edit;
        e.width = s.width;
        e.height = s.height;
        r.load(edit_scene(shipped, dir, e));
        const auto t = Clock::now();
        SettingResult res{&st, ref, {}};
        for (Pass& p : r.render_passes(st.spp, st.strategy)) {
            if (!st.curve && p.spp != st.spp) continue;
            res.points.push_back({p.spp, p.seconds, measure(p.image, *ref)});
            // The default's images at the points' sample count, to tell knobs that change
            // nothing in this scene.
            if (&st == &s.settings.front() && p.spp == plan.point_spp)
                default_at_point = std::move(p.image.rgb);
            if (!st.curve) res.same_as_default = p.image.rgb == default_at_point;
        }
        fmt::print(stderr, "  {}: {}, {} spp: {:.1f} s, relMSE {:.3g}\n", spec.name, st.label,
                   st.spp, seconds_since(t), res.points.back().err.all);
        s.results.push_back(std::move(res));
    }
    return s;
}

/** Least-squares slope of log relMSE against log time over the last kSlopePasses points; NaN
 *  with fewer points. */
double log_slope(const std::vector<Point>& points) {
    if (points.size() < kSlopePasses) return std::nan("");
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (std::size_t i = points.size() - kSlopePasses; i < points.size(); ++i) {
        const double x = std::log(points[i].seconds), y = std::log(points[i].err.all);
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    const double n = kSlopePasses;
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/** The passes a table shows: 1, 4, 16, ... samples, and a point's only one. */
bool shown(const Setting& st, uint32_t spp) {
    for (uint32_t k = 1; k <= spp; k *= 4)
        if (k == spp) return true;
    return spp == st.spp;
}

/** The point of `res` at `spp`, if measured. */
const Point* at_spp(const SettingResult& res, uint32_t spp) {
    for (const Point& p : res.points)
        if (p.spp == spp) return &p;
    return nullptr;
}

/** An error with three significant digits. */
std::string fmt_error(double e) {
    return fmt::format("{:.3g}", e);
}

/** The scene's section: reference, one-shot costs, the table of every point and the
 *  comparison with the default settings at equal samples. */
void scene_section(std::string& md, const SceneResult& s) {
    auto out = std::back_inserter(md);
    fmt::format_to(out, "\n## {} ({}x{})\n\n", s.spec->name, s.width, s.height);
    for (const auto& ref : s.refs)
        fmt::format_to(out,
                       "Reference ({}): {} spp, its glitter mask {} pixels ({:.1f}% of the image); "
                       "its own noise: relMSE {}, glitter relMSE {}, structure error {}.\n\n",
                       ref->label, ref->spp, ref->glitter_pixels,
                       100.0 * static_cast<double>(ref->glitter_pixels) /
                           static_cast<double>(ref->image.pixels()),
                       fmt_error(ref->noise.all), fmt_error(ref->noise.glitter),
                       fmt_error(ref->noise.structure));
    fmt::format_to(out,
                   "Not in the times below: loading the scene took {:.2f} s (parse, subdivision, "
                   "BVH), and the first sample per pixel on a fresh load took {:.2f} s (the flake "
                   "material's tables read from the table cache, or built where it has none) "
                   "against {:.2f} s once they are in memory.\n\n",
                   s.load_seconds, s.cold_first_spp, s.warm_first_spp);
    const Point* resolved = nullptr;
    for (const Point& p : s.results.front().points)
        if (!resolved && p.err.structure < 1.0) resolved = &p;
    if (resolved)
        fmt::format_to(out,
                       "The default settings' structure error is below 1 (glints better than none) "
                       "from {} spp ({:.2f} s) on.\n\n",
                       resolved->spp, resolved->seconds);
    else
        md +=
            "The default settings' structure error stays at 1 or above (glints no better than "
            "none) at every sample count measured.\n\n";
    md +=
        "\"(the default's image)\": a single point whose image is bit for bit the default "
        "settings' at the same sample count: the knob changes nothing in this scene.\n\n";
    md += "| setting | spp | time (s) | relMSE | relMSE glitter | structure error |\n";
    md += "|---|---:|---:|---:|---:|---:|\n";
    for (const SettingResult& res : s.results)
        for (const Point& p : res.points)
            if (shown(*res.setting, p.spp))
                fmt::format_to(out, "| {}{} | {} | {:.2f} | {} | {} | {} |\n", res.setting->label,
                               res.same_as_default ? " (the default's image)" : "", p.spp,
                               p.seconds, fmt_error(p.err.all), fmt_error(p.err.glitter),
                               fmt_error(p.err.structure));

    const SettingResult& def = s.results.front();
    fmt::format_to(out,
                   "\nEach setting at its highest sample count against the default settings at "
                   "the same count (ratios; below 1 is faster or more accurate), and the slope of "
                   "its relMSE against time on log-log axes over its last {} passes (-1: the "
                   "error is noise and halves when the time doubles; near 0: a floor, the "
                   "setting's difference from the reference):\n\n",
                   kSlopePasses);
    md += "| setting | spp | time | relMSE | relMSE glitter | structure error | relMSE slope |\n";
    md += "|---|---:|---:|---:|---:|---:|---:|\n";
    for (const SettingResult& res : s.results) {
        const Point& p = res.points.back();
        const Point* d = at_spp(def, p.spp);
        if (!d) continue;
        const double slope = log_slope(res.points);
        fmt::format_to(out, "| {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {} |\n",
                       res.setting->label, p.spp, p.seconds / d->seconds, p.err.all / d->err.all,
                       p.err.glitter / d->err.glitter, p.err.structure / d->err.structure,
                       std::isfinite(slope) ? fmt::format("{:.2f}", slope) : std::string("-"));
    }
}

/** Per scene and time budget, the measured setting and sample count with the lowest error of
 *  each kind. Settings compared with another reference (other gammas) are left out. */
void budget_section(std::string& md, const std::vector<SceneResult>& scenes) {
    auto out = std::back_inserter(md);
    md += "\n## Recommended setting at each time budget\n\n";
    md +=
        "Computed by the command: among every measured point (each pass of every curve, each "
        "single point) whose render time is within the budget, the one with the lowest error. "
        "Times are per frame at the report's resolution on this machine; at N times the pixels "
        "a budget grows about N times. Gamma variants change the look and are left out. relMSE "
        "counts noise and missing glints alike, so a setting without glints can have the "
        "lowest relMSE; the structure error tells whether glints are there (at 1 or above: no "
        "better than an image without them).\n";
    for (const SceneResult& s : scenes) {
        fmt::format_to(out, "\n### {}\n\n", s.spec->name);
        md += "| budget (s) | lowest relMSE | lowest relMSE glitter | lowest structure error |\n";
        md += "|---:|---|---|---|\n";
        for (double budget : kBudgets) {
            fmt::format_to(out, "| {} |", budget);
            for (int kind = 0; kind < 3; ++kind) {
                const auto value = [&](const Errors& e) {
                    return kind == 0 ? e.all : kind == 1 ? e.glitter : e.structure;
                };
                const SettingResult* best = nullptr;
                const Point* best_p = nullptr;
                for (const SettingResult& res : s.results) {
                    if (res.setting->ref_gamma != 1.0) continue;
                    for (const Point& p : res.points)
                        if (p.seconds <= budget && (!best_p || value(p.err) < value(best_p->err))) {
                            best = &res;
                            best_p = &p;
                        }
                }
                if (best)
                    fmt::format_to(
                        out, " {}, {} spp ({:.2f} s): {}{} |", best->setting->label, best_p->spp,
                        best_p->seconds, fmt_error(value(best_p->err)),
                        kind == 2 && value(best_p->err) >= 1.0 ? " (no glints resolved)" : "");
                else
                    md += " nothing measured is this fast |";
            }
            md += "\n";
        }
    }
}

/** accuracy.svg: per scene, relMSE and glitter relMSE against time. */
std::string plot_svg(const std::vector<SceneResult>& scenes) {
    std::vector<plot::Panel> panels;
    for (const SceneResult& s : scenes)
        for (int kind = 0; kind < 2; ++kind) {
            plot::Panel panel;
            panel.title = fmt::format("{} {}x{}: {}", s.spec->name, s.width, s.height,
                                      kind == 0 ? "whole image" : "glitter pixels");
            panel.x_label = "render time (s)";
            panel.y_label = kind == 0 ? "relMSE" : "relMSE, glitter pixels";
            panel.floor = kind == 0 ? s.refs.front()->noise.all : s.refs.front()->noise.glitter;
            panel.floor_label = "the reference's own noise";
            for (const SettingResult& res : s.results) {
                plot::Series series;
                const Setting& st = *res.setting;
                series.label = !st.curve ? fmt::format("tree precision knobs, {} spp", st.spp)
                               : st.legend.empty() ? st.label
                                                   : st.legend;
                series.color = st.color;
                series.marker = st.marker;
                series.line = st.curve;
                series.dashed = st.ref_gamma != 1.0;
                for (const Point& p : res.points)
                    series.points.emplace_back(p.seconds, kind == 0 ? p.err.all : p.err.glitter);
                panel.series.push_back(std::move(series));
            }
            panels.push_back(std::move(panel));
        }
    return plot::svg(panels, 2, 900);
}

/** The CPU's name from /proc/cpuinfo, or "unknown CPU". */
std::string cpu_model() {
    std::ifstream f("/proc/cpuinfo");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos)
            return trim(line.substr(line.find(':') + 1));
    return "unknown CPU";
}

/** How the report was made and what its numbers mean. */
void method_section(std::string& md, const Args& args, const Plan& plan,
                    const std::vector<SceneResult>& scenes, double total, double ref_seconds) {
    auto out = std::back_inserter(md);
    md += "# Accuracy against time\n\n";
    md +=
        "What the settings that trade accuracy for speed cost, measured on the shipped scenes. "
        "Regenerate both this page and its plot with a Release build:\n\n"
        "    ninja -C build spangle_accuracy\n"
        "    ./build/spangle_accuracy --out docs\n\n";
    fmt::format_to(
        out,
        "This run{} took {:.1f} minutes on a machine of {} hardware threads ({}; {} render "
        "threads), {}. References are cached in `build/accuracy-cache`{} "
        "(`--cache DIR` elsewhere, `--fresh` to render them again) and reused while their scene "
        "text, settings and the plugin libraries hash the same. Every render has a fixed seed: a "
        "second run changes only the timings, which vary from run to run (bit-identical renders "
        "took 10-15% more or less time from one run to the next on a shared 2-core virtual "
        "machine: time ratios nearer 1 than that are no difference). `--quick` is a smoke "
        "run of tiny images for ctest (`bench.accuracy_quick`); its numbers mean nothing.\n",
        args.quick ? " (`--quick`)" : "", total / 60.0, std::thread::hardware_concurrency(),
        cpu_model(), args.threads > 0 ? fmt::format("{}", args.threads) : std::string("all"),
        ref_seconds > 0 ? fmt::format("{:.1f} of them rendering references", ref_seconds / 60.0)
                        : std::string("every reference read from the cache"),
        args.quick ? " (`build/accuracy-cache-quick` for `--quick`)" : "");
    md += "\n## Scenes\n\n";
    for (const SceneResult& s : scenes)
        fmt::format_to(out, "- `assets/scenes/{}.toml` at {}x{}.\n", s.spec->name, s.width,
                       s.height);
    md +=
        "\nCamera, lights, materials, max_depth and filter are as shipped. The shipped sizes are "
        "four times larger in each direction, so here each pixel's footprint covers 16 times "
        "more flakes and more of the paint is in the blended and smooth regimes.\n";
    md += "\n## Settings\n\n";
    fmt::format_to(
        out,
        "- **default (as shipped)**: flake algorithm `tree`, `min_flakes` 500, `max_flakes` "
        "2000, MIS, the scene's `clamp_indirect` (beetle 20, spheres off). Its curve goes from 1 "
        "to {0} spp.\n"
        "- **all discrete** / **all smooth**: blending thresholds that give every footprint the "
        "discrete lobe, or the smooth lobe (only footprints of less than one expected flake stay "
        "discrete). The all-smooth curve goes to {0} spp too: it is cheap, and its difference "
        "from the flakes (its floor) shows only once the noise is below it.\n"
        "- **algorithm enumerate**: every flake of a footprint in a reflection cache instead of "
        "`tree`'s counting; default blending.\n"
        "- **NEE only** / **BSDF only**: `RenderOptions::strategy`; emitters are found only by "
        "light sampling, or only by BSDF-sampled rays. Same expectation as MIS, not the same "
        "noise: light sampling finds a small light through a near-mirror lobe (the beetle's "
        "chrome) by rare large samples, and that heavy-tailed noise falls unevenly, so a relMSE "
        "slope far from -1 over three passes is not by itself a floor.\n"
        "- **clamp_indirect**: off for the beetle; 20 (the beetle's value) for the spheres, which "
        "ship without it.\n"
        "- **gamma x0.5 / x2** (beetle): every flake material's gamma scaled. Gamma changes the "
        "look, so each is compared with a reference rendered at its own gamma (otherwise made "
        "like the others) and is left out of the recommendations.\n"
        "- **tree precision knobs**, one at a time, a single point at {1} spp each: `leaf_size` "
        "(default 16), `max_depth` (12), `exact_flakes` (256), `binomial_exact_below` (128).\n\n"
        "Other curves go to {2} spp. A curve is one progressive render: the engine adds each "
        "pixel's samples in the same order whatever the passes, so the image after the pass "
        "ending at n samples is the image of an n-sample render, and its time is the wall time "
        "at the end of that pass.\n",
        plan.default_spp, plan.point_spp, plan.curve_spp);
    md += "\n## Time\n\n";
    fmt::format_to(out,
                   "Wall time of the path tracing alone, all cores, with the scene loaded and the "
                   "flake material's tables built (each timed render follows an untimed {}-sample "
                   "render of the same scene through the same session): what a watch session "
                   "pays for a re-render. What a one-shot `spangle render` pays on top is given "
                   "per scene.\n",
                   kWarmUpSpp);
    md += "\n## Errors\n\n";
    fmt::format_to(
        out,
        "Against the reference of the scene (below), over the working-space RGB image "
        "(ACEScg for both scenes):\n\n"
        "- **relMSE**: the mean over all pixels and the three channels of (x - r)^2 / (r^2 + "
        "{}), x the image, r the reference. The constant keeps near-black pixels from "
        "dominating.\n"
        "- **relMSE glitter**: the same mean over the glitter pixels only.\n"
        "- **structure error**: on the glitter pixels, the relative RMS difference of the "
        "high-pass images, sqrt(sum (hx - hr)^2 / sum hr^2), where h is a pixel's brightness "
        "(mean of R, G, B) minus the mean brightness of the {}x{} box around it. 0: every glint "
        "in place with the right contrast; 1: as far off as an image without glints.\n\n"
        "**Glitter pixels** are defined by the reference alone: pixels where both halves of the "
        "reference (below) exceed the all-smooth render of the same scene by more than {} times "
        "its brightness and by more than {}, that is, where individual flakes reflect clearly "
        "more than their expectation, and the 8 neighbours of each (where a misplaced or "
        "blurred glint shows). Pixels dimmer than the expectation (flakes that miss the light) "
        "are not in the mask.\n",
        kRelMseEps, 2 * kHighPassRadius + 1, 2 * kHighPassRadius + 1, kGlintRatio, kGlintFloor);
    md += "\n## Reference\n\n";
    fmt::format_to(
        out,
        "The flake model without its approximations for speed: every footprint on the discrete "
        "lobe (`min_flakes` 9e8, `max_flakes` 1e9), `clamp_indirect` off, MIS, algorithm "
        "`tree`, otherwise as shipped. It is the mean of two renders of equal samples (the "
        "totals are given per scene below) with render seeds 1 and 2 (the timed renders use seed "
        "0, so their sample sequences are independent "
        "of the reference's). Its own noise is estimated from the two halves: each half minus "
        "the mean is half their difference, whose mean square is the variance of the mean. That "
        "noise is added to every error measured against it (the dashed grey line in the plot); "
        "errors near it are not resolved. The mask's all-smooth render (`min_flakes` 0, "
        "`max_flakes` 1) has {} spp and seed 3.\n\n"
        "`enumerate` would be the exact flake set, but costs several times more per sample at "
        "these footprints. Where `tree` aggregates a cell of more than `exact_flakes` flakes "
        "its glints are a different draw from the same distribution, so part of the "
        "`enumerate` curve's floor is the difference between the two algorithms, not an error "
        "of `enumerate`.\n",
        plan.smooth_spp);
    md += "\n## Error against time\n\n";
    md +=
        "![relMSE against render time, log-log, per scene: whole image and glitter pixels; one "
        "curve per setting](accuracy.svg)\n\n"
        "Each marker is one pass (1, 2, 4, ... spp); grey plus signs are the single points of "
        "the tree precision knobs; dashed curves are compared with their own gamma's reference. "
        "Few of a glitter pixel's samples catch its glint: after one sample most glitter pixels "
        "have caught none (an error near that of a pixel without its glint), and the few that "
        "have count it many times over, so the glitter errors of the first passes can rise "
        "before they fall.\n";
}

/** Failures of the self-checks (empty when all pass): every error finite, and the default
 *  curve's errors lower at its highest sample count than at 1 spp. */
std::vector<std::string> check(const std::vector<SceneResult>& scenes) {
    std::vector<std::string> fail;
    for (const SceneResult& s : scenes) {
        for (const auto& ref : s.refs)
            if (!ref->noise.finite())
                fail.push_back(
                    fmt::format("{}: reference ({}) noise not finite", s.spec->name, ref->label));
        for (const SettingResult& res : s.results)
            for (const Point& p : res.points)
                if (!p.err.finite())
                    fail.push_back(fmt::format("{}: {} at {} spp: an error is not finite",
                                               s.spec->name, res.setting->label, p.spp));
        const auto& pts = s.results.front().points;
        if (pts.size() < 2 || pts.front().spp != 1) {
            fail.push_back(fmt::format("{}: the default curve has no 1-spp point", s.spec->name));
            continue;
        }
        const Errors &lo = pts.front().err, &hi = pts.back().err;
        if (!(hi.all < lo.all) || !(hi.glitter < lo.glitter))
            fail.push_back(
                fmt::format("{}: default settings: relMSE {} / glitter {} at {} spp, not below {} "
                            "/ {} at 1 spp",
                            s.spec->name, hi.all, hi.glitter, pts.back().spp, lo.all, lo.glitter));
    }
    return fail;
}

/** Writes `text` to `path`; throws SpangleError when it cannot. */
void write_file(const std::string& path, const std::string& text) {
    std::ofstream f(path);
    f << text;
    if (!f) throw_error("cannot write '{}'", path);
}

/** The whole report; returns the exit status (1 when a self-check fails). */
int run(const Args& args) {
    const auto t0 = Clock::now();
    const Plan& plan = args.quick ? kQuickPlan : kFullPlan;
    fs::create_directories(args.out);
    ReferenceCache cache(args.cache, args.fresh);
    std::vector<SceneResult> scenes;
    double ref_seconds = 0;
    for (const SceneSpec& spec : kScenes) {
        fmt::print(stderr, "{}:\n", spec.name);
        scenes.push_back(run_scene(spec, args, plan, cache));
        for (const auto& ref : scenes.back().refs) ref_seconds += ref->seconds;
    }
    std::string plane;
    plane_section(plane, args.quick, args.cache, args.threads);
    std::string md;
    method_section(md, args, plan, scenes, seconds_since(t0), ref_seconds);
    for (const SceneResult& s : scenes) scene_section(md, s);
    budget_section(md, scenes);
    md += plane;
    write_file(args.out + "/accuracy.md", md);
    write_file(args.out + "/accuracy.svg", plot_svg(scenes));
    fmt::print(stderr, "wrote {0}/accuracy.md and {0}/accuracy.svg in {1:.1f} min\n", args.out,
               seconds_since(t0) / 60.0);
    const std::vector<std::string> fail = check(scenes);
    for (const std::string& f : fail) fmt::print(stderr, "check failed: {}\n", f);
    return fail.empty() ? 0 : 1;
}

constexpr const char* kUsage =
    "usage: spangle_accuracy --out DIR [--quick] [--cache DIR] [--fresh] [--threads N]\n"
    "  --out DIR      where accuracy.md and accuracy.svg are written\n"
    "  --quick        tiny images and few samples: a smoke run (its numbers mean nothing)\n"
    "  --cache DIR    where references are cached (default: accuracy-cache next to this "
    "program,\n"
    "                 accuracy-cache-quick with --quick)\n"
    "  --fresh        render the references again even when cached\n"
    "  --threads N    render threads (default: all cores)\n";

}  // namespace
}  // namespace spangle::accuracy

int main(int argc, char** argv) {
    using namespace spangle::accuracy;
    Args args;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const bool has_value = i + 1 < argc;
        if (a == "--quick") {
            args.quick = true;
        } else if (a == "--fresh") {
            args.fresh = true;
        } else if (a == "--out" && has_value) {
            args.out = argv[++i];
        } else if (a == "--cache" && has_value) {
            args.cache = argv[++i];
        } else if (a == "--threads" && has_value) {
            args.threads = std::atoi(argv[++i]);
        } else {
            fmt::print(stderr, "{}", kUsage);
            return a == "-h" || a == "--help" ? 0 : 2;
        }
    }
    if (args.out.empty()) {
        fmt::print(stderr, "{}", kUsage);
        return 2;
    }
    // A smoke run's references in a folder of their own: in the full run's, a --quick run
    // removed the full references as stale (same names, other keys), an hour of renders.
    if (args.cache.empty())
        args.cache =
            spangle::executable_dir() + (args.quick ? "/accuracy-cache-quick" : "/accuracy-cache");
    try {
        return run(args);
    } catch (const std::exception& e) {
        fmt::print(stderr, "spangle_accuracy: {}\n", e.what());
        return 1;
    }
}
