#include "scene/gltf/gltf_accessors.h"

#include <algorithm>
#include <cstring>

namespace spangle::gltf {

void check_index(const Context& ctx, const std::string& p, int index, std::size_t size,
                 const char* what) {
    if (index < 0 || static_cast<std::size_t>(index) >= size)
        throw_error(ctx.at(p), "{} {} does not exist (the file has {})", what, index, size);
}

namespace {

constexpr std::size_t kMaxViewless = std::size_t{1} << 24;  ///< elements of a view-less accessor

/** Bytes of one component of a glTF component type, or 0 for an unknown type. */
std::size_t component_size(int type) {
    switch (type) {
        case TINYGLTF_COMPONENT_TYPE_BYTE:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
            return 1;
        case TINYGLTF_COMPONENT_TYPE_SHORT:
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
            return 2;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
        case TINYGLTF_COMPONENT_TYPE_FLOAT:
            return 4;
        default:
            return 0;
    }
}

/** A T from unaligned bytes. */
template <class T>
T load(const unsigned char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

/** One component as a number; normalised integers map to [0, 1] or [-1, 1] (glTF 2.0, 3.11). */
double component(const unsigned char* p, int type, bool normalized) {
    switch (type) {
        case TINYGLTF_COMPONENT_TYPE_BYTE: {
            const double v = load<int8_t>(p);
            return normalized ? std::max(v / 127.0, -1.0) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: {
            const double v = load<uint8_t>(p);
            return normalized ? v / 255.0 : v;
        }
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            const double v = load<int16_t>(p);
            return normalized ? std::max(v / 32767.0, -1.0) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            const double v = load<uint16_t>(p);
            return normalized ? v / 65535.0 : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
            return load<uint32_t>(p);
        default:
            return load<float>(p);
    }
}

/** A checked run of `count` elements of `elem` bytes, `stride` apart, in one buffer view. */
struct Run {
    const unsigned char* first = nullptr;  ///< the first element's bytes
    std::size_t stride = 0;                ///< bytes from one element to the next
};

/** The elements of buffer view `view` from `offset`, checked to fit in the view and the view in
 *  its buffer. `natural` is the element's size (the stride when the view gives none). */
Run run_of(const Context& ctx, int view, std::size_t offset, std::size_t count, std::size_t natural,
           std::size_t align, const std::string& ref) {
    const tinygltf::Model& m = ctx.model;
    check_index(ctx, ref, view, m.bufferViews.size(), "buffer view");
    const std::string vp = fmt::format("bufferViews/{}", view);
    const tinygltf::BufferView& v = m.bufferViews[static_cast<std::size_t>(view)];
    check_index(ctx, vp + "/buffer", v.buffer, m.buffers.size(), "buffer");
    if (ctx.placeholder_buffers.count(v.buffer))
        throw_error(ctx.at(vp + "/buffer"),
                    "buffer view {} lies in buffer {}, a meshopt fallback buffer, which holds no "
                    "data (only views compressed with EXT_meshopt_compression may point there)",
                    view, v.buffer);
    const std::vector<unsigned char>& data = m.buffers[static_cast<std::size_t>(v.buffer)].data;
    if (v.byteOffset > data.size() || v.byteLength > data.size() - v.byteOffset)
        throw_error(ctx.at(vp),
                    "buffer view {} ({} bytes from byte {}) runs past the end of "
                    "buffer {} ({} bytes)",
                    view, v.byteLength, v.byteOffset, v.buffer, data.size());
    const std::size_t stride = v.byteStride ? v.byteStride : natural;
    if (v.byteStride && (v.byteStride < natural || v.byteStride % align != 0))
        throw_error(ctx.at(vp + "/byteStride"),
                    "byteStride {} of buffer view {} is smaller than an element ({} bytes) or "
                    "not a multiple of its component size",
                    v.byteStride, view, natural);
    if (count > 0 &&
        (offset > v.byteLength || count > v.byteLength || natural > v.byteLength - offset ||
         (count - 1) * stride > v.byteLength - offset - natural))
        throw_error(ctx.at(ref),
                    "{} elements of {} bytes, {} apart from byte {}, do not fit in "
                    "buffer view {} ({} bytes)",
                    count, natural, stride, offset, view, v.byteLength);
    if (offset % align != 0)
        throw_error(ctx.at(ref), "byteOffset {} is not a multiple of the component size {}", offset,
                    align);
    return {data.data() + v.byteOffset + offset, stride};
}

/** Accessor `index` checked: its element type and sizes. */
const tinygltf::Accessor& accessor(const Context& ctx, int index, const std::string& ref,
                                   std::size_t& csize, int& ncomp) {
    check_index(ctx, ref, index, ctx.model.accessors.size(), "accessor");
    const tinygltf::Accessor& a = ctx.model.accessors[static_cast<std::size_t>(index)];
    const std::string ap = fmt::format("accessors/{}", index);
    csize = component_size(a.componentType);
    if (csize == 0)
        throw_error(ctx.at(ap + "/componentType"), "accessor {} has an unknown componentType {}",
                    index, a.componentType);
    ncomp = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
    if (ncomp <= 0) throw_error(ctx.at(ap + "/type"), "accessor {} has an unknown type", index);
    if (a.count > (std::size_t{1} << 31))
        throw_error(ctx.at(ap + "/count"), "accessor {} has {} elements: more than 2^31", index,
                    a.count);
    return a;
}

/** Every element of accessor `index` as `ncomp` doubles per element, sparse substitution done. */
std::vector<double> read_numbers(const Context& ctx, int index, const std::string& ref,
                                 int& ncomp) {
    std::size_t csize = 0;
    const tinygltf::Accessor& a = accessor(ctx, index, ref, csize, ncomp);
    const std::string ap = fmt::format("accessors/{}", index);
    const auto n = static_cast<std::size_t>(ncomp);
    // An accessor without a view is zeros (before its sparse values): nothing in the file
    // bounds its size, so Spangle does.
    if (a.bufferView < 0 && a.count > kMaxViewless)
        throw_error(ctx.at(ap + "/count"),
                    "accessor {} has no buffer view and {} elements: more than {} zeros", index,
                    a.count, kMaxViewless);
    const Run r = a.bufferView >= 0 && a.count > 0
                      ? run_of(ctx, a.bufferView, a.byteOffset, a.count, csize * n, csize, ap)
                      : Run{};
    std::vector<double> out(a.count * n, 0.0);
    if (r.first) {
        for (std::size_t i = 0; i < a.count; ++i)
            for (std::size_t c = 0; c < n; ++c)
                out[i * n + c] =
                    component(r.first + i * r.stride + c * csize, a.componentType, a.normalized);
    }
    if (!a.sparse.isSparse) return out;
    const std::string sp = ap + "/sparse";
    const auto count = static_cast<std::size_t>(std::max(a.sparse.count, 0));
    if (a.sparse.count < 1 || count > a.count)
        throw_error(ctx.at(sp), "sparse count {} must be in [1, {}]", a.sparse.count, a.count);
    const int itype = a.sparse.indices.componentType;
    const std::size_t isize = component_size(itype);
    if (isize == 0 || itype == TINYGLTF_COMPONENT_TYPE_FLOAT ||
        itype == TINYGLTF_COMPONENT_TYPE_BYTE || itype == TINYGLTF_COMPONENT_TYPE_SHORT)
        throw_error(ctx.at(sp + "/indices"), "sparse indices must be unsigned integers");
    const Run ri = run_of(ctx, a.sparse.indices.bufferView,
                          static_cast<std::size_t>(std::max(a.sparse.indices.byteOffset, 0)), count,
                          isize, isize, sp + "/indices");
    const Run rv = run_of(ctx, a.sparse.values.bufferView,
                          static_cast<std::size_t>(std::max(a.sparse.values.byteOffset, 0)), count,
                          csize * n, csize, sp + "/values");
    for (std::size_t k = 0; k < count; ++k) {
        const double at = component(ri.first + k * isize, itype, false);
        if (!(at >= 0.0 && at < static_cast<double>(a.count)))
            throw_error(ctx.at(sp + "/indices"), "sparse index {} is out of range [0, {})", at,
                        a.count);
        const auto i = static_cast<std::size_t>(at);
        for (std::size_t c = 0; c < n; ++c)
            out[i * n + c] =
                component(rv.first + k * csize * n + c * csize, a.componentType, a.normalized);
    }
    return out;
}

}  // namespace

std::size_t accessor_count(const Context& ctx, int index, const std::string& ref) {
    std::size_t csize = 0;
    int ncomp = 0;
    return accessor(ctx, index, ref, csize, ncomp).count;
}

std::vector<float> read_floats(const Context& ctx, int index, int components, const char* what,
                               const std::string& ref, bool finite) {
    int ncomp = 0;
    const std::vector<double> v = read_numbers(ctx, index, ref, ncomp);
    if (ncomp != components)
        throw_error(ctx.at(fmt::format("accessors/{}/type", index)),
                    "{}: accessor {} has {} components per element, expected {}", what, index,
                    ncomp, components);
    std::vector<float> out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
        out[i] = static_cast<float>(v[i]);
        if (finite && !std::isfinite(out[i]))
            throw_error(ctx.at(fmt::format("accessors/{}", index)),
                        "{}: accessor {} holds a value that is not a finite float ({}) at element "
                        "{}",
                        what, index, v[i], i / static_cast<std::size_t>(components));
    }
    return out;
}

std::vector<uint32_t> read_indices(const Context& ctx, int index, const std::string& ref) {
    std::size_t csize = 0;
    int ncomp = 0;
    const tinygltf::Accessor& a = accessor(ctx, index, ref, csize, ncomp);
    const std::string ap = fmt::format("accessors/{}", index);
    if (ncomp != 1 || a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
        a.componentType == TINYGLTF_COMPONENT_TYPE_BYTE ||
        a.componentType == TINYGLTF_COMPONENT_TYPE_SHORT)
        throw_error(ctx.at(ap), "indices: accessor {} must hold unsigned integer scalars", index);
    if (a.sparse.isSparse || a.bufferView < 0) {
        const std::vector<double> v = read_numbers(ctx, index, ref, ncomp);
        return {v.begin(), v.end()};
    }
    std::vector<uint32_t> out(a.count);
    if (a.count == 0) return out;
    const Run r = run_of(ctx, a.bufferView, a.byteOffset, a.count, csize, csize, ap);
    for (std::size_t i = 0; i < a.count; ++i) {
        const unsigned char* p = r.first + i * r.stride;
        out[i] = csize == 1 ? load<uint8_t>(p) : csize == 2 ? load<uint16_t>(p) : load<uint32_t>(p);
    }
    return out;
}

std::vector<float> read_per_vertex(const Context& ctx, int index, int components, std::size_t nv,
                                   const char* what, const std::string& ref, bool finite) {
    std::vector<float> v = read_floats(ctx, index, components, what, ref, finite);
    if (v.size() != nv * static_cast<std::size_t>(components))
        throw_error(ctx.at(ref), "{} has {} elements, POSITION {}", what,
                    v.size() / static_cast<std::size_t>(components), nv);
    return v;
}

}  // namespace spangle::gltf
