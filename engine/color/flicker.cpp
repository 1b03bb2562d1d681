#include "color/flicker.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFloatVectorAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfMatrixAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <utility>

#include "color/exr_header.h"
#include "color/image_io.h"
#include "core/error.h"
#include "core/math.h"

namespace spangle {

namespace {

/** The layers of one frame that the measurement needs. */
struct Frame {
    int width = 0, height = 0;
    Imath::M44f world_to_ndc;
    std::vector<float> px, py, pz, z, a, glint;  ///< glint: luminance of the glints layer
    /** The object-space position and object number layers (Pobj, object) and each object's
     *  placement in this frame (spangle:objectToWorld, 12 floats each); empty when the frame
     *  lacks them (rendered before Spangle wrote them). */
    std::vector<float> ox, oy, oz, object, object_to_world;
    /** Per object: 1 when its Pobj is the position in its rest pose (a deforming mesh,
     *  spangle:restPose); empty when the frame does not say (no object deforms). */
    std::vector<float> rest_pose;
    std::string scene, time;  ///< spangle:scene and spangle:time; empty where not written
    std::string shutter;      ///< spangle:shutter, written when the frame's motion was blurred
    bool has_objects() const { return !object.empty() && !object_to_world.empty(); }
    /** Whether object k (from 0) deforms: its points are found by their rest position. */
    bool deforms(std::size_t k) const { return k < rest_pose.size() && rest_pose[k] > 0.5f; }
};

Frame read_frame(const std::string& path) {
    try {
        require_exr_file(path);
        Imf::InputFile in(path.c_str());
        const Imf::Header& h = in.header();
        const auto* m = h.findTypedAttribute<Imf::M44fAttribute>("worldToNDC");
        if (!m)
            throw_error(
                "'{}' has no worldToNDC matrix (render it with Spangle; a panoramic camera has "
                "none, and its frames cannot be compared)",
                path);
        const Imath::Box2i dw = h.dataWindow();
        if (dw != h.displayWindow())
            throw_error("'{}' is a crop window: merge the parts first (spangle merge)", path);
        Frame f;
        for (const auto& [name, out] :
             {std::pair{"spangle:scene", &f.scene}, std::pair{"spangle:time", &f.time},
              std::pair{"spangle:shutter", &f.shutter}})
            *out = string_attribute(h, name);
        f.width = dw.max.x - dw.min.x + 1;
        f.height = dw.max.y - dw.min.y + 1;
        f.world_to_ndc = m->value();
        const std::size_t n =
            static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height);
        std::vector<float> gr(n), gg(n), gb(n);
        const std::pair<const char*, std::vector<float>*> chans[] = {
            {"P.X", &f.px}, {"P.Y", &f.py},    {"P.Z", &f.pz},    {"Z", &f.z},
            {"A", &f.a},    {"glints.R", &gr}, {"glints.G", &gg}, {"glints.B", &gb}};
        Imf::FrameBuffer fb;
        for (const auto& [name, buf] : chans) {
            if (!h.channels().findChannel(name))
                throw_error("'{}' has no '{}' channel: render the frames with --layers", path,
                            name);
            buf->assign(n, 0.0f);
            fb.insert(name, Imf::Slice::Make(Imf::FLOAT, buf->data(), dw, sizeof(float),
                                             sizeof(float) * static_cast<std::size_t>(f.width)));
        }
        const auto* xf = h.findTypedAttribute<Imf::FloatVectorAttribute>("spangle:objectToWorld");
        if (xf && h.channels().findChannel("object")) {
            f.object_to_world = xf->value();
            if (const auto* rest =
                    h.findTypedAttribute<Imf::FloatVectorAttribute>("spangle:restPose"))
                f.rest_pose = rest->value();
            const std::pair<const char*, std::vector<float>*> objs[] = {
                {"Pobj.X", &f.ox}, {"Pobj.Y", &f.oy}, {"Pobj.Z", &f.oz}, {"object", &f.object}};
            for (const auto& [name, buf] : objs) {
                if (!h.channels().findChannel(name))
                    throw_error("'{}' has an 'object' channel but no '{}'", path, name);
                buf->assign(n, 0.0f);
                fb.insert(name,
                          Imf::Slice::Make(Imf::FLOAT, buf->data(), dw, sizeof(float),
                                           sizeof(float) * static_cast<std::size_t>(f.width)));
            }
        }
        in.setFrameBuffer(fb);
        in.readPixels(dw.min.y, dw.max.y);
        f.glint.resize(n);
        for (std::size_t i = 0; i < n; ++i)
            f.glint[i] = kRec709Y[0] * gr[i] + kRec709Y[1] * gg[i] + kRec709Y[2] * gb[i];
        return f;
    } catch (const SpangleError&) {
        throw;
    } catch (const std::exception& e) {
        throw_error("cannot read '{}': {}", path, e.what());
    }
}

/** Pixel index of (x, y) in `f`. */
std::size_t pixel(const Frame& f, int x, int y) {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(f.width) +
           static_cast<std::size_t>(x);
}

/** Squared distance between the Pobj of pixel i of `a` and pixel j of `b`. */
float pobj_distance2(const Frame& a, std::size_t i, const Frame& b, std::size_t j) {
    const float dx = b.ox[j] - a.ox[i], dy = b.oy[j] - a.oy[i], dz = b.oz[j] - a.oz[i];
    return dx * dx + dy * dy + dz * dz;
}

/** Where `b` shows the point of a deforming object that pixel i of `a` shows: the pixel of the
 *  same object whose rest position (Pobj) is nearest to it, searched within kDeformSearch
 *  pixels of (bx, by) (where the point was, seen from b's camera). Accepted when it lies within
 *  the pixel's own size in the rest pose (3/4 of the larger distance to its neighbours' rest
 *  positions, measured to the covered neighbours of the same object): the same point up to the
 *  pixel's width. */
bool find_rest_point(const Frame& a, std::size_t i, const Frame& b, int bx, int by, float id,
                     std::size_t& j) {
    constexpr int kDeformSearch = 8;
    float best = INFINITY;
    for (int y = std::max(0, by - kDeformSearch); y <= std::min(b.height - 1, by + kDeformSearch);
         ++y)
        for (int x = std::max(0, bx - kDeformSearch);
             x <= std::min(b.width - 1, bx + kDeformSearch); ++x) {
            const std::size_t c = pixel(b, x, y);
            if (!(b.a[c] > 0.999f) || std::round(b.object[c]) != std::round(id)) continue;
            const float d2 = pobj_distance2(a, i, b, c);
            if (d2 < best) {
                best = d2;
                j = c;
            }
        }
    if (!std::isfinite(best)) return false;
    const int jx = static_cast<int>(j % static_cast<std::size_t>(b.width));
    const int jy = static_cast<int>(j / static_cast<std::size_t>(b.width));
    float spacing2 = 0.0f;
    for (const auto& [dx, dy] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        const int x = jx + dx, y = jy + dy;
        if (x < 0 || y < 0 || x >= b.width || y >= b.height) continue;
        const std::size_t c = pixel(b, x, y);
        if (!(b.a[c] > 0.999f) || std::round(b.object[c]) != std::round(id)) continue;
        spacing2 = std::max(spacing2, pobj_distance2(b, j, b, c));
    }
    // The nearest pixel centre lies within half a pixel's diagonal (0.71 of its width).
    return best <= 0.75f * 0.75f * spacing2;
}

/** The glint-mask threshold when none is given: 4 x the mean glint luminance over the covered
 *  pixels of all frames (1 when none is covered). */
double default_threshold(const std::vector<Frame>& frames) {
    GlintMean mean;
    for (const Frame& f : frames) mean.add(f.glint, f.a);
    return mean.threshold();
}

/** Pixel j of `b` that shows the surface point pixel i of `a` shows, when there is one: the
 *  point carried by its object when the frames say where objects stand (`objects`: a turning
 *  object), found by its rest position on an object that deforms in both, else where it was (a
 *  still one); then projected with b's camera and checked to be the same point. */
bool next_pixel(const Frame& a, const Frame& b, std::size_t i, bool objects, std::size_t& j) {
    Imath::V3f w(a.px[i], a.py[i], a.pz[i]);
    float id = 0.0f;
    bool deforming = false;
    if (objects) {
        id = a.object[i];
        const float k_obj = std::round(id) - 1.0f;
        // A pixel shared by objects has no one number: skipped when its average is not a whole
        // number (halves of objects 1 and 3 average to 2: such a pixel fails the same-point
        // test below instead).
        if (!(std::fabs(id - std::round(id)) < 1e-3f && k_obj >= 0.0f &&
              12.0f * (k_obj + 1.0f) <= static_cast<float>(b.object_to_world.size())))
            return false;
        const auto obj = static_cast<std::size_t>(k_obj);
        // A deforming object's point is searched for from where it was (its world position in
        // this frame); a rigid one's is carried by its placement.
        deforming = a.deforms(obj) && b.deforms(obj);
        const float* m = &b.object_to_world[12 * obj];
        const Imath::V3f q(a.ox[i], a.oy[i], a.oz[i]);
        for (int r = 0; r < 3 && !deforming; ++r)
            w[r] = m[4 * r] * q.x + m[4 * r + 1] * q.y + m[4 * r + 2] * q.z + m[4 * r + 3];
    }
    // Where it lies in the next frame's image (row vectors, divide by w).
    const Imath::V4f p(w.x, w.y, w.z, 1.0f);
    const Imath::V4f q = p * b.world_to_ndc;
    if (!(q.w > 0.0f)) return false;
    const float nx = q.x / q.w, ny = q.y / q.w;
    if (!(nx >= 0.0f && nx < 1.0f && ny >= 0.0f && ny < 1.0f)) return false;
    const auto bx = static_cast<int>(nx * static_cast<float>(b.width));
    const auto by = static_cast<int>(ny * static_cast<float>(b.height));
    j = pixel(b, bx, by);
    if (deforming) {
        // A deforming object's point moved on the object: found by its rest pose.
        if (!find_rest_point(a, i, b, bx, by, id, j)) return false;
    } else {
        if (!(b.a[j] > 0.999f)) return false;
        // The same point (of the same object), not something in front of it.
        if (objects && std::round(b.object[j]) != std::round(id)) return false;
        const float dx = b.px[j] - w.x, dy = b.py[j] - w.y, dz = b.pz[j] - w.z;
        if (!(std::sqrt(dx * dx + dy * dy + dz * dz) <= 0.01f * b.z[j])) return false;
    }
    return true;
}

}  // namespace

FlickerReport measure_flicker(const std::vector<std::string>& paths, double threshold) {
    if (paths.size() < 2) throw_error("flicker needs at least two frames");
    std::vector<Frame> frames;
    frames.reserve(paths.size());
    for (const std::string& p : paths) {
        frames.push_back(read_frame(p));
        if (frames.back().width != frames.front().width ||
            frames.back().height != frames.front().height)
            throw_error("'{}' is {}x{}, '{}' {}x{}: frames of one sequence have one size", p,
                        frames.back().width, frames.back().height, paths.front(),
                        frames.front().width, frames.front().height);
        // Frames of one scene (by its file's name: frames may be rendered from other folders),
        // each moment once: another scene's frames, or a frame given twice, compared as if
        // they were a sequence.
        const Frame& f = frames.back();
        const Frame& first = frames.front();
        if (!f.scene.empty() && !first.scene.empty() &&
            std::filesystem::path(f.scene).filename() !=
                std::filesystem::path(first.scene).filename())
            throw_error(
                "'{}' is a frame of {}, '{}' of {}: frames of one sequence are of one "
                "scene",
                p, f.scene, paths.front(), first.scene);
        for (std::size_t k = 0; k + 1 < frames.size(); ++k)
            if (!f.time.empty() && frames[k].time == f.time)
                throw_error(
                    "'{}' and '{}' are the same moment of the scene ({} s): give each "
                    "frame of the sequence once, in order",
                    paths[k], p, f.time);
    }
    FlickerReport rep;
    // In time order: pairs are consecutive moments (a shell's glob gives -001 -002 -003 0000
    // for frames -3..0, which measured 0.31 persistence where the sequence has 0.38).
    if (std::all_of(frames.begin(), frames.end(), [](const Frame& f) { return !f.time.empty(); })) {
        std::vector<std::size_t> order(frames.size());
        for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
        const auto seconds = [](const Frame& f) { return std::strtod(f.time.c_str(), nullptr); };
        std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
            return seconds(frames[x]) < seconds(frames[y]);
        });
        for (std::size_t k = 0; k < order.size(); ++k)
            rep.reordered = rep.reordered || order[k] != k;
        if (rep.reordered) {
            std::vector<Frame> sorted;
            sorted.reserve(frames.size());
            for (const std::size_t k : order) sorted.push_back(std::move(frames[k]));
            frames = std::move(sorted);
        }
        // The steps between consecutive frames (unequal: a frame is missing).
        if (frames.size() > 2) {
            rep.step_min = std::numeric_limits<double>::infinity();
            for (std::size_t k = 0; k + 1 < frames.size(); ++k) {
                const double step = seconds(frames[k + 1]) - seconds(frames[k]);
                rep.step_min = std::min(rep.step_min, step);
                rep.step_max = std::max(rep.step_max, step);
            }
        }
    }
    for (const Frame& f : frames)
        for (std::size_t i = 0; i < f.glint.size() && i < f.a.size(); ++i)
            rep.nonfinite_glints += f.a[i] > 0.999f && !std::isfinite(f.glint[i]) ? 1u : 0u;
    rep.blurred = std::count_if(frames.begin(), frames.end(),
                                [](const Frame& f) { return !f.shutter.empty(); });
    rep.threshold = threshold > 0.0 ? threshold : default_threshold(frames);
    threshold = rep.threshold;
    std::vector<std::vector<uint8_t>> masks;
    for (const Frame& f : frames)
        masks.push_back(glint_pixels(f.glint, f.width, f.height, threshold));
    double diff = 0.0, coverage = 0.0, rel_num = 0.0, rel_den = 0.0, kept = 0.0, glints = 0.0;
    for (std::size_t k = 0; k + 1 < frames.size(); ++k) {
        const Frame& a = frames[k];
        const Frame& b = frames[k + 1];
        const bool objects = a.has_objects() && b.has_objects();
        rep.by_objects = rep.by_objects || objects;
        rep.by_rest = rep.by_rest || (objects && std::any_of(a.rest_pose.begin(), a.rest_pose.end(),
                                                             [](float v) { return v > 0.5f; }));
        ++rep.pairs;
        for (int y = 0; y < a.height; ++y)
            for (int x = 0; x < a.width; ++x) {
                const std::size_t i =
                    static_cast<std::size_t>(y) * static_cast<std::size_t>(a.width) +
                    static_cast<std::size_t>(x);
                if (!(a.a[i] > 0.999f)) continue;  // only pixels wholly on a surface
                std::size_t j = 0;
                if (!next_pixel(a, b, i, objects, j)) continue;
                const double ga = a.glint[i], gb = b.glint[j];
                if (!std::isfinite(ga) || !std::isfinite(gb)) continue;
                rep.pixels += 1.0;
                const double ma = masks[k][i], mb = masks[k + 1][j];
                diff += std::fabs(ma - mb);
                coverage += 0.5 * (ma + mb);
                rel_num += std::fabs(ga - gb);
                rel_den += 0.5 * (ga + gb);
                if (ma > 0.0) {
                    glints += 1.0;
                    kept += mb;
                }
            }
    }
    if (rep.pixels > 0.0) {
        rep.mask_flicker = diff / rep.pixels;
        rep.mask_fraction = coverage / rep.pixels;
    }
    rep.relative_difference = rel_den > 0.0 ? rel_num / rel_den : 0.0;
    rep.mask_persistence = glints > 0.0 ? kept / glints : 0.0;
    return rep;
}

void GlintMean::add(const std::vector<float>& glint, const std::vector<float>& alpha) {
    for (std::size_t i = 0; i < glint.size() && i < alpha.size(); ++i)
        if (alpha[i] > 0.999f && std::isfinite(glint[i])) {
            sum += static_cast<double>(glint[i]);
            count += 1.0;
        }
}

std::vector<uint8_t> glint_pixels(const std::vector<float>& glint, int width, int height,
                                  double threshold) {
    std::vector<uint8_t> m(glint.size(), 0);
    const auto at = [&](int x, int y) {
        return glint[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                     static_cast<std::size_t>(x)];
    };
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const double g = at(x, y);
            if (!(g > threshold)) continue;
            double sum = 0.0;
            int n = 0;
            for (int yy = std::max(y - 2, 0); yy <= std::min(y + 2, height - 1); ++yy)
                for (int xx = std::max(x - 2, 0); xx <= std::min(x + 2, width - 1); ++xx)
                    if (const float v = at(xx, yy); std::isfinite(v)) {
                        sum += static_cast<double>(v);
                        ++n;
                    }
            m[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
              static_cast<std::size_t>(x)] = n > 0 && g > 3.0 * sum / n ? 1 : 0;
        }
    return m;
}

GlintsKept glints_kept(const std::vector<float>& image, const std::vector<float>& reference,
                       const std::vector<uint8_t>& glints, int width, int height) {
    const auto n = static_cast<std::size_t>(std::max(width, 0)) *
                   static_cast<std::size_t>(std::max(height, 0));
    if (image.size() != n || reference.size() != n || glints.size() != n)
        throw_error("glints_kept: {} image, {} reference and {} mask values for {}x{} pixels",
                    image.size(), reference.size(), glints.size(), width, height);
    GlintsKept k;
    const auto index = [&](int x, int y) {
        return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
               static_cast<std::size_t>(x);
    };
    const auto contrast = [&](const std::vector<float>& lum, int x, int y) {
        double ring = 0.0;
        for (int yy = y - 1; yy <= y + 1; ++yy)
            for (int xx = x - 1; xx <= x + 1; ++xx)
                if (xx != x || yy != y) ring += static_cast<double>(lum[index(xx, yy)]);
        return static_cast<double>(lum[index(x, y)]) - ring / 8.0;
    };
    std::vector<double> ratios;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            if (!glints[index(x, y)]) continue;
            ++k.found;
            if (x == 0 || y == 0 || x == width - 1 || y == height - 1) {
                ++k.border;
                continue;
            }
            const double ref = contrast(reference, x, y);
            // A tenth of the pixel: a glint hardly standing out has no ratio worth measuring.
            if (!std::isfinite(ref) || !(ref > 0.1 * static_cast<double>(reference[index(x, y)]))) {
                ++k.faint;
                continue;
            }
            ++k.measured;
            double r = contrast(image, x, y) / ref;
            if (!std::isfinite(r)) r = 0.0;
            k.kept += r >= 0.5 ? 1u : 0u;
            ratios.push_back(r);
        }
    if (!ratios.empty()) {
        const std::size_t mid = ratios.size() / 2;
        std::nth_element(ratios.begin(), ratios.begin() + static_cast<std::ptrdiff_t>(mid),
                         ratios.end());
        k.median_ratio = ratios[mid];
        if (ratios.size() % 2 == 0) {
            const double below = *std::max_element(
                ratios.begin(), ratios.begin() + static_cast<std::ptrdiff_t>(mid));
            k.median_ratio = 0.5 * (k.median_ratio + below);
        }
    }
    return k;
}

}  // namespace spangle
