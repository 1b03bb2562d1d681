// The pbrt reader as a reader: files written here that use every directive, shape, material,
// texture and light it knows, read into a SceneDescription and built into a registry, checked
// for what each became; the version told from the spellings; what is dropped warned about once
// at its line; syntax errors at file:line:col.

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <fstream>

#include "desc_support.h"
#include "geometry/mesh_load.h"
#include "scene/pbrt/pbrt_reader.h"
#include "scene/scene_builder.h"
#include "scene/scene_loader.h"
#include "test_support.h"

namespace spangle::test_pbrt_reader {
namespace {

using test::has_note;
using test::param;

/** A folder with the files the scenes below name (an image, a PLY, a spectrum). */
class Files {
public:
    Files() : dir_("pbrt_reader") {
        std::ofstream(dir_.file("wood.png")) << "not read by the reader";
        std::ofstream(dir_.file("bumps.png")) << "not read by the reader";
        std::ofstream(dir_.file("sky.exr")) << "not read by the reader";
        std::ofstream(dir_.file("mesh.ply")) << "not read by the reader";
        std::ofstream(dir_.file("flat.spd")) << "# a flat spectrum\n400 0.5\n700 0.5\n";
    }
    std::string file(const std::string& name) const { return dir_.file(name); }

private:
    test::TempDir dir_;
};

/** `text` read as the file scene.pbrt of `files`' folder. */
SceneDescription read(const Files& files, const std::string& text, PbrtReadInfo* info = nullptr) {
    PbrtReadInfo local;
    return read_pbrt_text(files.file("scene.pbrt"), text, info ? *info : local);
}

/** The message of the SpangleError reading `text` throws ("" when it reads). */
std::string error_of(const Files& files, const std::string& text) {
    try {
        read(files, text);
    } catch (const SpangleError& e) {
        return e.what();
    }
    return "";
}

const MaterialDesc& material(const SceneDescription& d, const std::string& name) {
    for (const MaterialDesc& m : d.materials)
        if (m.name == name) return m;
    throw std::runtime_error("no material " + name);
}

double number(const MaterialDesc& m, const std::string& name) {
    const ParamDesc* p = param(m, name);
    return p ? p->number : -999.0;
}

/** Whether a note contains `text`. */
bool noted(const SceneDescription& d, const std::string& text) {
    for (const std::string& n : d.notes)
        if (n.find(text) != std::string::npos) return true;
    return false;
}

const TriangleMesh& mesh_of(const ObjectDesc& o) {
    return *std::get<InlineMeshShape>(o.shape).mesh;
}

constexpr const char* kQuad = R"(Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point3 P" [0 0 0  1 0 0  1 1 0  0 1 0])";

TEST(PbrtReader, TellsTheVersionFromItsSpellings) {
    const Files f;
    PbrtReadInfo v3, v4, none;
    read(f, "Film \"image\"\nWorldBegin\nWorldEnd\n", &v3);
    EXPECT_EQ(v3.version, PbrtVersion::V3);
    EXPECT_NE(v3.v3_sign.find("scene.pbrt:1"), std::string::npos) << v3.v3_sign;
    read(f, "ColorSpace \"srgb\"\nWorldBegin\nMaterial \"coateddiffuse\"\n", &v4);
    EXPECT_EQ(v4.version, PbrtVersion::V4);
    read(f, "WorldBegin\n", &none);
    EXPECT_EQ(none.version, PbrtVersion::Unknown);
    // Where the two disagree the file is read as v4, and said so.
    const SceneDescription mixed = read(f, "Film \"rgb\"\nWorldBegin\nMaterial \"matte\"\n");
    EXPECT_TRUE(noted(mixed, "mixes pbrt-v3"));
}

TEST(PbrtReader, TransformsComposeAsPbrtsDo) {
    const Files f;
    const SceneDescription d = read(f, std::string(R"(WorldBegin
AttributeBegin
  Translate 1 2 3
  Rotate 90 0 0 1
  Scale 2 2 2
)") + kQuad + R"(
AttributeEnd
AttributeBegin
  Transform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1]
  ConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1]
  CoordinateSystem "mine"
AttributeEnd
TransformBegin
  CoordSysTransform "mine"
)" + kQuad + R"(
TransformEnd
)" + kQuad + "\n");
    ASSERT_EQ(d.objects.size(), 3u);
    // Translate * Rotate * Scale: (1, 0, 0) -> scaled (2, 0, 0) -> turned (0, 2, 0) -> (1, 4, 3).
    const Affine a = *d.objects[0].placement.matrix;
    const Vec3 p = a.apply_point({1, 0, 0});
    EXPECT_NEAR(p.x, 1.0f, 1e-5f);
    EXPECT_NEAR(p.y, 4.0f, 1e-5f);
    EXPECT_NEAR(p.z, 3.0f, 1e-5f);
    // Transform's 16 numbers are read transposed (translation last); ConcatTransform multiplies
    // on the right; CoordinateSystem saves and CoordSysTransform restores it.
    const Vec3 q = d.objects[1].placement.matrix->apply_point({1, 1, 1});
    EXPECT_NEAR(q.x, 7.0f, 1e-5f);
    EXPECT_NEAR(q.y, 8.0f, 1e-5f);
    EXPECT_NEAR(q.z, 9.0f, 1e-5f);
    // TransformEnd restores the transform: the last quad is at the origin.
    EXPECT_EQ(*d.objects[2].placement.matrix, Affine());
}

TEST(PbrtReader, CoordSysTransformCameraPlacesThingsAtTheCamera) {
    const Files f;
    const SceneDescription d = read(f, R"(LookAt 3 4 5  0 0 0  0 1 0
Camera "perspective"
WorldBegin
AttributeBegin
  CoordSysTransform "camera"
  LightSource "point" "point3 from" [0 0 0]
AttributeEnd
)");
    ASSERT_EQ(d.lights.size(), 1u);
    const Vec3 p = std::get<PointLightDesc>(d.lights[0].shape).position;
    EXPECT_NEAR(p.x, 3.0f, 1e-5f);
    EXPECT_NEAR(p.y, 4.0f, 1e-5f);
    EXPECT_NEAR(p.z, 5.0f, 1e-5f);
}

TEST(PbrtReader, ActiveTransformMovesObjectsAndTheCameraOverTheShutter) {
    const Files f;
    const SceneDescription d = read(f, std::string(R"(TransformTimes 0 1
ActiveTransform StartTime
LookAt 0 0 5  0 0 0  0 1 0
ActiveTransform EndTime
LookAt 1 0 5  1 0 0  0 1 0
ActiveTransform All
Camera "perspective" "float shutteropen" 0 "float shutterclose" 0.5
WorldBegin
ActiveTransform EndTime
Translate 2 0 0
ActiveTransform All
)") + kQuad + "\n");
    ASSERT_EQ(d.objects.size(), 1u);
    const Keys<MatrixKey>& keys = d.objects[0].matrix_keys;
    ASSERT_EQ(keys.keys.size(), 2u);
    EXPECT_FALSE(keys.smooth) << "pbrt interpolates its two transforms linearly";
    EXPECT_EQ(keys.keys[1].time.seconds, 1.0);
    EXPECT_NEAR(keys.keys[1].matrix.t.x, 2.0f, 1e-6f);
    EXPECT_EQ(keys.keys[0].matrix.t.x, 0.0f);
    ASSERT_EQ(d.camera.keys.keys.size(), 2u);
    EXPECT_NEAR(d.camera.keys.keys[1].position->x, 1.0f, 1e-5f);
    // Seconds map onto Spangle's shutter at one frame per second.
    EXPECT_EQ(d.render.fps, 1.0);
    EXPECT_EQ(d.render.shutter_close, 0.5);
}

TEST(PbrtReader, WorldBeginResetsTheBlockStateAsPbrtDoes) {
    // ActiveTransform before WorldBegin does not reach into the world block (pbrt sets both
    // transforms active again there): the Translate moves the quad at both times, no blur.
    const Files f;
    const SceneDescription d = read(f, std::string(R"(ActiveTransform StartTime
WorldBegin
Translate 2 0 0
)") + kQuad + "\n");
    ASSERT_EQ(d.objects.size(), 1u);
    const Keys<MatrixKey>& keys = d.objects[0].matrix_keys;
    for (const MatrixKey& k : keys.keys) EXPECT_NEAR(k.matrix.t.x, 2.0f, 1e-6f);
    // A camera inside the world block is not the scene's camera (pbrt refuses or ignores it).
    const SceneDescription c = read(f, std::string(R"(LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 30
WorldBegin
Translate 0 0 -5
Camera "perspective" "float fov" 90
)") + kQuad + "\n");
    EXPECT_NEAR(c.camera.fov_deg, 30.0, 1e-9);
    EXPECT_NEAR(c.camera.position.z, 5.0f, 1e-5f);
    EXPECT_TRUE(has_note(c, "Camera inside the world block"));
    // Film inside it and a shape before it: pbrt refuses both; said (they were taken silently).
    const SceneDescription o = read(f, std::string(R"(LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
Shape "sphere"
WorldBegin
Film "rgb" "integer xresolution" 64 "integer yresolution" 64
)") + kQuad + "\n");
    EXPECT_TRUE(has_note(o,
                         ":5: Film inside the world block (after WorldBegin): pbrt does not "
                         "allow it; taken all the same"));
    EXPECT_TRUE(has_note(o, ":3: Shape before WorldBegin: pbrt does not allow it"));
}

TEST(PbrtReader, AVersion3LightScaleIsASpectrum) {
    // pbrt-v3 lights take "scale" as a spectrum (FindOneSpectrum): it multiplies the colour.
    const Files f;
    const SceneDescription d = read(f, std::string(R"(WorldBegin
LightSource "point" "point from" [0 0 3] "color I" [5 5 5] "rgb scale" [4 2 1]
AttributeBegin
AreaLightSource "area" "color L" [1 1 1] "color scale" [3 3 3]
Shape "sphere" "float radius" 0.3
AttributeEnd
)"));
    // The emitting sphere is a sphere light (PbrtReader.AnEmittingSphereIsASphereLight).
    ASSERT_EQ(d.lights.size(), 2u);
    EXPECT_EQ(d.lights[0].color->rgb, Vec3(20, 10, 5));
    EXPECT_EQ(d.lights[1].color->rgb, Vec3(3, 3, 3));
    EXPECT_TRUE(d.objects.empty());
    EXPECT_FALSE(has_note(d, "not supported"));
}

// pbrt samples a sphere emitter by the cone it subtends; Spangle's sphere light does the same,
// where its tessellation was sampled by triangle area (a floor under a small sphere had 3 times
// the noise of the point light of its power). A whole, outward-emitting, uniformly scaled sphere
// becomes one, placed where the transform puts it, its radiance and power kept; a cut, turned,
// two-sided, non-uniformly scaled or cut-out sphere stays an emitting object.
// Values Spangle cannot take as written are said, not changed silently: a depth of 0 (pbrt shows
// only the light seen directly; Spangle bounces once), 0 samples, several values where one
// belongs; a number beyond a double's range is an error that says so.
TEST(PbrtReader, ValuesTakenOtherwiseAreSaid) {
    const Files f;
    const SceneDescription d = read(f, std::string(R"(Sampler "halton" "integer pixelsamples" 0
Integrator "path" "integer maxdepth" 0
WorldBegin
Shape "sphere" "float radius" [1 2 3]
)"));
    EXPECT_EQ(d.render.max_depth, 1u);
    EXPECT_EQ(d.render.spp, 1u);
    EXPECT_TRUE(has_note(d, ":2: 'maxdepth' 0 is taken as 1"));
    EXPECT_TRUE(has_note(d, ":1: 'pixelsamples' 0 is taken as 1"));
    EXPECT_TRUE(has_note(d, ":4: 'float radius' of Shape \"sphere\" takes one value, got 3"));
    const std::string big = error_of(f, "WorldBegin\nShape \"sphere\" \"float radius\" 1e400\n");
    EXPECT_NE(big.find(":2:31: error: 'float radius': 1e400 is out of range"), std::string::npos)
        << big;
    // Too small for a double: 0, as pbrt reads it.
    const SceneDescription tiny = read(f, "WorldBegin\nShape \"sphere\" \"float zmin\" 1e-400\n");
    EXPECT_EQ(tiny.objects.size(), 1u);
    // A texture defined twice (pbrt-v4 refuses the file): the second stands, and it is said
    // where the first was; a float and a colour texture of one name are two textures.
    const SceneDescription twice = read(f, std::string(R"(WorldBegin
Texture "t" "spectrum" "constant" "rgb value" [0 0 1]
Texture "t" "float" "constant" "float value" 0.5
Texture "t" "spectrum" "constant" "rgb value" [0 1 0]
Material "diffuse" "texture reflectance" "t"
Shape "sphere"
)"));
    EXPECT_TRUE(has_note(twice, ":4: spectrum texture 't' is defined again (first at "));
    EXPECT_TRUE(has_note(twice, ":2:1): this definition stands from here on"));
    EXPECT_FALSE(has_note(twice, ":3: float texture 't' is defined again"));
    ASSERT_EQ(twice.materials.size(), 1u);
}

TEST(PbrtReader, AnEmittingSphereIsASphereLight) {
    const Files f;
    const SceneDescription d = read(f, std::string(R"(WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [2 3 4] "float scale" 1.5
  Translate 1 2 3
  Rotate 30 0 1 0
  Scale 2 2 2
  Shape "sphere" "float radius" 0.25
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1] "float power" 100
  Translate -1 0 0
  Shape "sphere" "float radius" 0.5
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "sphere" "float radius" 1 "float zmax" 0.5
  ReverseOrientation
  Shape "sphere" "float radius" 1
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" true
  Shape "sphere"
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Scale 1 2 1
  Shape "sphere"
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "sphere" "float alpha" 0.5
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Scale -1 1 1
  Shape "sphere"
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [0.2 0.2 0.2]
  Shape "sphere"
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  ActiveTransform EndTime
  Translate 0 1 0
  ActiveTransform All
  Shape "sphere"
AttributeEnd
ObjectBegin "lamp"
  AreaLightSource "diffuse" "rgb L" [1 1 1]
  Shape "sphere"
ObjectEnd
)"));
    ASSERT_EQ(d.lights.size(), 2u);
    const auto* a = std::get_if<SphereLightDesc>(&d.lights[0].shape);
    ASSERT_NE(a, nullptr);
    EXPECT_NEAR(a->center.x, 1.0f, 1e-5f);
    EXPECT_NEAR(a->center.y, 2.0f, 1e-5f);
    EXPECT_NEAR(a->center.z, 3.0f, 1e-5f);
    EXPECT_NEAR(a->radius, 0.5, 1e-6);
    EXPECT_EQ(d.lights[0].color->rgb, Vec3(2, 3, 4));
    EXPECT_NEAR(d.lights[0].intensity, 1.5, 1e-12);
    const auto* b = std::get_if<SphereLightDesc>(&d.lights[1].shape);
    ASSERT_NE(b, nullptr);
    EXPECT_NEAR(b->radius, 0.5, 1e-6);
    // power / (pi x 4 pi r^2): the radiance pbrt gives it.
    EXPECT_NEAR(d.lights[1].intensity, 100.0 / (M_PI * 4.0 * M_PI * 0.25), 1e-9);
    // The cut, turned, two-sided, stretched, cut-out, mirrored, dim and moving ones.
    EXPECT_EQ(d.objects.size(), 8u);
    for (const ObjectDesc& o : d.objects) EXPECT_TRUE(o.emission.has_value()) << o.what;
    EXPECT_TRUE(has_note(d, "an emitting sphere is a sphere light"));
}

TEST(PbrtReader, ObjectInstancesShareOneMesh) {
    const Files f;
    PbrtReadInfo info;
    const SceneDescription d = read(f, std::string(R"(WorldBegin
ObjectBegin "pair"
)") + kQuad + R"(
  Translate 0 0 1
)" + kQuad + R"(
ObjectEnd
ObjectInstance "pair"
Translate 5 0 0
ObjectInstance "pair"
ObjectInstance "nothing"
)",
                                    &info);
    ASSERT_EQ(d.objects.size(), 4u);
    EXPECT_EQ(info.instances, 2u);
    EXPECT_EQ(std::get<InlineMeshShape>(d.objects[0].shape).mesh,
              std::get<InlineMeshShape>(d.objects[2].shape).mesh)
        << "instances of one definition share its meshes (and so their BVHs)";
    // The instance's transform applies after the definition's own.
    EXPECT_NEAR(d.objects[3].placement.matrix->t.x, 5.0f, 1e-6f);
    EXPECT_NEAR(d.objects[3].placement.matrix->t.z, 1.0f, 1e-6f);
    EXPECT_TRUE(noted(d, "'nothing', which is not defined"));
}

TEST(PbrtReader, TriangleMeshKeepsItsPointsNormalsUvsAndTurnsWithReverseOrientation) {
    const Files f;
    const SceneDescription d = read(f, std::string(R"(WorldBegin
Shape "trianglemesh" "integer indices" [0 1 2] "point3 P" [0 0 0 1 0 0 0 1 0]
  "normal N" [0 0 2 0 0 2 0 0 2] "point2 uv" [0 0 1 0 0 1]
ReverseOrientation
)") + kQuad + R"(
Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0]
)");
    ASSERT_EQ(d.objects.size(), 3u);
    const TriangleMesh& a = mesh_of(d.objects[0]);
    EXPECT_EQ(a.indices, (std::vector<uint32_t>{0, 1, 2}));
    EXPECT_EQ(a.normals[2], 1.0f) << "normals are made unit";
    EXPECT_EQ(a.uvs, (std::vector<float>{0, 0, 1, 0, 0, 1}));
    // Without normals, ReverseOrientation turns the winding: Spangle's faces follow it.
    EXPECT_EQ(mesh_of(d.objects[1]).indices, (std::vector<uint32_t>{0, 2, 1, 0, 3, 2}));
    // v4: three points need no indices.
    EXPECT_EQ(mesh_of(d.objects[2]).triangle_count(), 1u);
}

TEST(PbrtReader, AttributeParametersGoWhereTheyAreTaken) {
    // Attribute "shape" "float radius" sizes the sphere, and the mesh that takes no radius says
    // nothing of it, as pbrt ignores it there (every trianglemesh warned).
    const Files f;
    const SceneDescription d = read(f, std::string(R"(WorldBegin
Attribute "shape" "float radius" 0.4
Shape "sphere"
)") + kQuad + "\n");
    ASSERT_EQ(d.objects.size(), 2u);
    ASSERT_TRUE(d.objects[0].placement.matrix.has_value());
    EXPECT_NEAR(
        length(d.objects[0].placement.matrix->apply_point(mesh_of(d.objects[0]).position(0))), 0.4f,
        1e-5f);
    EXPECT_FALSE(noted(d, "radius")) << d.notes.front();
}

TEST(PbrtReader, NamedMaterialsMayBeDefinedAfterTheirUse) {
    // pbrt-v4 looks named materials up once the scene is read: a file that writes its materials
    // after its shapes rendered them grey. A name never defined is said where first used.
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
NamedMaterial "red"
Shape "sphere"
ObjectBegin "ball"
NamedMaterial "red"
Shape "sphere"
ObjectEnd
ObjectInstance "ball"
NamedMaterial "nothere"
Shape "disk"
NamedMaterial "boundary"
Shape "disk"
MakeNamedMaterial "red" "string type" "diffuse" "rgb reflectance" [.8 .1 .1]
MakeNamedMaterial "boundary" "string type" "interface"
)");
    ASSERT_EQ(d.objects.size(), 3u) << "the interface's disk is a medium boundary: not drawn";
    EXPECT_EQ(d.objects[0].material, "red");
    EXPECT_EQ(d.objects[1].material, "red") << "an instance's shapes too";
    EXPECT_EQ(d.objects[2].material, "pbrt_default");
    EXPECT_TRUE(noted(d, ":9: NamedMaterial 'nothere' is not defined"))
        << ::testing::PrintToString(d.notes);
    EXPECT_FALSE(noted(d, "'red' is not defined"));
}

TEST(PbrtReader, AShapesAlphaCutsACopyOfItsMaterial) {
    // pbrt gives alpha to shapes, Spangle to materials: each (material, alpha) is one copy,
    // a forward NamedMaterial included; alpha 1 and an undefined texture stay opaque.
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Texture "mask" "float" "imagemap" "string filename" "wood.png"
Texture "half" "float" "constant" "float value" 0.5
NamedMaterial "leaf"
Shape "sphere" "float alpha" 0.25
Shape "sphere" "float alpha" 0.25
Shape "disk" "texture alpha" "mask"
Shape "disk" "texture alpha" "half"
Shape "disk" "float alpha" 1
Shape "disk" "texture alpha" "nothere"
Material "diffuse"
Shape "sphere" "texture alpha" "mask"
MakeNamedMaterial "leaf" "string type" "diffuse" "rgb reflectance" [.2 .6 .1]
)");
    ASSERT_EQ(d.objects.size(), 7u);
    const MaterialDesc& quarter = material(d, d.objects[0].material);
    EXPECT_EQ(quarter.name, "leaf_alpha");
    ASSERT_TRUE(quarter.alpha);
    EXPECT_EQ(quarter.alpha->kind, ParamDesc::Kind::Number);
    EXPECT_DOUBLE_EQ(quarter.alpha->number, 0.25);
    EXPECT_FALSE(quarter.alpha_cutoff) << "by chance, as pbrt-v4";
    EXPECT_NEAR(number(quarter, "albedo"), number(material(d, "leaf"), "albedo"), 0.0)
        << "a copy of the material";
    EXPECT_EQ(d.objects[1].material, d.objects[0].material) << "the same alpha: one copy";
    const MaterialDesc& masked = material(d, d.objects[2].material);
    ASSERT_TRUE(masked.alpha);
    EXPECT_EQ(masked.alpha->kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(masked.alpha->texture.channel, kAlphaPbrt) << "read as pbrt reads float images";
    EXPECT_NE(masked.alpha->texture.path.find("wood.png"), std::string::npos);
    const MaterialDesc& half = material(d, d.objects[3].material);
    ASSERT_TRUE(half.alpha);
    EXPECT_DOUBLE_EQ(half.alpha->number, 0.5) << "a constant texture is its value";
    EXPECT_EQ(d.objects[4].material, "leaf") << "alpha 1 is opaque";
    EXPECT_EQ(d.objects[5].material, "leaf");
    EXPECT_TRUE(noted(d, ":10: alpha texture 'nothere' is not defined"));
    const MaterialDesc& other = material(d, d.objects[6].material);
    ASSERT_TRUE(other.alpha);
    EXPECT_NE(other.name, masked.name) << "another material, another copy";
    EXPECT_FALSE(material(d, "leaf").alpha) << "the material itself stays opaque";
    // The anonymous material whose only shape has an alpha is used through its copy alone: it
    // is not kept (a converted scene said it was unused).
    const std::string base = other.name.substr(0, other.name.rfind("_alpha"));
    EXPECT_THROW(material(d, base), std::runtime_error) << base;
    // pbrt-v3 cuts only where alpha is 0: a cutoff just above it.
    const SceneDescription v3 = read(f, R"(WorldBegin
Material "matte" "rgb Kd" [.5 .5 .5]
Shape "sphere" "float alpha" 0.25
)");
    ASSERT_EQ(v3.objects.size(), 1u);
    const MaterialDesc& old = material(v3, v3.objects[0].material);
    ASSERT_TRUE(old.alpha && old.alpha_cutoff);
    EXPECT_GT(*old.alpha_cutoff, 0.0);
    EXPECT_LT(*old.alpha_cutoff, 1e-3);
}

TEST(PbrtReader, AQuadricWithoutSurfaceIsDroppedNotFatal) {
    // pbrt draws nothing for these; one of them failed the whole scene.
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Shape "disk" "float radius" 0.3 "float innerradius" 0.3
Shape "cylinder" "float zmin" 1 "float zmax" 1
Shape "sphere" "float radius" 0
Shape "sphere"
)");
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_TRUE(noted(d, ":2: disk: 'innerradius' 0.3 is not in [0, radius 0.3)"));
    EXPECT_TRUE(noted(d, ":3: cylinder: 'zmin' and 'zmax' are equal"));
    EXPECT_TRUE(noted(d, ":4: sphere: 'radius' 0 is not positive"));
    // A parameter given twice and a material type that is no pbrt type, said as such (both
    // were "is not supported").
    const SceneDescription t = read(f, R"(WorldBegin
Material "difuse"
Shape "sphere" "float radius" 1 "float radius" 2
)");
    EXPECT_TRUE(noted(t, ":2: Material \"difuse\": not a pbrt material type"));
    EXPECT_TRUE(noted(t,
                      ":3: 'float radius' of Shape \"sphere\" is given more than once: the "
                      "last one stands"));
    ASSERT_EQ(t.objects.size(), 1u);
    EXPECT_EQ(*t.objects[0].placement.matrix, Affine::scale(Vec3(2.0f)));
}

TEST(PbrtReader, AnInterfaceAreaLightAndAMixOfUndefinedMaterialsAreSaid) {
    // pbrt ignores an area light on an interface shape (it emitted here); a mix of names never
    // defined silently took the default material.
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
AttributeBegin
Material "interface"
AreaLightSource "diffuse" "rgb L" [5 5 5]
Shape "sphere"
AttributeEnd
Material "mix" "string materials" ["x" "y"]
Shape "disk"
)");
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_FALSE(d.objects[0].emission.has_value());
    EXPECT_TRUE(noted(d, ":5: an area light on a shape of material \"interface\""));
    EXPECT_TRUE(noted(d, ":7: Material \"mix\": its material 'x' is not defined"));
}

TEST(PbrtReader, AMixMayNameMaterialsDefinedFurtherOn) {
    // pbrt-v4 resolves names once the scene is read: a mix before its operands' definitions
    // took the default material (grey, not the operand's green).
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Material "mix" "string materials" ["a" "b"] "float amount" 0.3
Shape "sphere"
MakeNamedMaterial "a" "string type" "diffuse" "rgb reflectance" [0.1 0.8 0.1]
MakeNamedMaterial "b" "string type" "diffuse" "rgb reflectance" [0.8 0.1 0.1]
)");
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_EQ(d.objects[0].material, "a");
    EXPECT_FALSE(noted(d, "is not defined"));
    // A named mix used before it is defined, whose operand comes later still: both followed.
    const SceneDescription chain = read(f, R"(WorldBegin
NamedMaterial "m"
Shape "sphere"
MakeNamedMaterial "m" "string type" "mix" "string materials" ["a" "b"] "float amount" 0.7
MakeNamedMaterial "b" "string type" "diffuse" "rgb reflectance" [0.8 0.1 0.1]
)");
    ASSERT_EQ(chain.objects.size(), 1u);
    EXPECT_EQ(chain.objects[0].material, "b");
}

TEST(PbrtReader, QuadricsAreTessellatedOnTheirSurfaces) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Shape "sphere" "float radius" 2
Shape "sphere" "float radius" 0.7
Shape "disk" "float radius" 1 "float innerradius" 0.5 "float height" 0.25
Shape "cylinder" "float radius" 0.5 "float zmin" 0 "float zmax" 2 "float phimax" 180
)");
    ASSERT_EQ(d.objects.size(), 4u);
    const TriangleMesh& s = mesh_of(d.objects[0]);
    // Spheres of any radius share the unit sphere, scaled by their placement (2000 spheres of
    // as many radii took 13 GB as 2000 meshes).
    EXPECT_EQ(&s, &mesh_of(d.objects[1])) << "spheres share one mesh";
    EXPECT_EQ(*d.objects[0].placement.matrix, Affine::scale(Vec3(2.0f)));
    EXPECT_EQ(*d.objects[1].placement.matrix, Affine::scale(Vec3(0.7f)));
    EXPECT_GT(s.triangle_count(), 10000u);
    for (std::size_t v = 0; v < s.vertex_count(); ++v) {
        EXPECT_NEAR(length(s.position(static_cast<uint32_t>(v))), 1.0f, 1e-6f);
        // Outward normals, and faces wound to match them.
        const Vec3 n(s.normals[3 * v], s.normals[3 * v + 1], s.normals[3 * v + 2]);
        EXPECT_GT(dot(n, s.position(static_cast<uint32_t>(v))), 0.0f);
    }
    const Vec3 p0 = s.position(s.indices[0]), p1 = s.position(s.indices[1]),
               p2 = s.position(s.indices[2]);
    EXPECT_GT(dot(cross(p1 - p0, p2 - p0), p0 + p1 + p2), 0.0f);
    const TriangleMesh& disk = mesh_of(d.objects[2]);
    for (std::size_t v = 0; v < disk.vertex_count(); ++v) {
        const Vec3 p = disk.position(static_cast<uint32_t>(v));
        EXPECT_EQ(p.z, 0.25f);
        EXPECT_GE(std::hypot(p.x, p.y), 0.5f - 1e-5f);
    }
    const TriangleMesh& cyl = mesh_of(d.objects[3]);
    for (std::size_t v = 0; v < cyl.vertex_count(); ++v)
        EXPECT_GE(cyl.position(static_cast<uint32_t>(v)).y, -1e-6f) << "phimax 180: y >= 0";
}

TEST(PbrtReader, BilinearMeshesBecomeTrianglesAndCurvedPatchesAGrid) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Shape "bilinearmesh" "point3 P" [0 0 0 1 0 0 0 1 0 1 1 0] "integer indices" [0 1 2 3]
Shape "bilinearmesh" "point3 P" [0 0 0 1 0 0 0 1 0 1 1 1]
)");
    ASSERT_EQ(d.objects.size(), 2u);
    EXPECT_EQ(mesh_of(d.objects[0]).triangle_count(), 2u) << "a flat patch is two triangles";
    const TriangleMesh& curved = mesh_of(d.objects[1]);
    EXPECT_EQ(curved.triangle_count(), 128u) << "a twisted patch is an 8 x 8 grid";
    EXPECT_EQ(curved.uvs.size(), 2 * curved.vertex_count());
}

TEST(PbrtReader, LoopSubdivIsAnInlineCageOfTheLoopScheme) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Shape "loopsubdiv" "integer levels" 2 "integer indices" [0 1 2 0 2 3 0 3 1 1 3 2]
  "point3 P" [0 0 1  1 0 -1  -1 1 -1  -1 -1 -1]
)");
    ASSERT_EQ(d.objects.size(), 1u);
    const auto& s = std::get<SubdivShape>(d.objects[0].shape);
    ASSERT_TRUE(s.cage);
    EXPECT_TRUE(s.path.empty());
    EXPECT_EQ(s.cage->face_count(), 4u);
    EXPECT_EQ(s.options.scheme, SubdivOptions::Scheme::Loop);
    EXPECT_EQ(s.options.level, 2);
    // A cage index beyond its points is an error at its parameter.
    const std::string e = error_of(f,
                                   "Shape \"loopsubdiv\" \"integer indices\" [0 1 7] "
                                   "\"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    EXPECT_NE(e.find("scene.pbrt:1:20: error: loopsubdiv: index 7"), std::string::npos) << e;
}

TEST(PbrtReader, AByteOrderMarkAndOldMacLineEndsAreText) {
    const Files f;
    // A UTF-8 byte order mark before the first directive; carriage returns alone ending lines.
    const SceneDescription d = read(
        f, std::string("\xEF\xBB\xBFWorldBegin\r") + "LightSource \"point\" \"rgb I\" [1 1 1]\r");
    EXPECT_EQ(d.lights.size(), 1u);
    const std::string e = error_of(f, "WorldBegin\r\rFrobnicate\r");
    EXPECT_NE(e.find("scene.pbrt:3:1: error: unknown directive 'Frobnicate'"), std::string::npos)
        << e;
}

TEST(PbrtReader, PlyMeshesStayMeshFilesForMeshLoad) {
    const Files f;
    const SceneDescription d = read(f, "Shape \"plymesh\" \"string filename\" \"mesh.ply\"\n");
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_EQ(std::get<MeshFileShape>(d.objects[0].shape).path, f.file("mesh.ply"));
    const std::string e = error_of(f, "Shape \"plymesh\" \"string filename\" \"gone.ply\"\n");
    EXPECT_NE(e.find("scene.pbrt:1:1: error:"), std::string::npos) << e;
    EXPECT_NE(e.find("gone.ply"), std::string::npos) << e;
}

TEST(PbrtReader, APlyMeshOfQuadsLoadsAsTriangles) {
    // pbrt-v4 writes PLY meshes of quads: mesh_load (the PLY reader) splits each polygon.
    const Files f;
    std::ofstream(f.file("quads.ply")) << "ply\nformat ascii 1.0\nelement vertex 6\n"
                                          "property float x\nproperty float y\nproperty float z\n"
                                          "element face 2\nproperty list uchar int vertex_indices\n"
                                          "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n2 1 0\n"
                                          "4 0 1 2 3\n4 1 4 5 2\n";
    const SceneDescription d = read(f, "Shape \"plymesh\" \"string filename\" \"quads.ply\"\n");
    const auto& m = std::get<MeshFileShape>(d.objects.at(0).shape);
    EXPECT_EQ(load_mesh(m.path, m.loc).triangle_count(), 4u);
}

TEST(PbrtReader, APlyMeshTurnsAsPbrtTurnsIt) {
    // pbrt turns a mesh without normals under ReverseOrientation or a mirroring transform, and
    // v4 turns authored normals under ReverseOrientation: a PLY file as much as a trianglemesh
    // (its faces kept the file's winding: a one-sided PLY emitter lit the wrong side). Read
    // there and then, turned; one read per file and orientation; the file is one of the scene's.
    const Files f;
    const char* header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\n";
    std::ofstream(f.file("tri.ply")) << header
                                     << "element face 1\nproperty list uchar int vertex_indices\n"
                                        "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    std::ofstream(f.file("tri_n.ply"))
        << header
        << "property float nx\nproperty float ny\nproperty float nz\nelement face 1\n"
           "property list uchar int vertex_indices\nend_header\n0 0 0 0 0 1\n1 0 0 0 0 1\n"
           "0 1 0 0 0 1\n3 0 1 2\n";
    const SceneDescription d = read(f, R"(Film "rgb"
WorldBegin
Shape "plymesh" "string filename" "tri.ply"
AttributeBegin
  ReverseOrientation
  Shape "plymesh" "string filename" "tri.ply"
  Shape "plymesh" "string filename" "tri.ply"
  Shape "plymesh" "string filename" "tri_n.ply"
AttributeEnd
AttributeBegin
  Scale -1 1 1
  Shape "plymesh" "string filename" "tri.ply"
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 1 1] "float power" 10
  Shape "plymesh" "string filename" "tri.ply"
AttributeEnd
)");
    ASSERT_EQ(d.objects.size(), 6u);
    EXPECT_TRUE(std::holds_alternative<MeshFileShape>(d.objects[0].shape))
        << "an unturned PLY stays a file for the mesh system";
    const TriangleMesh& reversed = mesh_of(d.objects[1]);
    EXPECT_EQ(reversed.indices, (std::vector<uint32_t>{0, 2, 1}));
    EXPECT_EQ(&reversed, &mesh_of(d.objects[2])) << "one read per file and orientation";
    const TriangleMesh& normals = mesh_of(d.objects[3]);
    EXPECT_EQ(normals.indices, (std::vector<uint32_t>{0, 1, 2})) << "normals orient it";
    ASSERT_EQ(normals.normals.size(), 9u);
    EXPECT_EQ(normals.normals[2], -1.0f) << "v4 (Film \"rgb\") turns authored normals";
    EXPECT_EQ(mesh_of(d.objects[4]).indices, (std::vector<uint32_t>{0, 2, 1})) << "a mirror";
    // 'power' needs the area (0.5): 10 W = L pi A, so L = 20 / pi.
    ASSERT_TRUE(d.objects[5].emission.has_value());
    EXPECT_NEAR(d.objects[5].emission->intensity, 20.0 / M_PI, 1e-4);
    EXPECT_NE(std::find(d.files.begin(), d.files.end(), f.file("tri.ply")), d.files.end());
}

TEST(PbrtReader, TheDefaultMaterialNeverTakesAWrittenMaterialsName) {
    // A scene may name its own material pbrt_default: the default then gets a name of its own.
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
MakeNamedMaterial "pbrt_default" "string type" "matte" "rgb Kd" [1 0 0]
Shape "sphere"
)");
    ASSERT_EQ(d.materials.size(), 2u);
    EXPECT_EQ(param(material(d, "pbrt_default"), "albedo")->color.rgb, Vec3(1.0f, 0.0f, 0.0f));
    EXPECT_EQ(d.objects.at(0).material, "pbrt_default#2");
    EXPECT_EQ(param(material(d, "pbrt_default#2"), "albedo")->color.rgb, Vec3(0.5f));
}

TEST(PbrtReader, V3MaterialsMapOntoTheNearestModels) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
MakeNamedMaterial "matte" "string type" "matte" "rgb Kd" [0.2 0.3 0.4]
MakeNamedMaterial "plastic" "string type" "plastic" "rgb Kd" [0.5 0.5 0.5]
  "float roughness" 0.1
MakeNamedMaterial "raw" "string type" "plastic" "float roughness" 0.3 "bool remaproughness" false
MakeNamedMaterial "metal" "string type" "metal" "spectrum eta" "metal-Au-eta"
  "spectrum k" "metal-Au-k" "float roughness" 0.01
MakeNamedMaterial "custom" "string type" "metal" "rgb eta" [0.2 0.3 0.4] "rgb k" [3 2 1]
MakeNamedMaterial "mirror" "string type" "mirror"
MakeNamedMaterial "glass" "string type" "glass" "float index" 1.33
MakeNamedMaterial "uber" "string type" "uber" "rgb Kd" [0.1 0.2 0.3] "float eta" 1.4
MakeNamedMaterial "substrate" "string type" "substrate" "float uroughness" 0.2
  "float vroughness" 0.4 "bool remaproughness" false
MakeNamedMaterial "mix" "string type" "mix" "string namedmaterial1" "matte"
  "string namedmaterial2" "glass" "float amount" 0.8
MakeNamedMaterial "paint" "string type" "flake" "rgb Kd" [0.4 0 0] "rgb Ks" [0.9 0.9 0.9]
  "float roughness" 0.2 "float gamma" 5
MakeNamedMaterial "skin" "string type" "kdsubsurface" "rgb Kd" [0.8 0.6 0.5]
)");
    const MaterialDesc& matte = material(d, "matte");
    EXPECT_EQ(matte.model, "diffuse");
    EXPECT_EQ(param(matte, "albedo")->color.rgb, Vec3(0.2f, 0.3f, 0.4f));
    const MaterialDesc& plastic = material(d, "plastic");
    EXPECT_EQ(plastic.model, "plastic");
    // pbrt-v3's roughness remap (a quartic in log r): 0.1 is GGX alpha 0.4617.
    EXPECT_NEAR(number(plastic, "roughness"), 0.4617, 1e-3);
    EXPECT_NEAR(number(material(d, "raw"), "roughness"), 0.3, 1e-12);
    EXPECT_EQ(param(material(d, "metal"), "preset")->text, "gold");
    EXPECT_NEAR(number(material(d, "metal"), "roughness"), 0.1388, 1e-3);
    const MaterialDesc& custom = material(d, "custom");
    EXPECT_EQ(param(custom, "preset")->text, "custom");
    EXPECT_EQ(param(custom, "k")->color.rgb, Vec3(3, 2, 1));
    EXPECT_EQ(param(material(d, "mirror"), "preset")->text, "perfect");
    const MaterialDesc& glass = material(d, "glass");
    EXPECT_EQ(glass.model, "dielectric");
    EXPECT_NEAR(number(glass, "ior"), 1.33, 1e-12);
    EXPECT_EQ(number(glass, "roughness"), 0.0) << "v3 glass of roughness 0 is smooth";
    EXPECT_NEAR(number(material(d, "uber"), "ior"), 1.4, 1e-12);
    EXPECT_NEAR(number(material(d, "substrate"), "roughness_v"), 0.4, 1e-12);
    // v3's mix weighs namedmaterial1 by amount: 0.8 keeps the matte.
    EXPECT_EQ(material(d, "mix").model, "diffuse");
    const MaterialDesc& paint = material(d, "paint");
    EXPECT_EQ(paint.plugin, "flake");
    EXPECT_EQ(param(paint, "base_color")->color.rgb, Vec3(0.4f, 0, 0));
    EXPECT_NEAR(number(paint, "flake_roughness"), 0.2, 1e-12);
    EXPECT_NEAR(number(paint, "gamma"), 5.0, 1e-12);
    EXPECT_EQ(param(material(d, "skin"), "albedo")->color.rgb, Vec3(0.8f, 0.6f, 0.5f));
    EXPECT_TRUE(noted(d, "Material \"kdsubsurface\": not supported; a diffuse reflector"));
    EXPECT_TRUE(noted(d, "Material \"plastic\": 'Ks' is not supported"));
    EXPECT_TRUE(noted(d,
                      "Material \"mix\": blends are not supported: its heavier material "
                      "'matte'"));
}

TEST(PbrtReader, V4MaterialsMapOntoTheNearestModels) {
    const Files f;
    const SceneDescription d = read(f, R"(Film "rgb"
WorldBegin
MakeNamedMaterial "a" "string type" "diffuse" "rgb reflectance" [0.1 0.2 0.3]
MakeNamedMaterial "b" "string type" "coateddiffuse" "float roughness" 0.25
MakeNamedMaterial "c" "string type" "conductor" "spectrum eta" "metal-Cu-eta"
  "spectrum k" "metal-Cu-k" "float roughness" 0.04
MakeNamedMaterial "d" "string type" "conductor" "rgb reflectance" [0.8 0.8 0.8]
MakeNamedMaterial "e" "string type" "dielectric" "spectrum eta" "glass-BK7"
MakeNamedMaterial "f" "string type" "thindielectric" "float eta" 1.2
MakeNamedMaterial "g" "string type" "diffusetransmission" "rgb reflectance" [0.5 0.5 0.5]
MakeNamedMaterial "h" "string type" "coatedconductor" "spectrum conductor.eta" "metal-Al-eta"
  "spectrum conductor.k" "metal-Al-k"
MakeNamedMaterial "i" "string type" "mix" "string materials" ["a" "e"] "float amount" 0.9
MakeNamedMaterial "j" "string type" "conductor" "spectrum eta" "metal-CuZn-eta"
  "spectrum k" "metal-CuZn-k"
MakeNamedMaterial "k" "string type" "hair"
MakeNamedMaterial "l" "string type" "coatedconductor" "rgb reflectance" [0.9 0.6 0.3]
  "float interface.roughness" 0.01 "float interface.eta" 1.6
  "float conductor.uroughness" 0.04 "float conductor.vroughness" 0.09
MakeNamedMaterial "m" "string type" "coatedconductor" "float conductor.roughness" 0.09
  "float conductor.vroughness" 0.01 "float interface.roughness" 0.04
  "float interface.uroughness" 0.25
Material "interface"
Shape "sphere"
)");
    EXPECT_EQ(param(material(d, "a"), "albedo")->color.rgb, Vec3(0.1f, 0.2f, 0.3f));
    EXPECT_EQ(material(d, "b").model, "plastic");
    // pbrt-v4 remaps roughness r to alpha sqrt(r).
    EXPECT_NEAR(number(material(d, "b"), "roughness"), 0.5, 1e-12);
    EXPECT_EQ(param(material(d, "c"), "preset")->text, "copper");
    EXPECT_NEAR(number(material(d, "c"), "roughness"), 0.2, 1e-12);
    // A reflectance becomes index 1 with the extinction of the same normal reflectance.
    const float k = param(material(d, "d"), "k")->color.rgb.x;
    EXPECT_NEAR(k * k / (4.0f + k * k), 0.8f, 1e-5f);
    EXPECT_NEAR(number(material(d, "e"), "ior"), 1.5168, 1e-4) << "Schott N-BK7 n_d";
    EXPECT_EQ(material(d, "f").model, "dielectric");
    EXPECT_EQ(material(d, "g").model, "diffuse");
    EXPECT_EQ(param(material(d, "h"), "preset")->text, "aluminium");
    // The coat is the conductor's own, pbrt-v4's defaults: a smooth coat of index 1.5.
    EXPECT_EQ(number(material(d, "h"), "coat"), 1.0);
    EXPECT_NEAR(number(material(d, "h"), "coat_ior"), 1.5, 1e-12);
    EXPECT_EQ(number(material(d, "h"), "coat_roughness"), 0.0);
    EXPECT_FALSE(noted(d, "coat is dropped"));
    EXPECT_NEAR(number(material(d, "l"), "coat_ior"), 1.6, 1e-12);
    EXPECT_NEAR(number(material(d, "l"), "coat_roughness"), 0.1, 1e-12);
    EXPECT_NEAR(number(material(d, "l"), "roughness"), 0.2, 1e-12);
    EXPECT_NEAR(number(material(d, "l"), "roughness_v"), 0.3, 1e-12);
    // u falls back to conductor.roughness, as in pbrt-v4 (it fell back to 0).
    EXPECT_NEAR(number(material(d, "m"), "roughness"), 0.3, 1e-12);
    EXPECT_NEAR(number(material(d, "m"), "roughness_v"), 0.1, 1e-12);
    EXPECT_NEAR(number(material(d, "m"), "coat_roughness"), 0.5, 1e-12);
    // v4's mix picks the second material with probability amount: 0.9 keeps the dielectric.
    EXPECT_EQ(material(d, "i").model, "dielectric");
    EXPECT_EQ(param(material(d, "j"), "preset")->text, "copper");
    EXPECT_TRUE(noted(d, "no optical data for \"metal-CuZn-eta\" here: copper stands in"));
    EXPECT_TRUE(noted(d, "Material \"hair\": not supported; a diffuse reflector"));
    EXPECT_TRUE(d.objects.empty()) << "an interface is no surface";
}

TEST(PbrtReader, TexturesBecomeLookupsOrConstants) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
Texture "wood" "spectrum" "imagemap" "string filename" "wood.png" "float uscale" 4
  "float vscale" 2 "float udelta" 0.5 "float vdelta" 0.25 "string wrap" "clamp"
Texture "dark" "spectrum" "scale" "texture tex" "wood" "rgb scale" [0.5 0.5 0.5]
Texture "quarter" "float" "constant" "float value" 0.25
Texture "darker" "spectrum" "scale" "texture tex" "wood" "texture scale" "quarter"
Texture "grey" "spectrum" "constant" "rgb value" [0.3 0.3 0.3]
Texture "blend" "spectrum" "mix" "rgb tex1" [0 0 0] "rgb tex2" [1 1 1] "float amount" 0.25
Texture "check" "spectrum" "checkerboard" "rgb tex1" [1 1 1] "rgb tex2" [0 0 0]
Texture "rough" "float" "imagemap" "string filename" "wood.png" "string encoding" "linear"
Texture "bumps" "float" "imagemap" "string filename" "bumps.png" "float scale" 0.01
Texture "noise" "float" "fbm"
MakeNamedMaterial "m1" "string type" "matte" "texture Kd" "dark" "texture bumpmap" "bumps"
MakeNamedMaterial "m2" "string type" "matte" "texture Kd" "grey"
MakeNamedMaterial "m3" "string type" "matte" "texture Kd" "blend"
MakeNamedMaterial "m4" "string type" "matte" "texture Kd" "check"
MakeNamedMaterial "m5" "string type" "conductor" "texture roughness" "rough"
  "bool remaproughness" false
MakeNamedMaterial "m6" "string type" "diffuse" "string normalmap" "bumps.png"
MakeNamedMaterial "m7" "string type" "diffuse" "texture reflectance" "darker"
MakeNamedMaterial "m8" "string type" "coateddiffuse" "texture roughness" "rough"
)");
    const ParamDesc* kd = param(material(d, "m1"), "albedo");
    ASSERT_EQ(kd->kind, ParamDesc::Kind::Texture);
    const TextureDesc& t = kd->texture;
    EXPECT_EQ(t.path, f.file("wood.png"));
    EXPECT_EQ(std::vector<float>(t.uv, t.uv + 6), (std::vector<float>{4, 0, 0.5f, 0, 2, 0.25f}));
    EXPECT_EQ(t.wrap, 1);
    EXPECT_EQ(t.scale[0], 0.5f) << "a scale texture folds into the image's scale";
    EXPECT_EQ(*t.space, "srgb_texture") << "8-bit images are sRGB-encoded";
    const MaterialDesc& m1 = material(d, "m1");
    ASSERT_EQ(m1.maps.size(), 1u);
    EXPECT_EQ(m1.maps[0].name, "bump_map");
    EXPECT_FLOAT_EQ(m1.maps[0].texture.amount, 0.01f);
    // An 8-bit bump image is sRGB-decoded, as pbrt reads float image maps (it was read raw).
    EXPECT_EQ(*m1.maps[0].texture.space, "srgb_texture");
    EXPECT_EQ(param(material(d, "m2"), "albedo")->color.rgb, Vec3(0.3f));
    EXPECT_EQ(param(material(d, "m3"), "albedo")->color.rgb, Vec3(0.25f));
    EXPECT_EQ(param(material(d, "m4"), "albedo")->color.rgb, Vec3(0.5f));
    const ParamDesc* rough = param(material(d, "m5"), "roughness");
    ASSERT_EQ(rough->kind, ParamDesc::Kind::Texture);
    EXPECT_EQ(*rough->texture.space, "raw");
    EXPECT_EQ(material(d, "m6").maps.at(0).name, "normal_map");
    // pbrt-v4: a spectrum texture's "texture scale" names a float texture.
    EXPECT_EQ(param(material(d, "m7"), "albedo")->texture.scale[0], 0.25f);
    // Spangle's plastic takes one coat roughness: a roughness texture on coateddiffuse (zero-day
    // has 30) is dropped with a note and pbrt's default stands in (the scene failed to load).
    const ParamDesc* coat = param(material(d, "m8"), "roughness");
    ASSERT_EQ(coat->kind, ParamDesc::Kind::Number);
    EXPECT_EQ(coat->number, 0.0);
    EXPECT_TRUE(noted(d, "a texture of 'roughness' is not supported on this material"));
    EXPECT_FALSE(noted(d, "is not defined"));
    EXPECT_TRUE(noted(d, "checkerboard texture is not supported"));
    EXPECT_TRUE(noted(d, "texture \"fbm\" is not supported: a constant 0.5 stands in"));
}

TEST(PbrtReader, WhatRealScenesNeededIsReadAsPbrtReadsIt) {
    // From a run over ~110 real pbrt scenes (pbrt-v4-scenes, Bitterli's, v3 test scenes).
    const Files f;
    // pbrt-v4's sensor: the image is scaled by (shutterclose - shutteropen) x iso / 100 (most
    // of the official v4 scenes set iso; they came out 1.5 to 6 times too dark or bright).
    const SceneDescription d = read(f, R"(Film "rgb" "float iso" 400
Camera "perspective" "float shutteropen" 0 "float shutterclose" 0.5
WorldBegin
LightSource "point" "rgb I" [1 1 1]
LightSource "infinite" "rgb L" [0.5 0.5 0.5]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [2 2 2]
Shape "sphere"
AttributeEnd
MakeNamedMaterial "unused" "string type" "diffuse"
MakeNamedMaterial "ub" "string type" "uber" "float index" 1.25
)");
    ASSERT_EQ(d.lights.size(), 2u);  // the point and the emitting sphere
    EXPECT_DOUBLE_EQ(d.lights[0].intensity, 2.0);
    ASSERT_TRUE(d.environment);
    EXPECT_DOUBLE_EQ(d.environment->intensity, 2.0);
    EXPECT_TRUE(d.objects.empty());
    ASSERT_TRUE(std::holds_alternative<SphereLightDesc>(d.lights[1].shape));
    EXPECT_DOUBLE_EQ(d.lights[1].intensity, 2.0);
    EXPECT_TRUE(noted(d, "pbrt-v4's exposure (shutter 0.5 s x iso 400 / 100 = 2)"));
    EXPECT_FALSE(noted(d, "'float iso'")) << "iso is used, not dropped";
    // A material no shape uses is a library entry: no warning later (mix operands alike).
    EXPECT_TRUE(material(d, "unused").quiet_unused);
    // pbrt-v3's uber takes "index" where "eta" is absent (it was dropped: a 1.5 coat).
    EXPECT_NEAR(number(material(d, "ub"), "ior"), 1.25, 1e-12);
    EXPECT_FALSE(noted(d, "'float index'"));
    // A mix texture whose amount is an image and whose operands are constants: their average,
    // and a note that says so (it said "a mix texture of images").
    const SceneDescription m = read(f, R"(WorldBegin
Texture "amt" "float" "imagemap" "string filename" "wood.png"
Texture "bark" "spectrum" "mix" "rgb tex1" [0.2 0.2 0.2] "rgb tex2" [0.6 0.6 0.6]
  "texture amount" "amt"
Material "diffuse" "texture reflectance" "bark"
Shape "sphere"
)");
    EXPECT_TRUE(noted(m, "a mix texture whose 'amount' is an image is not supported"));
    EXPECT_FALSE(noted(m, "a mix texture of images"));
    // A v4 infinite light with a 2:1 image: read as lat-long (pbrt-v4 takes only square
    // equal-area maps; wrapped onto the octahedron it was a seamed, split sky); a square one
    // stays equal-area.
    const auto write = [&](const std::string& name, int w, int h) {
        const std::vector<float> px(static_cast<std::size_t>(w * h * 3), 0.5f);
        auto out = OIIO::ImageOutput::create(f.file(name));
        ASSERT_TRUE(out);
        ASSERT_TRUE(out->open(f.file(name), OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT)));
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        ASSERT_TRUE(out->close());
    };
    write("wide.exr", 16, 8);
    write("square.exr", 8, 8);
    for (const auto& [file, projection] : {std::pair{"wide.exr", MapProjection::LatLongZUp},
                                           std::pair{"square.exr", MapProjection::EqualArea}}) {
        const SceneDescription e = read(f, fmt::format(R"(Film "rgb"
WorldBegin
LightSource "infinite" "string filename" "{}"
)",
                                                       file));
        ASSERT_TRUE(e.environment && e.environment->map) << file;
        EXPECT_EQ(e.environment->map->projection, projection) << file;
        EXPECT_EQ(noted(e, "not square"), projection == MapProjection::LatLongZUp) << file;
    }
}

TEST(PbrtReader, LightsBecomeSpangleLights) {
    const Files f;
    const SceneDescription d = read(f, std::string(R"(Film "rgb"
WorldBegin
LightSource "point" "rgb I" [1 2 3] "point3 from" [0 1 0] "float scale" 2
LightSource "spot" "point3 from" [0 5 0] "point3 to" [0 0 0] "float coneangle" 20
  "float conedeltaangle" 4
LightSource "distant" "point3 from" [0 0 0] "point3 to" [0 -1 0] "blackbody L" 5500
LightSource "point" "float power" 100
AttributeBegin
  Rotate -90 1 0 0
  LightSource "infinite" "string filename" "sky.exr" "float scale" 1.5
AttributeEnd
LightSource "goniometric"
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 4 4] "bool twosided" true "float scale" 0.5
)") + kQuad + R"(
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "float power" 10
  Scale 2 2 2
)" + kQuad + R"(
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "float power" 10
  Scale 3 3 3
  Shape "sphere" "float radius" 0.5
AttributeEnd
)");
    ASSERT_EQ(d.lights.size(), 6u);  // the last the emitting sphere
    EXPECT_EQ(d.lights[0].color->rgb, Vec3(1, 2, 3));
    EXPECT_EQ(d.lights[0].intensity, 2.0);
    EXPECT_EQ(std::get<PointLightDesc>(d.lights[0].shape).position, Vec3(0, 1, 0));
    const auto& spot = std::get<SpotLightDesc>(d.lights[1].shape);
    EXPECT_EQ(spot.cone_angle, 20.0);
    EXPECT_EQ(spot.cone_falloff, 4.0);
    EXPECT_FALSE(spot.quartic) << "pbrt-v4's spot fades by smoothstep";
    // pbrt-v3's fades as t^4, decided by the whole file (its WorldEnd comes after the light).
    const SceneDescription v3 = read(f, R"(WorldBegin
LightSource "spot" "point from" [0 5 0] "point to" [0 0 0] "float coneangle" 30
WorldEnd
)");
    ASSERT_EQ(v3.lights.size(), 1u);
    EXPECT_TRUE(std::get<SpotLightDesc>(v3.lights[0].shape).quartic);
    EXPECT_EQ(std::get<DistantLightDesc>(d.lights[2].shape).direction, Vec3(0, 1, 0))
        << "towards the light: from - to";
    EXPECT_NEAR(luminance(d.lights[2].color->rgb), 1.0f, 1e-4f)
        << "v4 normalises a light's spectrum to unit luminance";
    EXPECT_GT(d.lights[2].color->rgb.x, d.lights[2].color->rgb.z) << "5500 K is warm";
    EXPECT_NEAR(d.lights[3].intensity, 100.0 / (4.0 * M_PI), 1e-9) << "v4 point 'power'";
    ASSERT_TRUE(d.environment && d.environment->map);
    const EnvironmentDesc::Map& map = *d.environment->map;
    EXPECT_EQ(map.projection, MapProjection::EqualArea) << "pbrt-v4's maps are equal-area";
    EXPECT_NEAR(map.to_world.apply_vector({0, 0, 1}).y, 1.0f, 1e-6f) << "the map's +z is up";
    EXPECT_EQ(d.environment->intensity, 1.5);
    EXPECT_TRUE(noted(d, "LightSource \"goniometric\" is not supported: a point light"));
    ASSERT_EQ(d.objects.size(), 2u);
    const EmissionDesc& e = *d.objects[0].emission;
    EXPECT_TRUE(e.two_sided);
    EXPECT_EQ(e.intensity, 0.5);
    // v4 area 'power': W over pi A (the scaled quad's area is 4).
    EXPECT_NEAR(d.objects[1].emission->intensity, 10.0 / (M_PI * 4.0), 1e-6);
    // A quadric's area is its own (pbrt's Sphere::Area(): 4 pi r^2 = pi, the scale aside).
    EXPECT_NEAR(d.lights[5].intensity, 10.0 / (M_PI * M_PI), 1e-9);
    EXPECT_NEAR(std::get<SphereLightDesc>(d.lights[5].shape).radius, 1.5, 1e-6);
}

TEST(PbrtReader, AV3InfiniteMapIsLatLongWithItsZUp) {
    const Files f;
    const SceneDescription d =
        read(f,
             "WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.exr\" \"rgb L\" [2 2 "
             "2]\nLightSource \"infinite\" \"rgb L\" [1 1 1]\n");
    ASSERT_TRUE(d.environment && d.environment->map);
    EXPECT_EQ(d.environment->map->projection, MapProjection::LatLongZUp);
    EXPECT_EQ(d.environment->intensity, 2.0);
    EXPECT_TRUE(noted(d, "a second infinite light"));
}

TEST(PbrtReader, CameraFovIsOnTheShorterAxisAndTheImageIsMirrored) {
    const Files f;
    const SceneDescription wide = read(f, R"(LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 40 "float lensradius" 0.1 "float focaldistance" 4
Film "image" "integer xresolution" 200 "integer yresolution" 100
)");
    EXPECT_NEAR(wide.camera.fov_deg, 40.0, 1e-9) << "landscape: pbrt's fov is vertical";
    EXPECT_TRUE(wide.camera.mirror) << "LookAt keeps handedness: pbrt's left-handed view";
    EXPECT_NEAR(length(wide.camera.position - Vec3(0, 0, 5)), 0.0f, 1e-5f);
    EXPECT_EQ(wide.camera.aperture, 0.1);
    EXPECT_EQ(*wide.camera.focus_distance, 4.0);
    const SceneDescription tall = read(f, R"(Scale -1 1 1
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "image" "integer xresolution" 100 "integer yresolution" 200
)");
    // Portrait: pbrt's 40 degrees span the shorter side, the width, of the size rendered (the
    // camera model resolves it: PbrtCamera.PointsProjectWherePbrtPutsThem and
    // ...AtAnotherSize... check where points land).
    EXPECT_EQ(tall.camera.fov_deg, 40.0);
    EXPECT_TRUE(tall.camera.fov_shorter);
    EXPECT_TRUE(wide.camera.fov_shorter);
    EXPECT_FALSE(tall.camera.mirror) << "Scale -1 1 1 undoes pbrt's mirror";
    const SceneDescription window =
        read(f, "Camera \"perspective\" \"float screenwindow\" [0 1 0 1]\n");
    ASSERT_TRUE(window.camera.screen);
    EXPECT_EQ((*window.camera.screen)[1], 1.0);
    EXPECT_EQ(window.camera.fov_deg, 90.0);
    const SceneDescription ortho =
        read(f, "Camera \"orthographic\" \"float screenwindow\" [0 1 0 1]\n");
    // Orthographic: the screen window is in camera space, so the view's unit is 1.
    EXPECT_FALSE(noted(ortho, "Camera \"orthographic\""));
    EXPECT_EQ(ortho.camera.ortho_height, 2.0);
    ASSERT_TRUE(ortho.camera.screen);
    EXPECT_EQ((*ortho.camera.screen)[1], 1.0);
    // A uniform scale before LookAt scales camera space: the view (and a lens) in world units.
    const SceneDescription scaled = read(
        f,
        "Scale 2 2 2\nLookAt 0 0 10 0 0 0 0 1 0\nCamera \"orthographic\" \"float lensradius\" 0.1 "
        "\"float focaldistance\" 4\n");
    EXPECT_NEAR(scaled.camera.ortho_height, 1.0, 1e-6) << "pbrt shows half as much";
    EXPECT_NEAR(scaled.camera.aperture, 0.05, 1e-7);
    EXPECT_NEAR(*scaled.camera.focus_distance, 2.0, 1e-6);
    EXPECT_THROW(
        read(f, "Camera \"perspective\" \"float lensradius\" 0.1 \"float focaldistance\" 0\n"),
        SpangleError)
        << "a lens focused at 0";
    const SceneDescription realistic = read(f, "Camera \"realistic\"\n");
    EXPECT_TRUE(noted(realistic, "Camera \"realistic\" is not supported"));
}

TEST(PbrtReader, FilmSamplerIntegratorAndFilterTakeEachVersionsDefaults) {
    const Files f;
    const SceneDescription v3 = read(f, R"(Film "image" "integer xresolution" 64
  "integer yresolution" 32 "string filename" "out.exr" "float cropwindow" [0.25 0.75 0 0.5]
Sampler "stratified" "integer xsamples" 3 "integer ysamples" 2
Integrator "path" "integer maxdepth" 7
WorldBegin
)");
    EXPECT_EQ(v3.render.width, 64u);
    EXPECT_EQ(v3.render.height, 32u);
    EXPECT_EQ(*v3.render.output, "out.exr");
    EXPECT_EQ((*v3.render.crop)[1], 0.75);
    EXPECT_EQ(v3.render.spp, 6u);
    EXPECT_EQ(v3.render.max_depth, 7u);
    EXPECT_EQ(v3.render.filter, FilterKind::Box) << "pbrt-v3's default filter";
    EXPECT_EQ(*v3.render.working_space, "lin_rec709");
    const SceneDescription v4 = read(f, R"(Film "rgb" "float iso" 400
Sampler "zsobol" "integer pixelsamples" 64
Integrator "bdpt"
PixelFilter "mitchell"
Option "integer seed" 7
)");
    EXPECT_EQ(v4.render.width, 640u);
    EXPECT_EQ(v4.render.height, 480u);
    EXPECT_EQ(v4.render.spp, 64u);
    EXPECT_EQ(v4.render.seed, 7u);
    EXPECT_EQ(v4.render.filter, FilterKind::Gaussian);
    // iso is pbrt-v4's exposure (WhatRealScenesNeeded... checks the lights it scales).
    EXPECT_TRUE(noted(v4, "pbrt-v4's exposure (shutter 1 s x iso 400 / 100 = 4)"));
    EXPECT_TRUE(noted(v4, "Integrator \"bdpt\": Spangle's path tracer stands in"));
    EXPECT_TRUE(noted(v4, "PixelFilter \"mitchell\": a Gaussian"));
    EXPECT_EQ(v4.render.filter_radius, 0.0f) << "the default reach: Spangle's own";
    // The filter's reach: a box of radius 1; a Gaussian keeps its sigma (radius 3 sigma), cut
    // where the file's radius is shorter (said), radii that differ by axis (their mean, said);
    // pbrt-v3's xwidth and alpha (sigma 1 / sqrt(2 alpha)).
    const SceneDescription box =
        read(f, "PixelFilter \"box\" \"float xradius\" 1 \"float yradius\" 1\n");
    EXPECT_EQ(box.render.filter, FilterKind::Box);
    EXPECT_EQ(box.render.filter_radius, 1.0f);
    const SceneDescription g = read(
        f, "PixelFilter \"gaussian\" \"float xradius\" 3 \"float yradius\" 2 \"float sigma\" 1\n");
    EXPECT_EQ(g.render.filter, FilterKind::Gaussian);
    EXPECT_EQ(g.render.filter_radius, 2.5f);
    EXPECT_TRUE(noted(g, "radii 3 and 2 (x, y): 2.5 on both axes"));
    EXPECT_TRUE(noted(g, "sigma 1 cut at radius 2.5"));
    const SceneDescription narrow = read(
        f, "PixelFilter \"gaussian\" \"float xwidth\" 2 \"float ywidth\" 2 \"float alpha\" 8\n");
    EXPECT_EQ(narrow.render.filter_radius, 0.75f);
    const SceneDescription plain = read(f, "PixelFilter \"gaussian\" \"float sigma\" 0.5\n");
    EXPECT_EQ(plain.render.filter_radius, 0.0f) << "sigma 0.5: Spangle's own Gaussian";
}

TEST(PbrtReader, WhatIsDroppedIsOneWarningAtItsLine) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
MakeNamedMedium "fog" "string type" "homogeneous"
MediumInterface "fog" ""
Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3]
Shape "sphere" "float alpha" 0.5 "float wobble" 3
Shape "sphere" "float wobble" 4
Accelerator "bvh"
)");
    EXPECT_TRUE(noted(d, "scene.pbrt:2: MakeNamedMedium: participating media are not supported"));
    EXPECT_TRUE(noted(d, "scene.pbrt:3: MediumInterface"));
    EXPECT_TRUE(noted(d, "scene.pbrt:4: Shape \"curve\" is not supported: dropped"));
    EXPECT_FALSE(noted(d, "alpha")) << "alpha is a cut-out now, said nowhere";
    // The same drop at two places is one note that counts the second.
    EXPECT_TRUE(noted(d,
                      "scene.pbrt:5: 'float wobble' of Shape \"sphere\" is not supported: "
                      "dropped (and 1 more time)"));
    EXPECT_TRUE(noted(d, "scene.pbrt:7: Accelerator"));
    EXPECT_EQ(d.objects.size(), 2u) << "the render goes on without what was dropped";
}

TEST(PbrtReader, SyntaxErrorsAreAtFileLineColumn) {
    const Files f;
    const auto has = [&](const std::string& text, const std::string& expected) {
        const std::string e = error_of(f, text);
        EXPECT_NE(e.find(expected), std::string::npos) << "got: " << e;
    };
    has("WorldBegin\n  Shape \"sphere\" \"float radius [1]\n",
        "scene.pbrt:2:18: error: a string must end");
    has("Shape \"sphere\" \"float radius\" [1\n",
        "scene.pbrt:1:31: error: '[' of 'float radius' is never closed");
    has("WorldBegin\nFrobnicate 1 2\n", "scene.pbrt:2:1: error: unknown directive 'Frobnicate'");
    has("SurfaceIntegrator \"path\"\n", "'SurfaceIntegrator' (a pbrt-v2 directive");
    has("Translate 1 two 3\n", "scene.pbrt:1:13: error: Translate expects 3 numbers, got 'two'");
    has("Shape \"sphere\" \"float radius\" [one]\n",
        "scene.pbrt:1:32: error: 'float radius' takes numbers");
    has("Shape \"sphere\" \"quaternion q\" [1]\n",
        "scene.pbrt:1:16: error: unknown parameter type 'quaternion'");
    has("Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0] \"integer indices\" [0 1 2]\n",
        "scene.pbrt:1:47: error: trianglemesh: index 2");
    has("LookAt 0 0 0 0 0 0 0 1 0\n", "scene.pbrt:1:1: error: LookAt: the eye must differ");
    has("Include \"missing.pbrt\"\n", "scene.pbrt:1:1: error:");
}

TEST(PbrtReader, IncludedAndGzippedFilesAreRead) {
    const Files f;
    std::ofstream(f.file("part.pbrt")) << "Shape \"sphere\"\nInclude \"deeper.pbrt\"\n";
    const std::string deeper = "Shape \"disk\"\n";
    gzFile gz = gzopen(f.file("deeper.pbrt").c_str(), "wb");
    gzwrite(gz, deeper.data(), static_cast<unsigned>(deeper.size()));
    gzclose(gz);
    const SceneDescription d = read(f, "WorldBegin\nInclude \"part.pbrt\"\nImport \"part.pbrt\"\n");
    EXPECT_EQ(d.objects.size(), 4u);
    EXPECT_EQ(d.files.size(), 4u) << "included files are watched";
    // A file that includes itself stops at a depth, with a message.
    std::ofstream(f.file("loop.pbrt")) << "Include \"loop.pbrt\"\n";
    EXPECT_NE(error_of(f, "Include \"loop.pbrt\"\n").find("nested more than 32 deep"),
              std::string::npos);
    // load_scene takes .pbrt.gz by its double extension.
    gz = gzopen(f.file("whole.pbrt.gz").c_str(), "wb");
    const std::string whole = "WorldBegin\nShape \"sphere\"\n";
    gzwrite(gz, whole.data(), static_cast<unsigned>(whole.size()));
    gzclose(gz);
    EXPECT_STREQ(scene_format_for(f.file("whole.pbrt.gz")).name, "pbrt");
    EXPECT_EQ(read_scene(f.file("whole.pbrt.gz")).objects.size(), 1u);
}

TEST(PbrtReader, AnImportedFileKeepsItsGraphicsStateToItself) {
    // pbrt-v4 reads an Import from a copy of the graphics state: the file's shapes, lights and
    // named materials join the scene, its transforms and current material do not carry back
    // (Spangle read it as an Include: the importer's next shape moved by the file's Translate).
    const Files f;
    std::ofstream(f.file("part.pbrt"))
        << "Translate 0 2 0\nMakeNamedMaterial \"red\" \"string type\" \"diffuse\"\n"
           "NamedMaterial \"red\"\nShape \"sphere\" \"float radius\" 0.3\n"
           "CoordinateSystem \"inside\"\nAttributeEnd\n";
    const SceneDescription d = read(f,
                                    "WorldBegin\nAttributeBegin\nImport \"part.pbrt\"\n"
                                    "Shape \"sphere\" \"float radius\" 0.5\nAttributeEnd\n"
                                    "NamedMaterial \"red\"\nShape \"disk\"\n");
    ASSERT_EQ(d.objects.size(), 3u);
    EXPECT_EQ(d.objects[0].placement.matrix->t.y, 2.0f);
    EXPECT_EQ(*d.objects[1].placement.matrix, Affine::scale(Vec3(0.5f)))
        << "the Translate stayed in the import (the sphere is the unit one scaled by its radius)";
    EXPECT_EQ(d.objects[0].material, "red");
    EXPECT_NE(d.objects[1].material, "red") << "the current material stayed in the import";
    EXPECT_EQ(d.objects[2].material, "red") << "the named material joined the scene";
    // Its AttributeEnd could not end the importer's block: said, and ignored.
    EXPECT_TRUE(noted(d, "part.pbrt:6: AttributeEnd without its begin"));
    // Its named coordinate system stayed in it too.
    EXPECT_TRUE(noted(read(f, "WorldBegin\nImport \"part.pbrt\"\nCoordSysTransform \"inside\"\n"),
                      "no coordinate system 'inside'"));
    // A block left open is said where it begins (the note had no line).
    const SceneDescription open =
        read(f, "WorldBegin\nShape \"sphere\"\nAttributeBegin\nShape \"disk\"\n");
    EXPECT_TRUE(noted(open,
                      "scene.pbrt:3: 1 AttributeBegin / TransformBegin / ObjectBegin never "
                      "ended"));
    // As in pbrt-v4, Import is for the world block.
    EXPECT_NE(error_of(f, "Import \"part.pbrt\"\nWorldBegin\n")
                  .find("scene.pbrt:1:1: error: Import is only allowed in the world block"),
              std::string::npos);
}

TEST(PbrtReader, ATomlSceneImportsAPbrtSceneAndOverridesItsMaterials) {
    // [[import]] takes any format the loader reads: a pbrt car with its paint replaced by name.
    const Files f;
    std::ofstream(f.file("car.pbrt")) << R"(Film "rgb" "integer xresolution" 40
  "integer yresolution" 30
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
WorldBegin
MakeNamedMaterial "paint" "string type" "diffuse" "rgb reflectance" [0.8 0.1 0.1]
NamedMaterial "paint"
Shape "sphere"
)";
    std::ofstream(f.file("look.toml")) << R"([[import]]
file = "car.pbrt"

[[material]]
name = "paint"
plugin = "smooth"
model = "diffuse"
params = { albedo = [0.1, 0.1, 0.8] }
)";
    const SceneDescription d = read_scene(f.file("look.toml"));
    ASSERT_EQ(d.objects.size(), 1u);
    EXPECT_EQ(d.objects[0].material, "paint");
    ASSERT_EQ(d.materials.size(), 1u) << "the override replaces the pbrt material";
    EXPECT_EQ(param(d.materials[0], "albedo")->color.rgb, Vec3(0.1f, 0.1f, 0.8f));
    EXPECT_EQ(d.render.width, 40) << "the pbrt film fills in what the TOML does not write";
    EXPECT_EQ(d.render.height, 30);
    EXPECT_TRUE(d.has_camera);
}

TEST(PbrtReader, SpectraAndBlackbodiesBecomeRec709) {
    const Files f;
    const SceneDescription d = read(f, R"(WorldBegin
MakeNamedMaterial "flat" "string type" "matte" "spectrum Kd" [400 0.5 700 0.5]
MakeNamedMaterial "file" "string type" "matte" "spectrum Kd" "flat.spd"
AreaLightSource "area" "blackbody L" [6504 1]
Shape "sphere"
)");
    // A flat reflectance is grey: a reflectance is seen under the working white (D65), as
    // pbrt-v4 takes it (taken as light under equal energy, it came out pink: 0.60, 0.47, 0.45).
    const Vec3 flat = param(material(d, "flat"), "albedo")->color.rgb;
    EXPECT_NEAR(flat.x, 0.5f, 1e-4f);
    EXPECT_NEAR(flat.y, 0.5f, 1e-4f);
    EXPECT_NEAR(flat.z, 0.5f, 1e-4f);
    EXPECT_EQ(param(material(d, "file"), "albedo")->color.rgb, flat);
    // A 6504 K blackbody is close to D65: near-equal channels.
    const Vec3 bb = d.lights.at(0).color->rgb;  // the sphere is a sphere light
    EXPECT_NEAR(bb.x / bb.y, 1.0f, 0.1f);
    EXPECT_NEAR(bb.z / bb.y, 1.0f, 0.1f);
    // Light is absolute: a flat emission spectrum is illuminant E's colour, XYZ (1, 1, 1), which
    // is Rec.709 (1.2048, 0.9483, 0.9088) (3% covers the colour-matching functions' fit).
    const SceneDescription e = read(f, R"(WorldBegin
AreaLightSource "diffuse" "spectrum L" [400 2 700 2]
Shape "sphere"
)");
    const Vec3 le = e.lights.at(0).color->rgb;
    EXPECT_NEAR(le.x / le.y, 1.2048f / 0.9483f, 0.03f);
    EXPECT_NEAR(le.z / le.y, 0.9088f / 0.9483f, 0.03f);
    // The fluorescent illuminants stand in by their colour temperatures, as the warning says
    // (they were D65's white): F12 (3000 K) warm, F7 (6500 K) near white.
    const SceneDescription fl = read(f, R"(WorldBegin
LightSource "point" "point3 from" [0 1 0] "spectrum I" "stdillum-F12"
LightSource "point" "point3 from" [0 1 0] "spectrum I" "stdillum-F7"
)");
    ASSERT_EQ(fl.lights.size(), 2u);
    const Vec3 f12 = fl.lights[0].color->rgb, f7 = fl.lights[1].color->rgb;
    EXPECT_GT(f12.x / f12.z, 3.0f);
    EXPECT_NEAR(f7.x / f7.z, 1.0f, 0.1f);
}

TEST(PbrtReader, ItsScenesBuildIntoTheRegistry) {
    // Every element above through the builder: colour spaces, materials by name, emission,
    // cages, screen windows and crop windows are accepted as the builder takes them.
    const Files f;
    const std::string text = std::string(R"(Film "image" "integer xresolution" 32
  "integer yresolution" 24 "float cropwindow" [0 0.5 0 1]
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float screenwindow" [-1 1 -0.5 0.5]
WorldBegin
LightSource "infinite" "rgb L" [0.2 0.2 0.2]
Material "plastic"
Shape "loopsubdiv" "integer indices" [0 1 2 0 2 3 0 3 1 1 3 2]
  "point3 P" [0 0 1  1 0 -1  -1 1 -1  -1 -1 -1]
AreaLightSource "diffuse" "bool twosided" true
)") + kQuad + "\n";
    ColorConfig color = test::shipped_config();
    ecs::Registry registry;
    const SceneInfo info = build_scene(read(f, text), color, registry);
    EXPECT_EQ(info.working_space, "lin_rec709");
    EXPECT_EQ((*info.crop)[1], 0.5);
    EXPECT_TRUE(info.camera.mirror);
    EXPECT_EQ(info.camera.screen[2], -0.5f);
    ASSERT_EQ(registry.count<Emission>(), 1u);
    EXPECT_TRUE(registry.pool<Emission>().columns().two_sided[0]);
    ASSERT_EQ(registry.count<SubdivSurface>(), 1u);
    const SubdivSurface s = registry.pool<SubdivSurface>().columns().get(0);
    EXPECT_TRUE(s.cage);
    EXPECT_NE(s.cage_content, 0u);
}

}  // namespace
}  // namespace spangle::test_pbrt_reader
