#!/usr/bin/env python3
"""Writes the pbrt scenes of the end-to-end tests and their TOML twins (run from this folder).

twin_v3.pbrt is a pbrt-v3 scene seen through pbrt's left-handed camera (plain LookAt): its image
is the mirror image of a right-handed camera's. Its twin, twin_v3.toml, is the same world mirrored
in x (meshes mirrored, their faces re-wound to keep their sides) seen by Spangle's right-handed
camera from the mirrored eye: the same picture. twin_v4.pbrt is a pbrt-v4 scene whose camera
undoes the mirror (Scale -1 1 1 before LookAt, as exporters write it); its twin has the same
world. Roughness values in the twins are pbrt's remaps written out (v3: the quartic in log r;
v4: sqrt r)."""
import math
import struct

FLOOR = ([(-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2)], [(0, 2, 1), (0, 3, 2)])
WALL = ([(-2, 0, -1.5), (2, 0, -1.5), (2, 2.5, -1.5), (-2, 2.5, -1.5)], [(0, 1, 2), (0, 2, 3)])
LIGHT = ([(-0.2, 2.2, -0.5), (0.8, 2.2, -0.5), (0.8, 2.2, 0.5), (-0.2, 2.2, 0.5)],
         [(0, 1, 2), (0, 2, 3)])  # wound to face down (-y)
PYRAMID = ([(-1.2, 0, 0), (-0.4, 0, 0), (-0.4, 0, 0.8), (-1.2, 0, 0.8), (-0.8, 0.9, 0.4)],
           [(0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4), (0, 3, 2), (0, 2, 1)])


def box(cx, cy, cz, h):
    v = [(cx + sx * h, cy + sy * h, cz + sz * h) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
         (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return v, f


BOX = box(0.6, 0.3, 0.0, 0.3)


def mirrored(mesh):
    v, f = mesh
    return [(-x, y, z) for x, y, z in v], [(a, c, b) for a, b, c in f]


def obj(path, mesh):
    v, f = mesh
    with open(path, "w") as out:
        out.write("# written by make_twins.py\n")
        for p in v:
            out.write("v %g %g %g\n" % p)
        for a, b, c in f:
            out.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))


def ply(path, mesh):
    v, f = mesh
    with open(path, "wb") as out:
        out.write(b"ply\nformat binary_little_endian 1.0\ncomment written by make_twins.py\n")
        out.write(b"element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % len(v))
        out.write(b"element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(f))
        for p in v:
            out.write(struct.pack("<3f", *p))
        for t in f:
            out.write(struct.pack("<B3i", 3, *t))


def trianglemesh(mesh):
    v, f = mesh
    idx = " ".join("%d %d %d" % t for t in f)
    pts = "  ".join("%g %g %g" % p for p in v)
    return 'Shape "trianglemesh" "integer indices" [%s]\n  "point3 P" [%s]\n' % (idx, pts)


def v3_alpha(r):
    x = math.log(max(r, 1e-3))
    return 1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x ** 3 + 0.000640711 * x ** 4


V3 = """# pbrt-v3 twin of twin_v3.toml (make_twins.py): pbrt's left-handed camera.
LookAt 0.5 1.2 4  0 0.6 0  0 1 0
Camera "perspective" "float fov" 40
Film "image" "integer xresolution" 96 "integer yresolution" 72 "string filename" "twin_v3.exr"
Sampler "halton" "integer pixelsamples" 64 "integer seed" 0
Integrator "path" "integer maxdepth" 4
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [2.5 2.5 2.5] "float scale" 2
  Material "matte" "rgb Kd" [0 0 0]
{light}AttributeEnd
Material "matte" "rgb Kd" [0.6 0.6 0.6]
{floor}MakeNamedMaterial "blue" "string type" "matte" "rgb Kd" [0.2 0.4 0.7]
NamedMaterial "blue"
{wall}Material "plastic" "rgb Kd" [0.7 0.2 0.1] "float roughness" 0.1
Shape "plymesh" "string filename" "twin_box.ply"
Material "metal" "rgb eta" [0.2 0.92 1.1] "rgb k" [3.9 2.45 2.14] "float roughness" 0.01
{pyramid}WorldEnd
"""

V3_TOML = """# TOML twin of twin_v3.pbrt (make_twins.py): the same world mirrored in x, a right-handed camera.
[render]
width = 96
height = 72
spp = 64
max_depth = 4
filter = "box"
working_space = "lin_rec709"
color_space = "lin_rec709"

[camera]
position = [-0.5, 1.2, 4]
look_at = [0, 0.6, 0]
fov = 40

[[material]]
name = "black"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0, 0, 0] }}

[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0.6, 0.6, 0.6] }}

[[material]]
name = "blue"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0.2, 0.4, 0.7] }}

[[material]]
name = "plastic"
plugin = "smooth"
model = "plastic"
params = {{ albedo = [0.7, 0.2, 0.1], ior = 1.5, roughness = {plastic_alpha:.9f} }}

[[material]]
name = "metal"
plugin = "smooth"
model = "conductor"
params = {{ preset = "custom", eta = [0.2, 0.92, 1.1], k = [3.9, 2.45, 2.14], roughness = {metal_alpha:.9f}, multiscatter = false }}

[[object]]
mesh = "twin_v3_light.obj"
material = "black"
emission = [5, 5, 5]

[[object]]
mesh = "twin_v3_floor.obj"
material = "floor"

[[object]]
mesh = "twin_v3_wall.obj"
material = "blue"

[[object]]
mesh = "twin_v3_box.obj"
material = "plastic"

[[object]]
mesh = "twin_v3_pyramid.obj"
material = "metal"
"""

V4 = """# pbrt-v4 twin of twin_v4.toml (make_twins.py): Scale -1 1 1 undoes pbrt's mirror.
Scale -1 1 1
LookAt 0.5 1.2 4  0 0.6 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 72 "integer yresolution" 96
Sampler "zsobol" "integer pixelsamples" 64
Integrator "volpath" "integer maxdepth" 4
ColorSpace "srgb"
WorldBegin
LightSource "infinite" "rgb L" [0.1 0.12 0.15]
LightSource "distant" "point3 from" [1 3 2] "point3 to" [0 0 0] "rgb L" [1.5 1.4 1.2]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [3 3 3]
  Material "diffuse" "rgb reflectance" [0 0 0]
{light}AttributeEnd
Texture "ramp" "spectrum" "imagemap" "string filename" "../textures/roughness_ramp.png"
  "float uscale" 2 "float vscale" 1
Material "diffuse" "texture reflectance" "ramp"
{floor}Material "diffuse" "rgb reflectance" [0.2 0.4 0.7]
{wall}Material "coateddiffuse" "rgb reflectance" [0.7 0.2 0.1] "float roughness" 0.04
Shape "plymesh" "string filename" "twin_box.ply"
Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.01
{pyramid}"""

V4_TOML = """# TOML twin of twin_v4.pbrt (make_twins.py): the same world, a right-handed camera.
[render]
width = 72
height = 96
spp = 64
max_depth = 4
working_space = "lin_rec709"
color_space = "lin_rec709"

[camera]
position = [0.5, 1.2, 4]
look_at = [0, 0.6, 0]
fov = {fov_v:.9f}

[environment]
color = [0.1, 0.12, 0.15]

[[material]]
name = "black"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0, 0, 0] }}

[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = {{ texture = "../textures/roughness_ramp.png", space = "srgb_texture", uv_transform = {{ scale = [2, 1] }} }} }}

[[material]]
name = "blue"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0.2, 0.4, 0.7] }}

[[material]]
name = "plastic"
plugin = "smooth"
model = "plastic"
params = {{ albedo = [0.7, 0.2, 0.1], ior = 1.5, roughness = 0.2 }}

[[material]]
name = "gold"
plugin = "smooth"
model = "conductor"
params = {{ preset = "gold", roughness = 0.1, multiscatter = false }}

[[object]]
mesh = "twin_v4_light.obj"
material = "black"
emission = [3, 3, 3]

[[object]]
mesh = "twin_v4_floor.obj"
material = "floor"

[[object]]
mesh = "twin_v4_wall.obj"
material = "blue"

[[object]]
mesh = "twin_v4_box.obj"
material = "plastic"

[[object]]
mesh = "twin_v4_pyramid.obj"
material = "gold"

[[light]]
type = "distant"
direction = [1, 3, 2]
color = [1.5, 1.4, 1.2]
"""


def uv_floor():
    v, f = FLOOR
    return v, f


def main():
    ply("twin_box.ply", BOX)
    meshes = {"light": LIGHT, "floor": FLOOR, "wall": WALL, "box": BOX, "pyramid": PYRAMID}
    for name, m in meshes.items():
        obj("twin_v3_%s.obj" % name, mirrored(m))
    for name in ("light", "wall", "box", "pyramid"):
        obj("twin_v4_%s.obj" % name, meshes[name])
    # The v4 floor carries uvs for its texture: pbrt's trianglemesh "point2 uv" and the OBJ's vt.
    fv, ff = FLOOR
    uv = [(0, 0), (1, 0), (1, 1), (0, 1)]
    with open("twin_v4_floor.obj", "w") as out:
        out.write("# written by make_twins.py\n")
        for p in fv:
            out.write("v %g %g %g\n" % p)
        for t in uv:
            out.write("vt %g %g\n" % t)
        for a, b, c in ff:
            out.write("f %d/%d %d/%d %d/%d\n" % (a + 1, a + 1, b + 1, b + 1, c + 1, c + 1))
    floor_uv = trianglemesh(FLOOR).rstrip("\n") + '\n  "point2 uv" [0 0 1 0 1 1 0 1]\n'
    parts = {k: trianglemesh(m) for k, m in meshes.items()}
    with open("twin_v3.pbrt", "w") as out:
        out.write(V3.format(**parts))
    with open("twin_v3.toml", "w") as out:
        out.write(V3_TOML.format(plastic_alpha=v3_alpha(0.1), metal_alpha=v3_alpha(0.01)))
    parts["floor"] = floor_uv
    with open("twin_v4.pbrt", "w") as out:
        out.write(V4.format(**parts))
    # Portrait: pbrt's 40 degrees span the width, 72 / 96 of the height.
    fov_v = 2 * math.degrees(math.atan(math.tan(math.radians(20)) / (72 / 96)))
    with open("twin_v4.toml", "w") as out:
        out.write(V4_TOML.format(fov_v=fov_v))


if __name__ == "__main__":
    main()
