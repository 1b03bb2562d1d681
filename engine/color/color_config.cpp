#include "color/color_config.h"

#include <OpenColorIO/OpenColorIO.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "core/error.h"
#include "core/hash.h"

namespace OCIO = OCIO_NAMESPACE;

namespace spangle {

struct ColorConfig::Impl {
    OCIO::ConstConfigRcPtr config;
    std::string path;
    std::string working;
    std::string default_working;  ///< the scene_linear role's space, or empty
    bool from_env = false;        ///< chosen through $OCIO
};

ColorConfig::ColorConfig(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ColorConfig::ColorConfig(ColorConfig&&) noexcept = default;
ColorConfig& ColorConfig::operator=(ColorConfig&&) noexcept = default;
ColorConfig::~ColorConfig() = default;

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
    return std::string(name);
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
    if (!encoding.empty() && encoding != "scene-linear")
        return fmt::format("its encoding is {}", encoding);
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
        return impl_->config->getProcessor(from.c_str(), to.c_str())->getCacheID();
    } catch (const OCIO::Exception& e) {
        throw_error("colour conversion from '{}' to '{}' failed: {}", from, to, e.what());
    }
}

uint64_t ColorConfig::content_hash() const {
    std::ostringstream text;
    impl_->config->serialize(text);
    return hash_text(text.str());
}

void ColorConfig::convert(const std::string& from, const std::string& to, float* rgb,
                          std::size_t count) const {
    if (count == 0) return;
    try {
        auto processor = impl_->config->getProcessor(from.c_str(), to.c_str());
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

std::string ColorConfig::default_display() const {
    return impl_->config->getDefaultDisplay();
}
std::string ColorConfig::default_view(const std::string& display) const {
    return impl_->config->getDefaultView(display.c_str());
}

std::optional<Chromaticities> ColorConfig::working_chromaticities() const {
    // OCIO 2.1 does not expose primaries. The spaces Spangle ships have exact, published
    // chromaticities, so those come from this table; any other space is measured through the
    // config's CIE XYZ (D65) interchange role, which gives D65-adapted primaries; without that
    // role, a space found under a common name of one in the table has its chromaticities.
    static const struct {
        const char* name;
        Chromaticities c;
    } known[] = {
        {"ACEScg", {{0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f}}},
        {"ACES2065-1", {{0.7347f, 0.2653f, 0.0f, 1.0f, 0.0001f, -0.077f, 0.32168f, 0.33767f}}},
        {"lin_rec709", {{0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}}},
    };
    for (const auto& k : known)
        if (impl_->working == k.name) return k.c;
    const char* xyz = impl_->config->getCanonicalName("cie_xyz_d65_interchange");
    if (!xyz || !*xyz) {
        // No way to measure: a foreign config's working space that is one of these spaces
        // under another common name ("Linear Rec.709", "ACES - ACEScg": what resolve() finds
        // by name, not a role standing in for it) has its chromaticities.
        for (const auto& k : known) {
            const auto r = resolve(k.name);
            if (r && r->name == impl_->working && r->via.find(" role") == std::string::npos)
                return k.c;
        }
        return std::nullopt;
    }
    float rgb[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    try {
        convert(impl_->working, xyz, rgb, 4);
    } catch (const SpangleError&) {
        return std::nullopt;
    }
    Chromaticities c{};
    for (int i = 0; i < 4; ++i) {
        const float sum = rgb[3 * i] + rgb[3 * i + 1] + rgb[3 * i + 2];
        if (!(std::fabs(sum) > 1e-12f)) return std::nullopt;
        c.xy[static_cast<std::size_t>(2 * i)] = rgb[3 * i] / sum;
        c.xy[static_cast<std::size_t>(2 * i + 1)] = rgb[3 * i + 1] / sum;
    }
    return c;
}

}  // namespace spangle
