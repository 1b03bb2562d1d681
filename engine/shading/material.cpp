#include "shading/material.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>

#include "color/image_io.h"
#include "core/hash.h"
#include "core/text.h"

namespace spangle {

namespace {

void host_log(void* context, SpangleLogLevel level, const char* message) {
    const auto* host = static_cast<const HostServices*>(context);
    const LogLevel l = level == SPANGLE_LOG_ERROR     ? LogLevel::Error
                       : level == SPANGLE_LOG_WARNING ? LogLevel::Warning
                       : level == SPANGLE_LOG_INFO    ? LogLevel::Info
                                                      : LogLevel::Debug;
    const char* text = message ? message : "";
    const PluginCallSite call = current_plugin_call();
    if (l < LogLevel::Warning && !call.label) {
        host->log().write(l, text);
        return;
    }
    // Messages name what they are about: the material being made, or the plugin call this
    // thread is in; each is said once (a plugin warning once per batch said it dozens of times
    // a frame), and a kernel's messages stop after kMaxKernelMessages different ones (a message
    // with a counter in it is a new one every batch).
    const std::string line = !host->subject().empty() ? fmt::format("{}: {}", host->subject(), text)
                             : call.label             ? fmt::format("{}: {}", call.label, text)
                                                      : std::string(text);
    if (!host->said().first_time(line)) return;
    if (call.label && host->subject().empty()) {
        const int n = host->count_kernel_message(call.label);
        if (n > HostServices::kMaxKernelMessages) return;
        if (n == HostServices::kMaxKernelMessages) {
            host->log().write(LogLevel::Warning,
                              fmt::format("{}: more messages than {}: the rest are not shown",
                                          call.label, HostServices::kMaxKernelMessages - 1));
            return;
        }
    }
    host->log().write(l, line);
}

int host_convert(void* context, const char* from, float* rgb, uint32_t count, char* error,
                 uint32_t capacity) {
    const auto* host = static_cast<const HostServices*>(context);
    try {
        if (!from) throw SpangleError("no source colour space given");
        auto resolved = host->color().resolve(from);
        if (!resolved)
            throw SpangleError(
                fmt::format("unknown colour space '{}'; {}", from, host->color().how_to_fix()));
        host->color().to_working(resolved->name, rgb, count);
        return 0;
    } catch (const std::exception& e) {
        if (error && capacity > 0) {
            const std::size_t n = std::min<std::size_t>(std::strlen(e.what()), capacity - 1);
            std::memcpy(error, e.what(), n);
            error[n] = '\0';
        }
        return 1;
    }
}

uint64_t host_hash2(uint64_t a, uint64_t b) {
    return hash2(a, b);
}

const char* type_name(SpangleParamType t) {
    switch (t) {
        case SPANGLE_PARAM_FLOAT:
            return "float";
        case SPANGLE_PARAM_INT:
            return "int";
        case SPANGLE_PARAM_BOOL:
            return "bool";
        case SPANGLE_PARAM_COLOR:
            return "color";
        case SPANGLE_PARAM_STRING:
            return "string";
        case SPANGLE_PARAM_VEC3:
            return "vec3";
    }
    return "?";
}

std::vector<std::string> split_choices(const char* choices) {
    std::vector<std::string> out;
    if (!choices) return out;
    std::string s(choices);
    std::size_t start = 0;
    while (start <= s.size()) {
        const std::size_t end = std::min(s.find('|', start), s.size());
        out.push_back(s.substr(start, end - start));
        start = end + 1;
    }
    return out;
}

std::string range_text(const SpangleParamDesc_v3& d) {
    return fmt::format("[{}, {}]", d.min_value, d.max_value);
}

}  // namespace

std::string plugin_label(const LoadedPlugin& plugin, const std::string& material) {
    return fmt::format("plugin '{}' ({}), material '{}'", plugin.table().name, plugin.path(),
                       material);
}

HostServices::HostServices(const ColorConfig& color, const Logger& log, TextureSettings textures)
    : color_(color),
      log_(log),
      textures_(color, log, std::move(textures)),
      working_(color.working_space()) {
    api_.abi_version = SPANGLE_MATERIAL_ABI_VERSION;
    api_.context = this;
    api_.working_space = working_.c_str();
    api_.log = host_log;
    api_.convert_to_working = host_convert;
    api_.hash2 = host_hash2;
}

std::string describe_param(const SpangleParamDesc_v3& p) {
    std::string def;
    switch (p.type) {
        case SPANGLE_PARAM_FLOAT:
            def = fmt::format("{}", p.default_value[0]);
            break;
        case SPANGLE_PARAM_INT:
            def = fmt::format("{}", static_cast<int64_t>(p.default_value[0]));
            break;
        case SPANGLE_PARAM_BOOL:
            def = p.default_value[0] != 0.0 ? "true" : "false";
            break;
        case SPANGLE_PARAM_COLOR:
        case SPANGLE_PARAM_VEC3:
            def = fmt::format("[{}, {}, {}]", p.default_value[0], p.default_value[1],
                              p.default_value[2]);
            break;
        case SPANGLE_PARAM_STRING:
            def = fmt::format("\"{}\"", p.default_string ? p.default_string : "");
            break;
    }
    std::string range;
    if (p.type == SPANGLE_PARAM_STRING)
        range = p.choices ? fmt::format(" one of {}", p.choices) : std::string(" any name");
    else if (p.type != SPANGLE_PARAM_BOOL)
        range = " in " + range_text(p);
    return fmt::format("{:<22} {:<6} = {:<16}{}  {}{}", p.name, type_name(p.type), def, range,
                       p.doc ? p.doc : "",
                       (p.flags & SPANGLE_PARAM_TEXTURABLE) ? " (texture ok)" : "");
}

ValidatedParams validate_params(const SpangleMaterialModel_v3& model, const Material& m,
                                const ColorConfig& color) {
    ValidatedParams out;
    out.strings.reserve(model.param_count);
    std::vector<const ParamEntry*> given(model.param_count, nullptr);
    for (const ParamEntry& p : m.params) {
        uint32_t k = 0;
        while (k < model.param_count && p.name != model.params[k].name) ++k;
        if (k == model.param_count) {
            std::vector<std::string> names;
            for (uint32_t i = 0; i < model.param_count; ++i)
                names.emplace_back(model.params[i].name);
            throw_error(
                p.key_loc,
                "material '{}': model '{}' of plugin '{}' has no parameter '{}'{} (parameters: {})",
                m.name, model.name, m.plugin, p.name, did_you_mean(p.name, names),
                names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", ")));
        }
        given[k] = &p;
    }
    for (uint32_t k = 0; k < model.param_count; ++k) {
        const SpangleParamDesc_v3& d = model.params[k];
        SpangleParamValue_v3 v{};
        v.name = d.name;
        v.type = d.type;
        std::copy(d.default_value, d.default_value + 3, v.number);
        out.strings.emplace_back(d.default_string ? d.default_string : "");
        const ParamEntry* p = given[k];
        if (p && p->kind == ParamEntry::Kind::Texture && p->texture.vertex_color &&
            d.type != SPANGLE_PARAM_COLOR)
            throw_error(p->loc,
                        "material '{}': parameter '{}' of model '{}' is a number; 'vertex_color' "
                        "gives colours (only colour parameters take it)",
                        m.name, d.name, model.name);
        if (p && p->kind == ParamEntry::Kind::Texture) {
            // The plugin reads the texture's values per point; create() sees its average.
            if (!(d.flags & SPANGLE_PARAM_TEXTURABLE) ||
                (d.type != SPANGLE_PARAM_FLOAT && d.type != SPANGLE_PARAM_COLOR)) {
                std::vector<std::string> can;
                for (uint32_t i = 0; i < model.param_count; ++i)
                    if (model.params[i].flags & SPANGLE_PARAM_TEXTURABLE)
                        can.emplace_back(model.params[i].name);
                throw_error(
                    p->loc,
                    "material '{}': parameter '{}' of model '{}' cannot take a texture: "
                    "the model needs it constant over the surface (parameters that "
                    "take textures: {})",
                    m.name, d.name, model.name,
                    can.empty() ? std::string("none") : fmt::format("{}", fmt::join(can, ", ")));
            }
            out.textured.emplace_back(k, p);
        } else if (p) {
            const auto bad_type = [&](const char* expected) {
                throw_error(p->loc, "material '{}': parameter '{}' must be {}", m.name, d.name,
                            expected);
            };
            const auto check_range = [&](double x) {
                if (!(x >= d.min_value && x <= d.max_value))
                    // Seven digits: a colour passes through single precision (1.2 printed
                    // as 1.2000000476837158).
                    // A whole number as written (2147483648 read as 2.147484e+09 beside a
                    // limit of 2147483647).
                    throw_error(p->loc, "material '{}': '{}' must be in {}, got {}", m.name, d.name,
                                range_text(d),
                                std::fabs(x) < 1e15 && x == std::floor(x)
                                    ? fmt::format("{:.0f}", x)
                                    : fmt::format("{:.7g}", x));
            };
            switch (d.type) {
                case SPANGLE_PARAM_FLOAT:
                    if (p->kind != ParamEntry::Kind::Number) bad_type("a number");
                    check_range(p->number[0]);
                    v.number[0] = p->number[0];
                    break;
                case SPANGLE_PARAM_INT:
                    if (p->kind != ParamEntry::Kind::Number || !p->is_integer)
                        bad_type("an integer");
                    check_range(p->number[0]);
                    v.number[0] = p->number[0];
                    break;
                case SPANGLE_PARAM_BOOL:
                    if (p->kind != ParamEntry::Kind::Bool) bad_type("true or false");
                    v.number[0] = p->number[0];
                    break;
                case SPANGLE_PARAM_COLOR: {
                    if (p->kind == ParamEntry::Kind::Number) {
                        // A single number is a grey, the same in every linear space of the config.
                        check_range(p->number[0]);
                        v.number[0] = v.number[1] = v.number[2] = p->number[0];
                        break;
                    }
                    if (p->kind != ParamEntry::Kind::Color) bad_type("a colour [r, g, b]");
                    for (int c = 0; c < 3; ++c) check_range(p->number[c]);
                    float rgb[3] = {static_cast<float>(p->number[0]),
                                    static_cast<float>(p->number[1]),
                                    static_cast<float>(p->number[2])};
                    color.to_working(p->text, rgb, 1);
                    // Gamut conversion may move a channel a hair outside the range that was
                    // checked on the written values; clamp it back. More than a hair is a colour
                    // outside the working space's gamut: said, as a light's or the sky's is
                    // (ACEScg green as albedo in lin_rec709 became (0, 1, 0) without a word).
                    const float most =
                        std::max({std::fabs(rgb[0]), std::fabs(rgb[1]), std::fabs(rgb[2])});
                    const double lo = d.min_value, hi = d.max_value;
                    bool clipped = false;
                    for (int c = 0; c < 3; ++c)
                        clipped =
                            clipped ||
                            static_cast<double>(rgb[c]) < lo - 1e-3 * static_cast<double>(most) ||
                            static_cast<double>(rgb[c]) > hi + 1e-3 * static_cast<double>(most);
                    if (clipped)
                        out.notes.push_back(fmt::format(
                            "{}: material '{}': '{}' ({}, {}, {}) in '{}' is ({:.4g}, {:.4g}, "
                            "{:.4g}) in the working space '{}', outside [{}, {}]: clipped to it "
                            "(render in a wider working space, such as ACEScg, to keep it)",
                            p->loc.str(), m.name, d.name, p->number[0], p->number[1], p->number[2],
                            p->text, rgb[0], rgb[1], rgb[2], color.working_space(), lo, hi));
                    for (int c = 0; c < 3; ++c)
                        v.number[c] =
                            std::clamp(static_cast<double>(rgb[c]), d.min_value, d.max_value);
                    break;
                }
                case SPANGLE_PARAM_VEC3:
                    if (p->kind == ParamEntry::Kind::Number) {
                        check_range(p->number[0]);
                        v.number[0] = v.number[1] = v.number[2] = p->number[0];
                        break;
                    }
                    if (p->kind != ParamEntry::Kind::Color) bad_type("three numbers [x, y, z]");
                    for (int c = 0; c < 3; ++c) {
                        check_range(p->number[c]);
                        v.number[c] = p->number[c];
                    }
                    break;
                case SPANGLE_PARAM_STRING: {
                    if (p->kind != ParamEntry::Kind::String) bad_type("a string");
                    const auto choices = split_choices(d.choices);
                    if (!choices.empty() &&
                        std::find(choices.begin(), choices.end(), p->text) == choices.end())
                        throw_error(p->loc, "material '{}': '{}' must be one of {}, got \"{}\"{}",
                                    m.name, d.name, fmt::join(choices, ", "), p->text,
                                    did_you_mean(p->text, choices));
                    out.strings.back() = p->text;
                    break;
                }
            }
        }
        out.values.push_back(v);
    }
    for (uint32_t k = 0; k < model.param_count; ++k)
        if (model.params[k].type == SPANGLE_PARAM_STRING)
            out.values[k].string = out.strings[k].c_str();
    return out;
}

namespace {

/** Where a plugin's refusal of a material is best said: the first parameter the material writes
 *  whose name the message names as a word ("min_flakes must be below max_flakes" at the
 *  min_flakes line, not the [[material]] line); the material's table when it names none. */
FileLoc blamed_param(const Material& m, const char* message) {
    const std::string_view text(message);
    const auto word_char = [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    };
    std::size_t first = std::string_view::npos;
    FileLoc at = m.loc;
    for (const ParamEntry& p : m.params) {
        if (p.name.empty() || p.loc.file.empty()) continue;
        for (std::size_t i = text.find(p.name); i != std::string_view::npos && i < first;
             i = text.find(p.name, i + 1)) {
            const std::size_t end = i + p.name.size();
            if ((i > 0 && word_char(text[i - 1])) || (end < text.size() && word_char(text[end])))
                continue;
            first = i;
            at = p.loc;
            break;
        }
    }
    return at;
}

/** The matrix taking linear Rec.709 (vertex colours as the mesh readers keep them) to the
 *  working space: the conversion of the three primaries (both spaces are linear). Identity
 *  where the config has no Rec.709 space (its own linear space then stands for it). */
void vertex_color_matrix(const ColorConfig& color, float out[9]) {
    float basis[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    const std::optional<ResolvedSpace> rec709 = color.resolve("lin_rec709");
    if (!rec709) return;
    color.convert(rec709->name, color.working_space(), basis, 3);
    // basis[3 j + i] is primary j's component i: column j of the matrix.
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) out[3 * i + j] = basis[3 * j + i];
}

}  // namespace

void Rec709Factor::init(const ColorConfig& color) {
    vertex_color_matrix(color, to_working);
    // The inverse by cofactors (in double: a 3 x 3 of primaries is well conditioned).
    const auto e = [&](int i, int j) { return static_cast<double>(to_working[3 * i + j]); };
    const double c00 = e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1),
                 c01 = e(1, 2) * e(2, 0) - e(1, 0) * e(2, 2),
                 c02 = e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0);
    const double det = e(0, 0) * c00 + e(0, 1) * c01 + e(0, 2) * c02;
    if (!(std::fabs(det) > 1e-12)) return;  // leaves the identity (no conversion known)
    const double inv[9] = {
        c00, e(0, 2) * e(2, 1) - e(0, 1) * e(2, 2), e(0, 1) * e(1, 2) - e(0, 2) * e(1, 1),
        c01, e(0, 0) * e(2, 2) - e(0, 2) * e(2, 0), e(0, 2) * e(1, 0) - e(0, 0) * e(1, 2),
        c02, e(0, 1) * e(2, 0) - e(0, 0) * e(2, 1), e(0, 0) * e(1, 1) - e(0, 1) * e(1, 0)};
    for (int k = 0; k < 9; ++k) from_working[k] = static_cast<float>(inv[k] / det);
}

std::unique_ptr<MaterialInstance> create_material(PluginLoader& loader, const Material& m,
                                                  const HostServices& host) {
    auto plugin = loader.open(m.plugin, m.plugin_loc);
    const SpangleMaterialModel_v3* model = nullptr;
    if (m.model.empty()) {
        if (plugin->table().model_count != 1)
            throw_error(m.loc,
                        "material '{}': plugin '{}' offers several models, so 'model' is "
                        "required (one of: {})",
                        m.name, m.plugin, fmt::join(plugin->model_names(), ", "));
        model = &plugin->table().models[0];
    } else {
        model = plugin->model(m.model);
        if (!model)
            throw_error(m.model_loc, "material '{}': plugin '{}' has no model '{}'{} (models: {})",
                        m.name, m.plugin, m.model, did_you_mean(m.model, plugin->model_names()),
                        fmt::join(plugin->model_names(), ", "));
    }
    ValidatedParams params = validate_params(*model, m, host.color());
    for (const std::string& note : params.notes) host.log().warn("{}", note);
    // Textures first: create() sees a textured parameter's average over the image (the
    // coarsest level of its box-filtered mips), scaled and clamped like the per-point values
    // (the flake model biases its colour table towards base_color's hue, for instance).
    std::vector<TextureBinding> textures;
    for (const auto& [k, p] : params.textured) {
        const SpangleParamDesc_v3& d = model->params[k];
        TextureBinding b;
        b.param = k;
        b.channels = d.type == SPANGLE_PARAM_COLOR ? 3 : 1;
        b.lo = static_cast<float>(d.min_value);
        b.hi = static_cast<float>(d.max_value);
        b.ref = p->texture;
        // A number read from a colour image's channel or luminance (`channel`).
        if (b.ref.channel != -1) {
            if (b.channels != 1)
                throw_error(p->loc,
                            "material '{}': parameter '{}' is a colour: 'channel' picks what a "
                            "number parameter reads of a colour image",
                            m.name, d.name);
            b.picks = true;
            b.pick[0] = b.pick[1] = b.pick[2] = 0.0f;
            if (b.ref.channel >= 0 && b.ref.channel <= 2) {
                b.pick[b.ref.channel] = 1.0f;
            } else {
                // Luminance: Rec.709's weights for data (numbers, as Blender's scene-linear
                // space takes them), the working space's for an image converted into it.
                const float* const kY = kRec709Y;
                if (b.ref.space == "raw") {
                    std::copy(kY, kY + 3, b.pick);
                } else {
                    Rec709Factor r;
                    r.init(host.color());
                    for (int j = 0; j < 3; ++j)
                        for (int i = 0; i < 3; ++i) b.pick[j] += kY[i] * r.from_working[3 * i + j];
                }
            }
        }
        // Vertex colours alone: create() sees the factor (the colours' average is the meshes').
        float mean[3] = {1, 1, 1};
        if (!b.ref.path.empty()) {
            b.texture = host.textures().open(p->texture, d.type == SPANGLE_PARAM_COLOR, p->loc);
            TextureQuery whole;
            whole.resize(1);
            whole.s[0] = whole.t[0] = 0.5f;
            whole.dsdx[0] = whole.dtdy[0] = 1.0f;
            whole.dtdx[0] = whole.dsdy[0] = 0.0f;
            host.textures().lookup(*b.texture, TextureRef{}, whole, 1, b.picks ? 3 : b.channels,
                                   mean);
            if (b.picks) mean[0] = b.pick[0] * mean[0] + b.pick[1] * mean[1] + b.pick[2] * mean[2];
        }
        // The factor the plugin sees: `scale`, in the working space; for vertex colours it is
        // linear Rec.709, as they are (stage_shade).
        float factor[3] = {b.ref.scale[0], b.ref.scale[1], b.ref.scale[2]};
        if (b.ref.vertex_color) {
            vertex_color_matrix(host.color(), b.vertex_to_working);
            const Vec3 f = b.vertex_factor(Vec3(1.0f));
            factor[0] = f.x;
            factor[1] = f.y;
            factor[2] = f.z;
        }
        // A colour image (or vertex colours) times a coloured factor: multiplied in linear
        // Rec.709, where the factor is given (not data: its channels are numbers).
        const bool data = b.ref.space == "raw" || b.ref.space == "data";
        b.rec709_product =
            b.channels == 3 && !data && (b.ref.vertex_color || !Rec709Factor::grey(b.ref.scale));
        if (b.rec709_product) {
            b.rec709.init(host.color());
            const Vec3 v = b.rec709.apply(Vec3(mean[0], mean[1], mean[2]),
                                          Vec3(b.ref.scale[0], b.ref.scale[1], b.ref.scale[2]));
            mean[0] = v.x;
            mean[1] = v.y;
            mean[2] = v.z;
            factor[0] = factor[1] = factor[2] = 1.0f;
        }
        for (int c = 0; c < b.channels; ++c)
            params.values[k].number[c] =
                std::clamp(static_cast<double>(mean[c] * factor[c]), d.min_value, d.max_value);
        if (b.channels == 1)
            params.values[k].number[1] = params.values[k].number[2] = params.values[k].number[0];
        textures.push_back(std::move(b));
    }
    const SpangleParams_v3 view = params.view();
    char error[512] = {0};
    void* instance = nullptr;
    {
        // The plugin's warnings name the material they are about.
        struct Subject {
            const HostServices& host;
            ~Subject() { host.set_subject({}); }
        } subject{host};
        host.set_subject(fmt::format("{}: material '{}'", m.loc.str(), m.name));
        try {
            call_plugin(plugin_label(*plugin, m.name), "create",
                        [&] { instance = model->create(&view, host.api(), error, sizeof(error)); });
        } catch (const SpangleError& e) {
            throw SpangleError(m.loc, e.what());
        }
    }
    if (!instance)
        throw_error(blamed_param(m, error),
                    "material '{}': plugin '{}' could not create model '{}': {}", m.name, m.plugin,
                    model->name, error[0] ? error : "no reason given");
    auto mat = std::make_unique<MaterialInstance>(std::move(plugin), model, instance, m.name);
    MapKind kind = MapKind::None;
    TextureBinding map;
    AlphaMap alpha;
    for (const ParamEntry& p : m.maps) {
        if (p.name == "alpha") {
            alpha.active = true;
            if (p.kind != ParamEntry::Kind::Texture) {
                alpha.value = static_cast<float>(p.number[0]);
                continue;
            }
            alpha.value = p.texture.scale[0];
            alpha.ref = p.texture;
            const std::shared_ptr<const Texture> texture =
                host.textures().open(p.texture, false, p.loc);
            // The channel asked for (r, g, b: a grey image's grey), else the alpha channel when
            // the image has one (grey + alpha, RGBA), else its first.
            const int have = texture->channels;
            const bool has_alpha = have == 2 || have >= 4;
            const int asked = p.texture.channel;
            if ((asked == 3 || asked == kAlphaOrOpaque) && !has_alpha) {
                // An image without alpha is opaque there, as glTF and Blender read it.
                if (asked == 3)
                    host.log().warn(
                        "{}: material '{}': '{}' has no alpha channel, so its alpha is 1 "
                        "there (times scale)",
                        p.loc.str(), m.name, p.texture.path);
                continue;
            }
            // The channel of the file as read (grey + alpha: grey, alpha; r, g, b of a grey image:
            // its grey).
            const int wanted = asked >= 0 && asked < 4 ? asked : has_alpha ? 3 : 0;
            const int channel = asked == kAlphaPbrt ? kAlphaPbrt
                                : have >= 3         ? std::min(wanted, have - 1)
                                : wanted == 3       ? 1
                                                    : 0;
            alpha.texels = alpha_texels(*texture, channel, p.loc);
            continue;
        }
        if (p.name == "alpha_cutoff") {
            alpha.cutoff = static_cast<float>(p.number[0]);
            continue;
        }
        kind = p.name == "normal_map" ? MapKind::Normal : MapKind::Bump;
        map.channels = kind == MapKind::Normal ? 3 : 1;
        map.ref = p.texture;
        map.texture = host.textures().open(p.texture, false, p.loc);
    }
    mat->bind(std::move(textures), kind, std::move(map), std::move(alpha));
    return mat;
}

float AlphaTexels::at(float s, float t, int wrap, bool closest) const {
    if (width <= 0 || height <= 0) return 1.0f;
    // Texel coordinates (centres at i + 0.5), wrapped per axis as the texture system wraps:
    // `wrap` holds s's mode + 4 x t's.
    const auto texel = [](int i, int n, int mode, bool& black) {
        if (i >= 0 && i < n) return i;
        switch (mode) {
            case 1:  // clamp
                return i < 0 ? 0 : n - 1;
            case 2:  // black
                black = true;
                return 0;
            case 3: {  // mirror
                const int period = 2 * n;
                int m = i % period;
                if (m < 0) m += period;
                return m < n ? m : period - 1 - m;
            }
            default: {  // periodic
                const int m = i % n;
                return m < 0 ? m + n : m;
            }
        }
    };
    const auto value = [&](int x, int y) {
        bool black = false;
        const int tx = texel(x, width, wrap & 3, black),
                  ty = texel(y, height, (wrap >> 2) & 3, black);
        if (black) return 0.0f;
        const std::size_t at = static_cast<std::size_t>(ty) * static_cast<std::size_t>(width) +
                               static_cast<std::size_t>(tx);
        return static_cast<float>(texels[at]) * (1.0f / 65535.0f);
    };
    const float x = s * static_cast<float>(width), y = t * static_cast<float>(height);
    // Far outside (or not a number): opaque, as a lookup that failed was.
    if (!(std::fabs(x) < 1e9f) || !(std::fabs(y) < 1e9f)) return 1.0f;
    if (closest) return value(static_cast<int>(std::floor(x)), static_cast<int>(std::floor(y)));
    const float fx = x - 0.5f, fy = y - 0.5f;
    const float x0 = std::floor(fx), y0 = std::floor(fy);
    const float wx = fx - x0, wy = fy - y0;
    const int ix = static_cast<int>(x0), iy = static_cast<int>(y0);
    return (value(ix, iy) * (1.0f - wx) + value(ix + 1, iy) * wx) * (1.0f - wy) +
           (value(ix, iy + 1) * (1.0f - wx) + value(ix + 1, iy + 1) * wx) * wy;
}

std::shared_ptr<const AlphaTexels> alpha_texels(const Texture& tex, int channel,
                                                const FileLoc& loc) {
    // One copy per converted file and channel while any material holds it (pbrt's alpha
    // copies of materials, glTF materials sharing a base colour texture).
    static std::mutex mutex;
    static std::map<std::string, std::weak_ptr<const AlphaTexels>> made;
    const std::string key = fmt::format("{}|{}", tex.converted, channel);
    std::lock_guard<std::mutex> lock(mutex);
    if (auto it = made.find(key); it != made.end())
        if (std::shared_ptr<const AlphaTexels> held = it->second.lock()) return held;
    auto out = std::make_shared<AlphaTexels>();
    made[key] = out;
    ImageHeader h;
    std::vector<float> pixels;
    try {
        pixels = read_image(tex.converted, 4, h, "alpha texture", true);
    } catch (const SpangleError& e) {
        throw_error(loc, "{}", e.what());
    }
    const int n = std::min(h.channels, 4);
    if (h.width <= 0 || h.height <= 0 || n <= 0) return out;
    out->width = h.width;
    out->height = h.height;
    const std::size_t count =
        static_cast<std::size_t>(h.width) * static_cast<std::size_t>(h.height);
    const auto px = [&](std::size_t i, int c) {
        return pixels[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(c)];
    };
    // pbrt's rule: an alpha channel that is 1 everywhere is dropped (pbrt-v4 drops it when it
    // reads the image), and a float lookup of colours is their mean.
    bool mean = false;
    int c = std::clamp(channel, 0, n - 1);
    if (channel == kAlphaPbrt) {
        const bool has_alpha = n == 2 || n == 4;
        bool opaque = true;
        for (std::size_t i = 0; has_alpha && opaque && i < count; ++i)
            opaque = px(i, n - 1) >= 1.0f;
        c = has_alpha && !opaque ? n - 1 : 0;
        mean = c == 0 && n >= 3;
    }
    out->texels.resize(count);
    for (std::size_t i = 0; i < count; ++i) {
        const float v = mean ? (px(i, 0) + px(i, 1) + px(i, 2)) / 3.0f : px(i, c);
        out->texels[i] = static_cast<uint16_t>(std::lround(65535.0f * (v >= 1.0f  ? 1.0f
                                                                       : v > 0.0f ? v
                                                                                  : 0.0f)));
    }
    return out;
}

float alpha_at(const AlphaMap& a, const TriangleMesh& mesh, uint32_t prim, float b1, float b2) {
    if (!a.texels) return std::clamp(a.value, 0.0f, 1.0f);
    float u = b1, v = b2;
    const std::size_t t = 3 * static_cast<std::size_t>(prim);
    if (!mesh.uvs.empty() && t + 2 < mesh.indices.size()) {
        const float b0 = 1.0f - b1 - b2;
        const std::size_t i0 = 2 * static_cast<std::size_t>(mesh.indices[t]),
                          i1 = 2 * static_cast<std::size_t>(mesh.indices[t + 1]),
                          i2 = 2 * static_cast<std::size_t>(mesh.indices[t + 2]);
        u = b0 * mesh.uvs[i0] + b1 * mesh.uvs[i1] + b2 * mesh.uvs[i2];
        v = b0 * mesh.uvs[i0 + 1] + b1 * mesh.uvs[i1 + 1] + b2 * mesh.uvs[i2 + 1];
    }
    float s = 0.0f, image_t = 0.0f;
    texture_st(a.ref, u, v, s, image_t);
    const float alpha = a.texels->at(s, image_t, a.ref.wraps(), a.ref.filter == 2) * a.value;
    return alpha >= 1.0f ? 1.0f : alpha > 0.0f ? alpha : 0.0f;  // NaN: 0
}

}  // namespace spangle
