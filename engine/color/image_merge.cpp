#include "color/image_merge.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <tuple>

#include "color/exr_header.h"
#include "color/image_io.h"
#include "color/image_output.h"
#include "core/error.h"
#include "core/memory.h"
#include "core/pixel_filter.h"

namespace spangle {

namespace {

struct Channel {
    std::string name;
    Imf::PixelType type;
};

std::vector<Channel> channels_of(const Imf::Header& h) {
    std::vector<Channel> out;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
        out.push_back({it.name(), it.channel().type});
    return out;
}

/** Whether h has exactly these channels (names and types, in order). */
bool same_channels(const Imf::Header& h, const std::vector<Channel>& chans) {
    const std::vector<Channel> c = channels_of(h);
    bool same = c.size() == chans.size();
    for (std::size_t i = 0; same && i < c.size(); ++i)
        same = c[i].name == chans[i].name && c[i].type == chans[i].type;
    return same;
}

/** Refuses a part whose header says it is of another scene (the bytes of its files) or of
 *  another moment of it than the first part. Parts written before these attributes pass. */
void check_same_render(const Imf::Header& hd, const Imf::Header& first, const std::string& path,
                       const std::string& first_path) {
    const auto differ = [&](const char* name) {
        const std::string a = string_attribute(hd, name), b = string_attribute(first, name);
        return !a.empty() && !b.empty() && a != b;
    };
    // A part that lacks what another part's header says (a tool that copied the pixels and
    // dropped Spangle's attributes) cannot be checked against it: refused, rather than merged
    // unchecked. Parts that all lack it (written before it was) pass.
    for (const char* name : {"spangle:sceneHash", "spangle:time", "spangle:spp", "worldToCamera",
                             "worldToNDC", "colorSpace", "chromaticities"}) {
        const bool has = hd.find(name) != hd.end(), first_has = first.find(name) != first.end();
        if (has != first_has)
            throw_error(
                "'{}' has no '{}' in its header, '{}' has: a part whose header lost Spangle's "
                "attributes (copied by another tool?) cannot be checked against the others; "
                "merge the parts spangle render wrote",
                has ? first_path : path, name, has ? path : first_path);
    }
    // The specific differences first, the scene's hash last (another frame of a deforming
    // sequence, another OCIO config also hash differently): the message then says which.
    // The colour space the pixels are in (another OCIO config or working space) and where the
    // camera stood (another --camera, a moved camera): parts of other renders.
    if (differ("colorSpace"))
        throw_error("'{}' is in colour space '{}', '{}' in '{}': parts of one render merge", path,
                    string_attribute(hd, "colorSpace"), first_path,
                    string_attribute(first, "colorSpace"));
    const auto* cam = hd.findTypedAttribute<Imf::M44fAttribute>("worldToCamera");
    const auto* cam_first = first.findTypedAttribute<Imf::M44fAttribute>("worldToCamera");
    if (cam && cam_first && cam->value() != cam_first->value())
        throw_error(
            "'{}' and '{}' were seen through different cameras (their worldToCamera differ: "
            "another --camera, or the camera moved): parts of one render merge",
            path, first_path);
    // Where the camera stood and what it saw: another lens at the same place (another --camera)
    // projects otherwise.
    const auto* ndc = hd.findTypedAttribute<Imf::M44fAttribute>("worldToNDC");
    const auto* ndc_first = first.findTypedAttribute<Imf::M44fAttribute>("worldToNDC");
    // (One part without it is refused above, as a header that lost it.)
    if (ndc && ndc_first && ndc->value() != ndc_first->value())
        throw_error(
            "'{}' and '{}' were seen through different cameras (their worldToNDC differ: another "
            "--camera, lens or projection): parts of one render merge",
            path, first_path);
    if (differ("spangle:time"))
        throw_error("'{}' is of the scene at {} s, '{}' at {} s: parts of one frame merge", path,
                    string_attribute(hd, "spangle:time"), first_path,
                    string_attribute(first, "spangle:time"));
    // Adaptive sampling's settings decide each pixel's samples: parts of other settings are
    // parts of other renders.
    const auto sampling = [](const Imf::Header& h) {
        const std::string s = string_attribute(h, "spangle:sampling");
        return s.empty() ? std::string("fixed") : s;
    };
    if (sampling(hd) != sampling(first))
        throw_error("'{}' was sampled '{}', '{}' '{}': parts of one render merge", path,
                    sampling(hd), first_path, sampling(first));
    // A denoised part was denoised from its own pixels alone: parts do not add up to the
    // denoised whole (a seam where they meet).
    if (!string_attribute(hd, "spangle:denoised").empty())
        throw_error(
            "'{}' was denoised (--denoise): the denoiser saw only that part's pixels, so denoised "
            "parts do not merge into the denoised whole; merge parts rendered without --denoise, "
            "or render the whole frame with --denoise (MPI denoises the assembled image)",
            path);
    const auto strategy = [](const Imf::Header& h) {
        const std::string s = string_attribute(h, "spangle:strategy");
        return s.empty() ? std::string("mis") : s;
    };
    if (strategy(hd) != strategy(first))
        throw_error(
            "'{}' was rendered with --strategy {}, '{}' with {}: parts of one render merge "
            "(another estimator has other noise in every pixel)",
            path, strategy(hd), first_path, strategy(first));
    if (differ("spangle:sceneHash"))
        throw_error(
            "'{}' and '{}' were rendered from different scenes (or the scene's files changed "
            "between them, or another --camera or --env was given): parts of one render merge",
            path, first_path);
}

/** A display window in words: "WxH", or "WxH at (x, y)" where it does not start at 0. */
std::string window_words(const Imath::Box2i& b) {
    const int w = b.max.x - b.min.x + 1, h = b.max.y - b.min.y + 1;
    if (b.min.x == 0 && b.min.y == 0) return fmt::format("{}x{}", w, h);
    return fmt::format("{}x{} at ({}, {})", w, h, b.min.x, b.min.y);
}

/** The lossy compression a part was written with (B44, DWA; PXR24, lossy for its 32-bit float
 *  channels only), or null. */
const char* lossy_compression(const Imf::Header& h) {
    switch (h.compression()) {
        case Imf::B44_COMPRESSION:
            return "b44";
        case Imf::B44A_COMPRESSION:
            return "b44a";
        case Imf::DWAA_COMPRESSION:
            return "dwaa";
        case Imf::DWAB_COMPRESSION:
            return "dwab";
        case Imf::PXR24_COMPRESSION:
            for (auto c = h.channels().begin(); c != h.channels().end(); ++c)
                if (c.channel().type == Imf::FLOAT) return "pxr24";
            return nullptr;
        default:
            return nullptr;
    }
}

/** A hint for overlapping parts that differ (this one or the first written lossily: each part's
 *  copy of the overlap changed its own way). Empty when both are lossless. */
std::string lossy_note(const Imf::Header& h, const Imf::Header& first) {
    const char* name = lossy_compression(h);
    if (!name) name = lossy_compression(first);
    if (!name) return {};
    return fmt::format(
        ", or its lossy compression ({}) changed each part's copy of the overlap its own way: "
        "render crops that overlap with a lossless --compression such as zip or piz",
        name);
}

/** What the merged header says of its parts as a whole: partial when any part was (a stopped
 *  render), and the render time of all of them together (it said the first part's). */
struct PartTotals {
    bool partial = false;
    double seconds = 0.0;
    bool timed = true;                  ///< every part has a render time
    std::vector<std::string> partials;  ///< the parts that were partial
    void add(const Imf::Header& h, const std::string& path) {
        if (string_attribute(h, "spangle:partial") == "1") {
            partial = true;
            partials.push_back(path);
        }
        const auto* t = h.findTypedAttribute<Imf::FloatAttribute>("renderTimeSeconds");
        if (t)
            seconds += static_cast<double>(t->value());
        else
            timed = false;
    }
    void apply(Imf::Header& h) const {
        h.insert("spangle:partial", Imf::StringAttribute(partial ? "1" : "0"));
        if (timed)
            h.insert("renderTimeSeconds", Imf::FloatAttribute(static_cast<float>(seconds)));
        else if (h.find("renderTimeSeconds") != h.end())
            // Not the first part's alone: unknown (copied without it: OpenEXR 3.1's
            // Header::erase leaks the attribute it removes).
            h = scanline_header(h, {"renderTimeSeconds"});
    }
};

/** Opens the part at `path` and hands it to read(); any failure but our own errors becomes
 *  "cannot read 'path': ...". */
template <class Read>
void read_part(const std::string& path, Read&& read) {
    try {
        require_exr_file(path);
        Imf::InputFile in(path.c_str());
        read(in);
    } catch (const SpangleError&) {
        throw;
    } catch (const std::exception& e) {
        throw_error("cannot read '{}': {}", path, e.what());
    }
}

/** Sample-range parts (render --spp-range) of one window: their exact sums add up. */
MergeReport merge_sample_ranges(const std::vector<std::string>& parts, const std::string& out) {
    MergeReport rep;
    rep.parts = parts.size();
    std::unique_ptr<Imf::Header> first;
    std::vector<Channel> chans;
    std::vector<SampleSum> total;
    std::size_t pw = 0, ph = 0;
    uint64_t spp_frame = 0;
    std::vector<std::tuple<uint64_t, uint64_t, std::string>> ranges;  // [a, b), file
    const std::vector<std::string>& sum_names = sample_sum_channels();
    PartTotals totals;
    for (const std::string& path : parts) {
        read_part(path, [&](Imf::InputFile& in) {
            const Imf::Header& hd = in.header();
            totals.add(hd, path);
            const std::string range = string_attribute(hd, "spangle:spp_range");
            if (range.empty())
                throw_error(
                    "'{}' is not a --spp-range part, but other parts are: merge the sample "
                    "ranges of each window first, then the windows",
                    path);
            for (const std::string& n : sum_names)
                if (!hd.channels().findChannel(n))
                    throw_error(
                        "'{}' lacks the exact sums (channel {}): a pass image (--pass-output) of "
                        "a --spp-range render, or a part saved by another program; merge the "
                        "parts the renders wrote at their end",
                        path, n);
            uint64_t a = 0, b = 0;
            if (std::sscanf(range.c_str(), "%" SCNu64 "..%" SCNu64, &a, &b) != 2 || !(a < b))
                throw_error("'{}': its sample range '{}' is not A..B", path, range);
            const Imath::Box2i dw = hd.dataWindow();
            if (!first) {
                first = std::make_unique<Imf::Header>(hd);
                chans = channels_of(hd);
                spp_frame =
                    std::strtoull(string_attribute(hd, "spangle:spp_frame").c_str(), nullptr, 10);
                pw = static_cast<std::size_t>(dw.max.x - dw.min.x + 1);
                ph = static_cast<std::size_t>(dw.max.y - dw.min.y + 1);
                rep.width = hd.displayWindow().max.x + 1;
                rep.height = hd.displayWindow().max.y + 1;
                if (const uint64_t have =
                        memory_short_for(2.0 * 96.0 * static_cast<double>(pw * ph)))
                    throw_error("merging {}x{} pixels of sums needs more than the {} available", pw,
                                ph, format_bytes(static_cast<double>(have)));
                total.assign(pw * ph * 3, SampleSum(0));
            } else {
                if (hd.displayWindow() != first->displayWindow() || dw != first->dataWindow())
                    throw_error(
                        "'{}' covers other pixels than '{}': sample ranges of one window merge "
                        "(render every part with the same --crop and --size)",
                        path, parts.front());
                if (!same_channels(hd, chans))
                    throw_error(
                        "'{}' has other channels than '{}' (render every part with the same "
                        "options: --float)",
                        path, parts.front());
                check_same_render(hd, *first, path, parts.front());
                if (string_attribute(hd, "spangle:filter_spread") !=
                    string_attribute(*first, "spangle:filter_spread"))
                    throw_error(
                        "'{}' and '{}' spread their pixels by different filters "
                        "(filter_samples): parts of one render merge",
                        path, parts.front());
                if (std::strtoull(string_attribute(hd, "spangle:spp_frame").c_str(), nullptr, 10) !=
                    spp_frame)
                    throw_error("'{}' is part of a frame of {} samples per pixel, '{}' of {}", path,
                                string_attribute(hd, "spangle:spp_frame"), parts.front(),
                                spp_frame);
            }
            if (b > spp_frame)
                throw_error("'{}' holds samples {}..{}, beyond the frame's {}", path, a, b,
                            spp_frame);
            ranges.emplace_back(a, b, path);
            std::vector<uint32_t> words(pw * ph * 12);
            Imf::FrameBuffer fb;
            for (std::size_t c = 0; c < 12; ++c)
                fb.insert(sum_names[c],
                          Imf::Slice::Make(Imf::UINT, words.data() + c, dw, 12 * sizeof(uint32_t),
                                           pw * 12 * sizeof(uint32_t)));
            in.setFrameBuffer(fb);
            in.readPixels(dw.min.y, dw.max.y);
            for (std::size_t i = 0; i < total.size(); ++i)
                total[i] += sample_sum_from_words(&words[4 * i]);
        });
    }
    // The ranges must cover the frame's samples 0..spp_frame-1, each once.
    std::sort(ranges.begin(), ranges.end());
    uint64_t next = 0;
    for (const auto& [a, b, path] : ranges) {
        if (a < next)
            throw_error("samples {}..{} are in '{}' and in another part", a, std::min(b, next),
                        path);
        if (a > next)
            throw_error(
                "samples {}..{} of the frame's {} are in no part (render them with "
                "--spp-range {}..{})",
                next, a, spp_frame, next, a);
        next = b;
    }
    if (next != spp_frame)
        throw_error(
            "samples {}..{} of the frame's {} are in no part (render them with --spp-range "
            "{}..{})",
            next, spp_frame, spp_frame, next, spp_frame);

    // The whole frame's image: the mean of all its samples, from the exact total.
    std::vector<float> rgb(total.size());
    for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = sample_mean(total[i], spp_frame);
    // filter_samples = "shared": the means spread by the weights the parts were rendered with,
    // as the whole render spreads them (parts of the whole frame only: the render refuses crops).
    if (const std::string text = string_attribute(*first, "spangle:filter_spread"); !text.empty()) {
        std::vector<double> weights;
        std::istringstream in(text);
        for (std::string word; in >> word;) {
            char* end = nullptr;
            const double w = std::strtod(word.c_str(), &end);
            if (end == word.c_str() || *end != '\0' || !(w >= 0.0 && w <= 1.0))
                throw_error("'{}': its spangle:filter_spread '{}' is not a list of weights",
                            parts.front(), text);
            weights.push_back(w);
        }
        double sum = 0.0;
        for (const double w : weights) sum += w;
        if (weights.size() % 2 == 0 || !(std::fabs(sum - 1.0) < 1e-9))
            throw_error(
                "'{}': its spangle:filter_spread holds {} weights of sum {}, not an odd number "
                "summing to 1",
                parts.front(), weights.size(), sum);
        if (first->dataWindow() != first->displayWindow())
            throw_error(
                "'{}' is a crop window of a render with filter_samples = \"shared\": its pixels "
                "need their neighbours' samples beyond the window",
                parts.front());
        const auto w = static_cast<uint32_t>(pw), h = static_cast<uint32_t>(ph);
        spread_pixels(rgb.data(), 3, std::vector<bool>(3, true), PixelRect{0, 0, w, h},
                      PixelRect{0, 0, w, h}, weights);
    }
    // The first part's header without the range's attributes (copied one by one: OpenEXR 3.1's
    // Header::erase leaks the attribute it removes).
    Imf::Header header = scanline_header(
        *first, {"spangle:spp_range", "spangle:spp_frame", "spangle:filter_spread", "channels"});
    Imf::ChannelList channels;
    for (const Channel& c : chans)
        if (std::find(sum_names.begin(), sum_names.end(), c.name) == sum_names.end())
            channels.insert(c.name, Imf::Channel(c.type));
    header.channels() = channels;
    header.insert("spangle:spp", Imf::StringAttribute(std::to_string(spp_frame)));
    totals.apply(header);
    rep.partial_parts = totals.partials;
    const Imath::Box2i dw = header.dataWindow();
    write_file_atomically(out, [&](const std::string& tmp) {
        Imf::OutputFile file(tmp.c_str(), header);
        std::vector<Imath::half> halves;
        Imf::FrameBuffer fb;
        for (std::size_t c = 0; c < 3; ++c) {
            const std::string name(1, "RGB"[c]);
            const Imf::Channel* ch = header.channels().findChannel(name);
            if (!ch) throw_error("'{}' has no channel {}", parts.front(), name);
            if (ch->type == Imf::HALF) {
                if (halves.empty()) halves.assign(rgb.begin(), rgb.end());
                fb.insert(name,
                          Imf::Slice::Make(Imf::HALF, halves.data() + c, dw,
                                           3 * sizeof(Imath::half), pw * 3 * sizeof(Imath::half)));
            } else {
                fb.insert(name, Imf::Slice::Make(Imf::FLOAT, rgb.data() + c, dw, 3 * sizeof(float),
                                                 pw * 3 * sizeof(float)));
            }
        }
        file.setFrameBuffer(fb);
        file.writePixels(static_cast<int>(ph));
    });
    rep.sample_ranges = ranges.size();
    return rep;
}

}  // namespace

MergeReport merge_exr_parts(const std::vector<std::string>& parts, const std::string& out) {
    if (parts.empty()) throw_error("nothing to merge: give the crop renders' EXR files");
    // Sample-range parts merge by their sums; crop windows by placing pixels.
    for (const std::string& path : parts) {
        bool range = false;
        read_part(path, [&](Imf::InputFile& in) {
            range = !string_attribute(in.header(), "spangle:spp_range").empty();
        });
        if (range) return merge_sample_ranges(parts, out);
    }
    MergeReport rep;
    rep.parts = parts.size();
    std::unique_ptr<Imf::Header> first;
    std::vector<Channel> chans;
    Imath::Box2i display;
    std::vector<float> full;         // display window, channels interleaved
    std::vector<uint8_t> covered;    // per pixel
    std::vector<std::string> owner;  // which part covered a pixel first (for messages)
    std::size_t nc = 0, w = 0, h = 0;
    PartTotals totals;
    for (const std::string& path : parts) {
        read_part(path, [&](Imf::InputFile& in) {
            const Imf::Header& hd = in.header();
            totals.add(hd, path);
            const Imath::Box2i dw = hd.dataWindow();
            if (!first) {
                first = std::make_unique<Imf::Header>(hd);
                chans = channels_of(hd);
                display = hd.displayWindow();
                if (display.min.x != 0 || display.min.y != 0)
                    throw_error("'{}': its display window does not start at (0, 0)", path);
                w = static_cast<std::size_t>(display.max.x + 1);
                h = static_cast<std::size_t>(display.max.y + 1);
                nc = chans.size();
                const double need =
                    4.0 * static_cast<double>(w * h * nc) + static_cast<double>(w * h);
                if (const uint64_t have = memory_short_for(2.0 * need))
                    throw_error(
                        "merging a {}x{} frame of {} channels needs about {}, but only {} "
                        "is available",
                        w, h, nc, format_bytes(2.0 * need),
                        format_bytes(static_cast<double>(have)));
                full.assign(w * h * nc, 0.0f);
                covered.assign(w * h, 0);
                rep.width = static_cast<int>(w);
                rep.height = static_cast<int>(h);
            } else {
                if (hd.displayWindow() != display)
                    throw_error("'{}' is part of a {} frame, '{}' of a {} one", path,
                                window_words(hd.displayWindow()), parts.front(),
                                window_words(display));
                if (!same_channels(hd, chans))
                    throw_error(
                        "'{}' has other channels than '{}' (render every part with the "
                        "same options: --layers, --float)",
                        path, parts.front());
                check_same_render(hd, *first, path, parts.front());
                if (string_attribute(hd, "spangle:spp") != string_attribute(*first, "spangle:spp"))
                    throw_error(
                        "'{}' has {} samples per pixel, '{}' {}: parts of one frame must "
                        "reach the same count",
                        path, string_attribute(hd, "spangle:spp"), parts.front(),
                        string_attribute(*first, "spangle:spp"));
            }
            if (dw.min.x < 0 || dw.min.y < 0 || dw.max.x >= static_cast<int>(w) ||
                dw.max.y >= static_cast<int>(h) || dw.max.x < dw.min.x || dw.max.y < dw.min.y)
                throw_error("'{}': its data window ({}, {})-({}, {}) is not inside the {}x{} frame",
                            path, dw.min.x, dw.min.y, dw.max.x, dw.max.y, w, h);
            const auto pw = static_cast<std::size_t>(dw.max.x - dw.min.x + 1);
            const auto ph = static_cast<std::size_t>(dw.max.y - dw.min.y + 1);
            std::vector<float> part(pw * ph * nc);
            Imf::FrameBuffer fb;
            for (std::size_t c = 0; c < nc; ++c)
                fb.insert(chans[c].name,
                          Imf::Slice::Make(Imf::FLOAT, part.data() + c, dw, nc * sizeof(float),
                                           pw * nc * sizeof(float)));
            in.setFrameBuffer(fb);
            in.readPixels(dw.min.y, dw.max.y);
            for (std::size_t y = 0; y < ph; ++y)
                for (std::size_t x = 0; x < pw; ++x) {
                    const std::size_t fx = x + static_cast<std::size_t>(dw.min.x);
                    const std::size_t fy = y + static_cast<std::size_t>(dw.min.y);
                    const std::size_t p = fy * w + fx;
                    const float* src = &part[(y * pw + x) * nc];
                    float* dst = &full[p * nc];
                    if (covered[p]) {
                        if (std::memcmp(src, dst, nc * sizeof(float)) != 0)
                            throw_error(
                                "'{}' and an earlier part both hold pixel ({}, {}) with "
                                "different values: they are not crops of one render{}",
                                path, fx, fy, lossy_note(hd, *first));
                        ++rep.overlap_pixels;
                        continue;
                    }
                    std::memcpy(dst, src, nc * sizeof(float));
                    covered[p] = 1;
                }
        });
    }
    std::size_t missing = 0, first_missing = 0;
    for (std::size_t p = covered.size(); p-- > 0;)
        if (!covered[p]) {
            ++missing;
            first_missing = p;
        }
    if (missing > 0)
        throw_error(
            "the parts leave {} of the {}x{} frame's pixels uncovered (the first at ({}, "
            "{})): render the missing windows with --crop",
            missing, w, h, first_missing % w, first_missing / w);

    // Non-finite values in R, G, B: infinity where a half float overflowed (said when the part
    // was written), NaN never from a render (its non-finite samples are dropped and counted).
    for (std::size_t c = 0; c < nc; ++c) {
        if (chans[c].name != "R" && chans[c].name != "G" && chans[c].name != "B") continue;
        for (std::size_t p = 0; p < w * h; ++p) {
            const float v = full[p * nc + c];
            rep.infinite += std::isinf(v) ? 1u : 0u;
            rep.nan += std::isnan(v) ? 1u : 0u;
        }
    }

    Imf::Header header = scanline_header(*first);
    header.dataWindow() = display;
    totals.apply(header);
    rep.partial_parts = totals.partials;
    write_file_atomically(out, [&](const std::string& tmp) {
        Imf::OutputFile file(tmp.c_str(), header);
        // Half channels are written from half copies (their values came from halves: exact).
        std::vector<std::vector<Imath::half>> halves(nc);
        Imf::FrameBuffer fb;
        for (std::size_t c = 0; c < nc; ++c) {
            if (chans[c].type == Imf::HALF) {
                halves[c].resize(w * h);
                for (std::size_t p = 0; p < w * h; ++p)
                    halves[c][p] = Imath::half(full[p * nc + c]);
                fb.insert(chans[c].name,
                          Imf::Slice::Make(Imf::HALF, halves[c].data(), display,
                                           sizeof(Imath::half), w * sizeof(Imath::half)));
            } else if (chans[c].type == Imf::FLOAT) {
                fb.insert(chans[c].name,
                          Imf::Slice::Make(Imf::FLOAT, full.data() + c, display, nc * sizeof(float),
                                           w * nc * sizeof(float)));
            } else {
                throw_error("'{}': channel '{}' is not a float or half channel", parts.front(),
                            chans[c].name);
            }
        }
        file.setFrameBuffer(fb);
        file.writePixels(static_cast<int>(h));
    });
    return rep;
}

}  // namespace spangle
