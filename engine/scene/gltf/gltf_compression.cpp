// Compressed glTF geometry, decoded before anything reads it: EXT_meshopt_compression buffer views
// (meshoptimizer's vertex and index codecs and filters, as gltfpack and glTF-Transform write them)
// and KHR_draco_mesh_compression primitives (Google's Draco, as Blender's exporter, Draco's own
// transcoder and glTF-Transform write them). What they decode to is written into the model as
// ordinary buffers, views and accessors, so the rest of the reader never knows.

#include <draco/compression/decode.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>

#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {
namespace {

/** The most bytes one compressed view or primitive may decode to (a corrupt count would ask for
 *  terabytes). */
constexpr double kMaxDecoded = 4294967296.0;

/** A number member of an extension object: its value, `fallback` when absent; an error at `at`
 *  when it is there but not a number. */
double number(const Context& ctx, const tinygltf::Value& o, const char* key, double fallback,
              const std::string& at) {
    if (!o.Has(key)) return fallback;
    const tinygltf::Value& v = o.Get(key);
    if (!v.IsNumber()) throw_error(ctx.at(at + "/" + key), "'{}' must be a number", key);
    return v.GetNumberAsDouble();
}

/** A whole number in [lo, hi] (a count, an index, an offset); an error at `at` otherwise, and
 *  when it is absent with a `fallback` below lo (a member the extension requires). */
std::size_t whole(const Context& ctx, const tinygltf::Value& o, const char* key, double fallback,
                  double lo, double hi, const std::string& at) {
    if (!o.Has(key) && fallback < lo)
        throw_error(ctx.at(at), "'{}' is missing (the extension requires it)", key);
    const double v = number(ctx, o, key, fallback, at);
    if (!(v >= lo && v <= hi) || v != std::floor(v))
        throw_error(ctx.at(at + "/" + key), "'{}' is {}: it must be a whole number from {} to {}",
                    key, v, lo, hi);
    return static_cast<std::size_t>(v);
}

/** A string member; `fallback` when absent. */
std::string text(const Context& ctx, const tinygltf::Value& o, const char* key,
                 const std::string& fallback, const std::string& at) {
    if (!o.Has(key)) return fallback;
    const tinygltf::Value& v = o.Get(key);
    if (!v.IsString()) throw_error(ctx.at(at + "/" + key), "'{}' must be a string", key);
    return v.Get<std::string>();
}

/** Bytes [offset, offset + length) of buffer `buffer`, checked to exist. */
const unsigned char* buffer_bytes(const Context& ctx, std::size_t buffer, std::size_t offset,
                                  std::size_t length, const std::string& at) {
    // The file's own buffers (the decoded ones added since are not the file's to name).
    if (buffer >= ctx.file_buffers)
        throw_error(ctx.at(at + "/buffer"), "buffer {} does not exist (the file has {})", buffer,
                    ctx.file_buffers);
    const std::vector<unsigned char>& data = ctx.model.buffers[buffer].data;
    if (offset > data.size() || length > data.size() - offset)
        throw_error(ctx.at(at),
                    "the compressed data ({} bytes from byte {}) runs past the end of buffer {} "
                    "({} bytes)",
                    length, offset, buffer, data.size());
    return data.data() + offset;
}

/** A new buffer holding `bytes`; its index. */
int add_buffer(Context& ctx, std::vector<unsigned char> bytes) {
    tinygltf::Buffer b;
    b.data = std::move(bytes);
    ctx.model.buffers.push_back(std::move(b));
    return static_cast<int>(ctx.model.buffers.size() - 1);
}

/** Buffer view `index` with an EXT_meshopt_compression object `x`: its bytes decoded into a
 *  buffer of their own, the view pointed at them (byteOffset 0, its byteLength and byteStride
 *  kept). */
void decode_meshopt_view(Context& ctx, std::size_t index, const tinygltf::Value& x) {
    const std::string at = fmt::format("bufferViews/{}/extensions/EXT_meshopt_compression", index);
    if (!x.IsObject())
        throw_error(ctx.at(at), "EXT_meshopt_compression of buffer view {} must be an object",
                    index);
    const std::size_t buffer = whole(ctx, x, "buffer", -1, 0, 1e9, at);
    const std::size_t offset = whole(ctx, x, "byteOffset", 0, 0, 9e15, at);
    const std::size_t length = whole(ctx, x, "byteLength", -1, 1, 9e15, at);
    const std::size_t stride = whole(ctx, x, "byteStride", -1, 1, 256, at);
    const std::size_t count = whole(ctx, x, "count", -1, 1, 4294967295.0, at);
    const std::string mode = text(ctx, x, "mode", "", at);
    const std::string filter = text(ctx, x, "filter", "NONE", at);
    if (static_cast<double>(count) * static_cast<double>(stride) > kMaxDecoded)
        throw_error(ctx.at(at + "/count"),
                    "{} elements of {} bytes would decode to more than 4 GiB", count, stride);
    if (ctx.placeholder_buffers.count(static_cast<int>(buffer)))
        throw_error(ctx.at(at + "/buffer"),
                    "buffer view {}: its compressed data is in buffer {}, a meshopt fallback "
                    "buffer, which holds no data",
                    index, buffer);
    const unsigned char* src = buffer_bytes(ctx, buffer, offset, length, at);
    // The view is the decoded data: count elements of byteStride bytes, exactly.
    const tinygltf::BufferView& parent = ctx.model.bufferViews[index];
    if (parent.byteLength != count * stride)
        throw_error(ctx.at(at),
                    "buffer view {} is {} bytes long, but its compressed data decodes to count {} "
                    "x byteStride {} = {} bytes (they must be equal)",
                    index, parent.byteLength, count, stride, count * stride);
    // What `length` compressed bytes can decode to at most, checked before the output is
    // made (a 7 KB file asked for 4 GiB, zeroed, before its data was found short): a vertex
    // stream packs 16 bytes into 2 bits at best (64:1, with a header and a tail of a few
    // blocks), an index buffer a triangle into a byte, an index sequence an index into a byte.
    const double bytes = static_cast<double>(length), width = static_cast<double>(stride);
    const double most = mode == "ATTRIBUTES"  ? 64.0 * bytes + 65536.0
                        : mode == "TRIANGLES" ? 3.0 * bytes * width
                        : mode == "INDICES"   ? bytes * width
                                              : std::numeric_limits<double>::infinity();
    if (static_cast<double>(count) * static_cast<double>(stride) > most)
        throw_error(ctx.at(at + "/count"),
                    "buffer view {}: count {} x byteStride {} cannot come from {} compressed "
                    "bytes in mode {}",
                    index, count, stride, length, mode);
    // Vertex data decode with byteStride between elements: a view that gives none reads them so.
    if (mode == "ATTRIBUTES" && parent.byteStride != 0 && parent.byteStride != stride)
        throw_error(ctx.at(fmt::format("bufferViews/{}/byteStride", index)),
                    "buffer view {}: byteStride {} differs from its compressed data's {}", index,
                    parent.byteStride, stride);
    if (mode == "ATTRIBUTES") ctx.model.bufferViews[index].byteStride = stride;
    std::vector<unsigned char> out(count * stride);
    int status = 0;
    if (mode == "ATTRIBUTES") {
        if (stride % 4 != 0)
            throw_error(ctx.at(at + "/byteStride"),
                        "byteStride {} of mode ATTRIBUTES must be a multiple of 4", stride);
        status = meshopt_decodeVertexBuffer(out.data(), count, stride, src, length);
    } else if (mode == "TRIANGLES" || mode == "INDICES") {
        if (stride != 2 && stride != 4)
            throw_error(ctx.at(at + "/byteStride"),
                        "byteStride {} of mode {} must be 2 or 4 (16- or 32-bit indices)", stride,
                        mode);
        if (mode == "TRIANGLES" && count % 3 != 0)
            throw_error(ctx.at(at + "/count"), "count {} of mode TRIANGLES must be a multiple of 3",
                        count);
        status = mode == "TRIANGLES"
                     ? meshopt_decodeIndexBuffer(out.data(), count, stride, src, length)
                     : meshopt_decodeIndexSequence(out.data(), count, stride, src, length);
    } else {
        throw_error(ctx.at(at + (x.Has("mode") ? "/mode" : "")),
                    "mode '{}' of buffer view {} is not one of ATTRIBUTES, TRIANGLES, INDICES",
                    mode, index);
    }
    if (status != 0)
        throw_error(ctx.at(at),
                    "buffer view {}: its meshopt data could not be decoded (error {}: the bytes "
                    "are damaged, or not what byteLength, byteStride and count say)",
                    index, status);
    if (filter == "OCTAHEDRAL") {
        if (mode != "ATTRIBUTES" || (stride != 4 && stride != 8))
            throw_error(ctx.at(at + "/filter"),
                        "filter OCTAHEDRAL needs mode ATTRIBUTES and byteStride 4 or 8");
        meshopt_decodeFilterOct(out.data(), count, stride);
    } else if (filter == "QUATERNION") {
        if (mode != "ATTRIBUTES" || stride != 8)
            throw_error(ctx.at(at + "/filter"),
                        "filter QUATERNION needs mode ATTRIBUTES and byteStride 8");
        meshopt_decodeFilterQuat(out.data(), count, stride);
    } else if (filter == "EXPONENTIAL") {
        if (mode != "ATTRIBUTES")
            throw_error(ctx.at(at + "/filter"), "filter EXPONENTIAL needs mode ATTRIBUTES");
        meshopt_decodeFilterExp(out.data(), count, stride);
    } else if (filter != "NONE") {
        throw_error(ctx.at(at + "/filter"),
                    "filter '{}' of buffer view {} is not one of NONE, OCTAHEDRAL, QUATERNION, "
                    "EXPONENTIAL",
                    filter, index);
    }
    tinygltf::BufferView& v = ctx.model.bufferViews[index];
    v.buffer = add_buffer(ctx, std::move(out));
    v.byteOffset = 0;
    v.extensions.erase("EXT_meshopt_compression");
}

/** The largest value of a Draco integer type (what a normalised integer of it divides by); 0
 *  for a type that is not one of glTF's integers. */
double integer_max(draco::DataType t) {
    switch (t) {
        case draco::DT_INT8:
            return 127.0;
        case draco::DT_UINT8:
            return 255.0;
        case draco::DT_INT16:
            return 32767.0;
        case draco::DT_UINT16:
            return 65535.0;
        default:
            return 0.0;
    }
}

/** The decoded values of Draco attribute `att` as floats, one element of `ncomp` components
 *  per point, tightly packed: normalised integers in [0, 1] or [-1, 1] where the stream marks
 *  them normalised (Draco converts them) or the accessor does (`normalized`: encoders that
 *  leave the stream unmarked, as Blender's older exporter and glTF-Transform did for colours
 *  and uvs); other integers as their values, floats as they are. */
std::vector<unsigned char> draco_floats(const draco::PointAttribute& att, std::size_t points,
                                        int ncomp, bool normalized) {
    const std::size_t elem = static_cast<std::size_t>(ncomp) * sizeof(float);
    std::vector<unsigned char> out(points * elem);
    const double max = att.normalized() || !normalized ? 0.0 : integer_max(att.data_type());
    float value[4] = {};
    for (std::size_t p = 0; p < points; ++p) {
        const auto i = att.mapped_index(draco::PointIndex(static_cast<uint32_t>(p)));
        if (!att.ConvertValue<float>(i, static_cast<int8_t>(ncomp), value))
            std::fill_n(value, 4, 0.0f);
        if (max > 0.0)
            for (int c = 0; c < ncomp; ++c)
                value[c] = static_cast<float>(std::max(static_cast<double>(value[c]) / max, -1.0));
        std::memcpy(out.data() + p * elem, value, elem);
    }
    return out;
}

/** A new view over the whole of a new buffer holding `bytes`; its index. */
int add_view(Context& ctx, std::vector<unsigned char> bytes) {
    tinygltf::BufferView v;
    v.byteLength = bytes.size();
    v.buffer = add_buffer(ctx, std::move(bytes));
    ctx.model.bufferViews.push_back(std::move(v));
    return static_cast<int>(ctx.model.bufferViews.size() - 1);
}

/** Accessor `a` (decoded data) where accessor `original` stood: in its place, so that messages
 *  about it name the accessor the file wrote, unless another Draco primitive decoded into that
 *  one already (two primitives naming one accessor, each with a stream of its own) or there is
 *  none (-1): then a new accessor. `taken` holds the accessors decoded into. Its index. */
int place_accessor(Context& ctx, int original, tinygltf::Accessor a, std::set<int>& taken) {
    if (original >= 0 && static_cast<std::size_t>(original) < ctx.model.accessors.size() &&
        taken.insert(original).second) {
        ctx.model.accessors[static_cast<std::size_t>(original)] = std::move(a);
        return original;
    }
    ctx.model.accessors.push_back(std::move(a));
    return static_cast<int>(ctx.model.accessors.size() - 1);
}

/** Primitive `prim` of mesh `mesh` with a KHR_draco_mesh_compression object `x`. A file that
 *  keeps all its uncompressed data (not requiring the extension) is read from that, exactly.
 *  Otherwise the stream is read whole: its indices and every attribute it compresses, in the
 *  stream's own vertex order (Draco renumbers vertices, so the file's data cannot be mixed with
 *  the stream's: a primitive without indices had the stream's triangles laid over the file's
 *  vertices). Decoded data go where the file's accessors without data stood (so that messages
 *  name them) and into new accessors beside those with data, which other primitives may read. */
void decode_draco_primitive(Context& ctx, std::size_t mesh, std::size_t prim,
                            const tinygltf::Value& x, std::set<int>& taken,
                            const std::vector<tinygltf::Accessor>& written) {
    const std::string pp = fmt::format("meshes/{}/primitives/{}", mesh, prim);
    const std::string at = pp + "/extensions/KHR_draco_mesh_compression";
    tinygltf::Primitive& p = ctx.model.meshes[mesh].primitives[prim];
    if (!x.IsObject()) throw_error(ctx.at(at), "KHR_draco_mesh_compression must be an object");
    // An accessor's count as the file wrote it.
    const auto written_count = [&](int accessor) {
        const auto k = static_cast<std::size_t>(accessor);
        return k < written.size()               ? written[k].count
               : k < ctx.model.accessors.size() ? ctx.model.accessors[k].count
                                                : std::size_t{0};
    };
    // (An accessor another primitive's stream was decoded into has no data of its own.)
    const auto has_data = [&](int accessor) {
        return accessor >= 0 && static_cast<std::size_t>(accessor) < ctx.model.accessors.size() &&
               ctx.model.accessors[static_cast<std::size_t>(accessor)].bufferView >= 0 &&
               !taken.count(accessor);
    };
    if (!x.Has("attributes") || !x.Get("attributes").IsObject())
        throw_error(ctx.at(at), "KHR_draco_mesh_compression needs its 'attributes' object");
    const tinygltf::Value::Object& ids = x.Get("attributes").Get<tinygltf::Value::Object>();
    // Indices the primitive does not have need nothing; the stream's are read with its
    // attributes.
    bool needed = p.indices >= 0 && !has_data(p.indices);
    for (const auto& [name, id] : ids) {
        (void)id;
        const auto it = p.attributes.find(name);
        if (it == p.attributes.end())
            throw_error(ctx.at(at + "/attributes/" + name),
                        "attribute {} is compressed but the primitive's attributes do not name "
                        "its accessor",
                        name);
        needed = needed || !has_data(it->second);
    }
    if (!needed) {
        p.extensions.erase("KHR_draco_mesh_compression");
        return;
    }
    const std::size_t view = whole(ctx, x, "bufferView", -1, 0, 1e9, at);
    if (view >= ctx.file_views)
        throw_error(ctx.at(at + "/bufferView"), "buffer view {} does not exist (the file has {})",
                    view, ctx.file_views);
    const tinygltf::BufferView& v = ctx.model.bufferViews[view];
    const std::string vp = fmt::format("bufferViews/{}", view);
    if (v.buffer < 0) throw_error(ctx.at(vp), "buffer view {} names no buffer", view);
    if (ctx.placeholder_buffers.count(v.buffer))
        throw_error(ctx.at(vp + "/buffer"),
                    "mesh {} primitive {}: its Draco data is in buffer {}, a meshopt fallback "
                    "buffer, which holds no data",
                    mesh, prim, v.buffer);
    const unsigned char* bytes =
        buffer_bytes(ctx, static_cast<std::size_t>(v.buffer), v.byteOffset, v.byteLength, vp);
    draco::DecoderBuffer stream;
    stream.Init(reinterpret_cast<const char*>(bytes), v.byteLength);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&stream);
    if (!decoded.ok() || !decoded.value())
        throw_error(ctx.at(at),
                    "mesh {} primitive {}: its Draco data (buffer view {}) could not be decoded: "
                    "{}",
                    mesh, prim, view,
                    decoded.ok() ? "no mesh" : decoded.status().error_msg_string());
    const std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
    const std::size_t points = dm->num_points();
    const std::size_t faces = dm->num_faces();
    if (static_cast<double>(points) * 64.0 + static_cast<double>(faces) * 12.0 > kMaxDecoded)
        throw_error(ctx.at(at), "mesh {} primitive {}: its Draco mesh is larger than 4 GiB", mesh,
                    prim);
    {
        if (p.indices >= 0 && !has_data(p.indices) && written_count(p.indices) != faces * 3)
            ctx.note("draco count", ctx.at(pp + "/indices"),
                     fmt::format("accessor {} gives count {}, its Draco stream {} indices: the "
                                 "stream's are read",
                                 p.indices, written_count(p.indices), faces * 3));
        std::vector<unsigned char> out(faces * 3 * sizeof(uint32_t));
        for (std::size_t f = 0; f < faces; ++f) {
            const draco::Mesh::Face& face = dm->face(draco::FaceIndex(static_cast<uint32_t>(f)));
            for (int c = 0; c < 3; ++c) {
                const uint32_t i = face[static_cast<std::size_t>(c)].value();
                std::memcpy(out.data() + (3 * f + static_cast<std::size_t>(c)) * 4, &i, 4);
            }
        }
        tinygltf::Accessor a;
        a.bufferView = add_view(ctx, std::move(out));
        a.byteOffset = 0;
        a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
        a.type = TINYGLTF_TYPE_SCALAR;
        a.count = faces * 3;
        p.indices = place_accessor(ctx, has_data(p.indices) ? -1 : p.indices, std::move(a), taken);
        // Draco decodes a list of triangles whatever mode the primitive was encoded from.
        p.mode = TINYGLTF_MODE_TRIANGLES;
    }
    // Morph targets are in the file's vertex order, not the stream's (Draco has none of its own).
    if (!p.targets.empty()) {
        ctx.note("draco targets", ctx.at(pp + "/targets"),
                 fmt::format("mesh {} primitive {}: its morph targets are not in its Draco "
                             "stream, whose vertices are in an order of their own: dropped",
                             mesh, prim));
        p.targets.clear();
    }
    // Attributes the stream does not hold are in the file's vertex order, not the stream's.
    for (auto it = p.attributes.begin(); it != p.attributes.end();) {
        if (ids.count(it->first)) {
            ++it;
            continue;
        }
        ctx.note("draco attribute", ctx.at(pp + "/attributes/" + it->first),
                 fmt::format("mesh {} primitive {}: attribute {} is not in its Draco stream, whose "
                             "vertices are in an order of their own: dropped",
                             mesh, prim, it->first));
        it = p.attributes.erase(it);
    }
    for (const auto& [name, id] : ids) {
        int& accessor = p.attributes[name];
        const bool own_data = has_data(accessor);
        const std::string ap = at + "/attributes/" + name;
        if (!id.IsNumber() || id.GetNumberAsDouble() < 0 || id.GetNumberAsDouble() > 4294967295.0 ||
            id.GetNumberAsDouble() != std::floor(id.GetNumberAsDouble()))
            throw_error(ctx.at(ap), "the Draco id of attribute {} must be a whole number", name);
        const draco::PointAttribute* att =
            dm->GetAttributeByUniqueId(static_cast<uint32_t>(id.GetNumberAsDouble()));
        if (!att)
            throw_error(ctx.at(ap), "attribute {}: the Draco data has no attribute of id {}", name,
                        id.GetNumberAsDouble());
        if (accessor < 0 || static_cast<std::size_t>(accessor) >= ctx.model.accessors.size())
            throw_error(ctx.at(pp + "/attributes/" + name),
                        "accessor {} does not exist (the file has {})", accessor,
                        ctx.model.accessors.size());
        // The accessor as the file wrote it (one decoded into already has been rewritten).
        tinygltf::Accessor a = static_cast<std::size_t>(accessor) < written.size()
                                   ? written[static_cast<std::size_t>(accessor)]
                                   : ctx.model.accessors[static_cast<std::size_t>(accessor)];
        const int ncomp = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
        if (ncomp < 1 || ncomp > 4)
            throw_error(ctx.at(fmt::format("accessors/{}/type", accessor)),
                        "attribute {}: a Draco attribute is a scalar or a vector", name);
        if (att->num_components() < ncomp)
            throw_error(ctx.at(ap),
                        "attribute {}: its accessor has {} components, the Draco attribute of id "
                        "{} has {}",
                        name, ncomp, id.GetNumberAsDouble(), att->num_components());
        if (a.count != points && !own_data)
            ctx.note("draco count", ctx.at(fmt::format("accessors/{}/count", accessor)),
                     fmt::format("accessor {} gives count {}, its Draco stream {} vertices: the "
                                 "stream's are read",
                                 accessor, a.count, points));
        // As floats, whatever the accessor's component type says: the stream's own type
        // decides how its values read (a float stream behind an integer accessor is not cast
        // to integers), the accessor's `normalized` as well as the stream's mark deciding
        // whether its integers are normalised.
        std::vector<unsigned char> out = draco_floats(*att, points, ncomp, a.normalized);
        a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
        a.normalized = false;
        // The accessor as written (its type, bounds), over the decoded values.
        a.bufferView = add_view(ctx, std::move(out));
        a.byteOffset = 0;
        a.count = points;
        if (a.sparse.isSparse && !own_data)
            ctx.note("draco sparse", ctx.at(fmt::format("accessors/{}/sparse", accessor)),
                     fmt::format("accessor {} is sparse and decoded from a Draco stream: its "
                                 "sparse values are dropped",
                                 accessor));
        a.sparse.isSparse = false;
        accessor = place_accessor(ctx, own_data ? -1 : accessor, std::move(a), taken);
    }
    p.extensions.erase("KHR_draco_mesh_compression");
}

}  // namespace

void decompress(Context& ctx) {
    ctx.file_buffers = ctx.model.buffers.size();
    ctx.file_views = ctx.model.bufferViews.size();
    for (std::size_t i = 0; i < ctx.model.bufferViews.size(); ++i) {
        const auto it = ctx.model.bufferViews[i].extensions.find("EXT_meshopt_compression");
        if (it != ctx.model.bufferViews[i].extensions.end()) {
            const tinygltf::Value x = it->second;
            decode_meshopt_view(ctx, i, x);
        }
    }
    std::set<int> taken;
    std::vector<tinygltf::Accessor> written;  // the accessors as the file wrote them
    for (std::size_t m = 0; m < ctx.model.meshes.size(); ++m)
        for (std::size_t p = 0; p < ctx.model.meshes[m].primitives.size(); ++p) {
            const tinygltf::ExtensionMap& e = ctx.model.meshes[m].primitives[p].extensions;
            const auto it = e.find("KHR_draco_mesh_compression");
            if (it == e.end()) continue;
            const tinygltf::Value x = it->second;
            if (written.empty()) written = ctx.model.accessors;
            decode_draco_primitive(ctx, m, p, x, taken, written);
        }
}

}  // namespace spangle::gltf
