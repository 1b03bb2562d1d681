// Reading a .gltf or .glb through tinygltf: the JSON's syntax is checked first by our own
// scanner (which also records where each value is written), images are kept as their encoded
// bytes (the texture system decodes them), and the extensions the file requires are checked
// against those this reader understands.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <regex>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "core/files.h"
#include "core/text.h"
#include "scene/gltf/gltf_glb.h"
#include "scene/gltf/gltf_parts.h"
#include "scene/gltf/gltf_schema.h"

namespace spangle::gltf {
namespace {

/** Extensions this reader reads (a file may require them). */
const std::set<std::string> kRead = {
    "KHR_lights_punctual",
    "KHR_materials_clearcoat",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_texture_transform",
    "KHR_materials_emissive_strength",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_sheen",
    "KHR_materials_unlit",
    "KHR_materials_volume",
    "KHR_mesh_quantization",
    "KHR_draco_mesh_compression",
    "EXT_meshopt_compression",
    "EXT_mesh_gpu_instancing",
    "EXT_texture_webp",
    "SPANGLE_materials_flakes",
};

/** tinygltf's image callback: keeps the encoded bytes, decodes nothing. */
bool keep_bytes(tinygltf::Image*, const int index, std::string*, std::string*, int, int,
                const unsigned char* bytes, int size, void* user) {
    auto& images = *static_cast<std::vector<std::vector<unsigned char>>*>(user);
    if (index < 0 || size < 0) return true;
    if (images.size() <= static_cast<std::size_t>(index))
        images.resize(static_cast<std::size_t>(index) + 1);
    images[static_cast<std::size_t>(index)].assign(bytes, bytes + size);
    return true;
}

/** tinygltf's file access: regular files only (a URI naming a pipe or a device must not hang
 *  the reader), read whole, never written, paths taken as they are. */
bool regular_file(const std::string& path, void*) {
    std::error_code ec;
    return std::filesystem::is_regular_file(path, ec);
}

/** Paths are not expanded (no ~, no variables), except a file:// URI joined to the file's
 *  folder (tinygltf looks for "DIR/file:///x.bin"): its path, as check_buffers() took it; and
 *  a path written with Windows backslashes, as slashed_where_missing() takes it. */
std::string same_path(const std::string& path, void*) {
    const std::size_t at = ascii_lower(path).find("file://");
    if (at == std::string::npos) return slashed_where_missing(path);
    std::string host, local;
    return split_file_uri(std::string_view(path).substr(at + 7), host, local) && !local.empty()
               ? local
               : path;
}

/** The byteLengths of the buffers naming each file, in buffer order, by the file's canonical
 *  path (check_buffers()); tinygltf reads the buffers in that order, so the n-th read of a file
 *  is the n-th buffer naming it (two buffers may name one file with different lengths). */
struct BufferLengths {
    std::unordered_map<std::string, std::vector<uintmax_t>> by_path;
    std::unordered_map<std::string, std::size_t> reads;  ///< reads of each file so far
};

std::string canonical_key(const std::string& path) {
    std::error_code ec;
    const std::filesystem::path p = std::filesystem::weakly_canonical(path, ec);
    return ec ? path : p.string();
}

/** tinygltf's file reading: a buffer's file longer than its byteLength is read up to it (glTF
 *  2.0, 5.10: the resource may be longer, as .bin files padded to 4 bytes are; tinygltf refused
 *  any size but byteLength's). `user` is the BufferLengths. */
bool read_regular_file(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                       void* user) {
    if (!regular_file(path, nullptr)) {
        if (err) *err += "'" + path + "' is not a regular file\n";
        return false;
    }
    std::ifstream in(path, std::ios::binary);
    out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    if (!in.eof() && in.fail()) {
        if (err) *err += "cannot read '" + path + "'\n";
        return false;
    }
    if (auto* lengths = static_cast<BufferLengths*>(user)) {
        const std::string key = canonical_key(path);
        if (const auto it = lengths->by_path.find(key); it != lengths->by_path.end()) {
            const std::size_t n = lengths->reads[key]++;
            if (n < it->second.size() && it->second[n] < out->size()) out->resize(it->second[n]);
        }
    }
    return true;
}

/** tinygltf's message made fit to print: its lines joined by "; ", control characters (a NUL
 *  from a bad percent escape) dropped, and each line cut at 200 characters (it quotes a whole
 *  base64 data URI, megabytes, when one does not decode). */
std::string readable(const std::string& text) {
    std::string out, line;
    const auto flush = [&] {
        while (!line.empty() && line.back() == ' ') line.pop_back();
        if (line.empty()) return;
        if (line.size() > 200) line = line.substr(0, 200) + "...";
        if (!out.empty()) out += "; ";
        out += line;
        line.clear();
    };
    for (const char c : text) {
        if (c == '\n' || c == '\r') {
            flush();
        } else if (static_cast<unsigned char>(c) >= 0x20) {
            line += c;
        }
    }
    flush();
    return out;
}

/** The reader never writes through tinygltf. */
bool write_nothing(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
    if (err) *err += "the glTF reader writes no files\n";
    return false;
}

/** Extensions noted where they are used (a material, a primitive, a texture), not here. */
bool noted_in_place(const std::string& e) {
    return (e.rfind("KHR_materials_", 0) == 0 && e != "KHR_materials_variants") ||
           e == "KHR_texture_basisu";
}

/** The buffers that only stand in for data EXT_meshopt_compression decodes: those its
 *  extension marks "fallback": true (gltfpack writes them without a uri; -cf with one, which
 *  need not exist), and those without a uri that compressed views decode into (the
 *  extension's own example marks none), except a .glb's first buffer without a uri (its BIN
 *  chunk). They hold nothing to read. */
std::set<int> placeholder_buffers(const Context& ctx, bool binary) {
    std::set<int> out;
    for (std::size_t i = 0; ctx.json.has(fmt::format("buffers/{}", i)); ++i) {
        const std::string b = fmt::format("buffers/{}", i);
        const std::string* fallback =
            ctx.json.scalar(b + "/extensions/EXT_meshopt_compression/fallback");
        if (fallback && *fallback == "true") out.insert(static_cast<int>(i));
    }
    for (std::size_t v = 0; ctx.json.has(fmt::format("bufferViews/{}", v)); ++v) {
        const std::string vp = fmt::format("bufferViews/{}", v);
        if (!ctx.json.has(vp + "/extensions/EXT_meshopt_compression")) continue;
        const std::string* buffer = ctx.json.scalar(vp + "/buffer");
        if (!buffer) continue;
        char* end = nullptr;
        const long b = std::strtol(buffer->c_str(), &end, 10);
        if (*end != '\0' || b < 0 || b > 1000000000) continue;
        const std::string bp = fmt::format("buffers/{}", b);
        const bool uri = ctx.json.scalar(bp + "/uri") || ctx.json.has(bp + "/uri");
        if (ctx.json.has(bp) && !uri && !(binary && b == 0)) out.insert(static_cast<int>(b));
    }
    return out;
}

/** The JSON tinygltf is given: the file's, with the values it refuses made acceptable
 *  (decompress() and load_document() undo them): each meshopt fallback buffer becomes a one-byte
 *  data URI (tinygltf refuses a .gltf buffer without a uri, and gave a .glb's the BIN chunk's
 *  bytes); each accessor without a view names view 0 (tinygltf refuses indices without one,
 *  which Draco-compressed primitives have), a file without views and buffers getting a one-byte
 *  buffer and a view of it; skins without inverseBindMatrices and animation targets without a
 *  node get -1 (absent). Empty when nothing needs it (the JSON as it is). `viewless` gets the
 *  accessors changed. */
std::string tinygltf_json(const Context& ctx, std::string_view json, std::vector<int>& viewless) {
    struct Edit {
        std::size_t start, end;
        std::string text;
    };
    std::vector<Edit> edits;
    for (std::size_t i = 0; ctx.json.has(fmt::format("buffers/{}", i)); ++i) {
        if (!ctx.placeholder_buffers.count(static_cast<int>(i))) continue;
        const auto [start, end] = ctx.json.span(fmt::format("buffers/{}", i));
        if (end > start && end <= json.size())
            edits.push_back(
                {start, end,
                 R"({"byteLength":1,"uri":"data:application/octet-stream;base64,AA=="})"});
    }
    // A file without buffer views whose accessors are all zeros or sparse (valid glTF): a view
    // for them to name, in a one-byte buffer of its own when the file has none either.
    const bool no_views = !ctx.json.has("bufferViews");
    if (no_views && !ctx.json.has("buffers")) {
        const std::size_t root = json.find('{');
        bool viewless_accessor = false;
        for (std::size_t i = 0; ctx.json.has(fmt::format("accessors/{}", i)); ++i)
            viewless_accessor =
                viewless_accessor || !ctx.json.has(fmt::format("accessors/{}/bufferView", i));
        if (root != std::string_view::npos && viewless_accessor)
            edits.push_back(
                {root, root + 1,
                 R"({"buffers":[{"byteLength":1,"uri":"data:application/octet-stream;base64,AA=="}],)"
                 R"("bufferViews":[{"buffer":0,"byteLength":1}],)"});
    }
    if (ctx.json.has("bufferViews/0") || (no_views && !ctx.json.has("buffers")))
        for (std::size_t i = 0; ctx.json.has(fmt::format("accessors/{}", i)); ++i) {
            const std::string a = fmt::format("accessors/{}", i);
            if (ctx.json.scalar(a + "/bufferView") || ctx.json.has(a + "/bufferView")) continue;
            const auto [start, end] = ctx.json.span(a);
            if (end <= start || end > json.size() || json[start] != '{') continue;
            edits.push_back({start, start + 1, R"({"bufferView":0,)"});
            // An accessor written "{}" has no member to follow the inserted one.
            const std::size_t next = json.find_first_not_of(" \t\r\n", start + 1);
            if (next != std::string_view::npos && json[next] == '}')
                edits.back().text = R"({"bufferView":0)";
            viewless.push_back(static_cast<int>(i));
        }
    // A member tinygltf 2.7 requires where glTF does not: a skin's inverseBindMatrices
    // (identity matrices when absent) and a channel target's node (KHR_animation_pointer's
    // channels have none; they are noted and dropped): -1, read as absent.
    const auto insert_member = [&](const std::string& path, const char* member) {
        const auto [start, end] = ctx.json.span(path);
        if (end <= start || end > json.size() || json[start] != '{') return;
        const std::size_t next = json.find_first_not_of(" \t\r\n", start + 1);
        const bool empty = next != std::string_view::npos && json[next] == '}';
        edits.push_back(
            {start, start + 1, fmt::format(R"({{"{}":-1{})", member, empty ? "" : ",")});
    };
    for (std::size_t i = 0; ctx.json.has(fmt::format("skins/{}", i)); ++i) {
        const std::string sk = fmt::format("skins/{}", i);
        if (!ctx.json.has(sk + "/joints"))
            throw_error(ctx.at(sk), "skin {} has no 'joints' (glTF requires them)", i);
        if (!ctx.json.has(sk + "/inverseBindMatrices") &&
            !ctx.json.scalar(sk + "/inverseBindMatrices"))
            insert_member(sk, "inverseBindMatrices");
    }
    for (std::size_t a = 0; ctx.json.has(fmt::format("animations/{}", a)); ++a)
        for (std::size_t c = 0; ctx.json.has(fmt::format("animations/{}/channels/{}", a, c)); ++c) {
            const std::string t = fmt::format("animations/{}/channels/{}/target", a, c);
            if (ctx.json.has(t) && !ctx.json.has(t + "/node")) insert_member(t, "node");
        }
    if (edits.empty()) return {};
    std::sort(edits.begin(), edits.end(),
              [](const Edit& a, const Edit& b) { return a.start < b.start; });
    std::string out;
    std::size_t copied = 0;
    for (const Edit& e : edits) {
        if (e.start < copied) continue;
        out.append(json.substr(copied, e.start - copied));
        out += e.text;
        copied = e.end;
    }
    out.append(json.substr(copied));
    return out;
}

/** Fails on a required extension Spangle does not read (from the JSON itself, before tinygltf
 *  reads the data it changes: Draco-compressed accessors without a buffer view failed there as
 *  "accessor[3] invalid bufferView"). */
void check_required(const Context& ctx) {
    const std::vector<std::string>& required = ctx.json.required_extensions();
    for (std::size_t i = 0; i < required.size(); ++i)
        // Material variants leave each primitive's default material in place, which is read
        // (Blender 3.3 wrote the extension as required): noted as unread, not refused.
        if (!kRead.count(required[i]) && required[i] != "KHR_materials_variants")
            throw_error(ctx.at(fmt::format("extensionsRequired/{}", i)),
                        "the file requires extension {}, which Spangle does not read: re-export "
                        "it without the extension, or take it out of extensionsRequired if the "
                        "file's core data stands without it (then what the extension adds is "
                        "left out){}",
                        required[i],
                        required[i] == "KHR_texture_basisu"
                            ? "; gltf-transform can turn its KTX2 textures into PNG"
                            : "");
}

/** The bytes a base64 data URI's payload decodes to; -1 when it is not base64 (RFC 4648: the
 *  alphabet, '=' padding only at the end). */
long long base64_bytes(std::string_view data) {
    std::size_t n = 0, pad = 0;
    for (const char c : data) {
        const bool letter = std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '/' ||
                            c == '-' || c == '_';
        if (c == '=') {
            ++pad;
        } else if (!letter || pad > 0) {
            return -1;
        } else {
            ++n;
        }
    }
    if (pad > 2 || n % 4 == 1) return -1;
    return static_cast<long long>(n / 4 * 3 + (n % 4 == 0 ? 0 : n % 4 - 1));
}

/** A JSON string's text without its escapes (\\/ for '/', as some writers write every slash;
 *  \\uXXXX as UTF-8): the uri tinygltf reads. */
std::string json_unescaped(std::string_view text) {
    std::string out;
    for (std::size_t i = 0; i < text.size(); ++i) {
        if (text[i] != '\\' || i + 1 >= text.size()) {
            out += text[i];
            continue;
        }
        const char c = text[++i];
        switch (c) {
            case 'b':
                out += '\b';
                break;
            case 'f':
                out += '\f';
                break;
            case 'n':
                out += '\n';
                break;
            case 'r':
                out += '\r';
                break;
            case 't':
                out += '\t';
                break;
            case 'u': {
                unsigned code = 0;
                std::size_t k = 0;
                for (; k < 4 && i + 1 + k < text.size() &&
                       std::isxdigit(static_cast<unsigned char>(text[i + 1 + k]));
                     ++k)
                    code = code * 16 + static_cast<unsigned>(
                                           std::stoi(std::string(1, text[i + 1 + k]), nullptr, 16));
                i += k;
                if (code < 0x80) {
                    out += static_cast<char>(code);
                } else if (code < 0x800) {
                    out += static_cast<char>(0xC0 | (code >> 6));
                    out += static_cast<char>(0x80 | (code & 0x3F));
                } else {
                    out += static_cast<char>(0xE0 | (code >> 12));
                    out += static_cast<char>(0x80 | ((code >> 6) & 0x3F));
                    out += static_cast<char>(0x80 | (code & 0x3F));
                }
                break;
            }
            default:
                out += c;  // \" \\ \/
        }
    }
    return out;
}

/** Each buffer's data checked before tinygltf reads it, each fault said at its "uri" or
 *  "byteLength" with what it holds (tinygltf said "File not found : x.bin" or "Failed to decode
 *  'uri'" at 1:1 without saying which buffer, where it looked, or that a data URI was short, and
 *  took a file:// URI for a relative path). A .glb's first buffer without a uri is its BIN
 *  chunk, which tinygltf checks. Returns the byteLength of each buffer's file (by canonical
 *  path), which is what is read of a longer file. */
BufferLengths check_buffers(const Context& ctx, bool binary) {
    BufferLengths lengths;
    for (std::size_t i = 0; ctx.json.has(fmt::format("buffers/{}", i)); ++i) {
        const std::string at = fmt::format("buffers/{}/uri", i);
        const std::string length_at = fmt::format("buffers/{}/byteLength", i);
        const std::string* uri_text = ctx.json.scalar(at);
        const std::string* length_text = ctx.json.scalar(length_at);
        if (!length_text && ctx.json.has(length_at))
            throw_error(ctx.at(length_at), "buffer {}: byteLength must be a number", i);
        if (!length_text)
            throw_error(ctx.at(fmt::format("buffers/{}", i)),
                        "buffer {} has no byteLength (its size in bytes, which glTF requires)", i);
        if (length_text->starts_with('"'))
            throw_error(ctx.at(length_at),
                        "buffer {}: byteLength {} is a string; write the number without quotes", i,
                        *length_text);
        char* end = nullptr;
        const double length = std::strtod(length_text->c_str(), &end);
        if (end != length_text->c_str() && *end == '\0' && length >= 1 && length <= 9.0e15 &&
            length == std::floor(length) && length_text->find_first_of(".eE") != std::string::npos)
            throw_error(ctx.at(length_at),
                        "buffer {}: byteLength {} must be written as a whole number ({:.0f}): "
                        "glTF readers take it as an integer",
                        i, *length_text, length);
        if (end == length_text->c_str() || *end != '\0' || !(length >= 1) ||
            length != std::floor(length) || length > 9.0e15)
            throw_error(ctx.at(length_at),
                        "buffer {}: byteLength {} is not a size in bytes (a whole number, at "
                        "least 1)",
                        i, *length_text);
        if (uri_text && !uri_text->starts_with('"'))
            throw_error(ctx.at(at), "buffer {}: its uri must be a string, not {}", i, *uri_text);
        const std::optional<std::string> uri_value =
            uri_text ? std::optional(json_unescaped(uri_text->substr(1, uri_text->size() - 2)))
                     : std::nullopt;
        const std::string* uri = uri_value ? &*uri_value : nullptr;
        if (!uri && ctx.json.has(at))
            throw_error(ctx.at(at), "buffer {}: its uri must be a string", i);
        if (ctx.placeholder_buffers.count(static_cast<int>(i))) continue;  // holds nothing
        if (!uri && binary && i == 0) {                                    // the BIN chunk
            // tinygltf said "Invalid `byteLength'" at 1:1, or "empty BIN chunk".
            if (!ctx.bin_chunk)
                throw_error(ctx.at(fmt::format("buffers/{}", i)),
                            "buffer 0 has no uri, so its data is the .glb's BIN chunk, but the "
                            "file has none");
            if (length > static_cast<double>(*ctx.bin_chunk))
                throw_error(ctx.at(length_at),
                            "buffer 0: byteLength {} is more than the .glb's BIN chunk holds ({} "
                            "bytes)",
                            *length_text, *ctx.bin_chunk);
            continue;
        }
        if (!uri)
            throw_error(ctx.at(fmt::format("buffers/{}", i)), "buffer {} has no uri: {}", i,
                        binary ? "only a .glb's first buffer is its BIN chunk, the others name "
                                 "their data"
                               : "a .gltf's buffers name their data (a .bin file or a data URI)");
        if (uri->empty())
            throw_error(ctx.at(at), "buffer {}: its uri is empty (it names no file)", i);
        if (uri->rfind("data:", 0) == 0) {
            const std::size_t comma = uri->find(',');
            const std::string_view head = std::string_view(*uri).substr(0, comma);
            if (comma != std::string::npos && ascii_lower(head).ends_with(";base64") &&
                !head.ends_with(";base64"))
                throw_error(ctx.at(at), "buffer {}: write ';base64' in a data URI in lower case",
                            i);
            if (comma == std::string::npos || !head.ends_with(";base64"))
                throw_error(ctx.at(at),
                            "buffer {}: a data URI must be base64 (\"data:...;base64,...\")", i);
            const std::string lower_head = ascii_lower(head);
            if (head != lower_head && (lower_head == "data:application/octet-stream;base64" ||
                                       lower_head == "data:application/gltf-buffer;base64"))
                throw_error(ctx.at(at),
                            "buffer {}: write the data URI's media type in lower case ('{}'): "
                            "glTF readers compare it as written",
                            i, lower_head.substr(5, lower_head.size() - 12));
            if (head != "data:application/octet-stream;base64" &&
                head != "data:application/gltf-buffer;base64")
                throw_error(ctx.at(at),
                            "buffer {}: data URI of type '{}': a buffer's is "
                            "application/octet-stream or application/gltf-buffer",
                            i, head.substr(5, head.size() - 12));
            const long long bytes = base64_bytes(std::string_view(*uri).substr(comma + 1));
            if (bytes < 0) throw_error(ctx.at(at), "buffer {}: its data URI is not base64", i);
            if (static_cast<double>(bytes) != length)
                throw_error(ctx.at(at),
                            "buffer {}: its data URI holds {} bytes, its byteLength says {}{}", i,
                            bytes, *length_text,
                            static_cast<double>(bytes) > length
                                ? " (Spangle reads a data URI of byteLength bytes exactly)"
                                : "");
            continue;
        }
        const UriTarget target = uri_target(ctx, *uri);
        if (target.path.empty() && target.host.empty())
            throw_error(ctx.at(at),
                        "buffer {}: URI '{}' is not fetched (Spangle reads files, not {} URIs)", i,
                        *uri, target.scheme);
        if (target.path.empty())
            throw_error(ctx.at(at), "buffer {}: URI '{}' names host '{}', not this machine", i,
                        *uri, target.host);
        std::error_code ec;
        if (!std::filesystem::is_regular_file(target.path, ec))
            throw_error(ctx.at(at), "buffer {}: file '{}' not found (looked for {})", i, *uri,
                        absolute_path(target.path));
        const uintmax_t size = std::filesystem::file_size(target.path, ec);
        if (!ec && static_cast<double>(size) < length)
            throw_error(ctx.at(at), "buffer {}: file '{}' holds {} bytes, its byteLength says {}",
                        i, *uri, size, *length_text);
        lengths.by_path[canonical_key(target.path)].push_back(static_cast<uintmax_t>(length));
    }
    return lengths;
}

/** Each accessor's count, componentType and type checked where written, before tinygltf reads
 *  them (it said "'count' property is not a positive integer" or "Invalid accessor type" at
 *  1:1, without saying which accessor). */
void check_accessors(const Context& ctx) {
    for (std::size_t i = 0; ctx.json.has(fmt::format("accessors/{}", i)); ++i) {
        const std::string ap = fmt::format("accessors/{}", i);
        const std::string* count = ctx.json.scalar(ap + "/count");
        if (!count)
            throw_error(ctx.at(ap), "accessor {} has no count (the number of its elements)", i);
        char* end = nullptr;
        const double n = std::strtod(count->c_str(), &end);
        if (count->starts_with('"') || end == count->c_str() || *end != '\0' || !(n >= 1) ||
            n != std::floor(n) || count->find_first_of(".eE") != std::string::npos ||
            n > 4294967295.0)
            throw_error(ctx.at(ap + "/count"),
                        "accessor {}: count {} is not a number of elements (a whole number, at "
                        "least 1, written without a fraction)",
                        i, *count);
        const std::string* component = ctx.json.scalar(ap + "/componentType");
        if (!component)
            throw_error(ctx.at(ap),
                        "accessor {} has no componentType (5120 to 5126: the type of its numbers)",
                        i);
        if (*component != "5120" && *component != "5121" && *component != "5122" &&
            *component != "5123" && *component != "5125" && *component != "5126")
            throw_error(ctx.at(ap + "/componentType"),
                        "accessor {}: componentType {} is not one of glTF's (5120 byte, 5121 "
                        "unsigned byte, 5122 short, 5123 unsigned short, 5125 unsigned int, 5126 "
                        "float)",
                        i, *component);
        const std::string* type = ctx.json.scalar(ap + "/type");
        if (!type)
            throw_error(ctx.at(ap), "accessor {} has no type (SCALAR, VEC2 to VEC4, MAT2 to MAT4)",
                        i);
        bool known = false;
        for (const char* t :
             {"\"SCALAR\"", "\"VEC2\"", "\"VEC3\"", "\"VEC4\"", "\"MAT2\"", "\"MAT3\"", "\"MAT4\""})
            known = known || *type == t;
        if (!known)
            throw_error(ctx.at(ap + "/type"),
                        "accessor {}: type {} is not one of glTF's (SCALAR, VEC2, VEC3, VEC4, "
                        "MAT2, MAT3, MAT4)",
                        i, *type);
    }
}

/** A whole number the file writes at `path` (kept by JsonLocations), or `fallback` when it
 *  writes none or something else there (tinygltf's own checks say what). */
double whole_at(const Context& ctx, const std::string& path, double fallback) {
    const std::string* t = ctx.json.scalar(path);
    if (!t || t->starts_with('"')) return fallback;
    char* end = nullptr;
    const double v = std::strtod(t->c_str(), &end);
    return end != t->c_str() && *end == '\0' && v >= 0 && v == std::floor(v) ? v : fallback;
}

/** Each image held in a buffer view checked to lie inside its buffer, before tinygltf reads it:
 *  tinygltf hands the view's bytes to the image callback without checking the view against the
 *  buffer (a view one byte past its buffer was read past the end of the buffer's memory). */
void check_image_views(const Context& ctx) {
    for (std::size_t i = 0; ctx.json.has(fmt::format("images/{}", i)); ++i) {
        const std::string ip = fmt::format("images/{}/bufferView", i);
        const double view = whole_at(ctx, ip, -1);
        if (view < 0) continue;
        const std::string vp = fmt::format("bufferViews/{:.0f}", view);
        if (!ctx.json.has(vp)) continue;  // tinygltf says the view does not exist
        const double buffer = whole_at(ctx, vp + "/buffer", -1);
        const double offset = whole_at(ctx, vp + "/byteOffset", 0);
        const double length = whole_at(ctx, vp + "/byteLength", -1);
        // (A buffer index beyond any file's: tinygltf says it does not exist.)
        if (buffer < 0 || buffer > 1e9 || length < 0) continue;
        const std::string bp = fmt::format("buffers/{:.0f}", buffer);
        if (ctx.placeholder_buffers.count(static_cast<int>(buffer)))
            throw_error(ctx.at(ip),
                        "image {}: buffer view {:.0f} lies in buffer {:.0f}, a meshopt fallback "
                        "buffer, which holds no data",
                        i, view, buffer);
        const double size = whole_at(ctx, bp + "/byteLength", -1);
        if (ctx.json.has(bp) && size >= 0 && offset + length > size)
            throw_error(ctx.at(ip),
                        "image {}: buffer view {:.0f} ({:.0f} bytes from byte {:.0f}) runs past "
                        "the end of buffer {:.0f} ({:.0f} bytes)",
                        i, view, length, offset, buffer, size);
    }
}

/** Notes used extensions not read (once each). */
void check_extensions(Context& ctx) {
    for (const std::string& e : ctx.model.extensionsUsed)
        if (!kRead.count(e) && !noted_in_place(e))
            ctx.note("extension " + e, ctx.at("extensionsUsed"),
                     e == "KHR_materials_variants"
                         ? std::string("extension KHR_materials_variants is not read: each "
                                       "primitive is drawn in its default material")
                         : fmt::format("extension {} is not read: what it adds is dropped (the "
                                       "core glTF data it extends stands in)",
                                       e));
}

/** Where an error of tinygltf's is written: its messages name an element ("accessor[0] invalid
 *  bufferView", "image[0] buffer \"1\" not found"), placed at that element's member when the
 *  message names one, else at the element; the document's start when it names none. */
FileLoc tinygltf_error_place(const Context& ctx, const std::string& err) {
    static const std::regex element(
        R"((accessor|bufferView|buffer|image|mesh|node|material|texture|sampler|skin|camera|animation|scene)\[(\d+)\])");
    std::smatch m;
    if (!std::regex_search(err, m, element)) return FileLoc{ctx.path, 1, 1};
    const std::string kind = m[1].str();
    std::string path = (kind == "mesh" ? std::string("meshes") : kind + "s") + "/" + m[2].str();
    const std::string rest = m.suffix().str();
    for (const char* member : {"bufferView", "byteLength", "byteOffset", "buffer", "indices",
                               "count", "sampler", "source", "mesh", "skin", "camera"})
        if (rest.find(member) != std::string::npos) {
            path += std::string("/") + member;
            break;
        }
    return ctx.at(path);
}

}  // namespace

void load_document(Context& ctx) {
    std::string bytes = read_file_bytes(ctx.path);
    // A UTF-8 byte-order mark before the JSON (Windows editors write one; RFC 8259 lets a
    // reader ignore it): skipped ("unexpected character" at 1:1 before).
    if (bytes.compare(0, 3, "\xEF\xBB\xBF") == 0) bytes.erase(0, 3);
    // A .glb is binary whatever its first bytes (one without the 'glTF' magic was read as JSON:
    // "unexpected character 'g'"); a file of another name is by its magic.
    const std::size_t first = bytes.find_first_not_of(" \t\r\n");
    // (An empty .glb, or one of white space, is a .glb too short, not JSON that ends early.)
    const bool binary =
        (bytes.size() >= 4 && bytes.compare(0, 4, "glTF") == 0) ||
        (ascii_lower(std::filesystem::path(ctx.path).extension().string()) == ".glb" &&
         (first == std::string::npos || bytes[first] != '{'));
    if (binary && bytes.size() >= 20 && bytes.compare(0, 4, "glTF") == 0) {
        // Its JSON chunk as writers get it wrong, mended in place (same length, so sizes and
        // places stand): a byte-order mark before it and NUL padding after it (the spec pads
        // with spaces) become spaces; both were "unexpected character" errors.
        const std::size_t end =
            std::min<std::size_t>(bytes.size(), 20 + std::size_t{glb_u32(bytes, 12)});
        if (bytes.compare(20, 3, "\xEF\xBB\xBF") == 0) bytes.replace(20, 3, "   ");
        for (std::size_t i = end; i > 20 && bytes[i - 1] == '\0'; --i) bytes[i - 1] = ' ';
        // An empty BIN chunk after it (draco_transcoder writes one for a file without buffer
        // data; the spec says to leave the chunk out): left out, as tinygltf refused it.
        if (bytes.size() == end + 8 && glb_u32(bytes, 8) == bytes.size() &&
            glb_u32(bytes, end) == 0 && glb_u32(bytes, end + 4) == 0x004E4942u) {
            bytes.resize(end);
            const auto length = static_cast<uint32_t>(end);
            std::memcpy(bytes.data() + 8, &length, 4);
        }
    }
    GlbChunks chunks{std::string_view(bytes), std::nullopt};
    if (binary) chunks = glb_chunks(bytes, ctx.path);
    const std::string_view json = chunks.json;
    ctx.bin_chunk = chunks.bin;
    ctx.json = JsonLocations(json, ctx.path);
    check_required(ctx);
    check_kinds(ctx);
    ctx.placeholder_buffers = placeholder_buffers(ctx, binary);
    BufferLengths buffer_lengths = check_buffers(ctx, binary);
    check_accessors(ctx);
    check_image_views(ctx);
    check_texture_indices(ctx);
    if (bytes.size() > 0xFFFFFFFFu)
        throw_error(FileLoc{ctx.path, 0, 0}, "the file is larger than 4 GiB");
    // Fallback buffers of compressed views made empty for tinygltf (the rest as written; a
    // .glb's JSON chunk rebuilt around the changed text).
    std::vector<int> viewless;
    if (std::string changed = tinygltf_json(ctx, json, viewless); !changed.empty()) {
        if (binary) {
            while (changed.size() % 4 != 0) changed += ' ';
            const std::size_t rest = 20 + std::size_t{glb_u32(bytes, 12)};
            std::string glb = bytes.substr(0, 12);
            const auto chunk = static_cast<uint32_t>(changed.size());
            glb.append(reinterpret_cast<const char*>(&chunk), 4);
            glb += "JSON";
            glb += changed;
            // The chunks after the JSON as far as the header's length (bytes past it are not
            // the file's: appended, they were read as a BIN chunk).
            const std::size_t length = std::min<std::size_t>(glb_u32(bytes, 8), bytes.size());
            if (rest < length) glb.append(bytes, rest, length - rest);
            const auto total =
                static_cast<uint32_t>(std::min<std::size_t>(glb.size(), 0xFFFFFFFFu));
            std::memcpy(glb.data() + 8, &total, 4);
            bytes = std::move(glb);
        } else {
            bytes = std::move(changed);
        }
    }
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(&keep_bytes, &ctx.images);
    loader.SetFsCallbacks(
        {&regular_file, &same_path, &read_regular_file, &write_nothing, &buffer_lengths});
    std::string err, warn;
    bool ok = false;
    try {
        const auto size = static_cast<unsigned int>(bytes.size());
        const std::string base = ctx.dir.string();
        ok = binary ? loader.LoadBinaryFromMemory(
                          &ctx.model, &err, &warn,
                          reinterpret_cast<const unsigned char*>(bytes.data()), size, base)
                    : loader.LoadASCIIFromString(&ctx.model, &err, &warn, bytes.data(), size, base);
    } catch (const std::exception& e) {
        err = e.what();
    }
    if (!ok || !err.empty()) {
        err = readable(err);
        // tinygltf's words for what a file misses, said where it is missed.
        if (err.find("Spot light description not found") != std::string::npos)
            throw_error(ctx.at("extensions/KHR_lights_punctual/lights"),
                        "a KHR_lights_punctual light of type \"spot\" needs its \"spot\" object "
                        "(the extension requires it; its cone angles default to 0 and pi/4)");
        throw_error(tinygltf_error_place(ctx, err), "glTF: {}",
                    err.empty() ? "could not be read" : err);
    }
    // tinygltf's own attempt at an external image (Spangle reads images itself, and notes a
    // missing one at its place): not said twice.
    {
        std::string kept, line;
        std::istringstream lines(warn);
        while (std::getline(lines, line)) {
            // (Any "File not found": a missing buffer is an error, said by check_buffers; an
            // image's URI is percent-decoded in tinygltf's line, so it was not matched.)
            const bool image_line =
                line.find("Failed to load external 'uri' for image") != std::string::npos ||
                line.find("File not found") == 0;
            if (!image_line) kept += line + "\n";
        }
        warn = kept;
    }
    if (!readable(warn).empty()) {
        ctx.note("tinygltf", FileLoc{ctx.path, 1, 1}, "glTF: " + readable(warn));
    }
    if (ctx.model.asset.version.empty() || ctx.model.asset.version[0] != '2')
        throw_error(ctx.at("asset/version"), "glTF version '{}': only 2.x is read",
                    ctx.model.asset.version);
    ctx.images.resize(ctx.model.images.size());
    // The files the buffers were read from, watched and hashed: the path a URI names (a
    // file:// or percent-escaped URI was added as written, so its file was never watched).
    for (const tinygltf::Buffer& b : ctx.model.buffers)
        if (!b.uri.empty() && b.uri.rfind("data:", 0) != 0)
            if (const UriTarget t = uri_target(ctx, b.uri); !t.path.empty())
                ctx.scene->files.push_back(t.path);
    for (const int a : viewless)
        if (static_cast<std::size_t>(a) < ctx.model.accessors.size())
            ctx.model.accessors[static_cast<std::size_t>(a)].bufferView = -1;
    decompress(ctx);
    check_extensions(ctx);
}

}  // namespace spangle::gltf
