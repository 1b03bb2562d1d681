#include "scene/gltf/gltf_schema.h"

#include <algorithm>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace spangle::gltf {
namespace {

/** The kinds glTF 2.0's schema gives the properties Spangle reads (a '*' is any one path
 *  segment: an index or a name): tinygltf skips a value of another kind without a word (a mesh's
 *  primitives written as an object drew nothing, "no node draws a mesh" at 1:1; a
 *  pbrMetallicRoughness written as an array left the material glTF's default white metal). */
struct KindRule {
    const char* pattern;
    char kind;
};
constexpr KindRule kKindRules[] = {
    {"asset", 'o'},
    {"scene", 'n'},
    {"scenes", 'a'},
    {"scenes/*/nodes", 'a'},
    {"nodes", 'a'},
    {"nodes/*/children", 'a'},
    {"nodes/*/mesh", 'n'},
    {"nodes/*/camera", 'n'},
    {"nodes/*/skin", 'n'},
    {"nodes/*/matrix", 'a'},
    {"nodes/*/translation", 'a'},
    {"nodes/*/rotation", 'a'},
    {"nodes/*/scale", 'a'},
    {"meshes", 'a'},
    {"meshes/*/primitives", 'a'},
    {"meshes/*/primitives/*/attributes", 'o'},
    {"meshes/*/primitives/*/attributes/*", 'n'},
    {"meshes/*/primitives/*/indices", 'n'},
    {"meshes/*/primitives/*/material", 'n'},
    {"meshes/*/primitives/*/mode", 'n'},
    {"meshes/*/primitives/*/targets", 'a'},
    {"materials", 'a'},
    {"materials/*/pbrMetallicRoughness", 'o'},
    {"materials/*/pbrMetallicRoughness/baseColorFactor", 'a'},
    {"materials/*/pbrMetallicRoughness/metallicFactor", 'n'},
    {"materials/*/pbrMetallicRoughness/roughnessFactor", 'n'},
    {"materials/*/pbrMetallicRoughness/baseColorTexture", 'o'},
    {"materials/*/pbrMetallicRoughness/metallicRoughnessTexture", 'o'},
    {"materials/*/normalTexture", 'o'},
    {"materials/*/occlusionTexture", 'o'},
    {"materials/*/emissiveTexture", 'o'},
    {"materials/*/pbrMetallicRoughness/*/index", 'n'},
    {"materials/*/pbrMetallicRoughness/*/texCoord", 'n'},
    {"materials/*/*/index", 'n'},
    {"materials/*/*/texCoord", 'n'},
    {"materials/*/normalTexture/scale", 'n'},
    {"materials/*/occlusionTexture/strength", 'n'},
    {"materials/*/emissiveFactor", 'a'},
    {"materials/*/alphaMode", 's'},
    {"materials/*/alphaCutoff", 'n'},
    {"materials/*/doubleSided", 'b'},
    {"textures", 'a'},
    {"textures/*/source", 'n'},
    {"textures/*/sampler", 'n'},
    {"images", 'a'},
    {"samplers", 'a'},
    {"cameras", 'a'},
    {"cameras/*/perspective", 'o'},
    {"cameras/*/orthographic", 'o'},
};

/** Whether `path` matches `pattern` segment by segment ('*' matches any one). */
bool path_matches(std::string_view path, std::string_view pattern) {
    for (;;) {
        const std::size_t ps = path.find('/'), qs = pattern.find('/');
        const std::string_view p = path.substr(0, ps), q = pattern.substr(0, qs);
        if (q != "*" && q != p) return false;
        if (ps == std::string_view::npos || qs == std::string_view::npos)
            return ps == std::string_view::npos && qs == std::string_view::npos;
        path.remove_prefix(ps + 1);
        pattern.remove_prefix(qs + 1);
    }
}

}  // namespace

/** Refuses a property of another kind than glTF's schema gives it (kKindRules), at its place;
 *  null stands for absent (tinygltf reads it so). The first in the file is said. */
void check_kinds(const Context& ctx) {
    const auto words = [](char k) {
        switch (k) {
            case 'o':
                return "an object";
            case 'a':
                return "an array";
            case 's':
                return "a string";
            case 'n':
                return "a number";
            case 'b':
                return "true or false";
            default:
                return "null";
        }
    };
    std::optional<std::pair<FileLoc, std::string>> first;
    ctx.json.for_each_kind([&](const std::string& path, char kind) {
        if (kind == 'z') return;
        for (const KindRule& r : kKindRules) {
            if (!path_matches(path, r.pattern)) continue;
            if (kind == r.kind) return;
            const FileLoc at = ctx.at(path);
            if (!first ||
                std::pair{at.line, at.column} < std::pair{first->first.line, first->first.column})
                first = {at,
                         fmt::format("'{}' must be {} (glTF 2.0), got {}",
                                     path.substr(path.rfind('/') + 1), words(r.kind), words(kind))};
            return;
        }
    });
    if (first) throw_error(first->first, "{}", first->second);
}

/** A material's texture index written negative: tinygltf reads -1 as no texture at all (a
 *  baseColorTexture of index -1 rendered untextured without a word; index 5 of 3 textures is an
 *  error). Sorted by place, so the first written is said. */
void check_texture_indices(const Context& ctx) {
    std::vector<std::pair<std::string, std::string>> negative;
    for (const auto& [path, text] : ctx.json.scalars())
        if (path.starts_with("materials/") && path.ends_with("/index") && text.starts_with('-'))
            negative.emplace_back(path, text);
    if (negative.empty()) return;
    std::sort(negative.begin(), negative.end());
    std::size_t textures = 0;
    while (ctx.json.has(fmt::format("textures/{}", textures))) ++textures;
    const std::string where = negative[0].first.substr(0, negative[0].first.size() - 6);
    throw_error(ctx.at(where),
                "texture {} does not exist (the file has {}): 'index' names one of "
                "the file's textures, from 0",
                negative[0].second, textures);
}

}  // namespace spangle::gltf
