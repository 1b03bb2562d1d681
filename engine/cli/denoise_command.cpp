// `spangle denoise IN.exr -o OUT.exr`: denoises a render written with --layers as render
// --denoise would have, for frames assembled from parts: crop windows and MPI bands cannot be
// denoised apart (a part's border lacks its neighbours, and merge refuses denoised parts), so a
// farm renders the parts with --layers, merges them, then denoises the whole frame here.

#include <fmt/format.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <memory>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/output_paths.h"
#include "cli/signals.h"
#include "cli/usage.h"
#include "color/exr_header.h"
#include "color/image_output.h"
#include "core/error.h"
#include "render/denoise.h"

namespace spangle {
namespace {

/** Options of `spangle denoise`. */
struct DenoiseArgs {
    std::string input, output;
    std::string glints = "keep";
    int threads = 0;
    bool quiet = false;
};

/** One channel of the input: its name, its pixel type and its values (data window). */
struct Plane {
    std::string name;
    Imf::PixelType type;
    std::vector<float> values;
};

int run_denoise(const DenoiseArgs& a) {
    if (same_file(a.input, a.output)) usage_error("the output '{}' is the input", a.output);
    const std::optional<GlintDenoise> glints = glint_denoise_named(a.glints);
    if (!glints) usage_error("--denoise-glints '{}': one of keep, apart, filter", a.glints);
    prepare_exr_output(a.output);
    install_exit_on_stop_signal();  // nothing polls: a stop signal ends it at once
    std::string why;
    if (!denoiser_available(&why)) throw_error("{}", why);

    std::unique_ptr<Imf::Header> header;
    std::vector<Plane> planes;
    int width = 0, height = 0;
    try {
        Imf::InputFile in(a.input.c_str());
        header = std::make_unique<Imf::Header>(in.header());
        const Imath::Box2i dw = header->dataWindow();
        width = dw.max.x - dw.min.x + 1;
        height = dw.max.y - dw.min.y + 1;
        if (!string_attribute(*header, "spangle:denoised").empty())
            throw_error("'{}' is denoised already (spangle:denoised = {})", a.input,
                        string_attribute(*header, "spangle:denoised"));
        if (!string_attribute(*header, "spangle:spp_range").empty())
            throw_error(
                "'{}' is a --spp-range part (samples {}): merge the ranges into the frame first, "
                "then denoise it",
                a.input, string_attribute(*header, "spangle:spp_range"));
        const Imf::ChannelList& list = header->channels();
        Imf::FrameBuffer fb;
        const auto n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
        for (auto it = list.begin(); it != list.end(); ++it)
            planes.push_back({it.name(), it.channel().type, std::vector<float>(n, 0.0f)});
        for (Plane& p : planes)
            fb.insert(p.name, Imf::Slice::Make(Imf::FLOAT, p.values.data(), dw, sizeof(float),
                                               sizeof(float) * static_cast<std::size_t>(width)));
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
    } catch (const SpangleError&) {
        throw;
    } catch (const std::exception& e) {
        throw_error("cannot read '{}': {}", a.input, e.what());
    }
    const auto find = [&](const std::string& name) -> Plane* {
        for (Plane& p : planes)
            if (p.name == name) return &p;
        return nullptr;
    };
    std::vector<std::string> missing;
    for (const char* need : {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z",
                             "glints.R", "glints.G", "glints.B"})
        if (!find(need)) missing.emplace_back(need);
    if (!missing.empty())
        throw_error(
            "'{}' lacks the channels the denoiser is guided by ({}): render it (or its parts) "
            "with --layers",
            a.input, fmt::join(missing, ", "));
    if (find("noisy.R")) throw_error("'{}' has a 'noisy' layer: it is denoised already", a.input);

    // The beauty and the layers as the renderer holds them: RGB per pixel, the other channels
    // per pixel in the file's order.
    const auto n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    const Plane *r = find("R"), *g = find("G"), *b = find("B");
    std::vector<float> image(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
        image[3 * i] = r->values[i];
        image[3 * i + 1] = g->values[i];
        image[3 * i + 2] = b->values[i];
    }
    // The other channels, the layers, in the file's order (the denoiser finds its guides by name).
    std::vector<const Plane*> layer_planes;
    for (const Plane& p : planes)
        if (p.name != "R" && p.name != "G" && p.name != "B") layer_planes.push_back(&p);
    std::vector<std::string> names;
    for (const Plane* p : layer_planes) names.push_back(p->name);
    std::vector<float> layers(n * names.size());
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t c = 0; c < layer_planes.size(); ++c)
            layers[i * names.size() + c] = layer_planes[c]->values[i];
    const std::size_t before = names.size();
    const bool done = denoise(DenoiseImage{&image, &layers, &names, static_cast<uint32_t>(width),
                                           static_cast<uint32_t>(height)},
                              *glints, a.threads);
    if (!done)
        fmt::print(
            stderr, "warning: {}\n",
            not_denoised_warning(static_cast<uint32_t>(width), static_cast<uint32_t>(height)));

    // The input's header (windows, metadata, compression) with the channels as they are now:
    // each keeps its type, the noisy beauty takes the beauty's.
    // (A tiled input is written as scanlines: its tile description is not copied.)
    Imf::Header out = scanline_header(*header, {"channels"});
    if (done) out.insert("spangle:denoised", Imf::StringAttribute(a.glints));
    // Every channel written, where its values are, and its type in the file: R, G, B from the
    // image, then the layers (those the denoiser added, the noisy beauty, of the beauty's type).
    struct Out {
        std::string name;
        Imf::PixelType type;
        const float* first;  ///< the value of pixel 0; pixel i's is `stride` floats on
        std::size_t stride;
    };
    std::vector<Out> outs;
    for (int c = 0; c < 3; ++c) {
        const Plane* p = c == 0 ? r : c == 1 ? g : b;
        outs.push_back({p->name, p->type, image.data() + c, 3});
    }
    for (std::size_t c = 0; c < names.size(); ++c)
        outs.push_back({names[c], c < before ? layer_planes[c]->type : r->type, layers.data() + c,
                        names.size()});
    // A half channel from a half copy (the library does not write floats into a half channel);
    // 32-bit integers read as floats are written as floats.
    std::vector<std::vector<float>> floats(outs.size());
    std::vector<std::vector<Imath::half>> halves(outs.size());
    for (std::size_t c = 0; c < outs.size(); ++c) {
        Out& o = outs[c];
        if (o.type == Imf::UINT) o.type = Imf::FLOAT;
        out.channels().insert(o.name, Imf::Channel(o.type));
        if (o.type == Imf::HALF) {
            halves[c].resize(n);
            for (std::size_t i = 0; i < n; ++i) halves[c][i] = Imath::half(o.first[i * o.stride]);
        } else {
            floats[c].resize(n);
            for (std::size_t i = 0; i < n; ++i) floats[c][i] = o.first[i * o.stride];
        }
    }
    write_file_atomically(a.output, [&](const std::string& tmp) {
        Imf::OutputFile file(tmp.c_str(), out);
        Imf::FrameBuffer fb;
        const Imath::Box2i dw = out.dataWindow();
        const std::size_t w = static_cast<std::size_t>(width);
        for (std::size_t c = 0; c < outs.size(); ++c) {
            if (outs[c].type == Imf::HALF)
                fb.insert(outs[c].name,
                          Imf::Slice::Make(Imf::HALF, halves[c].data(), dw, sizeof(Imath::half),
                                           sizeof(Imath::half) * w));
            else
                fb.insert(outs[c].name, Imf::Slice::Make(Imf::FLOAT, floats[c].data(), dw,
                                                         sizeof(float), sizeof(float) * w));
        }
        file.setFrameBuffer(fb);
        file.writePixels(height);
    });
    if (!a.quiet)
        fmt::print("{} {} into {}{}\n", done ? "denoised" : "copied", a.input, a.output,
                   done ? fmt::format(" (glints: {}; the noisy beauty kept as the layer 'noisy')",
                                      a.glints)
                        : std::string());
    return 0;
}

}  // namespace

Command add_denoise_command(CLI::App& app) {
    auto a = std::make_shared<DenoiseArgs>();
    CLI::App* sub = app.add_subcommand(
        "denoise",
        "denoise a render written with --layers (a frame merged from crop windows or MPI bands) "
        "as render --denoise would have");
    sub->add_option("image", a->input, "the EXR, with the albedo, N and glints layers")->required();
    sub->add_option("-o,--output", a->output, "the denoised EXR")->required();
    sub->add_option("--denoise-glints", a->glints,
                    "keep (the glints pass through unfiltered, the default), apart (filtered "
                    "on their own) or filter (with the rest)");
    sub->add_option("--threads", a->threads, "worker threads (default: all cores)")
        ->check(CLI::Range(1, 1024));
    sub->add_flag("-q,--quiet", a->quiet, "no line saying what was written");
    return {sub, [a] { return run_denoise(*a); }};
}

}  // namespace spangle
