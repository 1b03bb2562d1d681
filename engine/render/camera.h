#pragma once
// The camera: perspective or orthographic (pinhole or thin lens) or an equirectangular panorama, a
// pixel filter sampled by importance (each sample lands where the filter puts it and weighs 1;
// Ernst et al. 2006), and ray differentials towards the neighbouring pixels for texture and flake
// footprints.

#include <array>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/pixel_filter.h"

namespace spangle {

struct Camera;  // scene/components.h

/** A 1D filter tabulated for sampling: piecewise constant over kBins bins on [-radius, radius].
 *  The radius stretches the filter: box 0.5, Gaussian 1.5 (sigma = radius / 3: 0.5) and
 *  Blackman-Harris 2 pixels by default (radius 0). */
class FilterSampler {
public:
    explicit FilterSampler(FilterKind kind, float radius = 0.0f);
    /** Offset from the pixel centre, in pixels, distributed as the filter. */
    float sample(float u) const;
    float radius() const { return radius_; }

    static constexpr int kBins = 256;      ///< bins of the tabulated filter
    static constexpr int kInverse = 4096;  ///< entries of the inverse-CDF table used by sample()

private:
    float radius_;
    std::array<float, kInverse + 1> inverse_{};  ///< offset at u = i / kInverse
};

/** A ray with its two differential rays (towards +x and +y pixel neighbours). */
struct RayDifferential {
    Vec3 o, d;        ///< the ray; d unit length
    Vec3 dx_o, dx_d;  ///< origin and direction of the ray one pixel to the right
    Vec3 dy_o, dy_d;  ///< and one pixel down
};

/** The camera of a frame. */
/** The camera as the EXR header's standard matrices describe it (row vectors, p' = p M, as in
 *  Imath and OpenEXR's ImfStandardAttributes.h), row-major. worldToCamera: to a left-handed
 *  camera space, x right, y up, z along the view. worldToNDC: to homogeneous image coordinates,
 *  (0, 0) the top-left and (1, 1) the bottom-right corner of the image after dividing by w. */
struct CameraMatrices {
    std::array<float, 16> world_to_camera{}, world_to_ndc{};
};

/** How the image lies on the film beyond its field of view: pbrt's conventions. The defaults are
 *  Spangle's own (a right-handed view, the image centred on it) and give the very same rays. */
struct FilmLayout {
    /** The image's x axis runs along up x forward instead of forward x up: pbrt's left-handed
     *  camera space, whose images are the mirror image of a right-handed camera's. */
    bool mirror = false;
    /** The image's x0, x1, y0, y1 on the plane at distance 1, in units of tan(fov / 2) (pbrt's
     *  screen window; y up); all 0 = [-aspect, aspect] x [-1, 1]. */
    std::array<float, 4> screen{};
    /** fov spans the shorter side (pbrt's convention): on an image taller than wide it is the
     *  horizontal field of view. Without a screen window only. */
    bool fov_shorter = false;
    /** > 0: an orthographic camera whose view is this many scene units tall (or along its
     *  shorter side, with fov_shorter). It takes the place of tan(fov / 2) at distance 1: the
     *  screen window's unit is half of it. Rays leave the film plane through the position, all
     *  along the view (through the lens towards the plane in focus, with an aperture). */
    float ortho_height = 0.0f;
    /** An equirectangular panorama: the direction at film (x, y) has azimuth 360 (x / width -
     *  1/2) degrees from the view (positive to the right) and elevation 180 (1/2 - y / height)
     *  degrees; fov, the screen window and the lens do not apply. */
    bool equirect = false;
};

class CameraModel {
public:
    /** fov_deg vertical; aperture = lens radius in metres (0 = pinhole); focus_distance > 0. */
    CameraModel(Vec3 position, Vec3 look_at, Vec3 up, float fov_deg, float aperture,
                float focus_distance, uint32_t width, uint32_t height,
                const FilmLayout& layout = {});
    /** The model of a scene's Camera component on a width x height image, every field of it. */
    static CameraModel of(const Camera& c, uint32_t width, uint32_t height);

    /** The ray through film position (fx, fy) in pixels (0..width, 0..height, y down), with lens
     *  sample (lu, lv) in [0, 1)^2. */
    RayDifferential generate(float fx, float fy, float lu, float lv) const;

    /** World-space width of one pixel at distance 1 along the view direction (for footprints);
     *  0 for an orthographic camera. */
    float pixel_angle() const { return ortho_ ? 0.0f : pixel_angle_; }
    /** World-space width of one pixel at the camera: an orthographic camera's, else 0. */
    float pixel_width() const { return ortho_ ? pixel_angle_ : 0.0f; }
    /** The EXR header's worldToNDC exists: no projection onto a plane makes a panorama. */
    bool projects_to_ndc() const { return !equirect_; }
    /** The camera's frame and projection as the EXR header's matrices. */
    CameraMatrices matrices() const;

private:
    /** On the plane at distance 1 (perspective), or forward plus the offset on the film plane
     *  from the position (orthographic). */
    Vec3 point_on_film(float fx, float fy) const;
    bool has_screen() const;  ///< a screen window was given

    Vec3 origin_, forward_, right_, up_;
    float tan_half_, aspect_;
    std::array<float, 4> screen_;  ///< all 0: the default window
    float aperture_, focus_;
    float width_, height_;
    float pixel_angle_;  ///< a pixel's width at distance 1, or on the film (orthographic)
    bool ortho_ = false;
    bool equirect_ = false;
};

}  // namespace spangle
