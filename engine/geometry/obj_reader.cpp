#include "geometry/obj_reader.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>

#include "core/files.h"
#include "geometry/polygon.h"

namespace spangle {

namespace {

/** A corner's indices into the v, vt and vn lists (0-based; -1 = not given). */
struct Corner {
    int64_t v = -1, vt = -1, vn = -1;
    bool operator==(const Corner&) const = default;
};

struct CornerHash {
    std::size_t operator()(const Corner& c) const {
        uint64_t h = static_cast<uint64_t>(c.v) * 0x9E3779B97F4A7C15ull;
        h ^= static_cast<uint64_t>(c.vt) + 0x632BE59BD9B4E019ull + (h << 6) + (h >> 2);
        h ^= static_cast<uint64_t>(c.vn) + 0x8CB92BA72F3D8DD7ull + (h << 6) + (h >> 2);
        return static_cast<std::size_t>(h);
    }
};

class Reader {
public:
    /** `polygons`: keep each face's corners as written (a cage) instead of making triangles. */
    Reader(const std::string& path, const FileLoc& ref, bool polygons = false)
        : path_(path), ref_(ref), keep_polygons_(polygons), kind_(polygons ? "cage" : "mesh") {}

    TriangleMesh read() {
        parse();
        decode_colors();
        return finish();
    }

    ObjPolygons read_polygons() {
        parse();
        decode_colors();
        check_indices();
        raw_.positions = std::move(positions_);
        raw_.uvs = std::move(uvs_);
        raw_.colors = std::move(colors_);
        return std::move(raw_);
    }

private:
    void parse() {
        std::ifstream in(path_, std::ios::binary);
        if (!in) throw_error(ref_, "cannot open {} '{}': {}", kind_, path_, unreadable(path_));
        std::string line, joined;
        int first_line = 0;
        for (int number = 1; std::getline(in, line); ++number) {
            if (!line.empty() && line.back() == '\r') line.pop_back();
            // A UTF-8 byte order mark (some Windows tools write one) is not part of the text.
            if (number == 1 && line.starts_with("\xEF\xBB\xBF")) line.erase(0, 3);
            if (joined.empty()) first_line = number;
            // A backslash at the end of a line continues the statement on the next one.
            if (!line.empty() && line.back() == '\\') {
                line.back() = ' ';
                joined += line;
                continue;
            }
            joined += line;
            line_ = first_line;
            statement(joined);
            joined.clear();
        }
        if (!joined.empty()) {
            line_ = first_line;
            statement(joined);
        }
    }

    /** The colours as written (encoded; -1 where a vertex has none) to linear, one per vertex:
     *  fractions, or 0..255 where any exceeds 1 (as some tools write them); a vertex without a
     *  colour among coloured ones white. */
    void decode_colors() {
        float top = 0.0f;
        for (const float c : colors_) top = std::max(top, c);
        const double scale = top > 1.0f ? 1.0 / 255.0 : 1.0;
        if (top > 1.0f) notes_.push_back("its vertex colours exceed 1: read as 0..255");
        if (!colors_.empty()) colors_.resize(positions_.size(), -1.0f);  // the last without
        for (float& c : colors_)
            c = c >= 0.0f ? static_cast<float>(srgb_to_linear(
                                std::clamp(static_cast<double>(c) * scale, 0.0, 1.0)))
                          : 1.0f;
        if (zbrush_)
            notes_.push_back(
                "its ZBrush polypaint (#MRGB comments) is not read: export vertex "
                "colours as `v x y z r g b` (or PLY) to use them");
    }

    [[noreturn]] void fail(const std::string& what) const {
        throw_error(ref_, "{} '{}', line {}: {}", kind_, path_, line_, what);
    }

    static std::string_view next_token(std::string_view& s) {
        std::size_t b = 0;
        while (b < s.size() && (s[b] == ' ' || s[b] == '\t')) ++b;
        std::size_t e = b;
        while (e < s.size() && s[e] != ' ' && s[e] != '\t') ++e;
        const std::string_view token = s.substr(b, e - b);
        s.remove_prefix(e);
        return token;
    }

    float number(std::string_view token, const char* what) const {
        if (token.empty()) fail(fmt::format("{} is missing a number", what));
        const char* begin = token.data();
        if (*begin == '+') ++begin;  // from_chars does not take a leading '+'
        float value = 0.0f;
        const auto [end, ec] = std::from_chars(begin, token.data() + token.size(), value);
        if (ec == std::errc::result_out_of_range)
            fail(fmt::format("{} has '{}', out of the range of a float", what, token));
        if (ec != std::errc() || end != token.data() + token.size())
            fail(fmt::format("{} has '{}' where a number belongs", what, token));
        if (!std::isfinite(value))
            fail(fmt::format("{} has the non-finite value '{}'", what, token));
        return value;
    }

    /** Reads `count` numbers (more are allowed and ignored, fewer are an error). */
    void numbers(std::string_view rest, int count, std::vector<float>& out, const char* what) {
        for (int i = 0; i < count; ++i) out.push_back(number(next_token(rest), what));
    }

    /** One index of a corner: 1-based, or negative counting back from the last one read.
     *  Positive indices may point forward (checked at the end, in `worst`). */
    int64_t index(std::string_view token, std::size_t have, const char* kind,
                  std::pair<int64_t, int>& worst) const {
        int64_t i = 0;
        const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), i);
        if (ec != std::errc() || end != token.data() + token.size())
            fail(fmt::format("face corner has '{}' where a {} index belongs", token, kind));
        const auto n = static_cast<int64_t>(have);
        if (i == 0) fail(fmt::format("face refers to {} 0; OBJ indices start at 1", kind));
        if (i < 0 && n + i < 0)
            fail(fmt::format("face refers to {} {}, but only {} {} been read so far", kind, i, n,
                             n == 1 ? "has" : "have"));
        const int64_t resolved = i > 0 ? i - 1 : n + i;
        if (resolved > worst.first) worst = {resolved, line_};
        return resolved;
    }

    Corner corner(std::string_view token) {
        Corner c;
        const std::size_t s1 = token.find('/');
        c.v = index(token.substr(0, s1), positions_.size() / 3, "vertex", worst_v_);
        if (s1 == std::string_view::npos) return c;
        const std::string_view rest = token.substr(s1 + 1);
        const std::size_t s2 = rest.find('/');
        const std::string_view vt = rest.substr(0, s2);
        if (!vt.empty()) c.vt = index(vt, uvs_.size() / 2, "uv", worst_vt_);
        if (s2 != std::string_view::npos) {
            // "v/vt/" and "v//" (a trailing slash with nothing after it, as some exporters
            // write) give no normal.
            const std::string_view vn = rest.substr(s2 + 1);
            if (vn.find('/') != std::string_view::npos)
                fail(fmt::format("face corner '{}' is not v, v/vt, v//vn or v/vt/vn", token));
            if (!vn.empty()) c.vn = index(vn, normals_.size() / 3, "normal", worst_vn_);
        }
        return c;
    }

    uint32_t vertex_of(const Corner& c) {
        const auto [it, inserted] =
            vertices_.try_emplace(c, static_cast<uint32_t>(corners_.size()));
        if (inserted) {
            if (corners_.size() >= 0xFFFFFFFFull) fail("more than 2^32 - 1 distinct vertices");
            corners_.push_back(c);
        }
        return it->second;
    }

    void statement(std::string_view s) {
        // ZBrush writes its polypaint as `#MRGB` comments, which are not read: said once.
        if (s.starts_with("#MRGB")) zbrush_ = true;
        // A comment runs from '#' to the end of the line, also after a statement's data.
        s = s.substr(0, s.find('#'));
        const std::string_view keyword = next_token(s);
        if (keyword == "v") {
            std::string_view rest = s;
            for (int i = 0; i < 3; ++i) positions_.push_back(number(next_token(rest), "vertex"));
            // `v x y z r g b` (MeshLab and photogrammetry tools write vertex colours so; some add
            // an alpha; `v x y z w` is a weight, which Spangle ignores): sRGB-encoded fractions,
            // kept as written until the end (0..255 is recognised then).
            std::string_view more = rest;
            const std::string_view c0 = next_token(more), c1 = next_token(more),
                                   c2 = next_token(more), c3 = next_token(more);
            const bool colored = !c2.empty() && next_token(more).empty();
            if (colored) {
                colors_.resize(positions_.size() - 3, -1.0f);  // the vertices before without
                for (const std::string_view c : {c0, c1, c2})
                    colors_.push_back(std::max(number(c, "vertex colour"), 0.0f));
                if (!c3.empty()) number(c3, "vertex colour");  // an alpha: checked, not kept
                ++colored_;
            }
        } else if (keyword == "vt") {
            // u, and v when given (OBJ allows vt with one number).
            std::string_view rest = s;
            uvs_.push_back(number(next_token(rest), "uv"));
            const std::string_view v = next_token(rest);
            uvs_.push_back(v.empty() ? 0.0f : number(v, "uv"));
        } else if (keyword == "vn") {
            numbers(s, 3, normals_, "normal");
        } else if (keyword == "f" && keep_polygons_) {
            const std::size_t first = raw_.face_vertices.size();
            for (std::string_view t = next_token(s); !t.empty(); t = next_token(s)) {
                const Corner c = corner(t);
                raw_.face_vertices.push_back(c.v);
                raw_.face_uvs.push_back(c.vt);
            }
            const std::size_t n = raw_.face_vertices.size() - first;
            if (n < 3)
                fail(fmt::format("face has {} corner{}; a face needs at least 3", n,
                                 n == 1 ? "" : "s"));
            raw_.face_sizes.push_back(static_cast<int>(n));
            raw_.face_lines.push_back(line_);
        } else if (keyword == "f") {
            face_.clear();
            for (std::string_view t = next_token(s); !t.empty(); t = next_token(s))
                face_.push_back(vertex_of(corner(t)));
            // A point or an edge written as a face (scanners and some exporters write them):
            // not a surface, skipped and counted (it failed the whole mesh).
            if (face_.size() < 3) {
                ++short_faces_;
                return;
            }
            // Triangulated at the end, when every vertex a face may name forward is known.
            polygons_.insert(polygons_.end(), face_.begin(), face_.end());
            polygon_ends_.push_back(polygons_.size());
        } else if (keyword == "usemtl") {
            // Materials, lines and points are not read; a file of several materials is said
            // (its parts silently became one, the scene's material), once (finish()).
            // Everything else (comments, o, g, s, mtllib, curves) is not geometry Spangle
            // renders.
            const std::string name(next_token(s));
            if (materials_.insert(name).second && materials_.size() == 2) second_material_ = line_;
        } else if (keyword == "l" || keyword == "p") {
            if (!lines_seen_)
                notes_.push_back(
                    fmt::format("its lines and points ('{}' at line {}) are not surfaces: dropped",
                                keyword, line_));
            lines_seen_ = true;
        }
    }

    /** Checks the largest index of a kind against the number read. */
    void check(const std::pair<int64_t, int>& worst, std::size_t have, const char* kind) {
        if (worst.first < static_cast<int64_t>(have)) return;
        line_ = worst.second;
        fail(fmt::format("face refers to {} {}, but the file has {}", kind, worst.first + 1, have));
    }

    void check_indices() {
        check(worst_v_, positions_.size() / 3, "vertex");
        check(worst_vt_, uvs_.size() / 2, "uv");
        check(worst_vn_, normals_.size() / 3, "normal");
    }

    TriangleMesh finish() {
        check_indices();
        TriangleMesh mesh;
        mesh.source = path_;
        mesh.note_short_faces(short_faces_);
        mesh.notes.insert(mesh.notes.end(), notes_.begin(), notes_.end());
        bool all_normals = !corners_.empty(), any_uv = false;
        for (const Corner& c : corners_) {
            all_normals = all_normals && c.vn >= 0;
            any_uv = any_uv || c.vt >= 0;
        }
        mesh.positions.reserve(3 * corners_.size());
        for (const Corner& c : corners_) {
            const auto v = static_cast<std::size_t>(c.v);
            mesh.positions.insert(mesh.positions.end(), {positions_[3 * v], positions_[3 * v + 1],
                                                         positions_[3 * v + 2]});
            if (all_normals) {
                const auto n = static_cast<std::size_t>(c.vn);
                mesh.normals.insert(mesh.normals.end(),
                                    {normals_[3 * n], normals_[3 * n + 1], normals_[3 * n + 2]});
            }
            if (!colors_.empty())
                mesh.colors.insert(mesh.colors.end(),
                                   {colors_[3 * v], colors_[3 * v + 1], colors_[3 * v + 2]});
            if (any_uv) {
                const auto t = static_cast<std::size_t>(c.vt);
                mesh.uvs.insert(mesh.uvs.end(), {c.vt >= 0 ? uvs_[2 * t] : 0.0f,
                                                 c.vt >= 0 ? uvs_[2 * t + 1] : 0.0f});
            }
        }
        // Every face as triangles (geometry/polygon.h): a convex one as a fan around its first
        // corner, a concave one (an L, a U, a star, a ring cut open) by ear clipping in its
        // plane. The mesh's vertices are the distinct corners, in the order polygons_ names.
        triangulate_faces(mesh, polygons_, polygon_ends_);
        if (materials_.size() > 1)
            mesh.notes.push_back(fmt::format(
                "its {} materials (usemtl; the second at line {}) are not read: the object takes "
                "its scene material (split the file by material, or import it through glTF or "
                "pbrt, to give parts their own)",
                materials_.size(), second_material_));
        if (colored_ > 0 && colored_ < positions_.size() / 3)
            mesh.notes.push_back(fmt::format(
                "{} of its {} vertices have no colour among coloured ones: they are white",
                positions_.size() / 3 - colored_, positions_.size() / 3));
        return mesh;
    }

    std::string path_;
    FileLoc ref_;
    bool keep_polygons_ = false;
    const char* kind_ = "mesh";
    ObjPolygons raw_;
    int line_ = 0;
    std::vector<float> positions_, uvs_, normals_;
    /** rgb per vertex once any `v` had a colour: as written, -1 for vertices without; linear
     *  (white for those) after decode_colors(). */
    std::vector<float> colors_;
    std::size_t colored_ = 0;  ///< `v` statements with a colour
    bool zbrush_ = false;      ///< a `#MRGB` comment was seen
    std::vector<std::string> notes_;
    std::set<std::string> materials_;  ///< the usemtl names
    int second_material_ = 0;          ///< the line of the second usemtl name
    bool lines_seen_ = false;          ///< said once
    std::vector<uint32_t> face_;
    std::size_t short_faces_ = 0;            ///< faces of fewer than 3 corners, skipped
    std::vector<uint32_t> polygons_;         ///< every face's vertices, one after another
    std::vector<std::size_t> polygon_ends_;  ///< where each face ends in polygons_
    std::vector<Corner> corners_;
    std::pair<int64_t, int> worst_v_{-1, 0}, worst_vt_{-1, 0}, worst_vn_{-1, 0};
    std::unordered_map<Corner, uint32_t, CornerHash> vertices_;
};

}  // namespace

TriangleMesh read_obj(const std::string& path, const FileLoc& ref) {
    return Reader(path, ref).read();
}

ObjPolygons read_obj_polygons(const std::string& path, const FileLoc& ref) {
    return Reader(path, ref, true).read_polygons();
}

bool obj_counts(const std::string& path, uint64_t& vertices, uint64_t& faces, uint64_t& corners) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    vertices = faces = corners = 0;
    std::string line;
    const auto blank = [](char c) { return c == ' ' || c == '\t'; };
    while (std::getline(in, line)) {
        std::size_t i = 0;
        while (i < line.size() && blank(line[i])) ++i;
        if (i + 1 >= line.size() || !blank(line[i + 1])) continue;
        if (line[i] == 'v') {
            ++vertices;
        } else if (line[i] == 'f') {
            // Corners: the runs of non-blank characters after the "f" (a trailing '\r' is
            // blank to a run's end, not a corner of its own).
            uint64_t n = 0;
            bool in_run = false;
            for (std::size_t k = i + 1; k < line.size(); ++k) {
                const bool part = !blank(line[k]) && line[k] != '\r';
                if (part && !in_run) ++n;
                in_run = part;
            }
            if (n >= 3) {
                ++faces;
                corners += n;
            }
        }
    }
    return !in.bad();
}

}  // namespace spangle
