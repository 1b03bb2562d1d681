// Compressed glTF geometry (KHR_draco_mesh_compression, EXT_meshopt_compression): a mesh written
// here, compressed by the tools users compress with (Draco's draco_transcoder, meshoptimizer's
// gltfpack), read back and held against the uncompressed file vertex by vertex, within what each
// tool's quantisation allows; a damaged stream is an error at its place.
#include <dlfcn.h>
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "gltf_writer.h"
#include "scene/gltf/gltf_reader.h"
#include "test_support.h"

namespace spangle::test_gltf_compression {
namespace {

using test::GltfWriter;

/** Skips (or fails, with SPANGLE_REQUIRE_GLTF_TOOLS: the install script installs them) when a
 *  compression tool is not on the PATH. */
#define REQUIRE_TOOL(name)                                                                   \
    do {                                                                                     \
        if (std::system("command -v " name " > /dev/null 2>&1") != 0) {                      \
            if (std::getenv("SPANGLE_REQUIRE_GLTF_TOOLS")) FAIL() << name " not found";      \
            GTEST_SKIP() << name " not found (scripts/install-deps.sh --tests installs it)"; \
        }                                                                                    \
    } while (false)

/** Runs a shell command; its exit status. */
int run(const std::string& command) {
    return std::system((command + " > /dev/null 2>&1").c_str());
}

/** A 1 x 1 PNG (8-bit RGB), for a material's texture: both tools drop the uvs of a material
 *  without one. */
std::string tiny_png() {
    static const unsigned char k[] = {
        0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48,
        0x44, 0x52, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x08, 0x02, 0x00, 0x00,
        0x00, 0x90, 0x77, 0x53, 0xde, 0x00, 0x00, 0x00, 0x0c, 0x49, 0x44, 0x41, 0x54, 0x78,
        0x9c, 0x63, 0x38, 0x91, 0x62, 0x04, 0x00, 0x03, 0x56, 0x01, 0x5f, 0xe8, 0x17, 0x84,
        0x52, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
    return std::string(reinterpret_cast<const char*>(k), sizeof(k));
}

/** A torus of 24 x 12 quads (no degenerate triangle for a tool to drop) with normals, uvs and
 *  vertex colours, its material textured, written as a .gltf beside its .bin and the image (the
 *  form both tools read). */
void write_torus(const std::string& path) {
    constexpr int kU = 24, kV = 12;
    std::vector<float> pos, nrm, uv, col;
    for (int j = 0; j <= kV; ++j)
        for (int i = 0; i <= kU; ++i) {
            const float u = static_cast<float>(i) / kU, v = static_cast<float>(j) / kV;
            const float a = 6.2831853f * u, b = 6.2831853f * v;
            const float n[3] = {std::cos(a) * std::cos(b), std::sin(b), std::sin(a) * std::cos(b)};
            const float c[3] = {std::cos(a), 0.0f, std::sin(a)};
            for (int k = 0; k < 3; ++k) {
                pos.push_back(c[k] + 0.4f * n[k]);
                nrm.push_back(n[k]);
            }
            uv.push_back(u);
            uv.push_back(v);
            col.insert(col.end(), {u, v, 1.0f - u, 1.0f});
        }
    std::vector<uint16_t> idx;
    for (int j = 0; j < kV; ++j)
        for (int i = 0; i < kU; ++i) {
            const auto a = static_cast<uint16_t>(j * (kU + 1) + i);
            const auto b = static_cast<uint16_t>(a + kU + 1);
            idx.insert(idx.end(), {a, b, static_cast<uint16_t>(a + 1), static_cast<uint16_t>(a + 1),
                                   b, static_cast<uint16_t>(b + 1)});
        }
    GltfWriter w;
    const int p = w.floats(pos, "VEC3", 3), n = w.floats(nrm, "VEC3", 3),
              t = w.floats(uv, "VEC2", 2), c = w.floats(col, "VEC4", 4), i = w.u16(idx);
    // Positions carry their bounds (glTF requires them; the tools read them).
    w.accessors[static_cast<std::size_t>(p)].insert(
        w.accessors[static_cast<std::size_t>(p)].size() - 1,
        R"(,"min":[-1.4,-0.4,-1.4],"max":[1.4,0.4,1.4])");
    const std::string body = fmt::format(
        R"("scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],)"
        R"("images":[{{"uri":"tex.png"}}],"textures":[{{"source":0}}],)"
        R"("materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}}}}}}],)"
        R"("meshes":[{{"primitives":[{{"attributes":{{"POSITION":{},"NORMAL":{},)"
        R"("TEXCOORD_0":{},"COLOR_0":{}}},"indices":{},"material":0}}]}}])",
        p, n, t, c, i);
    const std::string name = std::filesystem::path(path).stem().string() + ".bin";
    w.write_gltf_bin(path, name, body);
    std::ofstream((std::filesystem::path(path).parent_path() / "tex.png").string(),
                  std::ios::binary)
        << tiny_png();
}

/** A Draco stream of the builder's mesh, and the ids of its attributes `pos` and `col` (empty
 *  bytes when Draco refused it). */
struct DracoStream {
    std::string bytes;
    uint32_t pos_id = 0, col_id = 0;
};
DracoStream encode(draco::TriangleSoupMeshBuilder& builder, int pos, int col) {
    DracoStream out;
    const std::unique_ptr<draco::Mesh> mesh = builder.Finalize();
    draco::Encoder encoder;
    draco::EncoderBuffer encoded;
    if (!mesh || !encoder.EncodeMeshToBuffer(*mesh, &encoded).ok()) return out;
    out.bytes.assign(encoded.data(), encoded.size());
    out.pos_id = mesh->attribute(pos)->unique_id();
    out.col_id = mesh->attribute(col)->unique_id();
    return out;
}

/** The one mesh of a glTF file as the reader makes it. */
TriangleMesh mesh_of(const std::string& path, SceneDescription* out = nullptr) {
    SceneDescription d = read_gltf_scene(path, {});
    EXPECT_EQ(d.objects.size(), 1u) << path;
    if (d.objects.empty()) return {};
    TriangleMesh m = *std::get<InlineMeshShape>(d.objects[0].shape).mesh;
    if (out) *out = std::move(d);
    return m;
}

/** The file's text. */
std::string slurp(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), {}};
}

/** Tolerances of one comparison: per attribute, the largest difference allowed; uv and color
 *  negative: not compared (a quantised file's uvs are scaled back by its material's texture
 *  transform, not in the mesh). */
struct Tolerance {
    float position, normal, uv, color;
};

/** Expects `got` to be `want` up to vertex and triangle order: the same number of triangles, and
 *  for every vertex of every triangle of `got` a vertex of `want` at most `tol` away in each
 *  attribute (the tools reorder, weld and quantise). Its largest differences are returned in the
 *  message. */
void expect_same_mesh(const TriangleMesh& got, const TriangleMesh& want, Tolerance tol,
                      const std::string& what) {
    ASSERT_EQ(got.indices.size(), want.indices.size()) << what;
    ASSERT_FALSE(got.normals.empty()) << what;
    ASSERT_FALSE(got.uvs.empty()) << what;
    ASSERT_FALSE(got.colors.empty()) << what;
    float worst[4] = {0, 0, 0, 0};
    for (std::size_t g = 0; g < got.vertex_count(); ++g) {
        // The vertex of `want` nearest in position and uv together (the seams hold several
        // vertices at one place, told apart by their uvs).
        std::size_t best = 0;
        float best_d = INFINITY, best_key = INFINITY;
        for (std::size_t k = 0; k < want.vertex_count(); ++k) {
            float d = 0, key = 0;
            for (int c = 0; c < 3; ++c)
                d = std::max(d, std::fabs(got.positions[3 * g + c] - want.positions[3 * k + c]));
            key = d;
            if (tol.uv >= 0)
                for (int c = 0; c < 2; ++c)
                    key = std::max(key, std::fabs(got.uvs[2 * g + c] - want.uvs[2 * k + c]));
            if (key < best_key) {
                best = k;
                best_key = key;
                best_d = d;
            }
        }
        worst[0] = std::max(worst[0], best_d);
        for (int c = 0; c < 3; ++c)
            worst[1] =
                std::max(worst[1], std::fabs(got.normals[3 * g + c] - want.normals[3 * best + c]));
        for (int c = 0; c < 2; ++c)
            worst[2] = std::max(worst[2], std::fabs(got.uvs[2 * g + c] - want.uvs[2 * best + c]));
        for (int c = 0; c < 3; ++c)
            worst[3] =
                std::max(worst[3], std::fabs(got.colors[3 * g + c] - want.colors[3 * best + c]));
    }
    EXPECT_LE(worst[0], tol.position) << what << ": positions";
    EXPECT_LE(worst[1], tol.normal) << what << ": normals";
    if (tol.uv >= 0) {
        EXPECT_LE(worst[2], tol.uv) << what << ": uvs";
    }
    if (tol.color >= 0) {
        EXPECT_LE(worst[3], tol.color) << what << ": colours";
    }
    // Every triangle keeps its area (no triangle lost to welding or a wrong index).
    const auto area = [](const TriangleMesh& m) {
        double a = 0;
        for (std::size_t t = 0; t + 2 < m.indices.size(); t += 3) {
            const float* p0 = &m.positions[3 * m.indices[t]];
            const float* p1 = &m.positions[3 * m.indices[t + 1]];
            const float* p2 = &m.positions[3 * m.indices[t + 2]];
            const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
            const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
            const double c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                                 e1[0] * e2[1] - e1[1] * e2[0]};
            a += 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        }
        return a;
    };
    EXPECT_NEAR(area(got), area(want), 1e-3 * area(want)) << what << ": surface area";
}

TEST(GltfCompression, DracoCompressedMeshReadsAsItsSource) {
    REQUIRE_TOOL("draco_transcoder");
    test::TempDir dir("gltf_draco");
    write_torus(dir.file("torus.gltf"));
    const TriangleMesh want = mesh_of(dir.file("torus.gltf"));
    // Fine quantisation: positions to 16 bits of the 2.8-unit box, normals, uvs and colours to
    // 12 and 14 bits.
    for (const char* out : {"draco.gltf", "draco.glb"}) {
        ASSERT_EQ(run(fmt::format("draco_transcoder -i {} -o {} -qp 16 -qt 14 -qn 12 -qc 12",
                                  dir.file("torus.gltf"), dir.file(out))),
                  0);
        const std::string text = slurp(dir.file(out));
        ASSERT_NE(text.find("\"extensionsRequired\""), std::string::npos) << out;
        ASSERT_NE(text.find("KHR_draco_mesh_compression"), std::string::npos) << out;
        SceneDescription d;
        const TriangleMesh got = mesh_of(dir.file(out), &d);
        expect_same_mesh(got, want, {1e-4f, 5e-3f, 1e-3f, 2e-3f}, out);
        for (const std::string& note : d.notes)
            EXPECT_EQ(note.find("KHR_draco"), std::string::npos) << note;
    }
    // An accessor whose component type disagrees with its Draco stream (the stream's floats
    // behind a normalised-short accessor): read as the stream holds them, not cast to shorts.
    std::string text = slurp(dir.file("draco.gltf"));
    const std::string first_float = R"("componentType": 5126,)";  // the transcoder's spacing
    ASSERT_NE(text.find(first_float), std::string::npos);
    text.replace(text.find(first_float), first_float.size(),
                 R"("componentType": 5122, "normalized": true,)");
    std::ofstream(dir.file("retyped.gltf"), std::ios::binary) << text;
    expect_same_mesh(mesh_of(dir.file("retyped.gltf")), want, {1e-4f, 5e-3f, 1e-3f, 2e-3f},
                     "retyped accessor");
}

TEST(GltfCompression, MeshoptCompressedMeshReadsAsItsSource) {
    REQUIRE_TOOL("gltfpack");
    test::TempDir dir("gltf_meshopt");
    write_torus(dir.file("torus.gltf"));
    const TriangleMesh want = mesh_of(dir.file("torus.gltf"));
    // -noq keeps the floats (the codec is lossless; gltfpack renormalises normals and re-packs
    // positions, so they move by an ulp or two, and stores colours in 8 bits); without it gltfpack
    // quantises (KHR_mesh_quantization), and -cc adds its filters (octahedral normals).
    struct Case {
        const char* flags;
        const char* out;
        Tolerance tol;
    };
    const Case cases[] = {
        {"-c -noq", "exact.gltf", {1e-6f, 1e-6f, 1e-6f, 2.5e-3f}},
        {"-c -noq", "exact.glb", {1e-6f, 1e-6f, 1e-6f, 2.5e-3f}},
        {"-c", "quantised.gltf", {5e-4f, 2e-2f, -1, -1}},
        {"-cc", "filtered.glb", {5e-4f, 2e-2f, -1, -1}},
    };
    for (const Case& c : cases) {
        ASSERT_EQ(run(fmt::format("gltfpack -i {} -o {} {} -kn -km", dir.file("torus.gltf"),
                                  dir.file(c.out), c.flags)),
                  0)
            << c.out;
        const std::string text = slurp(dir.file(c.out));
        ASSERT_NE(text.find("EXT_meshopt_compression"), std::string::npos) << c.out;
        if (std::string(c.flags) == "-cc") {
            ASSERT_NE(text.find(R"("filter":"OCTAHEDRAL")"), std::string::npos)
                << "the filtered case filters its normals";
        }
        SceneDescription d;
        const TriangleMesh got = mesh_of(dir.file(c.out), &d);
        // gltfpack may move the mesh into a node's transform when it quantises: the reader's
        // mesh is then in the node's space; the placement maps it back.
        TriangleMesh placed = got;
        ASSERT_FALSE(d.objects.empty());
        const Affine a = d.objects[0].placement.matrix.value_or(Affine{});
        for (std::size_t v = 0; v < placed.vertex_count(); ++v) {
            const Vec3 p = a.apply_point(
                Vec3(got.positions[3 * v], got.positions[3 * v + 1], got.positions[3 * v + 2]));
            placed.positions[3 * v] = p.x;
            placed.positions[3 * v + 1] = p.y;
            placed.positions[3 * v + 2] = p.z;
        }
        expect_same_mesh(placed, want, c.tol, std::string(c.out) + " (" + c.flags + ")");
    }
    // The placeholder buffer without its "fallback" mark (the extension's own example has
    // none): a buffer without a uri that compressed views decode into holds nothing to read.
    std::string text = slurp(dir.file("exact.gltf"));
    const std::string mark = R"(,"extensions":{"EXT_meshopt_compression":{"fallback":true}})";
    ASSERT_NE(text.find(mark), std::string::npos);
    text.erase(text.find(mark), mark.size());
    std::ofstream(dir.file("unmarked.gltf"), std::ios::binary) << text;
    expect_same_mesh(mesh_of(dir.file("unmarked.gltf")), want, cases[0].tol, "unmarked fallback");
}

TEST(GltfCompression, TinygltfIsDebiansNotDracos) {
    // libdraco.so carries a tinygltf of its own (another version, another FsCallbacks layout):
    // linked ahead of libtinygltf it provided the reader's tinygltf and every read crashed.
    Dl_info info{};
    const auto fn = &tinygltf::FileExists;
    ASSERT_NE(dladdr(reinterpret_cast<void*>(fn), &info), 0);
    ASSERT_NE(info.dli_fname, nullptr);
    EXPECT_NE(std::string(info.dli_fname).find("libtinygltf"), std::string::npos)
        << "tinygltf::FileExists comes from " << info.dli_fname;
}

TEST(GltfCompression, DracoIntegersUnmarkedInTheStreamAreNormalisedAsTheAccessorSays) {
    // Blender's older exporter and glTF-Transform wrote colours and uvs as integers the Draco
    // stream does not mark normalised; the accessor (normalized unsigned short) says they are.
    // Encoded here with Draco's own encoder: one triangle, colours 0, 32768, 65535.
    draco::TriangleSoupMeshBuilder builder;
    builder.Start(1);
    const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    const int col =
        builder.AddAttribute(draco::GeometryAttribute::COLOR, 4, draco::DT_UINT16, false);
    const float p[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const uint16_t c[3][4] = {
        {0, 0, 0, 65535}, {32768, 32768, 32768, 65535}, {65535, 65535, 65535, 65535}};
    builder.SetAttributeValuesForFace(pos, draco::FaceIndex(0), p[0], p[1], p[2]);
    builder.SetAttributeValuesForFace(col, draco::FaceIndex(0), c[0], c[1], c[2]);
    const DracoStream encoded = encode(builder, pos, col);
    ASSERT_FALSE(encoded.bytes.empty());
    const uint32_t pos_id = encoded.pos_id, col_id = encoded.col_id;

    test::TempDir dir("gltf_draco_unmarked");
    GltfWriter w;
    const int view = w.view(encoded.bytes.data(), encoded.bytes.size());
    w.accessors.push_back(R"({"componentType":5126,"count":3,"type":"VEC3"})");
    w.accessors.push_back(R"({"componentType":5123,"normalized":true,"count":3,"type":"VEC4"})");
    w.accessors.push_back(R"({"componentType":5123,"count":3,"type":"SCALAR"})");
    w.write_gltf(
        dir.file("tri.gltf"),
        fmt::format(
            R"("extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":)"
            R"(["KHR_draco_mesh_compression"],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":)"
            R"([{{"attributes":{{"POSITION":0,"COLOR_0":1}},"indices":2,"extensions":)"
            R"({{"KHR_draco_mesh_compression":{{"bufferView":{},"attributes":)"
            R"({{"POSITION":{},"COLOR_0":{}}}}}}}}}]}}])",
            view, pos_id, col_id));
    const TriangleMesh m = mesh_of(dir.file("tri.gltf"));
    ASSERT_EQ(m.vertex_count(), 3u);
    // Two primitives naming the same accessors, each with its stream (here the same one): each
    // decodes its own (the first into the accessors the file wrote, the second into new ones).
    std::string text = slurp(dir.file("tri.gltf"));
    const std::size_t open = text.find(R"("primitives":[)") + 14;
    const std::size_t close = text.find("]}]", open);
    ASSERT_NE(close, std::string::npos);
    const std::string prim = text.substr(open, close - open);
    text.insert(close, "," + prim);
    std::ofstream(dir.file("two.gltf"), std::ios::binary) << text;
    const SceneDescription two = read_gltf_scene(dir.file("two.gltf"), {});
    ASSERT_EQ(two.objects.size(), 2u);
    for (const ObjectDesc& o : two.objects) {
        const TriangleMesh& t = *std::get<InlineMeshShape>(o.shape).mesh;
        EXPECT_EQ(t.positions, m.positions) << o.name;
        EXPECT_EQ(t.colors, m.colors) << o.name;
    }
    ASSERT_EQ(m.colors.size(), 9u);
    // Each vertex's colour is its grey / 65535, wherever the decoder put the vertex.
    for (std::size_t v = 0; v < 3; ++v) {
        const float x = m.positions[3 * v], y = m.positions[3 * v + 1];
        const float want = x > 0.5f ? 32768.0f / 65535.0f : y > 0.5f ? 1.0f : 0.0f;
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(m.colors[3 * v + k], want, 1e-6f) << v;
    }
}

TEST(GltfCompression, ADracoStreamIsReadWholeOrNotAtAll) {
    // Draco renumbers vertices: a primitive reads either the file's uncompressed data (all of
    // it there) or the stream's indices and attributes together. A primitive without indices
    // whose file kept its vertices had the stream's triangles laid over the file's vertices.
    // A quad as two triangles, each corner's colour its x (red) and y (green).
    draco::TriangleSoupMeshBuilder builder;
    builder.Start(2);
    const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
    const int col = builder.AddAttribute(draco::GeometryAttribute::COLOR, 3, draco::DT_FLOAT32);
    const float p[6][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    for (int f = 0; f < 2; ++f) {
        const draco::FaceIndex face(static_cast<uint32_t>(f));
        builder.SetAttributeValuesForFace(pos, face, p[3 * f], p[3 * f + 1], p[3 * f + 2]);
        builder.SetAttributeValuesForFace(col, face, p[3 * f], p[3 * f + 1], p[3 * f + 2]);
    }
    const DracoStream encoded = encode(builder, pos, col);
    ASSERT_FALSE(encoded.bytes.empty());
    const uint32_t pos_id = encoded.pos_id, col_id = encoded.col_id;
    std::vector<float> soup(&p[0][0], &p[0][0] + 18);
    for (float& v : soup) v += 10.0f;  // the file's own data, told apart from the stream's

    test::TempDir dir("gltf_draco_whole");
    const auto write = [&](const std::string& name, bool colours_kept, bool required,
                           bool glb = false) {
        GltfWriter w;
        const int view = w.view(encoded.bytes.data(), encoded.bytes.size());
        const int a_pos = w.floats(soup, "VEC3", 3);
        int a_col = -1;
        if (colours_kept) {
            a_col = w.floats(soup, "VEC3", 3);
        } else {
            w.accessors.push_back(R"({"componentType":5126,"count":6,"type":"VEC3"})");
            a_col = static_cast<int>(w.accessors.size()) - 1;
        }
        const std::string body = fmt::format(
            R"("extensionsUsed":["KHR_draco_mesh_compression"],{}"nodes":[{{"mesh":0}}],)"
            R"("meshes":[{{"primitives":[{{"attributes":{{"POSITION":{},"COLOR_0":{}}},)"
            R"("extensions":{{"KHR_draco_mesh_compression":{{"bufferView":{},"attributes":)"
            R"({{"POSITION":{},"COLOR_0":{}}}}}}}}}]}}])",
            required ? R"("extensionsRequired":["KHR_draco_mesh_compression"],)" : "", a_pos, a_col,
            view, pos_id, col_id);
        if (glb)
            w.write_glb(dir.file(name), body);
        else
            w.write_gltf(dir.file(name), body);
    };
    // Every attribute kept: the file's six vertices as written, no stream.
    write("kept.gltf", true, false);
    const TriangleMesh kept = mesh_of(dir.file("kept.gltf"));
    EXPECT_EQ(kept.positions, soup);
    EXPECT_EQ(kept.indices, (std::vector<uint32_t>{0, 1, 2, 3, 4, 5}));
    // The colours only in the stream: the stream's positions, colours and triangles together,
    // the file's positions not mixed in.
    write("partial.gltf", false, true);
    const TriangleMesh part = mesh_of(dir.file("partial.gltf"));
    ASSERT_EQ(part.indices.size(), 6u);
    ASSERT_EQ(part.colors.size(), part.positions.size());
    for (std::size_t v = 0; v < part.vertex_count(); ++v) {
        EXPECT_LT(part.positions[3 * v], 2.0f) << "the stream's position, not the file's";
        EXPECT_EQ(part.colors[3 * v], part.positions[3 * v]) << v;
        EXPECT_EQ(part.colors[3 * v + 1], part.positions[3 * v + 1]) << v;
    }
    // The two triangles cover the unit square: areas add to 1.
    double area = 0.0;
    for (std::size_t t = 0; t < 2; ++t) {
        const auto at = [&](std::size_t k, int c) {
            return static_cast<double>(part.positions[3 * part.indices[3 * t + k] + c]);
        };
        area += 0.5 * std::fabs((at(1, 0) - at(0, 0)) * (at(2, 1) - at(0, 1)) -
                                (at(2, 0) - at(0, 0)) * (at(1, 1) - at(0, 1)));
    }
    EXPECT_NEAR(area, 1.0, 1e-6);
    // The same as a .glb with bytes after the length its header gives (ignored, as in a .glb
    // read as written): its JSON is rebuilt for tinygltf (the accessor without a view), and
    // the bytes past the length were carried into the rebuilt file and read as a BIN chunk.
    write("partial.glb", false, true, true);
    std::ofstream(dir.file("partial.glb"), std::ios::binary | std::ios::app)
        << std::string(4, '\0');
    const TriangleMesh glb = mesh_of(dir.file("partial.glb"));
    EXPECT_EQ(glb.positions, part.positions);
    EXPECT_EQ(glb.indices, part.indices);
}

TEST(GltfCompression, GltfpackInstancesStandWhereTheirNodesStood) {
    // Five nodes drawing one torus, turned and moved; gltfpack -mi makes them one node with
    // EXT_mesh_gpu_instancing (-noq: no quantisation, so the placements keep their floats).
    REQUIRE_TOOL("gltfpack");
    test::TempDir dir("gltf_instances");
    write_torus(dir.file("one.gltf"));
    std::string text = slurp(dir.file("one.gltf"));
    const std::string node = R"("nodes":[{"mesh":0}])";
    const std::size_t at = text.find(node);
    ASSERT_NE(at, std::string::npos);
    std::string nodes = R"("nodes":[)", roots;
    for (int i = 0; i < 5; ++i) {
        const double a = 0.3 * i, c = std::cos(0.5 * a), s = std::sin(0.5 * a);
        nodes += fmt::format(R"({}{{"mesh":0,"translation":[{},{},0],"rotation":[0,{},0,{}],)"
                             R"("scale":[{},{},{}]}})",
                             i ? "," : "", 3.0 * i, 0.5 * i, s, c, 1 + 0.1 * i, 1 + 0.1 * i,
                             1 + 0.1 * i);
        roots += fmt::format("{}{}", i ? "," : "", i);
    }
    nodes += "]";
    text.replace(at, node.size(), nodes);
    const std::string scene = R"("scenes":[{"nodes":[0]}])";
    ASSERT_NE(text.find(scene), std::string::npos);
    text.replace(text.find(scene), scene.size(), R"("scenes":[{"nodes":[)" + roots + "]}]");
    std::ofstream(dir.file("five.gltf"), std::ios::binary) << text;
    std::filesystem::copy_file(dir.file("one.bin"), dir.file("five.bin"));
    text = slurp(dir.file("five.gltf"));
    // The buffer's name follows the file's.
    text.replace(text.find("one.bin"), 7, "five.bin");
    std::ofstream(dir.file("five.gltf"), std::ios::binary) << text;
    const SceneDescription want = read_gltf_scene(dir.file("five.gltf"), {});
    ASSERT_EQ(want.objects.size(), 5u);
    ASSERT_EQ(run(fmt::format("gltfpack -i {} -o {} -mi -noq", dir.file("five.gltf"),
                              dir.file("inst.glb"))),
              0);
    ASSERT_NE(slurp(dir.file("inst.glb")).find("EXT_mesh_gpu_instancing"), std::string::npos);
    const SceneDescription got = read_gltf_scene(dir.file("inst.glb"), {});
    ASSERT_EQ(got.objects.size(), 5u);
    const auto* shared = std::get<InlineMeshShape>(got.objects[0].shape).mesh.get();
    // Each original node's placement is one of the instances' (in some order), to float
    // rounding: compared by where they put three points of the torus.
    const Vec3 probes[3] = {{1.4f, 0, 0}, {0, 0.4f, 1}, {-1, -0.4f, 0}};
    for (const ObjectDesc& w : want.objects) {
        float best = INFINITY;
        for (const ObjectDesc& g : got.objects) {
            EXPECT_EQ(std::get<InlineMeshShape>(g.shape).mesh.get(), shared);
            float d = 0;
            for (const Vec3& p : probes) {
                const Vec3 a = w.placement.matrix.value().apply_point(p);
                const Vec3 b = g.placement.matrix.value().apply_point(p);
                d = std::max({d, std::fabs(a.x - b.x), std::fabs(a.y - b.y), std::fabs(a.z - b.z)});
            }
            best = std::min(best, d);
        }
        EXPECT_LT(best, 1e-4f) << w.name;
    }
}

TEST(GltfCompression, DamagedStreamsAreErrorsAtTheirExtension) {
    REQUIRE_TOOL("gltfpack");
    REQUIRE_TOOL("draco_transcoder");
    test::TempDir dir("gltf_damaged");
    write_torus(dir.file("torus.gltf"));
    ASSERT_EQ(run(fmt::format("gltfpack -i {} -o {} -c -noq", dir.file("torus.gltf"),
                              dir.file("mo.gltf"))),
              0);
    ASSERT_EQ(run(fmt::format("draco_transcoder -i {} -o {}", dir.file("torus.gltf"),
                              dir.file("dr.gltf"))),
              0);
    // Every byte of the compressed buffers overwritten: neither decoder can make sense of it.
    for (const char* bin : {"mo.bin", "dr.bin"}) {
        std::string bytes = slurp(dir.file(bin));
        ASSERT_FALSE(bytes.empty()) << bin;
        for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<char>(0xA5 ^ i);
        std::ofstream(dir.file(bin), std::ios::binary) << bytes;
    }
    const auto error_of = [&](const std::string& file) {
        try {
            read_gltf_scene(dir.file(file), {});
        } catch (const SpangleError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string mo = error_of("mo.gltf");
    EXPECT_NE(mo.find("meshopt data could not be decoded"), std::string::npos) << mo;
    EXPECT_EQ(mo.rfind(dir.file("mo.gltf") + ":", 0), 0u) << mo;
    const std::string dr = error_of("dr.gltf");
    EXPECT_NE(dr.find("Draco data"), std::string::npos) << dr;
    EXPECT_EQ(dr.rfind(dir.file("dr.gltf") + ":", 0), 0u) << dr;

    // A mode that is not one of the three, said at its place.
    std::string text = slurp(dir.file("mo.gltf"));
    const std::size_t at = text.find("\"ATTRIBUTES\"");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, 12, "\"VERTICES\"");
    std::ofstream(dir.file("mode.gltf"), std::ios::binary) << text;
    const std::string mode = error_of("mode.gltf");
    EXPECT_NE(mode.find("mode 'VERTICES'"), std::string::npos) << mode;
    // A count that does not fill its view exactly (one vertex would be left at 0).
    text = slurp(dir.file("mo.gltf"));
    const std::size_t count_at = text.find(R"("count":)", text.find("\"ATTRIBUTES\"") - 40);
    ASSERT_NE(count_at, std::string::npos);
    text.insert(count_at + 8, "1");  // count N becomes 1N
    std::ofstream(dir.file("count.gltf"), std::ios::binary) << text;
    const std::string count = error_of("count.gltf");
    EXPECT_NE(count.find("(they must be equal)"), std::string::npos) << count;
    // A count (and view) of 2^24 vertices from a few hundred compressed bytes: refused before
    // anything is decoded (it made 4 GiB of zeros first).
    text = slurp(dir.file("mo.gltf"));
    const std::string key = R"("mode":"ATTRIBUTES","count":)";
    const std::size_t a = text.find(key);
    ASSERT_NE(a, std::string::npos);
    const std::size_t n_end = text.find_first_not_of("0123456789", a + key.size());
    const std::size_t view = text.rfind(R"({"buffer":)", text.rfind(R"("extensions")", a));
    const std::size_t length_at = text.find(R"("byteLength":)", view) + 13;
    const std::size_t stride_at = text.find(R"("byteStride":)", view) + 13;
    ASSERT_LT(length_at, a);
    ASSERT_LT(stride_at, a);
    const int stride = std::stoi(text.substr(stride_at));
    text.replace(a + key.size(), n_end - a - key.size(), "16777216");
    const std::size_t length_end = text.find_first_not_of("0123456789", length_at);
    text.replace(length_at, length_end - length_at, std::to_string(16777216LL * stride));
    std::ofstream(dir.file("huge.gltf"), std::ios::binary) << text;
    const std::string huge = error_of("huge.gltf");
    EXPECT_NE(
        huge.find("count 16777216 x byteStride " + std::to_string(stride) + " cannot come from"),
        std::string::npos)
        << huge;
    // A buffer index past the file's own buffers (the decoded ones are not the file's).
    text = slurp(dir.file("mo.gltf"));
    const std::string ext = R"("EXT_meshopt_compression":{"buffer":0)";
    ASSERT_NE(text.find(ext), std::string::npos);
    text.replace(text.find(ext), ext.size(), R"("EXT_meshopt_compression":{"buffer":2)");
    std::ofstream(dir.file("past.gltf"), std::ios::binary) << text;
    const std::string past = error_of("past.gltf");
    EXPECT_NE(past.find("buffer 2 does not exist (the file has 2)"), std::string::npos) << past;
}

TEST(GltfCompression, AnEmptyBinChunkIsLeftOut) {
    // A .glb whose BIN chunk holds no bytes (draco_transcoder writes one for a file without
    // buffer data): read as a .glb without the chunk.
    test::TempDir dir("gltf_empty_bin");
    std::string json = R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[]}]})";
    while (json.size() % 4) json += ' ';
    const auto u32le = [](std::string& s, uint32_t v) {
        s.append(reinterpret_cast<const char*>(&v), 4);
    };
    std::string glb = "glTF";
    u32le(glb, 2);
    u32le(glb, static_cast<uint32_t>(12 + 8 + json.size() + 8));
    u32le(glb, static_cast<uint32_t>(json.size()));
    u32le(glb, 0x4E4F534Au);
    glb += json;
    u32le(glb, 0);
    u32le(glb, 0x004E4942u);
    std::ofstream(dir.file("empty.glb"), std::ios::binary) << glb;
    SceneDescription d;
    EXPECT_NO_THROW(d = read_gltf_scene(dir.file("empty.glb"), {}));
    EXPECT_TRUE(d.objects.empty());
}

}  // namespace
}  // namespace spangle::test_gltf_compression
