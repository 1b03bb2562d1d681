#include "color/color_config.h"

#include <OpenColorIO/OpenColorIO.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"
#include "core/text.h"

namespace OCIO = OCIO_NAMESPACE;

namespace spangle {

/** The files (LUTs) the config's transforms read, as each was when a processor first read it:
 *  shared by a config's clones (the same config reads the same files). */
struct LutFiles {
    std::mutex mutex;
    std::map<std::string, std::string> identity;  ///< path -> file_identity() at first use
    /** Those the scene's own conversions read (colours, textures, the working space's test),
     *  not the preview's display nor the header's chromaticities: the scene hash's, so that
     *  the processes of one render (MPI ranks, crop parts) agree. (A watch session keeps those
     *  of earlier versions of its scene too.) */
    std::set<std::string> scene;
    /** path -> (its identity, its bytes' hash) when content_hash() last read it: read again
     *  only once it changed (every watch reload and Python edit hashes the scene). */
    std::map<std::string, std::pair<std::string, uint64_t>> bytes;
};

struct ColorConfig::Impl {
    OCIO::ConstConfigRcPtr config;
    std::shared_ptr<LutFiles> luts = std::make_shared<LutFiles>();
    std::string path;
    std::string working;
    std::string default_working;  ///< the scene_linear role's space, or empty
    bool from_env = false;        ///< chosen through $OCIO
};

ColorConfig::ColorConfig(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ColorConfig::ColorConfig(ColorConfig&&) noexcept = default;
ColorConfig& ColorConfig::operator=(ColorConfig&&) noexcept = default;
ColorConfig::~ColorConfig() = default;

namespace {

/** Records the files a processor read in `luts`, each with its identity at first use. */
void note_files(LutFiles& luts, const OCIO::ConstProcessorRcPtr& processor, bool of_scene) {
    const OCIO::ConstProcessorMetadataRcPtr meta = processor->getProcessorMetadata();
    if (!meta || meta->getNumFiles() == 0) return;
    std::lock_guard<std::mutex> lock(luts.mutex);
    for (int i = 0; i < meta->getNumFiles(); ++i)
        if (const char* f = meta->getFile(i); f && *f) {
            luts.identity.try_emplace(f, file_identity(f));
            if (of_scene) luts.scene.insert(f);
        }
}

}  // namespace

std::vector<std::string> ColorConfig::lut_files() const {
    std::lock_guard<std::mutex> lock(impl_->luts->mutex);
    std::vector<std::string> out;
    for (const auto& [path, id] : impl_->luts->identity) out.push_back(path);
    return out;
}

bool ColorConfig::lut_files_changed() const {
    std::lock_guard<std::mutex> lock(impl_->luts->mutex);
    for (const auto& [path, id] : impl_->luts->identity)
        if (file_identity(path) != id) return true;
    return false;
}

void ColorConfig::forget_read_files() {
    OCIO::ClearAllCaches();
}

ColorConfig ColorConfig::clone() const {
    return ColorConfig(std::make_unique<Impl>(*impl_));
}

ColorConfig ColorConfig::load(const std::string& path, const std::vector<std::string>& fallbacks) {
    std::vector<std::string> tried;
    std::string chosen = path;
    bool from_env = false;
    if (chosen.empty()) {
        if (const char* env = std::getenv("OCIO"); env && *env) {
            chosen = env;
            from_env = true;
        } else {
            for (const auto& f : fallbacks) {
                tried.push_back(f);
                if (std::filesystem::exists(f)) {
                    chosen = f;
                    break;
                }
            }
        }
    }
    if (chosen.empty())
        throw_error("no OpenColorIO config found: set $OCIO or install config.ocio (tried: {})",
                    fmt::join(tried, ", "));
    auto impl = std::make_unique<Impl>();
    try {
        impl->config = OCIO::Config::CreateFromFile(chosen.c_str());
        impl->config->validate();
    } catch (const OCIO::Exception& e) {
        throw_error("cannot load OpenColorIO config '{}': {}", chosen, e.what());
    }
    impl->path = chosen;
    impl->from_env = from_env;
    ColorConfig cfg(std::move(impl));
    const char* scene_linear = cfg.impl_->config->getCanonicalName(OCIO::ROLE_SCENE_LINEAR);
    cfg.impl_->working = (scene_linear && *scene_linear) ? scene_linear : "";
    cfg.impl_->default_working = cfg.impl_->working;
    return cfg;
}

const std::string& ColorConfig::path() const {
    return impl_->path;
}
const std::string& ColorConfig::working_space() const {
    return impl_->working;
}
const std::string& ColorConfig::default_working_space() const {
    return impl_->default_working;
}

std::optional<std::string> ColorConfig::canonical_name(const std::string& space) const {
    const char* name = impl_->config->getCanonicalName(space.c_str());
    if (!name || !*name) return std::nullopt;
    // OCIO names named transforms too; they convert between spaces but are none.
    if (!impl_->config->getColorSpace(name)) return std::nullopt;
    return std::string(name);
}

bool ColorConfig::is_named_transform(const std::string& name) const {
    return impl_->config->getNamedTransform(name.c_str()) != nullptr;
}

bool ColorConfig::is_data(const std::string& space) const {
    const OCIO::ConstColorSpaceRcPtr cs = impl_->config->getColorSpace(space.c_str());
    return cs && cs->isData();
}

std::optional<ResolvedSpace> ColorConfig::resolve(const std::string& space) const {
    if (auto name = canonical_name(space)) return ResolvedSpace{*name, ""};
    // Spangle's own names, in a config that does not have them: common names for the same
    // space, then the role that stands for that kind of space.
    struct Fallback {
        const char* name;
        std::vector<const char*> aliases, roles;
    };
    static const std::vector<Fallback> fallbacks = {
        {"ACEScg", {"ACES - ACEScg", "acescg", "ACES AP1"}, {"scene_linear", "rendering"}},
        {"lin_rec709",
         {"Linear Rec.709 (sRGB)", "Linear Rec.709", "Utility - Linear - sRGB", "lin_srgb",
          "Linear"},
         {"scene_linear", "rendering"}},
        {"srgb_texture",
         {"sRGB - Texture", "Utility - sRGB - Texture", "srgb_tx", "sRGB"},
         {"color_picking", "texture_paint", "matte_paint"}},
        {"raw", {"Raw", "Utility - Raw", "Non-Color"}, {"data"}},
    };
    for (const Fallback& f : fallbacks) {
        if (space != f.name) continue;
        for (const char* alias : f.aliases)
            if (auto name = canonical_name(alias))
                return ResolvedSpace{*name, fmt::format("its colour space '{}'", *name)};
        for (const char* role : f.roles)
            if (impl_->config->hasRole(role))
                if (auto name = canonical_name(role))
                    return ResolvedSpace{*name, fmt::format("its {} role, '{}'", role, *name)};
    }
    return std::nullopt;
}

std::string ColorConfig::how_to_fix() const {
    if (impl_->from_env)
        return fmt::format(
            "the OpenColorIO config comes from $OCIO ('{}'): use a colour space "
            "it has, or unset OCIO (or pass --ocio) to use Spangle's own config",
            impl_->path);
    return fmt::format("the OpenColorIO config is '{}': use a colour space it has", impl_->path);
}

std::vector<std::string> ColorConfig::space_names() const {
    std::vector<std::string> names;
    const int n = impl_->config->getNumColorSpaces();
    for (int i = 0; i < n; ++i) names.emplace_back(impl_->config->getColorSpaceNameByIndex(i));
    return names;
}

std::optional<std::string> ColorConfig::not_scene_linear(const std::string& space) const {
    OCIO::ConstColorSpaceRcPtr cs = impl_->config->getColorSpace(space.c_str());
    if (!cs) return std::nullopt;
    if (cs->isData()) return std::string("it is a data space (isdata: true)");
    if (cs->getReferenceSpaceType() == OCIO::REFERENCE_SPACE_DISPLAY)
        return std::string("it is a display colour space");
    const std::string encoding = cs->getEncoding() ? cs->getEncoding() : "";
    if (encoding == "scene-linear") return std::nullopt;  // as the config says
    if (!encoding.empty()) return fmt::format("its encoding is {}", encoding);
    // Most configs say nothing of encodings (every v1 config, many v2 ones): the space's own
    // transform to the reference is tried on colours within [0, 1] (a LUT's usual domain). A
    // linear one maps 0 to 0, a doubled colour to its double and a sum to the sum (a log, gamma
    // or sRGB curve fails at once).
    // Rows: 0, x, 2x, y, x + y, and a colour and its tenth; px is transformed in place.
    static constexpr float kIn[7][3] = {
        {0.0f, 0.0f, 0.0f},    {0.18f, 0.05f, 0.5f}, {0.36f, 0.1f, 1.0f},  {0.7f, 0.3f, 0.02f},
        {0.88f, 0.35f, 0.52f}, {0.6f, 0.3f, 0.9f},   {0.06f, 0.03f, 0.09f}};
    float px[7][3];
    std::memcpy(px, kIn, sizeof px);
    try {
        OCIO::ConstProcessorRcPtr proc;
        if (auto t = cs->getTransform(OCIO::COLORSPACE_DIR_TO_REFERENCE))
            proc = impl_->config->getProcessor(t, OCIO::TRANSFORM_DIR_FORWARD);
        else if (auto f = cs->getTransform(OCIO::COLORSPACE_DIR_FROM_REFERENCE))
            proc = impl_->config->getProcessor(f, OCIO::TRANSFORM_DIR_INVERSE);
        else
            return std::nullopt;  // the reference itself
        note_files(*impl_->luts, proc, true);
        auto cpu = proc->getDefaultCPUProcessor();
        for (auto& row : px) cpu->applyRGB(row);
    } catch (const OCIO::Exception& e) {
        throw_error("colour space '{}': its transform to the reference cannot be made: {}", space,
                    e.what());
    }
    const auto far = [](const float* a, const float* b, float scale) {
        float size = 0.0f, diff = 0.0f;
        for (int c = 0; c < 3; ++c) {
            if (!std::isfinite(a[c]) || !std::isfinite(b[c])) return true;
            size = std::max({size, std::fabs(a[c]), std::fabs(b[c])});
            diff = std::max(diff, std::fabs(a[c] - scale * b[c]));
        }
        return diff > 1e-3f * size + 1e-5f;
    };
    const float zero[3] = {0.0f, 0.0f, 0.0f};
    float sum[3];
    for (int c = 0; c < 3; ++c) sum[c] = px[1][c] + px[3][c];
    if (far(px[0], zero, 1.0f) || far(px[2], px[1], 2.0f) || far(px[4], sum, 1.0f) ||
        far(px[5], px[6], 10.0f))
        return fmt::format(
            "its transform to the reference is not linear: ({}, {}, {}) becomes "
            "({:.4g}, {:.4g}, {:.4g}) and twice it ({:.4g}, {:.4g}, {:.4g}), "
            "0 becomes ({:.4g}, {:.4g}, {:.4g})",
            kIn[1][0], kIn[1][1], kIn[1][2], px[1][0], px[1][1], px[1][2], px[2][0], px[2][1],
            px[2][2], px[0][0], px[0][1], px[0][2]);
    return std::nullopt;
}

void ColorConfig::set_working_space(const std::string& space) {
    auto name = resolve(space);
    if (!name)
        throw_error("unknown colour space '{}' (known: {}); {}", space,
                    fmt::join(space_names(), ", "), how_to_fix());
    impl_->working = name->name;
}

std::string ColorConfig::conversion_id(const std::string& from, const std::string& to) const {
    try {
        auto processor = impl_->config->getProcessor(from.c_str(), to.c_str());
        note_files(*impl_->luts, processor, true);
        return processor->getCacheID();
    } catch (const OCIO::Exception& e) {
        throw_error("colour conversion from '{}' to '{}' failed: {}", from, to, e.what());
    }
}

uint64_t ColorConfig::content_hash() const {
    std::ostringstream text;
    impl_->config->serialize(text);
    uint64_t h = hash_text(text.str());
    // And the bytes of the LUT files the scene's conversions read (a texture's, a colour's),
    // sorted by content: the same path may hold another LUT on another node, or under another
    // $SHOT of the config's context.
    std::vector<uint64_t> luts;
    LutFiles& files = *impl_->luts;
    std::lock_guard<std::mutex> lock(files.mutex);
    for (const std::string& path : files.scene) {
        const std::string id = file_identity(path);
        auto& [seen, hash] = files.bytes[path];
        if (seen != id) {
            seen = id;
            hash = file_content_hash(path);
        }
        luts.push_back(hash);
    }
    std::sort(luts.begin(), luts.end());
    for (const uint64_t l : luts) h = hash2(h, l);
    return h;
}

void ColorConfig::convert(const std::string& from, const std::string& to, float* rgb,
                          std::size_t count) const {
    convert_noting(from, to, rgb, count, true);
}

void ColorConfig::convert_noting(const std::string& from, const std::string& to, float* rgb,
                                 std::size_t count, bool of_scene) const {
    if (count == 0) return;
    try {
        auto processor = impl_->config->getProcessor(from.c_str(), to.c_str());
        note_files(*impl_->luts, processor, of_scene);
        auto cpu = processor->getDefaultCPUProcessor();
        OCIO::PackedImageDesc desc(rgb, static_cast<long>(count), 1, 3);
        cpu->apply(desc);
    } catch (const OCIO::Exception& e) {
        throw_error("colour conversion from '{}' to '{}' failed: {}", from, to, e.what());
    }
}

void ColorConfig::to_display(const std::string& display, const std::string& view, float* rgb,
                             std::size_t count) const {
    if (count == 0) return;
    try {
        auto processor = impl_->config->getProcessor(impl_->working.c_str(), display.c_str(),
                                                     view.c_str(), OCIO::TRANSFORM_DIR_FORWARD);
        note_files(*impl_->luts, processor, false);
        auto cpu = processor->getDefaultCPUProcessor();
        OCIO::PackedImageDesc desc(rgb, static_cast<long>(count), 1, 3);
        cpu->apply(desc);
    } catch (const OCIO::Exception& e) {
        throw_error("display transform from '{}' to display '{}', view '{}' failed: {}",
                    impl_->working, display, view, e.what());
    }
}

void ColorConfig::resolve_view(std::string& display, std::string& view) const {
    const auto& config = impl_->config;
    std::vector<std::string> displays;
    for (int i = 0; i < config->getNumDisplays(); ++i) displays.emplace_back(config->getDisplay(i));
    if (display.empty()) display = config->getDefaultDisplay();
    if (std::find(displays.begin(), displays.end(), display) == displays.end())
        throw_error("the OCIO config '{}' has no display '{}' (displays: {})", path(), display,
                    fmt::join(displays, ", "));
    std::vector<std::string> views;
    for (int i = 0; i < config->getNumViews(display.c_str()); ++i)
        views.emplace_back(config->getView(display.c_str(), i));
    if (view.empty()) view = config->getDefaultView(display.c_str());
    if (std::find(views.begin(), views.end(), view) == views.end())
        throw_error("display '{}' of the OCIO config '{}' has no view '{}' (views: {})", display,
                    path(), view, fmt::join(views, ", "));
}

bool ColorConfig::view_is_srgb(const std::string& display, const std::string& view) const {
    const auto& config = impl_->config;
    const std::string d = display.empty() ? config->getDefaultDisplay() : display;
    const std::string v = view.empty() ? config->getDefaultView(d.c_str()) : view;
    const char* space = config->getDisplayViewColorSpaceName(d.c_str(), v.c_str());
    const OCIO::ConstColorSpaceRcPtr cs = space ? config->getColorSpace(space) : nullptr;
    if (cs && cs->isData()) return false;
    const auto names_srgb = [](std::string_view text) {
        return ascii_lower(text).find("srgb") != std::string::npos;
    };
    return names_srgb(d) || (space && names_srgb(space));
}

std::string ColorConfig::default_display() const {
    return impl_->config->getDefaultDisplay();
}
std::string ColorConfig::default_view(const std::string& display) const {
    return impl_->config->getDefaultView(display.c_str());
}

namespace {

/** A 3x3 matrix in double, row-major. */
using M3 = std::array<std::array<double, 3>, 3>;

M3 m3_mul(const M3& a, const M3& b) {
    M3 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) r[i][j] += a[i][k] * b[k][j];
    return r;
}

std::optional<M3> m3_inverse(const M3& m) {
    const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                       m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                       m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if (!(std::fabs(det) > 1e-15)) return std::nullopt;
    M3 r{};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, d = (i + 2) % 3;
            r[i][j] = (m[a][c] * m[b][d] - m[a][d] * m[b][c]) / det;
        }
    return r;
}

/** XYZ (Y = 1) of chromaticity (x, y). */
std::array<double, 3> chroma_xyz(double x, double y) {
    return {x / y, 1.0, (1.0 - x - y) / y};
}

/** The chromaticities c seen through a Bradford adaptation of its white to D65, as a config's
 *  CIE XYZ (D65) interchange shows a space of another white (ACEScg's red at (0.7132, 0.2927),
 *  its white at D65's). Unchanged when c's white is D65's already, or when c is degenerate. */
Chromaticities adapted_to_d65(const Chromaticities& c) {
    constexpr double kD65[2] = {0.3127, 0.3290};
    M3 primaries{};
    for (int i = 0; i < 3; ++i) {
        const auto p = chroma_xyz(c.xy[2 * i], c.xy[2 * i + 1]);
        for (int r = 0; r < 3; ++r) primaries[r][i] = p[r];
    }
    const auto w = chroma_xyz(c.xy[6], c.xy[7]);
    const auto inv = m3_inverse(primaries);
    if (!inv) return c;
    // RGB to XYZ: the primaries scaled so that RGB (1, 1, 1) is the white.
    M3 rgb_to_xyz = primaries;
    for (int i = 0; i < 3; ++i) {
        const double s = (*inv)[i][0] * w[0] + (*inv)[i][1] * w[1] + (*inv)[i][2] * w[2];
        for (int r = 0; r < 3; ++r) rgb_to_xyz[r][i] *= s;
    }
    const M3 bradford = {
        {{0.8951, 0.2664, -0.1614}, {-0.7502, 1.7135, 0.0367}, {0.0389, -0.0685, 1.0296}}};
    const auto bradford_inv = m3_inverse(bradford);
    const auto d65 = chroma_xyz(kD65[0], kD65[1]);
    M3 gain{};
    for (int r = 0; r < 3; ++r) {
        const double src = bradford[r][0] * w[0] + bradford[r][1] * w[1] + bradford[r][2] * w[2];
        const double dst =
            bradford[r][0] * d65[0] + bradford[r][1] * d65[1] + bradford[r][2] * d65[2];
        gain[r][r] = dst / src;
    }
    const M3 adapted = m3_mul(m3_mul(m3_mul(*bradford_inv, gain), bradford), rgb_to_xyz);
    Chromaticities out = c;
    for (int i = 0; i < 3; ++i) {
        const double sum = adapted[0][i] + adapted[1][i] + adapted[2][i];
        out.xy[static_cast<std::size_t>(2 * i)] = static_cast<float>(adapted[0][i] / sum);
        out.xy[static_cast<std::size_t>(2 * i + 1)] = static_cast<float>(adapted[1][i] / sum);
    }
    out.xy[6] = static_cast<float>(kD65[0]);
    out.xy[7] = static_cast<float>(kD65[1]);
    return out;
}

float chroma_distance(const Chromaticities& a, const Chromaticities& b) {
    float d = 0.0f;
    for (std::size_t i = 0; i < 8; ++i) d = std::max(d, std::fabs(a.xy[i] - b.xy[i]));
    return d;
}

}  // namespace

std::optional<Chromaticities> ColorConfig::working_chromaticities() const {
    // OCIO 2.1 does not expose primaries. The spaces Spangle ships have exact, published
    // chromaticities (this table). Where the config has a CIE XYZ (D65) interchange role, the
    // working space is measured through it: a measurement that is one of the table's spaces
    // (as measured, or as seen from D65: the interchange adapts other whites, and ACEScg
    // measured under "ACES - ACEScg" was written with D65-adapted primaries) is that space's
    // published chromaticities, whatever its name (a space named ACEScg defined as Rec.709 was
    // written as AP1); any other is the measurement. Without the role, a space found under a
    // common name of one in the table has its chromaticities.
    static const struct {
        const char* name;
        Chromaticities c;
    } known[] = {
        {"ACEScg", {{0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f}}},
        {"ACES2065-1", {{0.7347f, 0.2653f, 0.0f, 1.0f, 0.0001f, -0.077f, 0.32168f, 0.33767f}}},
        {"lin_rec709", {{0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}}},
    };
    const auto by_name = [&]() -> std::optional<Chromaticities> {
        for (const auto& k : known)
            if (impl_->working == k.name) return k.c;
        // A foreign config's working space that is one of these spaces under another common
        // name ("Linear Rec.709", "ACES - ACEScg": what resolve() finds by name, not a role
        // standing in for it).
        for (const auto& k : known) {
            const auto r = resolve(k.name);
            if (r && r->name == impl_->working && r->via.find(" role") == std::string::npos)
                return k.c;
        }
        return std::nullopt;
    };
    const char* xyz = impl_->config->getCanonicalName("cie_xyz_d65_interchange");
    if (!xyz || !*xyz) return by_name();
    float rgb[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    try {
        convert_noting(impl_->working, xyz, rgb, 4, false);
    } catch (const SpangleError&) {
        return by_name();
    }
    Chromaticities c{};
    for (int i = 0; i < 4; ++i) {
        const float sum = rgb[3 * i] + rgb[3 * i + 1] + rgb[3 * i + 2];
        if (!(std::fabs(sum) > 1e-12f) || !std::isfinite(sum)) return by_name();
        c.xy[static_cast<std::size_t>(2 * i)] = rgb[3 * i] / sum;
        c.xy[static_cast<std::size_t>(2 * i + 1)] = rgb[3 * i + 1] / sum;
    }
    // Within 0.01 in x and y: the adaptations configs use (Bradford, CAT02, von Kries) differ
    // by less; the table's spaces by more than 0.03.
    for (const auto& k : known)
        if (chroma_distance(c, k.c) < 1e-2f || chroma_distance(c, adapted_to_d65(k.c)) < 1e-2f)
            return k.c;
    return c;
}

}  // namespace spangle
