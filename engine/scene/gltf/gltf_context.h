#pragma once
// What the parts of the glTF reader share: the document tinygltf read, where its JSON says what,
// the description being filled, and the warnings given so far (one per kind of thing dropped).
// Internal to engine/scene/gltf/.

#include <tiny_gltf.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "scene/gltf/json_locations.h"
#include "scene/scene_description.h"

namespace spangle::gltf {

/** One read glTF file and the scene it becomes. */
struct Context {
    std::string path;                                ///< the .gltf or .glb
    std::filesystem::path dir;                       ///< its folder (relative URIs)
    tinygltf::Model model;                           ///< what tinygltf read
    JsonLocations json;                              ///< places of the JSON's values
    std::vector<std::vector<unsigned char>> images;  ///< each image's encoded bytes, or empty
    /** Buffers that only stand in for EXT_meshopt_compression's decoded data (its "fallback"
     *  buffers, and buffers without a uri that compressed views decode into): they hold no
     *  bytes; decompress() points every view into them at decoded bytes of its own. */
    std::set<int> placeholder_buffers;
    /** A .glb's BIN chunk: its length in bytes (nullopt: none, or not a .glb). */
    std::optional<std::size_t> bin_chunk;
    /** The file's own counts of buffers and views, before decompress() added the decoded
     *  ones (indices in the extensions are checked against these). */
    std::size_t file_buffers = 0, file_views = 0;
    /** EXT_mesh_gpu_instancing objects made so far (instances x primitives), bounded. */
    std::size_t instance_objects = 0;
    SceneDescription* scene = nullptr;  ///< what the reader fills
    /** Per kind of warning: its note's index in scene->notes and the other places it applies
     *  to ("line:col", each once). */
    std::map<std::string, std::pair<std::size_t, std::vector<std::string>>> repeats;
    std::map<int, std::string> material_names;  ///< glTF material -> Spangle name (-1: default)
    std::map<int, std::optional<EmissionDesc>> emissions;  ///< glTF material -> its emission
    std::map<std::pair<int, int>, std::shared_ptr<const TriangleMesh>>
        meshes;  ///< (mesh, primitive)
    /** Still shapes made by skins and morph targets (gltf_deform.cpp), by primitive, skin and
     *  weights: nodes that draw one primitive alike share one mesh. */
    std::map<std::string, std::shared_ptr<const TriangleMesh>> posed;
    /** Meshes with their winding reversed, for mirrored nodes (gltf_mirror.cpp), by the mesh they
     *  turn: every mirrored node drawing one mesh shares one copy. */
    std::map<const TriangleMesh*, std::shared_ptr<const TriangleMesh>> reversed;
    std::map<int, std::string> image_files;  ///< glTF image -> file ("" = none)
    std::string texture_cache;               ///< --texture-cache (empty: the default folders)
    /** The uv set of the material being read (uv_set_of); its textures reading another are
     *  noted. */
    int uv_set = 0;
    /** The material being read colours primitives with COLOR_0 (has_vertex_colors). */
    bool vertex_colors = false;

    /** Where the value at JSON path `p` is written. */
    FileLoc at(const std::string& p) const { return json.at(p); }

    /** Adds "file:line:col: message" to the scene's notes, once per `kind`: a warning names
     *  the first place it applies to; finish_notes() adds how many more there are and where. */
    void note(const std::string& kind, const FileLoc& where, const std::string& message) {
        const auto [it, first] = repeats.try_emplace(kind);
        if (!first) {
            // Said once; the other places are counted and the first few listed (an artist with
            // 80 materials could not tell which lost what).
            if (where.line > 0) {
                const std::string place = fmt::format("{}:{}", where.line, where.column);
                if (std::find(it->second.second.begin(), it->second.second.end(), place) ==
                    it->second.second.end())
                    it->second.second.push_back(place);
            }
            return;
        }
        it->second.first = scene->notes.size();
        scene->notes.push_back(fmt::format("{}: {}", where.str(), message));
    }
    /** Adds to each note said at several places how many more and where (the first five). */
    void finish_notes() {
        for (const auto& [kind, r] : repeats) {
            const std::vector<std::string>& more = r.second;
            if (more.empty() || r.first >= scene->notes.size()) continue;
            std::string places;
            for (std::size_t i = 0; i < std::min<std::size_t>(more.size(), 5); ++i) {
                if (i > 0) places += ", ";
                places += more[i];
            }
            scene->notes[r.first] +=
                fmt::format(" (and {} more place{}: {}{})", more.size(),
                            more.size() == 1 ? "" : "s", places, more.size() > 5 ? ", ..." : "");
        }
        repeats.clear();
    }
};

/** A JSON number as a float: out of a float's range it is +-infinity (a plain conversion of
 *  such a double is undefined behaviour), so that the finiteness checks catch it. */
inline float narrow(double v) {
    if (v > 3.4028234663852886e38) return std::numeric_limits<float>::infinity();
    if (v < -3.4028234663852886e38) return -std::numeric_limits<float>::infinity();
    return static_cast<float>(v);
}

/** Throws at `p` unless 0 <= index < size: "<what> N does not exist (the file has M)". */
void check_index(const Context& ctx, const std::string& p, int index, std::size_t size,
                 const char* what);

}  // namespace spangle::gltf
