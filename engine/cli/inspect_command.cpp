// `spangle inspect IMAGE`: the image's size, mean luminance, non-finite and negative pixels,
// outliers (pixels above 10x the median of their 3x3 neighbourhood) told apart into glints and
// fireflies by the glints layer when the EXR has one, and every channel's min, max and mean (an
// EXR's render layers included: the tool to check a denoised or adaptive glitter render with).
// With --against REF: the relMSE against it and, when REF has a glints layer, how many of its
// glints (as `spangle flicker` finds them) the image keeps; with two references (two seeds),
// against their mean, on the glints both find, and how the two agree on them.

#include <fmt/format.h>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTestFile.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "cli/commands.h"
#include "color/exr_header.h"
#include "color/flicker.h"
#include "color/image_io.h"
#include "core/error.h"
#include "core/math.h"
#include "render/image_metrics.h"

namespace fs = std::filesystem;

namespace spangle {
namespace {

/** Every channel of an image, by name, one plane each. */
struct Planes {
    int width = 0, height = 0;
    int x0 = 0, y0 = 0;                   ///< the data window's corner (a crop part's place)
    int full_width = 0, full_height = 0;  ///< the display window's size
    int parts = 1;                        ///< parts of a multi-part file (the first is read)
    /** Luminance weights of its primaries (its chromaticities attribute; Rec.709 without). */
    std::array<double, 3> luma = kRec709Luma;
    bool luma_from_header = false;
    /** Its chromaticities (red, green, blue, white as x, y), when its header has them, and the
     *  colour space it names ("colorSpace"). */
    std::optional<std::array<float, 8>> chromaticities;
    std::string space;
    std::vector<std::string> names;        ///< in the file's order (OpenEXR's: by name)
    std::vector<std::vector<float>> data;  ///< one plane per name (empty: not read)
    std::vector<bool> sums;  ///< a --spp-range part's exact sums (32-bit integers, not read)
    /** How the image was rendered, from Spangle's header attributes ("partial: 8 of 64 samples
     *  per pixel", ...); empty for another renderer's file. */
    std::vector<std::string> state;
    bool decoded = false;  ///< an encoded (sRGB) image, decoded to linear for the measures
    const std::vector<float>* find(const std::string& name) const {
        const auto it = std::find(names.begin(), names.end(), name);
        return it == names.end() || data[static_cast<std::size_t>(it - names.begin())].empty()
                   ? nullptr
                   : &data[static_cast<std::size_t>(it - names.begin())];
    }
    /** Channels a, b, c interleaved (RGB per pixel); empty when one is missing. */
    std::vector<float> three(const std::string& a, const std::string& b,
                             const std::string& c) const {
        const std::vector<float>*x = find(a), *y = find(b), *z = find(c);
        if (!x || !y || !z) return {};
        std::vector<float> out(3 * x->size());
        for (std::size_t i = 0; i < x->size(); ++i) {
            out[3 * i] = (*x)[i];
            out[3 * i + 1] = (*y)[i];
            out[3 * i + 2] = (*z)[i];
        }
        return out;
    }
};

/** Every channel of an OpenEXR file (UINT channels, the exact sums of a --spp-range part, are
 *  named but not read). Throws SpangleError. */
Planes read_exr_planes(const std::string& path) {
    try {
        Imf::InputFile in(path.c_str());
        const Imath::Box2i dw = in.header().dataWindow();
        const Imath::Box2i disp = in.header().displayWindow();
        Planes p;
        p.width = dw.max.x - dw.min.x + 1;
        p.height = dw.max.y - dw.min.y + 1;
        p.x0 = dw.min.x;
        p.y0 = dw.min.y;
        p.full_width = disp.max.x - disp.min.x + 1;
        p.full_height = disp.max.y - disp.min.y + 1;
        p.parts = Imf::MultiPartInputFile(path.c_str()).parts();
        // Luminance in the image's own primaries (an ACEScg render weighed as Rec.709 read
        // 0.246 where its luminance is 0.257): the Y row of its RGB to XYZ matrix.
        if (const auto* c =
                in.header().findTypedAttribute<Imf::ChromaticitiesAttribute>("chromaticities")) {
            const Imf::Chromaticities& ch = c->value();
            p.chromaticities = std::array<float, 8>{ch.red.x,  ch.red.y,  ch.green.x, ch.green.y,
                                                    ch.blue.x, ch.blue.y, ch.white.x, ch.white.y};
            const Imath::M44f m = Imf::RGBtoXYZ(c->value(), 1.0f);
            const std::array<double, 3> w = {m[0][1], m[1][1], m[2][1]};
            if (std::isfinite(w[0] + w[1] + w[2]) && w[0] + w[1] + w[2] > 0.5) {
                p.luma = w;
                p.luma_from_header = true;
            }
        }
        const auto text = [&](const char* name) { return string_attribute(in.header(), name); };
        p.space = text("colorSpace");
        const std::string spp = text("spangle:spp"), range = text("spangle:spp_range");
        if (text("spangle:partial") == "1")
            p.state.push_back(
                fmt::format("partial: stopped at {} samples per pixel", spp.empty() ? "?" : spp));
        else if (!spp.empty())
            p.state.push_back(fmt::format("{} samples per pixel", spp));
        if (!range.empty()) {
            const std::string frame = text("spangle:spp_frame");
            p.state.push_back(
                frame.empty()
                    ? fmt::format("samples {} of the frame's (a pass image: no sums)", range)
                    : fmt::format("samples {} of a frame of {}", range, frame));
        }
        if (const std::string v = text("spangle:sampling"); !v.empty()) p.state.push_back(v);
        if (const std::string v = text("spangle:denoised"); !v.empty())
            p.state.push_back("denoised: " + v);
        if (const std::string v = text("spangle:preview_stride"); !v.empty())
            p.state.push_back(fmt::format("a preview pass (one path per {0}x{0} block)", v));
        const auto n = static_cast<std::size_t>(p.width) * static_cast<std::size_t>(p.height);
        Imf::FrameBuffer fb;
        const Imf::ChannelList& list = in.header().channels();
        for (auto it = list.begin(); it != list.end(); ++it) p.names.emplace_back(it.name());
        p.data.resize(p.names.size());
        p.sums.assign(p.names.size(), false);
        for (std::size_t c = 0; c < p.names.size(); ++c) {
            // A --spp-range part's integer channels are exact sums, not pixel values; another
            // file's integer channels are read as numbers (OpenEXR converts them).
            if (list.findChannel(p.names[c])->type == Imf::UINT && !range.empty()) {
                p.sums[c] = true;
                continue;
            }
            p.data[c].assign(n, 0.0f);
            fb.insert(p.names[c],
                      Imf::Slice::Make(Imf::FLOAT, p.data[c].data(), dw, sizeof(float),
                                       sizeof(float) * static_cast<std::size_t>(p.width)));
        }
        if (fb.begin() != fb.end()) {
            in.setFrameBuffer(fb);
            in.readPixels(dw.min.y, dw.max.y);
        }
        return p;
    } catch (const SpangleError&) {
        throw;
    } catch (const std::exception& e) {
        throw_error("cannot read '{}': {}", path, e.what());
    }
}

/** Prints one line per channel: min, max, mean over its finite values, and non-finite count. */
void print_channels(const Planes& p) {
    fmt::print("channels ({}):\n", p.names.size());
    for (std::size_t c = 0; c < p.names.size(); ++c) {
        if (p.data[c].empty()) {
            if (p.sums[c])
                fmt::print("  {:<20} (32-bit integer: exact sums of a sample range)\n", p.names[c]);
            continue;
        }
        // Cryptomatte's id channels hold hashes as float bits: a range of them means nothing.
        const std::string& name = p.names[c];
        const std::size_t dot = name.rfind('.');
        const std::string last = dot == std::string::npos ? name : name.substr(dot + 1);
        if (name.rfind("Crypto", 0) == 0 && (last == "R" || last == "B")) {
            fmt::print("  {:<20} (Cryptomatte ids: hashes, no range)\n", name);
            continue;
        }
        double lo = std::numeric_limits<double>::infinity(), hi = -lo, sum = 0.0;
        std::size_t bad = 0;
        for (const float v : p.data[c]) {
            if (!std::isfinite(v)) {
                ++bad;
                continue;
            }
            lo = std::min(lo, static_cast<double>(v));
            hi = std::max(hi, static_cast<double>(v));
            sum += static_cast<double>(v);
        }
        const std::size_t good = p.data[c].size() - bad;
        if (good == 0) {
            fmt::print("  {:<20} no finite value (non-finite {})\n", p.names[c], bad);
            continue;
        }
        fmt::print("  {:<20} min {:<12.6g} max {:<12.6g} mean {:<12.6g}{}\n", p.names[c], lo, hi,
                   sum / static_cast<double>(good), bad ? fmt::format(" non-finite {}", bad) : "");
    }
}

/** The RGB of an image; an EXR's every channel goes into `planes` too (only the size, for any
 *  other format, read through OpenImageIO). Throws SpangleError. */
std::vector<float> read_rgb(const std::string& path, Planes& planes) {
    if (Imf::isOpenExrFile(path.c_str())) {
        planes = read_exr_planes(path);
        std::vector<float> rgb = planes.three("R", "G", "B");
        // A grey image (a single Y channel, as luminance-only EXRs hold): its value in all three.
        if (rgb.empty() && planes.find("Y")) rgb = planes.three("Y", "Y", "Y");
        // Only layers (an AOV file: diffuse.R, ...): no image measures, the channels still.
        return rgb;
    }
    ImageHeader spec;
    std::vector<float> rgb = read_image(path, 3, spec);
    planes.width = spec.width;
    planes.height = spec.height;
    // PNG, JPEG and the like hold sRGB-encoded values: measured linear, as a render is (a PNG
    // preview's mean read 0.26 where its EXR's is 0.20, and a relMSE against the EXR of 2.2).
    if (usual_image_space(path) == "srgb_texture") {
        for (float& v : rgb) v = static_cast<float>(srgb_to_linear(static_cast<double>(v)));
        planes.decoded = true;
    }
    if (spec.channels >= 3) return rgb;
    // Grey (and grey + alpha): the grey in all three.
    const int stride = std::max(spec.channels, 1);
    const auto n = static_cast<std::size_t>(spec.width) * static_cast<std::size_t>(spec.height);
    std::vector<float> grey(3 * n);
    for (std::size_t i = 0; i < n; ++i)
        grey[3 * i] = grey[3 * i + 1] = grey[3 * i + 2] = rgb[i * static_cast<std::size_t>(stride)];
    return grey;
}

/** Adds the image's 'background' layer (the sky seen directly, which --layers and --denoise
 *  keep apart from the premultiplied RGB) into its RGB: the whole picture, as the preview shows
 *  it. False when it has no such layer. */
bool add_background(std::vector<float>& rgb, const Planes& planes) {
    const std::vector<float> sky = planes.three("background.R", "background.G", "background.B");
    if (sky.empty()) return false;
    for (std::size_t i = 0; i < rgb.size() && i < sky.size(); ++i) rgb[i] += sky[i];
    return true;
}

/** Where an image lies in its frame (a crop part is a window of it). */
struct Window {
    int x0, y0, w, h, fw, fh;
};

/** An image's window: its own, or (a PNG, another program's file) the whole of itself. */
Window window_of(const Planes& q) {
    return q.full_width > 0 ? Window{q.x0, q.y0, q.width, q.height, q.full_width, q.full_height}
                            : Window{0, 0, q.width, q.height, q.width, q.height};
}

std::string window_text(const Window& w) {
    return fmt::format("pixels ({}, {}) to ({}, {}) of a {}x{} frame", w.x0, w.y0, w.x0 + w.w,
                       w.y0 + w.h, w.fw, w.fh);
}

/** Refuses to compare an image with a reference of another colour space: values of two colour
 *  spaces are not comparable (one scene rendered in ACEScg and in lin_rec709 read relMSE 0.019
 *  where converted they match). An image without chromaticities is Rec.709 (OpenEXR's default;
 *  a PNG's sRGB). */
void check_same_space(const std::string& path, const Planes& planes, const std::string& ref_path,
                      const Planes& ref) {
    if (!planes.chromaticities && !ref.chromaticities) return;
    constexpr std::array<float, 8> kRec709 = {0.64f, 0.33f, 0.30f,   0.60f,
                                              0.15f, 0.06f, 0.3127f, 0.3290f};
    const std::array<float, 8> ca = planes.chromaticities.value_or(kRec709),
                               cb = ref.chromaticities.value_or(kRec709);
    float apart = 0.0f;
    for (std::size_t k = 0; k < 8; ++k) apart = std::max(apart, std::fabs(ca[k] - cb[k]));
    const auto said = [](const Planes& q, const std::array<float, 8>& c) {
        return fmt::format(
            "{}primaries ({:.4g}, {:.4g}) ({:.4g}, {:.4g}) ({:.4g}, {:.4g}), white ({:.4g}, "
            "{:.4g}){}",
            q.space.empty() ? "" : "'" + q.space + "': ", c[0], c[1], c[2], c[3], c[4], c[5], c[6],
            c[7], q.chromaticities ? "" : " (none written: Rec.709's)");
    };
    if (apart > 1e-4f)
        throw_error(
            "'{}' and the reference '{}' are in different colour spaces ({}; {}): their values "
            "cannot be compared; render both in one working_space, or convert one (oiiotool "
            "--colorconvert)",
            path, ref_path, said(planes, ca), said(ref, cb));
}

/** A reference image: its RGB plus its sky, its planes and its glints. */
struct Reference {
    std::string path;
    Planes planes;
    std::vector<float> rgb;
    bool sky = false;               ///< its 'background' layer was added to its RGB
    std::vector<uint8_t> glints;    ///< its glint pixels (empty: no glints or A layer)
    std::vector<float> glint_luma;  ///< its glints layer's luminance (empty: none)
};

/** Reads the references (one, or two renders of it) and finds their glints as `spangle flicker`
 *  finds a sequence's: one threshold, 4 x the mean glint luminance over the covered pixels of
 *  them all; each on the whole of its image (the detector looks 2 pixels around). */
std::vector<Reference> read_references(const std::vector<std::string>& paths) {
    std::vector<Reference> refs(paths.size());
    GlintMean mean;
    for (std::size_t r = 0; r < refs.size(); ++r) {
        Reference& rf = refs[r];
        rf.path = paths[r];
        rf.rgb = read_rgb(rf.path, rf.planes);
        if (rf.rgb.empty())
            throw_error("the reference '{}' has no R, G and B channels (nor Y) to compare with",
                        rf.path);
        rf.sky = add_background(rf.rgb, rf.planes);
        const std::vector<float> g = rf.planes.three("glints.R", "glints.G", "glints.B");
        const std::vector<float>* alpha = rf.planes.find("A");
        if (g.empty() || !alpha) continue;
        rf.glint_luma.resize(g.size() / 3);
        for (std::size_t i = 0; i < rf.glint_luma.size(); ++i)
            rf.glint_luma[i] =
                kRec709Y[0] * g[3 * i] + kRec709Y[1] * g[3 * i + 1] + kRec709Y[2] * g[3 * i + 2];
        mean.add(rf.glint_luma, *alpha);
    }
    for (Reference& rf : refs)
        if (!rf.glint_luma.empty())
            rf.glints =
                glint_pixels(rf.glint_luma, rf.planes.width, rf.planes.height, mean.threshold());
    return refs;
}

/** "K of N (P%)". */
std::string share_of(std::size_t k, std::size_t n) {
    return fmt::format(
        "{} of {} ({:.1f}%)", k, n,
        100.0 * static_cast<double>(k) / static_cast<double>(std::max<std::size_t>(n, 1)));
}

/** Compares the image (RGB plus its sky where `own_sky`) with one reference, or with the mean of
 *  two renders of it (two seeds): relMSE, and the glints of the reference it keeps. */
void compare_with_references(const std::string& path, const Planes& planes,
                             const std::vector<float>& rgb, bool own_sky,
                             const std::vector<std::string>& references) {
    std::vector<Reference> refs = read_references(references);
    const std::string& reference = refs[0].path;
    const Planes& ref_planes = refs[0].planes;
    // The pixels compared are those of one place (crops of two places were compared pixel by
    // pixel, and a crop against the whole frame holding it was refused). An image without a
    // window of its own (a PNG, another program's file) is taken at the other's place when it
    // is the same size.
    const Window iw = window_of(planes), rw = window_of(ref_planes);
    const bool windows = planes.full_width > 0 && ref_planes.full_width > 0;
    const bool same_frame = !windows || (iw.fw == rw.fw && iw.fh == rw.fh);
    const bool same_place = iw.w == rw.w && iw.h == rw.h &&
                            (!windows || (same_frame && iw.x0 == rw.x0 && iw.y0 == rw.y0));
    const bool inside = windows && same_frame && iw.x0 >= rw.x0 && iw.y0 >= rw.y0 &&
                        iw.x0 + iw.w <= rw.x0 + rw.w && iw.y0 + iw.h <= rw.y0 + rw.h;
    if (!same_place && !inside)
        throw_error(
            "'{}' holds {}, the reference '{}' {}: the reference must hold the image's pixels "
            "(the same window, or the whole frame of a crop)",
            path, window_text(iw), reference, window_text(rw));
    // A second reference is another render of the very same pixels (one without a window of
    // its own is taken at the first's place when it is the same size).
    for (std::size_t r = 1; r < refs.size(); ++r) {
        const Planes& q = refs[r].planes;
        const Window w = q.full_width > 0 || ref_planes.full_width <= 0
                             ? window_of(q)
                             : Window{rw.x0, rw.y0, q.width, q.height, rw.fw, rw.fh};
        if (w.x0 != rw.x0 || w.y0 != rw.y0 || w.w != rw.w || w.h != rw.h || w.fw != rw.fw ||
            w.fh != rw.fh)
            throw_error(
                "the references '{}' ({}) and '{}' ({}) hold different pixels: a second "
                "reference is another render of the same frame (another seed)",
                reference, window_text(rw), refs[r].path, window_text(w));
    }
    for (const Reference& rf : refs) check_same_space(path, planes, rf.path, rf.planes);
    if (!same_place) {
        // The image's window of each reference: its RGB and its glints.
        const auto cut_of = [&](const auto& whole, std::size_t channels) {
            std::remove_cvref_t<decltype(whole)> cut(static_cast<std::size_t>(iw.w) * iw.h *
                                                     channels);
            for (int y = 0; y < iw.h; ++y)
                std::copy_n(
                    whole.begin() +
                        static_cast<std::ptrdiff_t>(
                            (static_cast<std::size_t>(y + iw.y0 - rw.y0) * rw.w + iw.x0 - rw.x0) *
                            channels),
                    static_cast<std::size_t>(iw.w) * channels,
                    cut.begin() +
                        static_cast<std::ptrdiff_t>(static_cast<std::size_t>(y) * iw.w * channels));
            return cut;
        };
        for (Reference& rf : refs) {
            rf.rgb = cut_of(rf.rgb, 3);
            if (!rf.glints.empty()) rf.glints = cut_of(rf.glints, 1);
        }
        fmt::print("compared: {} of the reference{}, the image's window\n", window_text(iw),
                   refs.size() > 1 ? "s" : "");
    }
    // One render with --layers (or --denoise) keeps the sky seen directly in its 'background'
    // layer, not in RGB; one without has it in RGB. RGB plus background is the whole picture
    // (the preview shows it): both are measured so, and where only one had the layer the
    // comparison says so (RGB alone measured the sky, not the noise: a denoised render read
    // 0.15 against its reference).
    for (const Reference& rf : refs)
        if (own_sky != rf.sky)
            fmt::print(
                "compared: '{}' as its RGB plus its 'background' layer (the sky seen directly), "
                "as '{}' holds the sky in its RGB\n",
                own_sky ? path : rf.path, own_sky ? rf.path : path);
    // With two references (two seeds), the image is compared with their mean, whose own error is
    // about a quarter of their relMSE against each other (independent noise of equal size: the
    // difference has twice the variance of one, the mean half of it). Its glints are the pixels
    // where both find one: a glint that one render of the reference's quality finds and the
    // other does not is the noise of one render (two 1024-sample renders of the beetle at
    // 320x180 found 23 and 28 glints and kept 83% and 82% of each other's).
    std::vector<float> ref = refs[0].rgb;
    std::vector<uint8_t> ref_glints = refs[0].glints;
    std::string ref_name = fmt::format("the reference '{}'", reference);
    if (refs.size() == 2) {
        const std::vector<float>& second = refs[1].rgb;
        for (std::size_t i = 0; i < ref.size(); ++i) ref[i] = 0.5f * (ref[i] + second[i]);
        if (ref_glints.empty() || refs[1].glints.empty()) {
            ref_glints.clear();
        } else {
            for (std::size_t i = 0; i < ref_glints.size(); ++i)
                ref_glints[i] = ref_glints[i] & refs[1].glints[i];
        }
        ref_name = fmt::format("the mean of '{}' and '{}'", reference, refs[1].path);
    }
    // Over the pixels finite in both (a NaN made the figure nan); how many were left out.
    // Which image a left-out pixel was not finite in: a glint stored as infinity (a half
    // float's overflow) against a finite reference is a difference, not a match.
    std::size_t only_image = 0, only_ref = 0;
    const auto finite_pairs = [](const std::vector<float>& x, const std::vector<float>& y,
                                 std::vector<float>& a, std::vector<float>& b, std::size_t& only_x,
                                 std::size_t& only_y) {
        std::size_t skipped = 0;
        for (std::size_t i = 0; i + 2 < x.size() && i + 2 < y.size(); i += 3) {
            const bool fine = std::isfinite(x[i] + x[i + 1] + x[i + 2]);
            const bool y_fine = std::isfinite(y[i] + y[i + 1] + y[i + 2]);
            if (!fine || !y_fine) {
                ++skipped;
                only_x += fine ? 0u : (y_fine ? 1u : 0u);
                only_y += y_fine ? 0u : (fine ? 1u : 0u);
                continue;
            }
            a.insert(a.end(), x.begin() + static_cast<std::ptrdiff_t>(i),
                     x.begin() + static_cast<std::ptrdiff_t>(i + 3));
            b.insert(b.end(), y.begin() + static_cast<std::ptrdiff_t>(i),
                     y.begin() + static_cast<std::ptrdiff_t>(i + 3));
        }
        return skipped;
    };
    std::vector<float> a, b;
    const std::size_t skipped = finite_pairs(rgb, ref, a, b, only_image, only_ref);
    // No pixel finite in both: nothing was compared (it read relMSE 0, a perfect match).
    if (a.empty())
        throw_error(
            "'{}' and {} have no pixel finite in both ({} of {} not finite in the image, {} in "
            "the reference): nothing to compare",
            path, ref_name, skipped - only_ref, skipped, skipped - only_image);
    std::string left_out;
    if (skipped)
        left_out = fmt::format(
            " (over the pixels finite in both; {} left out: {} not finite in the image alone, {} "
            "in the reference alone, {} in both)",
            skipped, only_image, only_ref, skipped - only_image - only_ref);
    fmt::print("relMSE against {}: {:.6g}{}\n",
               refs.size() == 2 ? fmt::format("the mean of {} and {}", reference, refs[1].path)
                                : reference,
               relative_mse(a, b), left_out);
    if (refs.size() == 2) {
        std::vector<float> x, y;
        std::size_t ox = 0, oy = 0;
        finite_pairs(refs[0].rgb, refs[1].rgb, x, y, ox, oy);
        if (!x.empty()) {
            const double apart = relative_mse(x, y);
            fmt::print(
                "the references against each other: relMSE {:.6g}; their mean's own error about "
                "a quarter of it, {:.6g}\n",
                apart, 0.25 * apart);
        }
    }
    if (!ref_glints.empty()) {
        // Luminance of the whole picture (RGB plus sky), both weighed as the reference.
        const auto luminance = [&](const std::vector<float>& c) {
            std::vector<float> y(c.size() / 3);
            for (std::size_t i = 0; i < y.size(); ++i)
                y[i] = static_cast<float>(ref_planes.luma[0] * static_cast<double>(c[3 * i]) +
                                          ref_planes.luma[1] * static_cast<double>(c[3 * i + 1]) +
                                          ref_planes.luma[2] * static_cast<double>(c[3 * i + 2]));
            return y;
        };
        const GlintsKept k = glints_kept(luminance(rgb), luminance(ref), ref_glints, iw.w, iw.h);
        fmt::print(
            "glints of the reference (as `spangle flicker` finds them{}): {}; {} measured ({} on "
            "the border, {} standing out of their 8 neighbours by less than a tenth of "
            "themselves)\n",
            refs.size() == 2 ? ", in both references" : "", k.found, k.measured, k.border, k.faint);
        if (k.measured > 0)
            fmt::print(
                "glints kept (contrast over their 8 neighbours at least half the reference's): "
                "{}, median contrast {:.2f} of the reference's\n",
                share_of(k.kept, k.measured), k.median_ratio);
        if (refs.size() == 2 && k.measured > 0) {
            // How the two references agree on those glints. Both chose them (each found them
            // bright), so this is above what a third render of their quality would keep.
            const std::vector<float> l0 = luminance(refs[0].rgb), l1 = luminance(refs[1].rgb);
            const GlintsKept k01 = glints_kept(l0, l1, ref_glints, iw.w, iw.h),
                             k10 = glints_kept(l1, l0, ref_glints, iw.w, iw.h);
            fmt::print(
                "the references on these glints (both chose them: above what a third render of "
                "their quality keeps): '{}' against '{}' keeps {}, '{}' against '{}' keeps {}\n",
                reference, refs[1].path, share_of(k01.kept, k01.measured), refs[1].path, reference,
                share_of(k10.kept, k10.measured));
        }
    } else if (planes.find("glints.R") ||
               std::any_of(refs.begin(), refs.end(),
                           [](const Reference& rf) { return rf.planes.find("glints.R"); })) {
        std::string lacking;
        for (const Reference& rf : refs)
            if (rf.glints.empty()) lacking += (lacking.empty() ? "'" : " and '") + rf.path + "'";
        fmt::print(
            "glints kept: not measured ({} lack{} glints.R, G, B or A: render {} with --layers)\n",
            lacking, refs.size() == 2 && lacking.find(" and ") != std::string::npos ? "" : "s",
            lacking.find(" and ") != std::string::npos ? "them" : "it");
    }
    if (only_image + only_ref > 0)
        fmt::print(stderr,
                   "spangle: warning: {} pixels are finite in one of the image and {} and not in "
                   "the other (NaN, or infinity: a half float's 65504 overflowed, render with "
                   "--float where so): the relMSE leaves them out\n",
                   only_image + only_ref, ref_name);
}

/** Measures and prints the image at `path` (against `references` when there are any: one, or two
 *  renders of it with two seeds). */
int run_inspect(const std::string& path, const std::vector<std::string>& references) {
    if (references.size() > 2)
        throw_error("--against takes one reference, or two renders of it (two seeds): {} given",
                    references.size());
    std::vector<std::string> files = {path};
    files.insert(files.end(), references.begin(), references.end());
    for (const std::string& p : files) {
        std::error_code ec;
        if (fs::is_directory(p, ec)) throw_error("'{}' is a folder, not an image", p);
    }
    Planes planes;
    std::vector<float> rgb = read_rgb(path, planes);
    if (rgb.empty()) {
        if (!references.empty())
            throw_error("'{}' has no R, G and B channels (nor Y) to compare with '{}'", path,
                        references[0]);
        fmt::print("{}: {}x{}, no R, G and B channels (nor Y): its channels alone\n", path,
                   planes.width, planes.height);
        for (const std::string& st : planes.state) fmt::print("render: {}\n", st);
        print_channels(planes);
        return 0;
    }
    // Measured whole: RGB alone of a layered render left the sky out of the mean, and its black
    // sky next to the horizon's faint pixels made fireflies of them.
    const bool own_sky = add_background(rgb, planes);
    const std::vector<float> glints = planes.three("glints.R", "glints.G", "glints.B");
    const ImageMetrics m = measure_image(rgb, planes.width, planes.height, 10.0, 1e-3,
                                         glints.empty() ? nullptr : &glints, planes.luma);
    // A crop part says where it lies in its frame; a multi-part file that only its first part
    // was read.
    const bool crop = planes.full_width > 0 &&
                      (planes.width != planes.full_width || planes.height != planes.full_height ||
                       planes.x0 != 0 || planes.y0 != 0);
    fmt::print("{}: {}x{}{}{}\n", path, planes.width, planes.height,
               crop ? fmt::format(" at ({}, {}) of a {}x{} frame", planes.x0, planes.y0,
                                  planes.full_width, planes.full_height)
                    : std::string(),
               planes.parts > 1
                   ? fmt::format(" (part 1 of {}: the others are not read)", planes.parts)
                   : std::string());
    for (const std::string& st : planes.state) fmt::print("render: {}\n", st);
    if (planes.decoded) fmt::print("values: sRGB-encoded, decoded to linear for the measures\n");
    if (own_sky)
        fmt::print(
            "measured: RGB plus its 'background' layer (the sky seen directly, kept apart by "
            "--layers): the whole picture, as its preview shows it\n");
    // Over no pixel at all, a mean is no figure (it read 0).
    const bool none_finite = m.nonfinite >= static_cast<std::size_t>(planes.width) *
                                                static_cast<std::size_t>(planes.height);
    fmt::print("mean luminance: {}{}\nnon-finite pixels: {}\nnegative pixels: {}\n",
               none_finite ? std::string("none (no pixel is finite)")
                           : fmt::format("{:.6g}", m.mean_luminance),
               none_finite               ? ""
               : planes.luma_from_header ? " (weighed by the primaries of its chromaticities)"
                                         : " (Rec.709 weights)",
               m.nonfinite, m.negative);
    if (m.told_apart) {
        fmt::print("glints (> 10x the 3x3 median, mostly light through a glint): {}\n", m.glints);
        fmt::print("fireflies (> 10x the 3x3 median, not glints): {} ({:.4f}% of pixels)\n",
                   m.fireflies, 100.0 * m.firefly_fraction);
    } else {
        fmt::print(
            "fireflies (> 10x the 3x3 median): {} ({:.4f}% of pixels; glints count too: render "
            "with --layers to tell them apart)\n",
            m.fireflies, 100.0 * m.firefly_fraction);
    }
    if (!references.empty()) compare_with_references(path, planes, rgb, own_sky, references);
    if (!planes.names.empty()) print_channels(planes);
    return 0;
}

}  // namespace

Command add_inspect_command(CLI::App& app) {
    auto path = std::make_shared<std::string>();
    auto references = std::make_shared<std::vector<std::string>>();
    CLI::App* sub = app.add_subcommand(
        "inspect",
        "measure an image: mean, non-finite pixels, glints and fireflies, every channel's range");
    sub->add_option("image", *path, "EXR (or any image OpenImageIO reads, through its module)")
        ->required();
    sub->add_option("--against", *references,
                    "a reference image of the same size: print the relMSE, the mean over "
                    "pixels and channels of (x - r)^2 / (r^2 + 0.01), and, when it has a glints "
                    "layer, how many of its glints the image keeps. Given twice (two renders of "
                    "the reference with two seeds): against their mean, the glints both find, "
                    "and how the two agree on them")
        ->allow_extra_args(false);  // one image each: the image after it is not a reference
    return {sub, [path, references] { return run_inspect(*path, *references); }};
}

}  // namespace spangle
