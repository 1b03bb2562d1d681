"""Builds a Blender scene from a Spangle scene file, for rendering it in Cycles.

    import spangle_to_blender
    scene = spangle_to_blender.build(path, width, height)

For tests/bench/cycles_time_to_quality.py: the beetle and the bench interior are Spangle's own
scenes, and the time-to-quality comparison renders each in Cycles as close as Cycles allows. This
reads the subset of the scene format those scenes use and says on stderr what it approximates:

- placement (`matrix`, or `translate` / `rotate` / `scale`), PLY and OBJ meshes, `subdiv` as a
  Subdivision Surface modifier (a fixed level; `"auto"` the level Spangle picks at that size,
  from subdivision_levels, else AUTO_LEVEL, at most max_level);
- the smooth plugin's models as a Principled BSDF (GGX alpha -> Blender's perceptual roughness
  sqrt(alpha)); the conductor presets as a metal of their colour at normal incidence;
- the flake plugin as Blender's usual glitter: a Voronoi texture in object space, one cell per
  flake (scale sqrt(density)), whose random colour tilts a metallic layer's normal by up to
  flake_roughness and tints it (a colour table: hues about base_color's by hue_spread), mixed
  over the base by flake_weight, under the clear coat when there is one; always in object
  space, whatever density_space says (uv-space flakes scale with the mesh's uvs). Cycles has
  no counted flakes: this is the look an artist gets there, not the same BRDF;
- lights: sphere -> point light of that radius (power 4 pi^2 r^2 L, Cycles' radiance for a
  sphere), quad -> area light (power pi A L, emitting along edge1 x edge2), point -> point light
  (4 pi I), distant -> sun (irradiance, angle twice the angular radius);
- the environment's colour or lat-long map (Spangle's map centre looks down -z, turned by
  `rotation` about +y), its intensity;
- colours (three numbers) in the file's colour space `srgb_texture` are decoded to linear (a
  single number is linear, as Spangle reads it); other spaces are
  taken as linear Rec.709 (Spangle's working space may be ACEScg: each renderer is measured
  against its own reference, so colour differences do not enter the comparison).

Spangle is y-up (its default camera up); Blender is z-up: every position and direction goes
through (x, y, z) -> (x, -z, y).
"""

import colorsys
import math
import os
import re
import subprocess
import sys
import tempfile
import tomllib

import bpy
import mathutils

AUTO_LEVEL = 3

# Colours at normal incidence of the conductor presets (linear Rec.709, from their indices).
PRESETS = {
    "gold": (1.0, 0.78, 0.34),
    "silver": (0.97, 0.96, 0.91),
    "copper": (0.95, 0.64, 0.54),
    "aluminium": (0.91, 0.92, 0.92),
    "perfect": (1.0, 1.0, 1.0),
    "custom": (0.9, 0.9, 0.9),
}

# Spangle's y-up world into Blender's z-up one.
TO_BLENDER = mathutils.Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))


def note(text):
    print(f"# spangle_to_blender: {text}", file=sys.stderr)


def vec(v):
    return mathutils.Vector(TO_BLENDER.to_3x3() @ mathutils.Vector(v))


class Colours:
    def __init__(self, space):
        self.space = space

    def __call__(self, value, default=(1.0, 1.0, 1.0)):
        if value is None:
            return default
        space = self.space
        if isinstance(value, dict):
            if "texture" in value or "vertex_color" in value:
                note("a textured colour is taken as its default")
                return default
            space = value.get("space", space)
            value = value["rgb"]
        if isinstance(value, (int, float)):
            return (float(value),) * 3  # a single number is linear, whatever the file's space
        if space == "srgb_texture":
            return tuple(c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in value)
        return tuple(float(c) for c in value)


def number(value, default):
    if value is None:
        return default
    if isinstance(value, dict):
        note("a textured number is taken as its default")
        return default
    return float(value)


def perceptual(alpha):
    return math.sqrt(max(alpha, 0.0))


def principled(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    return m, m.node_tree.nodes["Principled BSDF"]


def set_inputs(b, **values):
    names = {"base": "Base Color", "rough": "Roughness", "metal": "Metallic", "ior": "IOR",
             "spec": "Specular IOR Level", "coat": "Coat Weight", "coat_rough": "Coat Roughness",
             "coat_ior": "Coat IOR", "trans": "Transmission Weight"}
    for k, v in values.items():
        b.inputs[names[k]].default_value = (*v, 1.0) if k == "base" else v


def smooth_material(name, model, p, colour):
    m, b = principled(name)
    if model == "diffuse":
        set_inputs(b, base=colour(p.get("albedo"), (0.8, 0.8, 0.8)), rough=1.0, spec=0.0)
    elif model == "plastic":
        set_inputs(b, base=colour(p.get("albedo"), (0.8, 0.8, 0.8)),
                   rough=perceptual(number(p.get("roughness"), 0.1)), ior=number(p.get("ior"), 1.5))
    elif model == "conductor":
        if p.get("preset", "gold") == "custom":
            note(f"material '{name}': a custom conductor (eta, k) drawn as a 0.9 grey metal")
        set_inputs(b, base=PRESETS[p.get("preset", "gold")], metal=1.0,
                   rough=perceptual(number(p.get("roughness"), 0.2)))
        if number(p.get("coat"), 0.0) > 0.0:
            set_inputs(b, coat=number(p.get("coat"), 0.0), coat_ior=number(p.get("coat_ior"), 1.5),
                       coat_rough=perceptual(number(p.get("coat_roughness"), 0.0)))
    elif model == "dielectric":
        set_inputs(b, base=colour(p.get("transmission_color")), trans=1.0,
                   ior=number(p.get("ior"), 1.5), rough=perceptual(number(p.get("roughness"), 0.0)))
        if not p.get("multiscatter", False):  # Spangle's glass is single-scattering by default
            b.distribution = "GGX"
    elif model == "metal_rough":
        set_inputs(b, base=colour(p.get("base_color")), metal=number(p.get("metallic"), 1.0),
                   rough=number(p.get("roughness"), 1.0), ior=number(p.get("ior"), 1.5),
                   spec=0.5 * number(p.get("specular"), 1.0),
                   coat=number(p.get("clearcoat"), 0.0),
                   coat_rough=number(p.get("clearcoat_roughness"), 0.0))
        b.inputs["Specular Tint"].default_value = (*colour(p.get("specular_color")), 1.0)
    else:
        note(f"material '{name}': model '{model}' drawn as a grey diffuse")
        set_inputs(b, base=(0.5, 0.5, 0.5), rough=1.0, spec=0.0)
    return m


def flake_material(name, p, colour):
    """Blender's usual glitter: Voronoi cells as flakes tilting a metallic layer's normal."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nodes, links = nt.nodes, nt.links
    base = nodes["Principled BSDF"]
    out = nodes["Material Output"]
    base_colour = colour(p.get("base_color"), (0.05, 0.05, 0.05))
    set_inputs(base, base=base_colour, rough=1.0, spec=0.0)
    flake = nodes.new("ShaderNodeBsdfPrincipled")
    # The flake's own spread: its reflection cone of half-angle gamma as a GGX lobe.
    gamma = math.radians(number(p.get("gamma"), 3.0))
    set_inputs(flake, metal=1.0, rough=perceptual(math.tan(gamma)))
    coord = nodes.new("ShaderNodeTexCoord")
    vor = nodes.new("ShaderNodeTexVoronoi")
    vor.voronoi_dimensions = "3D"
    vor.inputs["Scale"].default_value = math.sqrt(number(p.get("density"), 200000.0))
    links.new(coord.outputs["Object"], vor.inputs["Vector"])
    # Tilt: (cell colour - 0.5) x 2 alpha along each axis, added to the normal.
    tilt = nodes.new("ShaderNodeVectorMath")
    tilt.operation = "MULTIPLY_ADD"
    links.new(vor.outputs["Color"], tilt.inputs[0])
    a = 2.0 * number(p.get("flake_roughness"), 0.15)
    tilt.inputs[1].default_value = (a, a, a)
    tilt.inputs[2].default_value = (-0.5 * a, -0.5 * a, -0.5 * a)
    geo = nodes.new("ShaderNodeNewGeometry")
    add = nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    links.new(geo.outputs["Normal"], add.inputs[0])
    links.new(tilt.outputs["Vector"], add.inputs[1])
    norm = nodes.new("ShaderNodeVectorMath")
    norm.operation = "NORMALIZE"
    links.new(add.outputs["Vector"], norm.inputs[0])
    links.new(norm.outputs["Vector"], flake.inputs["Normal"])
    if p.get("color_table", False):
        # Hues about the base colour's (hue_spread degrees) or all hues, at the table's lightness.
        hsv = nodes.new("ShaderNodeHueSaturation")
        sep = nodes.new("ShaderNodeSeparateColor")
        links.new(vor.outputs["Color"], sep.inputs["Color"])
        spread = number(p.get("hue_spread"), 0.0)
        shift = nodes.new("ShaderNodeMath")
        shift.operation = "MULTIPLY_ADD"
        links.new(sep.outputs["Red"], shift.inputs[0])
        if spread > 0.0:
            shift.inputs[1].default_value = spread / 360.0
            shift.inputs[2].default_value = 0.5 - 0.5 * spread / 360.0
            hue = mathutils.Color(base_colour).h
        else:
            shift.inputs[1].default_value = 1.0
            shift.inputs[2].default_value = 0.0
            hue = 0.0
        # The table's HSL colour (in sRGB, as its default table_space) decoded to linear.
        seed = colorsys.hls_to_rgb(hue, number(p.get("table_l"), 0.5), number(p.get("table_s"), 1.0))
        hsv.inputs["Color"].default_value = (*Colours("srgb_texture")(seed), 1.0)
        links.new(shift.outputs["Value"], hsv.inputs["Hue"])
        links.new(hsv.outputs["Color"], flake.inputs["Base Color"])
    else:
        tint = colour(p.get("flake_color"))
        metal = PRESETS.get(p.get("preset", "aluminium"), (0.9, 0.9, 0.9))
        flake.inputs["Base Color"].default_value = (*(t * c for t, c in zip(tint, metal)), 1.0)
    if p.get("coat", False):
        for b in (base, flake):
            set_inputs(b, coat=1.0, coat_ior=number(p.get("coat_ior"), 1.5),
                       coat_rough=perceptual(number(p.get("coat_roughness"), 0.0)))
            links.new(geo.outputs["Normal"], b.inputs["Coat Normal"])
    mix = nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = number(p.get("flake_weight"), 0.6)
    links.new(base.outputs["BSDF"], mix.inputs[1])
    links.new(flake.outputs["BSDF"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return m


def placement(o):
    if "matrix" in o:
        v = o["matrix"]
        rows = [v[0:4], v[4:8], v[8:12], (0, 0, 0, 1)]
        return mathutils.Matrix(rows)
    t = mathutils.Matrix.Translation(o.get("translate", (0, 0, 0)))
    r = mathutils.Euler([math.radians(a) for a in o.get("rotate", (0, 0, 0))], "XYZ").to_matrix().to_4x4()
    s = o.get("scale", 1.0)
    s = (s, s, s) if isinstance(s, (int, float)) else s
    return t @ r @ mathutils.Matrix.Diagonal((*s, 1.0))


def import_mesh(path):
    before = set(bpy.data.objects)
    if path.lower().endswith(".obj"):
        bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z",
                              use_split_objects=False, use_split_groups=False)
    elif path.lower().endswith(".ply"):
        bpy.ops.wm.ply_import(filepath=path, forward_axis="Y", up_axis="Z")
    else:
        raise ValueError(f"{path}: only OBJ and PLY meshes are read")
    made = [o for o in bpy.data.objects if o not in before]
    if len(made) != 1:
        raise ValueError(f"{path}: made {len(made)} objects")
    me = made[0].data
    if me.has_custom_normals and len(me.loops) > 0:
        # Spangle turns a triangle to follow its file's normals; Cycles shades a face whose
        # normals point against its winding as lit from behind (black). Such a mesh (the bench
        # interior writes some) has its winding reversed, its normals kept.
        against = sum(l.normal.dot(me.polygons[i].normal) < 0.0
                      for i, p in enumerate(me.polygons) for l in me.loops[p.loop_start:p.loop_start + p.loop_total])
        if 2 * against > len(me.loops):
            normals = [(0.0, 0.0, 0.0)] * len(me.vertices)
            for l in me.loops:
                normals[l.vertex_index] = l.normal[:]
            me.flip_normals()
            me.normals_split_custom_set_from_vertices(normals)
    return made[0]


def light(scene, l, colour):
    kind = l["type"]
    c = colour(l.get("color"))
    k = float(l.get("intensity", 1.0))
    if kind == "sphere":
        r = float(l["radius"])
        data = bpy.data.lights.new("sphere", "POINT")
        data.shadow_soft_size = r
        data.use_soft_falloff = False  # on by default: it dims a sphere light by about 1.3%
        data.energy = 4.0 * math.pi ** 2 * r * r * k
        obj = bpy.data.objects.new("sphere", data)
        obj.location = vec(l["center"])
    elif kind == "point":
        data = bpy.data.lights.new("point", "POINT")
        data.shadow_soft_size = 0.0
        data.energy = 4.0 * math.pi * k
        obj = bpy.data.objects.new("point", data)
        obj.location = vec(l["position"])
    elif kind == "quad":
        e1, e2 = vec(l["edge1"]), vec(l["edge2"])
        data = bpy.data.lights.new("quad", "AREA")
        data.shape = "RECTANGLE"
        data.size, data.size_y = e1.length, e2.length
        data.energy = math.pi * e1.cross(e2).length * k
        obj = bpy.data.objects.new("quad", data)
        z = -e1.cross(e2).normalized()  # Blender's area light emits along its -Z
        x = e1.normalized()
        y = z.cross(x)
        m = mathutils.Matrix((x, y, z)).transposed().to_4x4()
        m.translation = vec(l["corner"]) + 0.5 * (e1 + e2)
        obj.matrix_world = m
        if l.get("two_sided", False):
            note("a two-sided quad light emits from one side in Blender")
    elif kind == "distant":
        data = bpy.data.lights.new("sun", "SUN")
        data.energy = k
        data.angle = 2.0 * math.radians(float(l.get("angular_radius", 0.0)))
        obj = bpy.data.objects.new("sun", data)
        d = vec(l["direction"]).normalized()
        obj.rotation_euler = d.to_track_quat("Z", "Y").to_euler()  # its -Z: where light goes
    else:
        note(f"a {kind} light is left out")
        return
    data.color = c
    scene.collection.objects.link(obj)


def environment(scene, env, colour, folder):
    world = bpy.data.worlds.new("environment")
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Strength"].default_value = float(env.get("intensity", 1.0))
    if "map" in env:
        nodes, links = world.node_tree.nodes, world.node_tree.links
        tex = nodes.new("ShaderNodeTexEnvironment")
        tex.image = bpy.data.images.load(os.path.join(folder, env["map"]))
        mapping = nodes.new("ShaderNodeMapping")
        coord = nodes.new("ShaderNodeTexCoord")
        # Spangle's u = 1/2 + atan2(x', -z') / 2 pi of the direction turned back by `rotation`
        # about +y; Cycles' u = 1/2 - atan2(Y', X') / 2 pi of the direction the Mapping node
        # turns by its Z rotation. In Blender's axes (x = X, z = -Y) the two agree for a turn of
        # rotation - 90 degrees, and both grow to the viewer's right (no mirror). Checked on the
        # beetle's studio: its floor and backdrop as bright as Spangle draws them, which no other
        # turn in 30-degree steps, mirrored or not, gives.
        turn = math.radians(float(env.get("rotation", 0.0)) - 90.0)
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, turn)
        links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        links.new(tex.outputs["Color"], bg.inputs["Color"])
    else:
        bg.inputs["Color"].default_value = (*colour(env.get("color"), (0.0, 0.0, 0.0)), 1.0)


def subdivision_levels(spangle, path, width, height):
    """The level Spangle's "auto" subdivision picks for each cage at this size (from a 1-spp
    render's --stats), by the cage's real path."""
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([spangle, "render", os.path.abspath(path), "--size", f"{width}x{height}",
                              "--spp", "1", "--stats", "--no-preview", "-o", os.path.join(tmp, "levels.exr")],
                             capture_output=True, text=True, cwd=os.path.dirname(os.path.abspath(path)))
    levels = {}
    for line in (out.stdout + out.stderr).splitlines():
        m = re.match(r"subdivision: (.+) level (\d+)", line)
        if m:
            cage = os.path.join(os.path.dirname(os.path.abspath(path)), m.group(1))
            levels[os.path.realpath(cage)] = int(m.group(2))
    return levels


def build(path, width, height, levels=None):
    """A fresh Blender scene of the Spangle scene at `path`, at width x height; `levels`: the
    subdivision level of each "auto" cage by real path (subdivision_levels), else AUTO_LEVEL."""
    path = os.path.abspath(path)
    folder = os.path.dirname(path)
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    r = doc.get("render", {})
    colour = Colours(r.get("color_space", "lin_rec709"))
    materials = {}
    for m in doc.get("material", []):
        if m["plugin"] == "flake":
            materials[m["name"]] = flake_material(m["name"], m.get("params", {}), colour)
        else:
            materials[m["name"]] = smooth_material(m["name"], m.get("model", ""), m.get("params", {}), colour)
    for o in doc.get("object", []):
        obj = import_mesh(os.path.join(folder, o["mesh"]))
        obj.matrix_world = TO_BLENDER @ placement(o)
        obj.data.materials.clear()
        obj.data.materials.append(materials[o["material"]])
        sub = o.get("subdiv")
        if sub is not None:
            level = sub.get("level", "auto")
            if level == "auto":
                level = (levels or {}).get(os.path.realpath(os.path.join(folder, o["mesh"])),
                                           min(AUTO_LEVEL, int(sub.get("max_level", 5))))
            mod = obj.modifiers.new("subdivision", "SUBSURF")
            mod.levels = mod.render_levels = int(level)
            # Blender keeps boundaries (edge_only) or also their corners (edge_and_corner); it has
            # no "none" (boundaries that shrink).
            boundary = sub.get("boundary", "edge_and_corner")
            mod.boundary_smooth = "ALL" if boundary != "edge_and_corner" else "PRESERVE_CORNERS"
            if boundary == "none":
                note(f"object {o.get('name', o['mesh'])}: boundary 'none' drawn as edge_only")
            for poly in obj.data.polygons:
                poly.use_smooth = True
        if "emission" in o:
            raise ValueError(f"object {o.get('name', o['mesh'])}: emissive objects are not "
                             "imported (the comparison would light the two scenes differently)")
    for l in doc.get("light", []):
        light(scene, l, colour)
    environment(scene, doc.get("environment", {}), colour, folder)
    cam = doc["camera"]
    pos = mathutils.Vector(cam["position"])
    f = (mathutils.Vector(cam["look_at"]) - pos).normalized()
    right = f.cross(mathutils.Vector(cam.get("up", (0, 1, 0)))).normalized()
    up = right.cross(f)
    m = mathutils.Matrix((right, up, -f)).transposed().to_4x4()
    m.translation = pos
    data = bpy.data.cameras.new("camera")
    data.sensor_fit = "VERTICAL"
    data.angle_y = math.radians(float(cam.get("fov", 40.0)))
    obj = bpy.data.objects.new("camera", data)
    obj.matrix_world = TO_BLENDER @ m
    scene.collection.objects.link(obj)
    scene.camera = obj
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    c = scene.cycles
    c.max_bounces = int(r.get("max_depth", 5))
    # Spangle's depth bounds every path alike; Cycles' per-kind limits must not bite first.
    c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = c.max_bounces
    c.sample_clamp_indirect = float(r.get("clamp_indirect", 0.0))
    c.blur_glossy = float(r.get("filter_glossy", 0.0))
    # Spangle's filters as Cycles has them: its Blackman-Harris of radius w is Cycles' of width
    # w (default 2), its Gaussian of radius r (sigma r / 3, default 1.5) Cycles' of width r / 0.75.
    kind = r.get("filter", "gaussian")
    radius = float(r.get("filter_radius", 0.0))
    if kind == "blackman-harris":
        c.pixel_filter_type, c.filter_width = "BLACKMAN_HARRIS", radius or 2.0
    elif kind == "gaussian":
        c.pixel_filter_type, c.filter_width = "GAUSSIAN", (radius or 1.5) / 0.75
    else:
        c.pixel_filter_type = "BOX"
    return scene
