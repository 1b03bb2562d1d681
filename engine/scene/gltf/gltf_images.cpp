// glTF images as files for the texture system: a URI names a file beside the scene; embedded
// images (data URIs, buffer views of a .glb) are written once into the user's cache folder,
// named by a hash of their bytes, so that a second read finds the same file unchanged (and the
// texture cache, keyed by the file's identity, keeps its converted texture).

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>

#include "core/files.h"
#include "core/hash.h"
#include "core/text.h"
#include "scene/gltf/gltf_parts.h"
#include "scene/gltf/gltf_reader.h"

namespace spangle::gltf {
namespace {

namespace fs = std::filesystem;

/** A URI's percent escapes decoded (glTF 2.0, 2.8: URIs are RFC 3986). */
std::string percent_decoded(const std::string& uri) {
    std::string out;
    for (std::size_t i = 0; i < uri.size(); ++i) {
        // (%00 is kept as written: a NUL cut the path short, so "a%00b.bin" was looked for
        // as "a" and said missing as a name cut at the NUL.)
        if (uri[i] == '%' && i + 2 < uri.size() &&
            std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
            std::isxdigit(static_cast<unsigned char>(uri[i + 2])) &&
            uri.compare(i, 3, "%00") != 0) {
            out += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

/** The file name extension of encoded image bytes, from their signature; empty if unknown. */
std::string image_extension(const std::vector<unsigned char>& b) {
    if (b.size() >= 8 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G') return ".png";
    if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return ".jpg";
    if (b.size() >= 12 && b[0] == 'R' && b[1] == 'I' && b[2] == 'F' && b[3] == 'F' && b[8] == 'W' &&
        b[9] == 'E' && b[10] == 'B' && b[11] == 'P')
        return ".webp";
    return "";
}

/** 128 bits of hash of the bytes, as 32 hexadecimal digits. */
std::string bytes_hash(const std::vector<unsigned char>& b) {
    uint64_t h1 = hash2(0x676c5446ull, b.size()), h2 = 0xcbf29ce484222325ull;
    for (std::size_t i = 0; i < b.size(); i += 8) {
        uint64_t w = 0;
        for (std::size_t k = 0; k < 8 && i + k < b.size(); ++k)
            w |= static_cast<uint64_t>(b[i + k]) << (8 * k);
        h1 = hash2(h1, w);
    }
    for (unsigned char c : b) h2 = (h2 ^ c) * 0x100000001b3ull;  // FNV-1a
    return fmt::format("{:016x}{:016x}", h1, mix64(h2));
}

/** Writes `bytes` to `file` unless a file of that name and size is there (named by the hash
 *  of its content, it is the same image); through a temporary file renamed into place. Returns
 *  why it could not, or an empty string. */
std::string write_once(const fs::path& file, const std::vector<unsigned char>& bytes) {
    std::error_code ec;
    if (fs::is_regular_file(file, ec) && fs::file_size(file, ec) == bytes.size()) return {};
    fs::create_directories(file.parent_path(), ec);
    if (ec) return fmt::format("cannot create {}: {}", file.parent_path().string(), ec.message());
    const fs::path tmp = file.string() + fmt::format(".{}.tmp", ::getpid());
    {
        std::ofstream out(tmp, std::ios::binary);
        if (!out) return fmt::format("cannot write {}: {}", tmp.string(), std::strerror(errno));
        out.write(reinterpret_cast<const char*>(bytes.data()),
                  static_cast<std::streamsize>(bytes.size()));
        out.close();
        if (!out) {
            const std::string why = std::strerror(errno);
            fs::remove(tmp, ec);
            return fmt::format("cannot write {}: {}", tmp.string(), why);
        }
    }
    fs::rename(tmp, file, ec);
    if (ec) {
        const std::string why = ec.message();
        fs::remove(tmp, ec);
        return fmt::format("cannot write {}: {}", file.string(), why);
    }
    return {};
}

}  // namespace

std::vector<std::string> embedded_image_dirs(const std::string& texture_cache) {
    std::vector<std::string> dirs;
    if (!texture_cache.empty()) {
        dirs.push_back((fs::path(texture_cache) / "gltf-images").string());
    } else if (const char* env = std::getenv("SPANGLE_TEXTURE_CACHE"); env && *env) {
        dirs.push_back((fs::path(env) / "gltf-images").string());
    } else if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
        dirs.push_back((fs::path(xdg) / "spangle" / "gltf-images").string());
    } else if (const char* home = std::getenv("HOME"); home && *home) {
        dirs.push_back((fs::path(home) / ".cache" / "spangle" / "gltf-images").string());
    }
    dirs.push_back(
        (fs::temp_directory_path() / fmt::format("spangle-gltf-images-{}", ::getuid())).string());
    return dirs;
}

std::string slashed_where_missing(const std::string& path) {
    std::error_code ec;
    if (path.find('\\') == std::string::npos || fs::exists(path, ec)) return path;
    std::string slashed = path;
    std::replace(slashed.begin(), slashed.end(), '\\', '/');
    return fs::exists(slashed, ec) ? slashed : path;
}

UriTarget uri_target(const Context& ctx, const std::string& uri) {
    UriTarget t;
    const std::size_t colon = uri.find("://");
    const std::string scheme = colon == std::string::npos ? "" : uri.substr(0, colon);
    const bool has_scheme =
        !scheme.empty() && std::all_of(scheme.begin(), scheme.end(), [](char c) {
            return std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.';
        });
    if (!has_scheme) {
        t.path =
            slashed_where_missing((ctx.dir / percent_decoded(uri)).lexically_normal().string());
        return t;
    }
    t.scheme = scheme;
    // (Schemes are case-insensitive, RFC 3986 3.1: FILE:///x names a file as file:///x does.)
    if (ascii_lower(scheme) != "file") return t;
    std::string host, rest;
    if (!split_file_uri(std::string_view(uri).substr(colon + 3), host, rest)) {
        t.host = host;
        return t;
    }
    t.path = (ctx.dir / percent_decoded(rest)).lexically_normal().string();
    return t;
}

bool split_file_uri(std::string_view rest, std::string& host, std::string& path) {
    // file://host/path or file:///path (a host other than localhost is not this machine's).
    const std::size_t slash = rest.find('/');
    host = std::string(rest.substr(0, slash));
    path = slash == std::string_view::npos ? std::string() : std::string(rest.substr(slash));
    return host.empty() || host == "localhost";
}

std::string image_file(Context& ctx, int image, const std::string& ref) {
    check_index(ctx, ref, image, ctx.model.images.size(), "image");
    if (auto it = ctx.image_files.find(image); it != ctx.image_files.end()) return it->second;
    std::string& out = ctx.image_files[image];
    const tinygltf::Image& img = ctx.model.images[static_cast<std::size_t>(image)];
    const std::string ip = fmt::format("images/{}", image);
    if (!img.uri.empty() && img.uri.rfind("data:", 0) != 0) {
        // A URI with a scheme: file:// names a path on this machine; others (https://) are not
        // fetched (they were looked for as relative paths: ".../file:/tmp/...").
        const UriTarget target = uri_target(ctx, img.uri);
        if (target.path.empty() && target.host.empty()) {
            ctx.note("remote image " + img.uri, ctx.at(ip + "/uri"),
                     fmt::format("image URI '{}' is not fetched (Spangle reads files, not {} "
                                 "URIs): the textures using it are dropped, their factors stand in",
                                 img.uri, target.scheme));
            return out;
        }
        if (target.path.empty()) {
            ctx.note("remote image " + img.uri, ctx.at(ip + "/uri"),
                     fmt::format("image URI '{}' names host '{}', not this machine: the "
                                 "textures using it are dropped, their factors stand in",
                                 img.uri, target.host));
            return out;
        }
        const fs::path file = target.path;
        std::error_code ec;
        if (fs::is_regular_file(file, ec)) return out = file.string();
        ctx.note("missing image " + file.string(), ctx.at(ip + "/uri"),
                 fmt::format("image file '{}' not found (looked for {}): the textures using it "
                             "are dropped, their factors stand in",
                             img.uri, absolute_path(file.string())));
        return out;
    }
    const std::vector<unsigned char>& bytes = ctx.images[static_cast<std::size_t>(image)];
    const std::string ext = image_extension(bytes);
    if (ext.empty()) {
        ctx.note(
            fmt::format("image {}", image), ctx.at(ip),
            fmt::format("image {} is not a PNG, JPEG or WebP image ({}): the textures using it are "
                        "dropped, their factors stand in",
                        image, bytes.empty() ? "no bytes" : img.mimeType));
        return out;
    }
    return out = cached_image_file(ctx, bytes, ext, ip);
}

std::string cached_image_file(Context& ctx, const std::vector<unsigned char>& bytes,
                              const std::string& ext, const std::string& ref) {
    // The first folder that takes it (a farm node's read-only home: the temporary folder, as
    // for converted textures; the render failed).
    const std::vector<std::string> dirs = embedded_image_dirs(ctx.texture_cache);
    std::vector<std::string> failures;
    for (const std::string& dir : dirs) {
        const fs::path file = fs::path(dir) / (bytes_hash(bytes) + ext);
        const std::string why = write_once(file, bytes);
        if (why.empty()) {
            if (!failures.empty())
                ctx.note("embedded image folder", ctx.at(ref),
                         fmt::format("{}: embedded images are written to {} instead (give "
                                     "--texture-cache a folder that can be written)",
                                     failures.front(), dir));
            return file.string();
        }
        failures.push_back(why);
    }
    throw_error(ctx.at(ref),
                "cannot write the embedded image anywhere ({}): give --texture-cache a "
                "folder that can be written",
                fmt::join(failures, "; "));
}

}  // namespace spangle::gltf

namespace spangle {

std::vector<std::string> gltf_embedded_image_dirs(const std::string& texture_cache) {
    return gltf::embedded_image_dirs(texture_cache);
}

}  // namespace spangle
