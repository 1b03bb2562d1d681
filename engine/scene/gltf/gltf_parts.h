#pragma once
// The parts of the glTF reader, each in its own file, over the shared Context. Internal to
// engine/scene/gltf/.

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "scene/gltf/gltf_context.h"

namespace spangle::gltf {

/** gltf_document.cpp: reads ctx.path (a .gltf with its buffers, or a .glb) into ctx.model and
 *  ctx.json, the images' encoded bytes into ctx.images, and refuses a file that requires an
 *  extension this reader does not read. Throws SpangleError at file:line:col. */
void load_document(Context& ctx);

/** gltf_compression.cpp: compressed data decoded into ctx.model as if it had been written
 *  plainly: each EXT_meshopt_compression buffer view gets its decoded bytes (in a buffer of its
 *  own), and each KHR_draco_mesh_compression primitive whose attributes or indices have no data
 *  of their own gets them from its Draco stream (in new buffers; its accessors rewritten in
 *  place, or new ones where two primitives name one accessor). Throws
 *  SpangleError at the extension for data that cannot be decoded. */
void decompress(Context& ctx);

/** gltf_meshes.cpp: the triangles of primitive `prim` of mesh `mesh`, shared by every node that
 *  draws it; null (with a note) for a primitive of points or lines. */
std::shared_ptr<const TriangleMesh> read_primitive(Context& ctx, int mesh, int prim);

/** gltf_images.cpp: a file the texture system can open for image `image` (referred to at JSON
 *  path `ref`): the file a URI names, or the embedded bytes written once, named by their hash,
 *  into the user's cache folder. Empty (with a note) for an image that cannot be had. */
std::string image_file(Context& ctx, int image, const std::string& ref);

/** gltf_images.cpp: `bytes` (an image file's, of extension `ext`) written once, named by their
 *  hash, into the first of embedded_image_dirs() that takes them; the file. Throws at `ref`
 *  when none does. */
std::string cached_image_file(Context& ctx, const std::vector<unsigned char>& bytes,
                              const std::string& ext, const std::string& ref);

/** Where an external URI (of an image or a buffer) points: `path` the file it names (relative
 *  to the glTF file's folder, percent escapes decoded; file:///path and file://localhost/path
 *  taken as this machine's paths), or `scheme` (and `host`) of one Spangle does not fetch
 *  (https://, a file:// URI of another host): then `path` is empty. */
struct UriTarget {
    std::string path;
    std::string scheme, host;
};
UriTarget uri_target(const Context& ctx, const std::string& uri);

/** What follows "file://" in a URI, split: `host` (empty for "file:///path") and `path` (from
 *  its first '/', escapes as written). True when the host is this machine (none, or localhost). */
bool split_file_uri(std::string_view rest, std::string& host, std::string& path);

/** `path` with its backslashes as slashes where the file is not found as written and is found
 *  so (a path written on Windows, "textures\\wood.png", which glTF forbids but exporters
 *  write); else `path`. For the checks, images and tinygltf's own reads alike. */
std::string slashed_where_missing(const std::string& path);

/** The folders embedded images are written to, in the order tried: `texture_cache`/gltf-images
 *  when given (--texture-cache), else $SPANGLE_TEXTURE_CACHE/gltf-images, else
 *  $XDG_CACHE_HOME/spangle/gltf-images or ~/.cache/spangle/gltf-images, then the temporary
 *  directory's spangle-gltf-images-UID (when the others cannot be written). */
std::vector<std::string> embedded_image_dirs(const std::string& texture_cache);

/** gltf_materials.cpp: the uv set (TEXCOORD_n) a material's textures read: its base colour
 *  texture's, else its first texture's; 0 without textures or for the default material (-1). */
int uv_set_of(const Context& ctx, int material);
/** Whether a primitive drawn with glTF material `material` (-1: the default material) has
 *  COLOR_0, which multiplies its base colour. */
bool has_vertex_colors(const Context& ctx, int material);

/** gltf_materials.cpp: the name of the Spangle material standing for glTF material `index` (-1:
 *  glTF's default material), made and added to the scene on first use; its emission, if any. */
std::string use_material(Context& ctx, int index, std::optional<EmissionDesc>& emission);

/** One node's placement through time: its world matrix at rest and, when it or a parent is
 *  animated, at every key time. */
struct NodeMotion {
    Affine rest;                   ///< world matrix with no animation applied (time 0)
    std::vector<double> times;     ///< seconds; empty: not animated
    std::vector<Affine> matrices;  ///< world matrix at each time
    bool cubic = false;            ///< a CUBICSPLINE channel was sampled into segments
};

/** gltf_animation.cpp: every node's world placement, animations applied (translation,
 *  rotation and scale channels of every animation), given the node parents (-1 = a root). */
std::vector<NodeMotion> node_motions(Context& ctx, const std::vector<int>& parent);

/** gltf_animation.cpp: translation x rotation (quaternion x, y, z, w, normalised; a zero one
 *  is none) x scale as one matrix, as glTF composes a node's parts. */
Affine trs_matrix(Vec3 t, const float r[4], Vec3 s);

/** gltf_animation.cpp: node `n`'s own matrix (its matrix, or T R S), with no animation. */
Affine local_matrix(const Context& ctx, int n);

/** gltf_animation.cpp: a glTF 4 x 4 matrix (16 numbers, column-major) as a placement; its last
 *  row, (0, 0, 0, 1) for a placement, is not read. */
Affine column_major_affine(const float* m);

/** An animation of a node's morph-target weights (a `weights` channel). */
struct WeightTrack {
    std::vector<float> times;  ///< seconds, increasing
    std::vector<float>
        values;             ///< `count` per key (CUBICSPLINE: in-tangents, values, out-tangents)
    std::size_t count = 0;  ///< weights per key
    int interp = 0;         ///< 0 LINEAR, 1 STEP, 2 CUBICSPLINE
    FileLoc loc;            ///< its sampler
};

/** gltf_animation.cpp: the weight animation of every node that has one (the first channel of
 *  a node's weights, as for its transform). */
std::map<int, WeightTrack> weight_tracks(Context& ctx);

/** gltf_animation.cpp: a weight track's `count` weights at time t (held outside its keys). */
void evaluate_weights(const WeightTrack& w, double t, float* out);

/** A primitive as node `n` draws it: its mesh at time 0 and, when its shape changes with time,
 *  what gives it at any time. */
struct DrawnPrimitive {
    std::shared_ptr<const TriangleMesh> mesh;
    std::shared_ptr<const MeshDeformation> deformation;
};

/** gltf_deform.cpp: primitive `prim` (read as `base`) as node `n` draws it: deformed by the
 *  node's skin (placed by `placement`, the skinned motion, its vertices expressed in that
 *  placement's space) and its mesh's morph targets (the node's or the mesh's weights, or their
 *  animation in `weights`). `base` itself where neither changes it. */
DrawnPrimitive drawn_primitive(Context& ctx, int n, int prim,
                               std::shared_ptr<const TriangleMesh> base,
                               const std::vector<NodeMotion>& motions, const NodeMotion& placement,
                               const std::map<int, WeightTrack>& weights);

/** gltf_nodes.cpp: whether placement `a` squashes space onto a plane, a line or a point (or is
 *  not finite). */
bool flattens(const Affine& a);

/** gltf_mirror.cpp: whether a placement mirrors: its determinant is negative, and it does not
 *  flatten its mesh (a flattened placement's determinant is 0 as written; made thin for Embree
 *  it takes a sign of no meaning). `keys` (an animated placement's matrices, empty: none) decide
 * instead of `a`: where they disagree, the first stands and that is noted at `at`. */
bool mirrors(Context& ctx, const Affine& a, const std::vector<Affine>& keys, const FileLoc& at,
             const std::string& what);

/** gltf_mirror.cpp: o's shape (an InlineMeshShape) with its winding reversed when
 *  `mirrored_placement` (glTF fronts a mirrored node's clockwise side, Spangle the
 *  counter-clockwise one in world space; without it a mirrored emissive quad lit its back and a
 *  mirrored glass ball without normals refracted as a bubble of air). A still mesh's reversed copy
 * is shared by every mirrored node drawing it (ctx.reversed); a deforming one's is made once per
 * primitive and node (`mirrored`). */
void face_for(Context& ctx, ObjectDesc& o, bool mirrored_placement,
              std::optional<InlineMeshShape>& mirrored);

/** gltf_nodes.cpp: the objects, cameras and lights of the scene's node tree, and the default
 *  camera and light when the file has none. */
void read_nodes(Context& ctx, const SceneReadOptions& options);

}  // namespace spangle::gltf
