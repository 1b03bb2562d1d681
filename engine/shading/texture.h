#pragma once
// Image textures. A texture file is converted once into what lookups need -- a tiled, mip-mapped
// half-float OpenEXR whose colours are already in the working space -- and kept in a cache
// directory keyed by the source file's identity, its colour space, the working space and the
// config, so a second render (or a reload) opens it straight away. Lookups go through
// OpenImageIO's TextureSystem (in the dlopen'ed OpenImageIO module: a scene without textures
// never loads it), filtered by the footprint the ray differentials give, with a tile cache
// bounded in memory.

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "color/color_config.h"
#include "color/image_io.h"
#include "core/error.h"
#include "core/log.h"
#include "scene/components.h"

namespace spangle {

/** Where converted textures go and how much memory the tile cache may hold. */
struct TextureSettings {
    std::string cache_dir;      ///< empty: $SPANGLE_TEXTURE_CACHE, else ~/.cache/spangle/textures
    uint32_t memory_mb = 1024;  ///< tile cache bound
};

/** The cache directories to try, in order: the one `settings` or $SPANGLE_TEXTURE_CACHE
 *  chooses alone; else the user's ($XDG_CACHE_HOME or ~/.cache /spangle/textures), then the
 *  temporary directory's spangle-textures-UID for when the user's cannot be written. */
std::vector<std::string> texture_cache_dirs(const TextureSettings& settings);

/** One opened texture: the converted file and its handle in the texture system. */
struct Texture {
    std::string source;     ///< the scene's file
    std::string converted;  ///< the cached working-space texture
    int channels = 0;       ///< channels of the converted file (1 to 4)
    void* handle = nullptr;
};

/** A batch of lookups: texture coordinates after the uv transform (s right, t down, as
 *  OpenImageIO has them) and their screen-space derivatives. */
struct TextureQuery {
    std::vector<float> s, t, dsdx, dtdx, dsdy, dtdy;
    void resize(std::size_t n) {
        for (auto* a : {&s, &t, &dsdx, &dtdx, &dsdy, &dtdy}) a->resize(n);
    }
};

/** The image coordinates (s right, t down) of surface uv (u, v) through the texture's uv
 *  transform (v runs up in uv, t down in the image). */
inline void texture_st(const TextureRef& ref, float u, float v, float& s, float& t) {
    const float* m = ref.uv;
    s = m[0] * u + m[1] * v + m[2];
    t = 1.0f - (m[3] * u + m[4] * v + m[5]);
}

/** Fills q from surface uvs and their derivatives through the texture's uv transform (v up in
 *  uv, t down in the image). */
void texture_coordinates(const TextureRef& ref, const float* u, const float* v, const float* dudx,
                         const float* dudy, const float* dvdx, const float* dvdy, std::size_t n,
                         TextureQuery& q);

/** Opens and looks up textures for one scene (or one watch session). Lookups are thread-safe. */
class TextureService {
public:
    TextureService(const ColorConfig& color, const Logger& log, TextureSettings settings = {});
    ~TextureService();
    TextureService(const TextureService&) = delete;
    TextureService& operator=(const TextureService&) = delete;

    /** The texture for `ref` as a colour (`color`: its values converted from ref.space, or from
     *  the file type's usual space when none is given -- srgb_texture for 8-bit formats,
     *  lin_rec709 for EXR and HDR) or as data (no conversion unless ref.space names a space).
     *  Converts and caches on first use. Throws SpangleError at `loc`. */
    std::shared_ptr<const Texture> open(const TextureRef& ref, bool color, const FileLoc& loc);

    /** `channels` values per query into out (and their s and t derivatives when ds/dt are not
     *  null), wrapped and filtered as `ref` says. A texture with fewer channels repeats its last
     *  one; more are dropped. */
    void lookup(const Texture& tex, const TextureRef& ref, const TextureQuery& q, std::size_t n,
                int channels, float* out, float* ds = nullptr, float* dt = nullptr) const;

    const TextureSettings& settings() const { return settings_; }

private:
    void* system();  ///< the OpenImageIO texture system, made on first use

    const ColorConfig& color_;
    const Logger& log_;
    TextureSettings settings_;
    bool fallback_said_ = false;  ///< the unwritable-cache warning was given
    const OiioTextureApi* api_ = nullptr;
    void* system_ = nullptr;
    std::mutex mutex_;
    std::vector<std::pair<std::string, std::shared_ptr<const Texture>>> opened_;
};

}  // namespace spangle
