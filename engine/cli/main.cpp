// The spangle command. The only place in Spangle that prints errors as exit codes:
//   0  success
//   1  a problem with the input (scene, mesh, plugin, output path): one message, file:line:col
//   2  bad command line
//   3  internal error (a bug in Spangle)

#include <fmt/format.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/progress.h"
#include "color/image_output.h"
#include "core/error.h"
#include "render/frame.h"
#include "render/image_metrics.h"

#include <OpenImageIO/imageio.h>
#include "shading/material.h"
#include "shading/plugin_loader.h"

#ifndef SPANGLE_VERSION
#define SPANGLE_VERSION "0.0.0"
#endif

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Options of `spangle render`. */
struct RenderArgs {
    std::string scene;
    std::string output;
    std::string preview;
    bool no_preview = false;
    uint32_t spp = 0;
    int threads = 0;
    std::vector<std::string> plugin_dirs;
    bool stats = false;
    bool full_float = false;
    bool quiet = false;
    std::string compression = "zip";
    std::string ocio;
    std::string strategy = "mis";
    std::string size;
};

void print_stats(const FrameResult& r, const std::string& exr) {
    fmt::print("systems:\n");
    for (const auto& s : r.systems) {
        if (s.ran)
            fmt::print("  {:<16} ran      {:9.3f} s\n", s.name, s.seconds);
        else
            fmt::print("  {:<16} skipped  ({})\n", s.name, s.reason);
    }
    fmt::print("plugins opened: {}\n", r.plugins_opened.empty()
                                           ? std::string("none")
                                           : fmt::format("{}", fmt::join(r.plugins_opened, ", ")));
    const RenderStats& st = r.stats;
    if (st.samples > 0) {
        const double rays = static_cast<double>(st.camera_rays + st.bounce_rays + st.shadow_rays);
        fmt::print("render: {}x{}, {} samples in {:.3f} s: {:.3f} Msamples/s, {:.3f} Mrays/s\n",
                   r.width, r.height, st.samples, st.seconds,
                   static_cast<double>(st.samples) / st.seconds * 1e-6, rays / st.seconds * 1e-6);
        fmt::print("rays: {} camera, {} bounce, {} shadow\n", st.camera_rays, st.bounce_rays,
                   st.shadow_rays);
        fmt::print("non-finite samples replaced by black: {}\n", st.nonfinite);
    }
    for (const auto& sd : r.subdiv)
        fmt::print("subdivision: {} level {}{}: {} cage faces -> {} triangles in {:.3f} s\n",
                   sd.cage, sd.level, sd.from_camera ? " (from the camera)" : "", sd.cage_faces,
                   sd.triangles, sd.seconds);
    for (const auto& [name, values] : r.material_stats) {
        fmt::print("material '{}':\n", name);
        for (const auto& [key, value] : values) fmt::print("  {:<44} {:.4g}\n", key, value);
    }
    fmt::print("working space: {}\noutput: {}\n", r.color.working_space(), exr);
}

int run_render(const RenderArgs& a) {
    Logger log;
    if (a.quiet) log.threshold = LogLevel::Warning;
    const std::string output =
        a.output.empty() ? fs::path(a.scene).stem().string() + ".exr" : a.output;
    if (fs::path(output).extension() != ".exr") throw_error("output '{}' must end in .exr", output);
    const auto& comps = exr_compressions();
    if (std::find(comps.begin(), comps.end(), a.compression) == comps.end())
        throw_error("unknown EXR compression '{}' (valid: {})", a.compression,
                    fmt::join(comps, ", "));
    const std::string preview =
        a.no_preview
            ? std::string()
            : (a.preview.empty() ? fs::path(output).replace_extension(".png").string() : a.preview);

    FrameRequest req;
    req.scene = a.scene;
    req.plugin_dirs = a.plugin_dirs;
    req.ocio_config = a.ocio;
    req.options.threads = a.threads;
    req.options.spp_override = a.spp;
    if (!a.size.empty()) {
        unsigned w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(a.size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 1 || h < 1 ||
            w > 16384 || h > 16384)
            throw_error("--size must be WIDTHxHEIGHT with each in 1..16384, got '{}'", a.size);
        req.options.width_override = w;
        req.options.height_override = h;
    }
    req.options.strategy = a.strategy == "nee"    ? Strategy::NeeOnly
                           : a.strategy == "bsdf" ? Strategy::BsdfOnly
                                                  : Strategy::Mis;
    req.log = &log;
    Progress progress(::isatty(STDERR_FILENO) != 0);
    if (!a.quiet)
        req.options.progress = [&](uint64_t done, uint64_t total) { progress.update(done, total); };

    FrameResult frame = render_frame(req);
    progress.finish();
    if (frame.image.empty()) throw_error("the scene has no camera to render from");
    if (frame.stats.nonfinite > 0)
        log.warn(
            "{} non-finite sample values were replaced by black; the first at pixel ({}, {}), "
            "sample {}",
            frame.stats.nonfinite, frame.stats.first_bad_pixel_x, frame.stats.first_bad_pixel_y,
            frame.stats.first_bad_sample);

    ExrOptions exr;
    exr.half = !a.full_float;
    exr.compression = a.compression;
    exr.metadata = {
        {"spangle:scene", a.scene},
        {"spangle:version", SPANGLE_VERSION},
        {"spangle:spp", std::to_string(frame.stats.samples /
                                       (static_cast<uint64_t>(frame.width) * frame.height))}};
    write_exr(output, frame.image, static_cast<int>(frame.width), static_cast<int>(frame.height),
              frame.color, exr);
    if (!preview.empty())
        write_png_preview(preview, frame.image, static_cast<int>(frame.width),
                          static_cast<int>(frame.height), frame.color);
    if (a.stats)
        print_stats(frame, output);
    else if (!a.quiet)
        log.info("wrote {}{}", output, preview.empty() ? "" : " and " + preview);
    return 0;
}

int run_plugins(const std::vector<std::string>& dirs) {
    PluginLoader loader(plugin_search_path(dirs));
    fmt::print("plugin search path:\n");
    for (const auto& d : loader.search_path()) fmt::print("  {}\n", d);
    const auto files = loader.discover();
    if (files.empty()) fmt::print("no plugins found\n");
    int bad = 0;
    for (const auto& f : files) {
        try {
            auto p = PluginLoader::open_file(f, "");
            const SpangleMaterialPlugin_v2& t = p->table();
            fmt::print("\n{} ({}): {}\n", t.name, f, t.doc ? t.doc : "");
            for (uint32_t m = 0; m < t.model_count; ++m) {
                const SpangleMaterialModel_v2& model = t.models[m];
                fmt::print("  model {}: {}\n", model.name, model.doc ? model.doc : "");
                for (uint32_t k = 0; k < model.param_count; ++k)
                    fmt::print("    {}\n", describe_param(model.params[k]));
            }
        } catch (const SpangleError& e) {
            fmt::print("\n{}: not usable: {}\n", f, e.what());
            ++bad;
        }
    }
    return bad > 0 ? 1 : 0;
}

int run_inspect(const std::string& path) {
    auto in = OIIO::ImageInput::open(path);
    if (!in) throw_error("cannot read '{}': {}", path, OIIO::geterror());
    const OIIO::ImageSpec spec = in->spec();
    if (spec.nchannels < 3) throw_error("'{}' has {} channels; expected RGB", path, spec.nchannels);
    std::vector<float> all(static_cast<std::size_t>(spec.width) * spec.height * spec.nchannels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data()))
        throw_error("cannot read '{}': {}", path, in->geterror());
    std::vector<float> rgb(static_cast<std::size_t>(spec.width) * spec.height * 3);
    for (std::size_t i = 0; i < rgb.size() / 3; ++i)
        for (std::size_t c = 0; c < 3; ++c)
            rgb[3 * i + c] = all[i * static_cast<std::size_t>(spec.nchannels) + c];
    const ImageMetrics m = measure_image(rgb, spec.width, spec.height);
    fmt::print("{}: {}x{}, colour space '{}'\n", path, spec.width, spec.height,
               spec.get_string_attribute("colorSpace", "unknown"));
    fmt::print("mean luminance: {:.6g}\nnon-finite pixels: {}\nnegative pixels: {}\n",
               m.mean_luminance, m.nonfinite, m.negative);
    fmt::print("fireflies (> 10x the 3x3 median): {} ({:.4f}% of pixels)\n", m.fireflies,
               100.0 * m.firefly_fraction);
    return 0;
}

void print_error(const std::string& msg) {
    // Located messages already read "file:line:col: error: ..."; others get the prefix here.
    if (msg.find(": error: ") != std::string::npos)
        fmt::print(stderr, "{}\n", msg);
    else
        fmt::print(stderr, "spangle: error: {}\n", msg);
}

}  // namespace
}  // namespace spangle

int main(int argc, char** argv) {
    using namespace spangle;
    CLI::App app{"Spangle: a physically based renderer for glittering surfaces"};
    app.set_version_flag("--version", std::string("spangle ") + SPANGLE_VERSION);
    app.require_subcommand(1);

    RenderArgs ra;
    CLI::App* render = app.add_subcommand("render", "render a scene file to a colour-managed EXR");
    render->add_option("scene", ra.scene, "scene file (TOML)")->required();
    render->add_option("-o,--output", ra.output, "output EXR (default: <scene name>.exr)");
    render->add_option("--preview", ra.preview, "PNG preview path (default: the output with .png)");
    render->add_flag("--no-preview", ra.no_preview, "write no PNG preview");
    render->add_option("--size", ra.size, "image size WIDTHxHEIGHT (overrides the scene)");
    render->add_option("--spp", ra.spp, "samples per pixel (overrides the scene)")
        ->check(CLI::Range(1u, 1u << 20));
    render->add_option("--threads", ra.threads, "worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    render->add_option("--plugin-path", ra.plugin_dirs,
                       "directory searched for plugins first (repeatable)");
    render->add_flag("--stats", ra.stats, "print which systems ran and render statistics");
    render->add_flag("--float", ra.full_float, "write 32-bit float EXR instead of half");
    render->add_option("--compression", ra.compression, "EXR compression (default zip)");
    render->add_option("--ocio", ra.ocio,
                       "OpenColorIO config (default: $OCIO, then the shipped one)");
    render->add_flag("-q,--quiet", ra.quiet, "no progress or info output");
    render
        ->add_option("--strategy", ra.strategy,
                     "light transport estimator: mis (default), nee or bsdf (for debugging)")
        ->check(CLI::IsMember({"mis", "nee", "bsdf"}));

    std::vector<std::string> plugin_dirs;
    CLI::App* plugins =
        app.add_subcommand("plugins", "list the plugins found and their parameters");
    plugins->add_option("--plugin-path", plugin_dirs,
                        "directory searched for plugins first (repeatable)");

    std::string inspect_path;
    CLI::App* inspect =
        app.add_subcommand("inspect", "measure an image: mean, non-finite pixels, fireflies");
    inspect->add_option("image", inspect_path, "EXR (or any image OpenImageIO reads)")->required();

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    try {
        if (*render) return run_render(ra);
        if (*plugins) return run_plugins(plugin_dirs);
        if (*inspect) return run_inspect(inspect_path);
    } catch (const SpangleError& e) {
        print_error(e.what());
        return 1;
    } catch (const std::logic_error& e) {
        fmt::print(stderr, "spangle: {}\n", e.what());
        return 3;
    } catch (const std::exception& e) {
        print_error(e.what());
        return 1;
    }
    return 0;
}
