#include "geometry/ply_reader.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <tuple>
#include <vector>

#include "core/files.h"
#include "geometry/polygon.h"

namespace spangle {
namespace {

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
enum class Format { Ascii, BinaryLittle, BinaryBig };

std::optional<Type> parse_type(const std::string& t) {
    if (t == "char" || t == "int8") return Type::Int8;
    if (t == "uchar" || t == "uint8") return Type::UInt8;
    if (t == "short" || t == "int16") return Type::Int16;
    if (t == "ushort" || t == "uint16") return Type::UInt16;
    if (t == "int" || t == "int32") return Type::Int32;
    if (t == "uint" || t == "uint32") return Type::UInt32;
    if (t == "float" || t == "float32") return Type::Float32;
    if (t == "double" || t == "float64") return Type::Float64;
    return std::nullopt;
}

std::size_t size_of(Type t) {
    switch (t) {
        case Type::Int8:
        case Type::UInt8:
            return 1;
        case Type::Int16:
        case Type::UInt16:
            return 2;
        case Type::Int32:
        case Type::UInt32:
        case Type::Float32:
            return 4;
        case Type::Float64:
            return 8;
    }
    return 8;
}

/** A vertex colour component as linear: integer ones are sRGB-encoded fractions of their type's
 *  largest value (as scanners, MeshLab and Blender write 8-bit colours; 32-bit integers hold
 *  0..255, as the writers that use them write them), floating-point ones linear as written (as
 *  Spangle's own writer writes them). */
float color_component(Type t, double v) {
    double top = 0.0;
    switch (t) {
        case Type::Int8:
        case Type::UInt8:
            top = 255.0;
            break;
        case Type::Int16:
        case Type::UInt16:
            top = 65535.0;
            break;
        case Type::Int32:
        case Type::UInt32:
            top = 255.0;
            break;
        case Type::Float32:
        case Type::Float64:
            return static_cast<float>(v);
    }
    return static_cast<float>(srgb_to_linear(std::clamp(v / top, 0.0, 1.0)));
}

struct Property {
    std::string name;
    Type type = Type::Float32;
    bool list = false;
    Type count_type = Type::UInt8;
};

struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> props;
};

/** The data after the header: binary values or ASCII tokens, every read bounded. */
class BodyReader {
public:
    BodyReader(const std::string& data, std::size_t pos, Format format, const std::string& path,
               const FileLoc& ref)
        : data_(data), pos_(pos), format_(format), path_(path), ref_(ref) {}

    std::size_t remaining() const { return data_.size() - pos_; }

    /** Whether what remains is a line end or a few spaces at most (writers that end a binary
     *  body with a newline, as they end an ASCII one). */
    bool only_line_end_remains() const {
        if (remaining() > 4) return false;
        for (std::size_t i = pos_; i < data_.size(); ++i)
            if (data_[i] != '\n' && data_[i] != '\r' && data_[i] != ' ') return false;
        return true;
    }

    /** The next n bytes, raw (binary formats), or an error naming `what` when fewer remain. */
    const char* take(std::size_t n, const char* what) {
        if (remaining() < n)
            throw_error(ref_, "mesh '{}' ends early, in {} (the header promised more data)", path_,
                        what);
        const char* at = data_.data() + pos_;
        pos_ += n;
        return at;
    }

    double read(Type t, const char* what) {
        if (format_ == Format::Ascii) return read_ascii(t, what);
        const std::size_t n = size_of(t);
        unsigned char b[8];
        std::memcpy(b, take(n, what), n);
        if (format_ == Format::BinaryBig) std::reverse(b, b + n);
        switch (t) {
            case Type::Int8:
                return static_cast<double>(static_cast<int8_t>(b[0]));
            case Type::UInt8:
                return static_cast<double>(b[0]);
            case Type::Int16:
                return static_cast<double>(load<int16_t>(b));
            case Type::UInt16:
                return static_cast<double>(load<uint16_t>(b));
            case Type::Int32:
                return static_cast<double>(load<int32_t>(b));
            case Type::UInt32:
                return static_cast<double>(load<uint32_t>(b));
            case Type::Float32:
                return static_cast<double>(load<float>(b));
            case Type::Float64:
                return load<double>(b);
        }
        return 0.0;
    }

private:
    template <class T>
    static T load(const unsigned char* b) {
        T v;
        std::memcpy(&v, b, sizeof(T));
        return v;
    }

    double read_ascii(Type t, const char* what) {
        while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) ++pos_;
        const std::size_t start = pos_;
        while (pos_ < data_.size() && !std::isspace(static_cast<unsigned char>(data_[pos_])))
            ++pos_;
        if (pos_ == start)
            throw_error(ref_, "mesh '{}' ends early, in {} (the header promised more data)", path_,
                        what);
        const std::string token = data_.substr(start, std::min<std::size_t>(pos_ - start, 64));
        char* end = nullptr;
        const double v = std::strtod(token.c_str(), &end);
        if (end != token.c_str() + token.size() || pos_ - start > 64)
            throw_error(ref_, "mesh '{}': '{}' in {} is not a number", path_, token, what);
        const bool integer = t != Type::Float32 && t != Type::Float64;
        if (integer && v != std::floor(v))
            throw_error(ref_, "mesh '{}': '{}' in {} is not an integer", path_, token, what);
        return v;
    }

    const std::string& data_;
    std::size_t pos_;
    Format format_;
    const std::string& path_;
    const FileLoc& ref_;
};

/** A face corner with its own uv (MeshLab's per-corner texcoords). */
struct Wedge {
    uint32_t vertex = 0;
    float u = 0.0f, v = 0.0f;
    bool operator<(const Wedge& o) const {
        return std::tie(vertex, u, v) < std::tie(o.vertex, o.u, o.v);
    }
};

/** The index of e's list of corner indices (`vertex_indices`, or `vertex_index` as some
 *  writers name it); -1 when it has none. */
int corner_list(const Element& e) {
    int list = -1;
    for (std::size_t k = 0; k < e.props.size(); ++k)
        if (e.props[k].list &&
            (e.props[k].name == "vertex_indices" || e.props[k].name == "vertex_index"))
            list = static_cast<int>(k);
    return list;
}

}  // namespace

TriangleMesh read_ply(const std::string& path, const FileLoc& ref) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw_error(ref, "cannot read mesh '{}'", path);
    // Read whole: a regular file in one read of its size, anything else through the stream.
    std::string data;
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size > 0) {
        data.resize(static_cast<std::size_t>(size));
        in.seekg(0, std::ios::beg);
        in.read(data.data(), size);
        if (in.gcount() != size) throw_error(ref, "cannot read mesh '{}'", path);
    } else {
        in.clear();
        in.seekg(0, std::ios::beg);
        std::ostringstream ss;
        ss << in.rdbuf();
        data = ss.str();
    }

    // gzip'd (pbrt-v4's scenes ship meshes as .ply.gz): inflated whole.
    if (is_gzip(data)) data = inflate_gzip_file(path, ref);

    // The header: text lines up to "end_header". Its first line is "ply" (after a UTF-8 byte
    // order mark some tools write, and before trailing blanks some leave).
    if (data.starts_with("\xEF\xBB\xBF")) data.erase(0, 3);
    {
        const std::size_t eol = data.find('\n');
        std::string first = data.substr(0, std::min<std::size_t>(eol, 64));
        while (!first.empty() &&
               (first.back() == '\r' || first.back() == ' ' || first.back() == '\t'))
            first.pop_back();
        if (first != "ply" || eol == std::string::npos) {
            std::string shown;
            for (const char c : first.substr(0, 16))
                shown +=
                    static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7F
                        ? c
                        : '?';
            throw_error(ref,
                        "mesh '{}' is not a PLY file (its first line must be 'ply', it is '{}'{})",
                        path, shown,
                        eol == std::string::npos || first.find('\r') != std::string::npos
                            ? "; lines must end in a line feed"
                            : "");
        }
    }
    std::optional<Format> format;
    std::vector<Element> elements;
    std::size_t pos = data.find('\n') + 1;
    bool ended = false;
    for (int line_no = 2; pos < data.size(); ++line_no) {
        const std::size_t eol = data.find('\n', pos);
        if (eol == std::string::npos) break;
        std::string line = data.substr(pos, eol - pos);
        pos = eol + 1;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream words(line);
        std::string key;
        words >> key;
        const auto bad = [&](const std::string& why) {
            throw_error(ref, "mesh '{}': header line {}: {}", path, line_no, why);
        };
        if (key == "end_header") {
            ended = true;
            break;
        }
        if (key.empty() || key == "comment" || key == "obj_info") continue;
        if (key == "format") {
            std::string f, version;
            words >> f >> version;
            if (f == "ascii")
                format = Format::Ascii;
            else if (f == "binary_little_endian")
                format = Format::BinaryLittle;
            else if (f == "binary_big_endian")
                format = Format::BinaryBig;
            else
                bad(fmt::format("unknown format '{}'", f));
        } else if (key == "element") {
            Element e;
            std::string count;
            words >> e.name >> count;
            if (e.name.empty() || count.empty() ||
                count.find_first_not_of("0123456789") != std::string::npos || count.size() > 18)
                bad(fmt::format("'element' needs a name and a count, got '{}'", line));
            e.count = std::stoull(count);
            elements.push_back(e);
        } else if (key == "property") {
            if (elements.empty()) bad("a property before any element");
            Property p;
            std::string type;
            words >> type;
            if (type == "list") {
                std::string count_type, item_type;
                words >> count_type >> item_type >> p.name;
                const auto ct = parse_type(count_type), it = parse_type(item_type);
                if (!ct || !it || p.name.empty())
                    bad(fmt::format("malformed list property '{}'", line));
                if (*ct == Type::Float32 || *ct == Type::Float64)
                    bad("a list count must be an integer type");
                p.list = true;
                p.count_type = *ct;
                p.type = *it;
            } else {
                words >> p.name;
                const auto t = parse_type(type);
                if (!t || p.name.empty()) bad(fmt::format("malformed property '{}'", line));
                p.type = *t;
            }
            elements.back().props.push_back(p);
        } else {
            bad(fmt::format("unknown keyword '{}'", key));
        }
    }
    if (!ended)
        throw_error(ref, "mesh '{}' has no 'end_header' line (a truncated or damaged file)", path);
    if (!format) throw_error(ref, "mesh '{}' has no 'format' line in its header", path);

    // Every element takes at least this many bytes: what the header claims must fit the file.
    BodyReader reader(data, pos, *format, path, ref);
    {
        long double need = 0.0L;
        for (const Element& e : elements) {
            std::size_t each = 0;
            for (const Property& p : e.props)
                each += *format == Format::Ascii ? 2 : size_of(p.list ? p.count_type : p.type);
            need += static_cast<long double>(e.count) * static_cast<long double>(each);
        }
        if (need > static_cast<long double>(reader.remaining()) + 1.0L)
            throw_error(
                ref,
                "mesh '{}': its header claims {} but only {} bytes of data follow (a "
                "truncated or damaged file)",
                path,
                [&] {
                    std::string s;
                    for (const Element& e : elements)
                        s += (s.empty() ? "" : ", ") + fmt::format("{} {}", e.count, e.name);
                    return s;
                }(),
                reader.remaining());
    }

    TriangleMesh mesh;
    mesh.source = path;
    std::vector<Wedge> wedges;  // with per-corner uvs: each distinct (vertex, u, v)
    std::map<Wedge, uint32_t> wedge_ids;
    std::vector<uint32_t> polygons;         // faces of more than three corners, one after another
    std::vector<std::size_t> polygon_ends;  // where each ends in `polygons`
    bool have_vertices = false, have_faces = false;
    uint32_t largest_index = 0;
    uint64_t largest_face = 0;
    bool from_strips = false;  ///< the faces are a tristrips element's (its entries are strips)
    for (const Element& e : elements) {
        const auto find = [&](std::initializer_list<const char*> names) -> int {
            for (const char* n : names)
                for (std::size_t k = 0; k < e.props.size(); ++k)
                    if (e.props[k].name == n && !e.props[k].list) return static_cast<int>(k);
            return -1;
        };
        if (e.name == "vertex" && !have_vertices) {
            have_vertices = true;
            const int x = find({"x"}), y = find({"y"}), z = find({"z"});
            if (x < 0 || y < 0 || z < 0)
                throw_error(ref, "mesh '{}': its vertices have no x, y, z properties", path);
            const int nx = find({"nx"}), ny = find({"ny"}), nz = find({"nz"});
            const int u = find({"u", "s", "texture_u", "texture_s"});
            const int v = find({"v", "t", "texture_v", "texture_t"});
            const int cr = find({"red", "r", "diffuse_red"});
            const int cg = find({"green", "g", "diffuse_green"});
            const int cb = find({"blue", "b", "diffuse_blue"});
            const bool normals = nx >= 0 && ny >= 0 && nz >= 0, uvs = u >= 0 && v >= 0;
            const bool colors = cr >= 0 && cg >= 0 && cb >= 0;
            if (!colors && (cr >= 0 || cg >= 0 || cb >= 0))
                mesh.notes.push_back(
                    "its vertices have some of red, green and blue but not all "
                    "three: their colours are not read");
            mesh.positions.reserve(3 * e.count);
            if (colors) mesh.colors.reserve(3 * e.count);
            if (normals) mesh.normals.reserve(3 * e.count);
            if (uvs) mesh.uvs.reserve(2 * e.count);
            // The common layout, little-endian float properties only, is copied row by row (the
            // same values as the general path below, which converts through double).
            const bool raw_floats =
                *format == Format::BinaryLittle && std::endian::native == std::endian::little &&
                std::all_of(e.props.begin(), e.props.end(),
                            [](const Property& p) { return !p.list && p.type == Type::Float32; });
            if (raw_floats) {
                const std::size_t stride = 4 * e.props.size();
                const char* rows = reader.take(stride * e.count, "the vertices");
                mesh.positions.resize(3 * e.count);
                if (normals) mesh.normals.resize(3 * e.count);
                if (uvs) mesh.uvs.resize(2 * e.count);
                const auto copy = [&](std::vector<float>& out, std::initializer_list<int> props) {
                    const std::size_t width = props.size();
                    for (uint64_t i = 0; i < e.count; ++i) {
                        std::size_t c = 0;
                        for (const int k : props)
                            std::memcpy(&out[width * i + c++], rows + stride * i + 4 * k, 4);
                    }
                };
                copy(mesh.positions, {x, y, z});
                if (normals) copy(mesh.normals, {nx, ny, nz});
                if (uvs) copy(mesh.uvs, {u, v});
                if (colors) {
                    mesh.colors.resize(3 * e.count);
                    copy(mesh.colors, {cr, cg, cb});
                }
                continue;
            }
            std::vector<double> values(e.props.size());
            for (uint64_t i = 0; i < e.count; ++i) {
                for (std::size_t k = 0; k < e.props.size(); ++k) {
                    const Property& p = e.props[k];
                    if (!p.list) {
                        values[k] = reader.read(p.type, "the vertices");
                        continue;
                    }
                    const double n = reader.read(p.count_type, "the vertices");
                    if (n < 0 || n > static_cast<double>(reader.remaining()))
                        throw_error(ref,
                                    "mesh '{}': a vertex list of {} items does not fit the "
                                    "file",
                                    path, n);
                    for (uint64_t j = 0; j < static_cast<uint64_t>(n); ++j)
                        reader.read(p.type, "the vertices");
                }
                const auto f = [&](int k) { return static_cast<float>(values[k]); };
                mesh.positions.insert(mesh.positions.end(), {f(x), f(y), f(z)});
                if (normals) mesh.normals.insert(mesh.normals.end(), {f(nx), f(ny), f(nz)});
                if (uvs) mesh.uvs.insert(mesh.uvs.end(), {f(u), f(v)});
                if (colors)
                    for (const int k : {cr, cg, cb})
                        mesh.colors.push_back(
                            color_component(e.props[static_cast<std::size_t>(k)].type, values[k]));
            }
        } else if (e.name == "face" && !have_faces) {
            have_faces = true;
            const int list = corner_list(e);
            if (list < 0)
                throw_error(ref, "mesh '{}': its faces have no vertex_indices list", path);
            mesh.indices.reserve(3 * e.count);
            // The checks of a face's list, and where its corners go, for both paths below.
            const auto check_count = [&](uint64_t i, double n, double fit) {
                if (n < 0 || n > fit)
                    throw_error(ref,
                                "mesh '{}': face {} claims {} corners, more than the file holds",
                                path, i, n);
            };
            // A face of fewer than 3 corners (a point or an edge, as scanners write them) is not a
            // surface: skipped and counted (it failed the whole mesh).
            std::size_t short_faces = 0;
            // The largest corner index and its face, checked once the vertices are known (the
            // mesh's check named the triangle, not the file's face: face 0 a quad, "triangle 1").
            const auto track = [&](uint64_t i, uint32_t c) {
                if (c >= largest_index) {
                    largest_index = c;
                    largest_face = i;
                }
            };
            const auto bad_index = [&](uint64_t i, double c) {
                throw_error(ref, "mesh '{}': face {} has corner index {}", path, i, c);
            };
            // Triangles at once; polygons once every position is known (the vertex element
            // may come after the faces), by polygon.h (fans, or ear clipping when concave).
            const auto add_face = [&](const uint32_t* c, std::size_t n) {
                if (n == 3) {
                    mesh.indices.insert(mesh.indices.end(), {c[0], c[1], c[2]});
                    return;
                }
                polygons.insert(polygons.end(), c, c + n);
                polygon_ends.push_back(polygons.size());
            };
            // The common layout, one little-endian list of uchar count and int or uint indices,
            // read directly, with the general path's checks and messages.
            const Property& lp = e.props[static_cast<std::size_t>(list)];
            if (*format == Format::BinaryLittle && std::endian::native == std::endian::little &&
                e.props.size() == 1 && lp.count_type == Type::UInt8 &&
                (lp.type == Type::Int32 || lp.type == Type::UInt32)) {
                const bool is_signed = lp.type == Type::Int32;
                uint32_t corner[256];
                for (uint64_t i = 0; i < e.count; ++i) {
                    const auto n = static_cast<unsigned char>(*reader.take(1, "the faces"));
                    check_count(i, n, static_cast<double>(reader.remaining()));
                    const char* at = reader.take(4 * std::size_t{n}, "the faces");
                    for (unsigned j = 0; j < n; ++j) {
                        uint32_t c;
                        std::memcpy(&c, at + 4 * j, 4);
                        if (is_signed ? static_cast<int32_t>(c) < 0 : c == 0xffffffffu)
                            bad_index(i, is_signed ? static_cast<double>(static_cast<int32_t>(c))
                                                   : static_cast<double>(c));
                        corner[j] = c;
                        track(i, c);
                    }
                    if (n < 3) {
                        ++short_faces;
                        continue;
                    }
                    add_face(corner, n);
                }
                mesh.note_short_faces(short_faces);
                continue;
            }
            // Per-corner uvs (MeshLab's "wedge" texcoords: a list of u, v per corner on the
            // face): each distinct (vertex, u, v) becomes a vertex of its own (a seam splits).
            int texcoord = -1;
            for (std::size_t k = 0; k < e.props.size(); ++k)
                if (e.props[k].list && e.props[k].name == "texcoord")
                    texcoord = static_cast<int>(k);
            std::vector<uint32_t> corners;
            std::vector<double> uv;
            for (uint64_t i = 0; i < e.count; ++i) {
                uv.clear();
                corners.clear();
                for (std::size_t k = 0; k < e.props.size(); ++k) {
                    const Property& p = e.props[k];
                    if (!p.list) {
                        reader.read(p.type, "the faces");
                        continue;
                    }
                    const double n = reader.read(p.count_type, "the faces");
                    const double fit = static_cast<double>(reader.remaining()) /
                                       (*format == Format::Ascii ? 2.0 : 1.0);
                    check_count(i, n, fit);
                    if (static_cast<int>(k) == texcoord) {
                        for (uint64_t j = 0; j < static_cast<uint64_t>(n); ++j)
                            uv.push_back(reader.read(p.type, "the faces"));
                        continue;
                    }
                    if (static_cast<int>(k) != list) {
                        for (uint64_t j = 0; j < static_cast<uint64_t>(n); ++j)
                            reader.read(p.type, "the faces");
                        continue;
                    }
                    for (uint64_t j = 0; j < static_cast<uint64_t>(n); ++j) {
                        const double c = reader.read(p.type, "the faces");
                        if (!(c >= 0 && c < 4294967295.0) || c != std::floor(c)) bad_index(i, c);
                        corners.push_back(static_cast<uint32_t>(c));
                        track(i, static_cast<uint32_t>(c));
                    }
                    if (n < 3) {
                        ++short_faces;
                        corners.clear();
                    }
                }
                if (texcoord >= 0 && !corners.empty()) {
                    if (!uv.empty() && uv.size() != 2 * corners.size())
                        throw_error(ref,
                                    "mesh '{}': face {} has {} corners but {} texcoord values "
                                    "(two per corner)",
                                    path, i, corners.size(), uv.size());
                    for (std::size_t j = 0; j < corners.size(); ++j) {
                        const float cu = uv.empty() ? 0.0f : static_cast<float>(uv[2 * j]);
                        const float cv = uv.empty() ? 0.0f : static_cast<float>(uv[2 * j + 1]);
                        if (!std::isfinite(cu) || !std::isfinite(cv))
                            throw_error(ref, "mesh '{}': face {} has a non-finite texcoord", path,
                                        i);
                        const auto [it, added] = wedge_ids.try_emplace(
                            Wedge{corners[j], cu, cv}, static_cast<uint32_t>(wedges.size()));
                        if (added) wedges.push_back(Wedge{corners[j], cu, cv});
                        corners[j] = it->second;
                    }
                }
                if (!corners.empty()) add_face(corners.data(), corners.size());
            }
            mesh.note_short_faces(short_faces);
        } else if (e.name == "tristrips" && !have_faces) {
            // Triangle strips (the Stanford and Cyberware scans' layout: one list of indices per
            // entry, strips parted by -1): their triangles, every other one turned so that all
            // wind as the first. (They were "no face element".)
            have_faces = true;
            const int list = corner_list(e);
            if (list < 0)
                throw_error(ref, "mesh '{}': its tristrips have no vertex_indices list", path);
            from_strips = true;
            uint32_t strip[3] = {0, 0, 0};
            uint64_t in_strip = 0;
            for (uint64_t i = 0; i < e.count; ++i) {
                in_strip = 0;  // each entry's list is strips of its own
                for (std::size_t k = 0; k < e.props.size(); ++k) {
                    const Property& p = e.props[k];
                    const double n = p.list ? reader.read(p.count_type, "the strips") : 1.0;
                    if (n < 0 || n > static_cast<double>(reader.remaining()))
                        throw_error(ref, "mesh '{}': a strip of {} indices does not fit the file",
                                    path, n);
                    for (uint64_t j = 0; j < static_cast<uint64_t>(n); ++j) {
                        const double v = reader.read(p.type, "the strips");
                        if (static_cast<int>(k) != list) continue;
                        // The end of a strip: -1, or its unsigned 32-bit form.
                        if (v < 0.0 || v == 4294967295.0) {
                            in_strip = 0;
                            continue;
                        }
                        if (!(v < 4294967295.0) || v != std::floor(v))
                            throw_error(ref, "mesh '{}': strip {} has corner index {}", path, i, v);
                        const auto c = static_cast<uint32_t>(v);
                        if (c >= largest_index) {
                            largest_index = c;
                            largest_face = i;
                        }
                        strip[0] = strip[1];
                        strip[1] = strip[2];
                        strip[2] = c;
                        if (++in_strip < 3) continue;
                        const uint32_t a = strip[0], b = strip[1];
                        if (a == b || b == c || a == c) continue;  // a strip's turn: no area
                        if (in_strip % 2 == 1)
                            mesh.indices.insert(mesh.indices.end(), {a, b, c});
                        else
                            mesh.indices.insert(mesh.indices.end(), {b, a, c});
                    }
                }
            }
        } else if (!e.props.empty()) {
            // Skipped, but read through: its data lies before later elements'. (An element
            // without properties has no data, however many entries it claims.)
            for (uint64_t i = 0; i < e.count; ++i)
                for (const Property& p : e.props) {
                    const double n = p.list ? reader.read(p.count_type, "an element") : 1.0;
                    if (n < 0 || n > static_cast<double>(reader.remaining()))
                        throw_error(ref, "mesh '{}': a list of {} items does not fit the file",
                                    path, n);
                    for (uint64_t j = 0; j < static_cast<uint64_t>(n); ++j)
                        reader.read(p.type, "an element");
                }
        }
    }
    if (!have_vertices) throw_error(ref, "mesh '{}' has no vertex element", path);
    if (!have_faces) throw_error(ref, "mesh '{}' has no face element", path);
    if (largest_index >= mesh.vertex_count() && (!mesh.indices.empty() || !polygons.empty()))
        throw_error(ref, "mesh '{}': {} {} refers to vertex {}, but there are {} vertices", path,
                    from_strips ? "strip" : "face", largest_face, largest_index,
                    mesh.vertex_count());
    // Data left over in a binary file: its header's counts and its data disagree (a damaged or
    // mis-written file), said beside what was read.
    if (*format != Format::Ascii && reader.remaining() > 0 && !reader.only_line_end_remains())
        mesh.notes.push_back(
            fmt::format("{} byte{} follow the data its header describes (do "
                        "its element counts match the data?)",
                        reader.remaining(), reader.remaining() == 1 ? "" : "s"));
    if (!wedges.empty()) {
        // The corners' vertices, one per distinct (vertex, u, v); the faces index them.
        const std::size_t nv = mesh.vertex_count();
        TriangleMesh split;
        split.source = mesh.source;
        split.notes = std::move(mesh.notes);
        for (const Wedge& w : wedges) {
            if (w.vertex >= nv)
                throw_error(ref, "mesh '{}': a face refers to vertex {}, but there are {} vertices",
                            path, w.vertex, nv);
            const std::size_t v = w.vertex;
            split.positions.insert(split.positions.end(), mesh.positions.begin() + 3 * v,
                                   mesh.positions.begin() + 3 * v + 3);
            if (!mesh.normals.empty())
                split.normals.insert(split.normals.end(), mesh.normals.begin() + 3 * v,
                                     mesh.normals.begin() + 3 * v + 3);
            split.uvs.insert(split.uvs.end(), {w.u, w.v});
            if (!mesh.colors.empty())
                split.colors.insert(split.colors.end(), mesh.colors.begin() + 3 * v,
                                    mesh.colors.begin() + 3 * v + 3);
        }
        split.indices = std::move(mesh.indices);
        mesh = std::move(split);
    }
    triangulate_faces(mesh, polygons, polygon_ends);
    return mesh;
}

bool ply_header_counts(const std::string& path, uint64_t& vertices, uint64_t& faces) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    std::string line;
    bool first = true, has_vertices = false;
    vertices = faces = 0;
    for (int n = 0; n < 1000 && std::getline(in, line); ++n) {
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (first) {
            if (line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);
            while (!line.empty() && (line.back() == ' ' || line.back() == '\t')) line.pop_back();
            if (line != "ply") return false;
            first = false;
            continue;
        }
        std::istringstream words(line);
        std::string key, name, count;
        words >> key;
        if (key == "end_header") return has_vertices;
        if (key != "element") continue;
        words >> name >> count;
        if (count.empty() || count.size() > 18 ||
            count.find_first_not_of("0123456789") != std::string::npos)
            return false;
        if (name == "vertex") {
            vertices = std::stoull(count);
            has_vertices = true;
        } else if (name == "face") {
            faces = std::stoull(count);
        }
    }
    return false;
}

}  // namespace spangle
