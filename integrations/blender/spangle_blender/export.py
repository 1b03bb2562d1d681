"""Blender scene -> Spangle scene: a TOML file and binary PLY meshes in a folder.

What is exported, from the evaluated depsgraph (modifiers applied, instances expanded):
meshes (and anything that converts to one) per material slot, with corner normals and the
active uv map; their world matrices; the camera (perspective, with depth of field); point, spot,
sun and area lights; the world's background colour (an environment texture's mean colour stands
in for it); Principled BSDF materials onto the smooth plugin's metal_rough (or dielectric for
transmission), emission onto the object, and materials whose "Spangle Flakes" panel is on onto
the flake plugin. What cannot be carried over is a warning each (returned), never an error.
"""

import hashlib
import math
import os
import tempfile

import numpy as np

try:  # Blender's own modules; absent when the exporter's helpers are tested alone
    import bpy
    import mathutils  # noqa: F401
except ImportError:  # pragma: no cover
    bpy = None


def _fmt(x):
    return repr(float(x))


def spot_falloff(half_deg, blend):
    """The cone_falloff (degrees) that gives a Blender spot's edge as Cycles draws it: Cycles
    fades with a smoothstep in the cosine from cos(half) up to cos(half) + (1 - cos(half)) blend
    (checked against a Cycles render of a plane under a spot: no other factor), and Spangle's
    spot fades with a smoothstep in the cosine from cos(cone_angle) to cos(cone_angle -
    cone_falloff), so the falloff ends where that cosine is reached. (Half the cone times the
    blend, as Blender's glTF exporter writes it, is linear in the angle: 0.5-0.8x Cycles' light
    off the axis.)"""
    c = math.cos(math.radians(half_deg))
    inner = c + (1.0 - c) * min(max(blend, 0.0), 1.0)
    return min(max(half_deg - math.degrees(math.acos(min(inner, 1.0))), 0.0), half_deg)


def _vec(v):
    return "[" + ", ".join(_fmt(c) for c in v) + "]"


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return _fmt(v)
    if isinstance(v, str):
        # A TOML basic string: quotes and backslashes escaped, and control characters too (a
        # newline in a material's name made the whole scene invalid TOML).
        out = []
        for ch in v:
            o = ord(ch)
            if ch in '"\\':
                out.append("\\" + ch)
            elif o < 0x20 or o == 0x7F:
                out.append("\\u%04x" % o)
            else:
                out.append(ch)
        return '"' + "".join(out) + '"'
    return _vec(v)


def _toml_string(s):
    return _toml_value(str(s))


def write_ply(path, positions, normals, uvs, triangles, colors=None):
    """Binary little-endian PLY: positions, normals, uvs (n x 3, n x 3, n x 2 float32),
    optionally linear vertex colours (n x 3 float32: Spangle reads float colours as linear) and
    triangles (m x 3 int32)."""
    n, m = len(positions), len(triangles)
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment Spangle's Blender add-on\n"
        f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "property float s\nproperty float t\n"
        + ("property float red\nproperty float green\nproperty float blue\n"
           if colors is not None else "")
        + f"element face {m}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    vert = np.empty((n, 8 if colors is None else 11), dtype="<f4")
    vert[:, 0:3] = positions
    vert[:, 3:6] = normals
    vert[:, 6:8] = uvs
    if colors is not None:
        vert[:, 8:11] = colors
    face = np.empty(m, dtype=[("n", "u1"), ("v", "<i4", 3)])
    face["n"] = 3
    face["v"] = triangles
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vert.tobytes())
        f.write(face.tobytes())


def _corner_colors(mesh, loop_vert):
    """The mesh's render colour attribute (its active one without) per corner, linear rgb
    (Blender gives byte colours' linear values too), or None when it has none."""
    attrs = getattr(mesh, "color_attributes", None)
    if attrs is None or len(attrs) == 0:
        return None
    index = getattr(attrs, "render_color_index", -1)
    attr = attrs[index] if 0 <= index < len(attrs) else attrs.active_color
    if attr is None or attr.domain not in ("POINT", "CORNER"):
        return None
    flat = np.empty(len(attr.data) * 4, dtype=np.float32)
    attr.data.foreach_get("color", flat)
    rgb = flat.reshape(-1, 4)[:, :3]
    return rgb[loop_vert] if attr.domain == "POINT" else rgb


def mesh_arrays(mesh):
    """Triangles of an evaluated mesh, one vertex per corner (corner normals and uvs kept):
    positions, normals, uvs and colours (None without) of the corners (triangle t's are rows
    3t .. 3t + 2), and each triangle's material index."""
    mesh.calc_loop_triangles()
    ntri = len(mesh.loop_triangles)
    loops = np.empty(ntri * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    mat_index = np.empty(ntri, dtype=np.int32)
    mesh.loop_triangles.foreach_get("material_index", mat_index)
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    loop_vert = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", loop_vert)
    normals = np.empty(len(mesh.loops) * 3, dtype=np.float32)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1 and later
        mesh.corner_normals.foreach_get("vector", normals)
    else:  # pragma: no cover (4.0)
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", normals)
    normals = normals.reshape(-1, 3)
    uv = np.zeros((len(mesh.loops), 2), dtype=np.float32)
    if mesh.uv_layers.active is not None:
        flat = np.empty(len(mesh.loops) * 2, dtype=np.float32)
        mesh.uv_layers.active.data.foreach_get("uv", flat)
        uv = flat.reshape(-1, 2)
    positions = co[loop_vert[loops]]
    colors = _corner_colors(mesh, loop_vert)
    return (positions, normals[loops], uv[loops], None if colors is None else colors[loops],
            mat_index)


def _principled(mat):
    if not mat.use_nodes or mat.node_tree is None:
        return None
    for node in mat.node_tree.nodes:
        if node.type == "OUTPUT_MATERIAL" and node.is_active_output:
            surf = node.inputs.get("Surface")
            if surf is not None and surf.is_linked:
                src = surf.links[0].from_node
                if src.type == "BSDF_PRINCIPLED":
                    return src
    return None


def _input(node, *names, default=None):
    for name in names:
        sock = node.inputs.get(name)
        if sock is not None:
            return sock
    return default


_WRAPS = {"REPEAT": "periodic", "EXTEND": "clamp", "CLIP": "black", "MIRROR": "mirror"}


def _texture_placement(node, warnings, what):
    """An Image Texture node's wrap and its Vector input as Spangle's uv_transform: UV (or
    nothing) through at most one Mapping node of type Point or Texture (its scale, Z rotation
    and location; they were ignored). Anything else is a warning."""
    out = {}
    wrap = _WRAPS.get(getattr(node, "extension", "REPEAT"), "periodic")
    if wrap != "periodic":
        out["wrap"] = wrap
    vec = node.inputs.get("Vector")
    if vec is None or not vec.is_linked:
        return out
    src = vec.links[0].from_node
    if src.type != "MAPPING":
        if not (src.type == "TEX_COORD" and vec.links[0].from_socket.name == "UV") and not (
                src.type == "UVMAP"):
            warnings.append(f"{what}: a texture's coordinates come from a {src.type} node; "
                            "the mesh's uvs stand in")
        return out
    inner = src.inputs.get("Vector")
    if inner is not None and inner.is_linked:
        feed = inner.links[0]
        if not ((feed.from_node.type == "TEX_COORD" and feed.from_socket.name == "UV") or
                feed.from_node.type == "UVMAP"):
            warnings.append(f"{what}: a texture's mapping reads {feed.from_node.type} "
                            "coordinates; the mesh's uvs stand in")
            return out
    if any(src.inputs[n].is_linked for n in ("Location", "Rotation", "Scale") if n in src.inputs):
        warnings.append(f"{what}: a texture mapping's linked inputs are not exported")
        return out
    if src.vector_type not in ("POINT", "TEXTURE"):
        warnings.append(f"{what}: a {src.vector_type.lower()} texture mapping is not exported")
        return out
    loc = src.inputs["Location"].default_value
    rot = src.inputs["Rotation"].default_value
    sc = src.inputs["Scale"].default_value
    if abs(rot[0]) > 1e-6 or abs(rot[1]) > 1e-6:
        warnings.append(f"{what}: a texture mapping's X/Y rotation is not exported")
    # Point: uv' = R (S uv) + L. Texture is its inverse: uv' = S^-1 R^-1 (uv - L).
    a = rot[2]
    c, s_ = math.cos(a), math.sin(a)
    if src.vector_type == "POINT":
        m = [c * sc[0], -s_ * sc[1], loc[0], s_ * sc[0], c * sc[1], loc[1]]
    else:
        if abs(sc[0]) < 1e-12 or abs(sc[1]) < 1e-12:
            return out
        r = [[c / sc[0], s_ / sc[0]], [-s_ / sc[1], c / sc[1]]]
        m = [r[0][0], r[0][1], -(r[0][0] * loc[0] + r[0][1] * loc[1]),
             r[1][0], r[1][1], -(r[1][0] * loc[0] + r[1][1] * loc[1])]
    if m != [1.0, 0.0, 0.0, 0.0, 1.0, 0.0]:
        out["uv_transform"] = {"matrix": m}
    return out


def _abspath(path):
    """A Blender path as an absolute one: `//` paths from the .blend's folder, and a path
    relative to the working directory (an image loaded as "tex/a.png", or `//` in an unsaved
    file) from there: the scene file is read from a temporary folder, where a relative path
    named nothing and the render failed."""
    return os.path.abspath(bpy.path.abspath(path))


# The most an emitter's colour x strength may be (Spangle refuses brighter: a sample carries
# at most about 1e18).
_MOST_LIGHT = 1e18


def _bounded_light(color, strength, warnings, what):
    """strength, lowered (with a warning) where colour x strength exceeds what Spangle takes."""
    most = max(max(color), 0.0) * strength
    if most > _MOST_LIGHT:
        warnings.append(f"{what}: colour x strength {most:.4g} is beyond {_MOST_LIGHT:g}, the "
                        "brightest light Spangle takes; lowered to it")
        return strength * _MOST_LIGHT / most
    return strength


def _unit_color(c, warnings, what, label):
    """A colour input as a reflectance in [0, 1]: components above 1 (Blender allows them; a
    surface then reflects more light than it receives) are clamped, with a warning."""
    if not isinstance(c, tuple):
        return c
    if any(v > 1.0 for v in c[:3]) or any(v < 0.0 for v in c[:3]):
        warnings.append(f"{what}: {label} {tuple(round(v, 4) for v in c[:3])} is outside [0, 1] "
                        "(a surface reflecting more light than it receives); clamped into it")
        return tuple(min(max(float(v), 0.0), 1.0) for v in c[:3])
    return c


_EXTENSIONS = {"PNG": ".png", "JPEG": ".jpg", "OPEN_EXR": ".exr", "OPEN_EXR_MULTILAYER": ".exr",
               "HDR": ".hdr", "TIFF": ".tif", "TARGA": ".tga", "TARGA_RAW": ".tga", "BMP": ".bmp",
               "WEBP": ".webp"}


def _image_file(image, warnings=None, what=""):
    """The file an image node reads: its own file when it is there; a packed image's bytes,
    written once to a cache folder under a name from their hash (Cycles renders packed images:
    the render failed on their missing file); None (with a warning) when it has neither."""
    path = _abspath(image.filepath) if image.filepath else ""
    if path and os.path.isfile(path):
        return path
    packed = getattr(image, "packed_file", None)
    if packed is not None:
        data = bytes(packed.data)
        ext = os.path.splitext(path)[1] or _EXTENSIONS.get(image.file_format, ".png")
        folder = os.path.join(tempfile.gettempdir(), "spangle-blender-packed")
        os.makedirs(folder, exist_ok=True)
        out = os.path.join(folder, hashlib.sha1(data).hexdigest()[:20] + ext.lower())
        if not os.path.isfile(out):
            tmp = f"{out}.{os.getpid()}.tmp"
            with open(tmp, "wb") as f:
                f.write(data)
            os.replace(tmp, out)
        return out
    if warnings is not None:
        warnings.append(f"{what}: image '{image.name}' has no file ({path or 'no path'}) and is "
                        "not packed; its node's own value stands in")
    return None


def _socket_value(sock, warnings, what):
    if sock is None:
        return None
    if sock.is_linked:
        src = sock.links[0].from_node
        if src.type == "TEX_IMAGE" and src.image is not None:
            # Its file, or (with a warning from _image_file) the input's own value.
            file = _image_file(src.image, warnings, what)
            if file is not None:
                # The image's own colour space (a Non-Color roughness map is data, a linear
                # EXR is linear: every texture was tagged sRGB).
                tex = {"texture": file, "space": _image_space(src.image)}
                # A colour into a number input (Roughness, Metallic): Blender takes its
                # luminance (its first channel was read: a red/blue map 7x too rough in half
                # its squares). A grey image's luminance is its grey.
                if sock.type == "VALUE" and sock.links[0].from_socket.name == "Color":
                    tex["channel"] = "luminance"
                tex.update(_texture_placement(src, warnings, what))
                return tex
        else:
            warnings.append(f"{what}: a node input ({sock.name}) is linked to a {src.type} node; "
                            "its own value stands in")
    v = sock.default_value
    try:
        return tuple(v)[:3]
    except TypeError:
        return float(v)


def _image_of(sock):
    """The file of an image texture node linked into sock, or None."""
    if sock is None or not sock.is_linked:
        return None
    src = sock.links[0].from_node
    if src.type == "TEX_IMAGE" and src.image is not None:
        return _image_file(src.image)
    return None


def _surface_map(node, warnings, what):
    """("normal_map" or "bump_map", its table) for what drives the Principled BSDF's Normal
    input: a tangent-space Normal Map node or a Bump node reading an image texture (both the
    engine applies to any material); None (with a warning for anything else linked there)."""
    sock = _input(node, "Normal")
    if sock is None or not sock.is_linked:
        return None
    src = sock.links[0].from_node
    if src.type == "NORMAL_MAP":
        image = _image_of(src.inputs.get("Color"))
        if src.space == "TANGENT" and image is not None:
            strength = src.inputs["Strength"]
            if strength.is_linked:
                warnings.append(f"{what}: the normal map's Strength is linked; its own value "
                                "stands in")
            if src.uv_map:
                warnings.append(f"{what}: the normal map's uv map '{src.uv_map}' is not exported; "
                                "the active one stands in")
            return "normal_map", {"texture": image,
                                  "strength": min(max(float(strength.default_value), 0.0), 10.0)}
        warnings.append(f"{what}: a normal map that is not a tangent-space image texture "
                        f"({src.space.lower()} space) is not exported")
        return None
    if src.type == "BUMP":
        image = _image_of(src.inputs.get("Height"))
        if image is not None:
            if src.invert or src.inputs["Normal"].is_linked:
                warnings.append(f"{what}: the bump node's Invert and Normal input are not exported")
            # Cycles displaces by height x Distance, and Strength blends the bumped normal with
            # the unbumped one: for gentle slopes the tilt scales with both.
            # Cycles displaces by height x Distance and blends the bumped normal with the
            # surface's by Strength: the bump map's height and strength.
            strength = min(max(float(src.inputs["Strength"].default_value), 0.0), 1.0)
            height = float(src.inputs["Distance"].default_value)
            bump = {"texture": image, "height": min(max(height, 0.0), 1.0)}
            if strength < 1.0:
                bump["strength"] = strength
            return "bump_map", bump
        warnings.append(f"{what}: a bump node whose Height is not an image texture is not "
                        "exported")
        return None
    warnings.append(f"{what}: the Normal input is linked to a {src.type} node; it is not exported")
    return None


def _dropped_inputs(node, transmission, warnings, what):
    """Warnings for the Principled inputs the export does not carry (each set away from its
    neutral value: they were dropped silently)."""
    def value(*names):
        sock = _input(node, *names)
        if sock is None:
            return None
        if sock.is_linked:
            return "linked"
        try:
            return float(sock.default_value)
        except TypeError:
            return None

    sheen = value("Sheen Weight", "Sheen")
    if sheen == "linked":
        warnings.append(f"{what}: a sheen weight from a texture is not exported")
    for names, label in ((("Subsurface Weight", "Subsurface"), "subsurface scattering"),
                         (("Anisotropic",), "anisotropy"),
                         (("Thin Film Thickness",), "a thin film")):
        v = value(*names)
        if v == "linked" or (isinstance(v, float) and v > 0.0):
            warnings.append(f"{what}: {label} is not exported")
    if isinstance(transmission, float) and 0.0 < transmission <= 0.5:
        warnings.append(f"{what}: transmission {transmission:g} is not exported (at most 0.5: "
                        "an opaque surface; above it, glass)")
    coat_normal = _input(node, "Coat Normal")
    if coat_normal is not None and coat_normal.is_linked:
        warnings.append(f"{what}: the coat's normal input is not exported")


def _alpha(node, warnings, what):
    """The Principled BSDF's Alpha as the material's `alpha` (a cut-out: a ray meets the surface
    with probability alpha, as Cycles draws it): a number below 1, or the image linked into it
    (its Alpha output: the image's A channel; its Color output: its first channel); None when
    opaque."""
    sock = _input(node, "Alpha")
    if sock is None:
        return None
    if not sock.is_linked:
        v = float(sock.default_value)
        return min(max(v, 0.0), 1.0) if v < 1.0 else None
    link = sock.links[0]
    src = link.from_node
    if src.type != "TEX_IMAGE" or src.image is None:
        warnings.append(f"{what}: Alpha is linked to a {src.type} node, which is not exported; "
                        "the surface is opaque")
        return None
    file = _image_file(src.image, warnings, what)
    if file is None:
        return None
    if link.from_socket.name == "Alpha":
        # An image without alpha (or whose alpha Blender is told to ignore) gives 1: opaque.
        if (getattr(src.image, "channels", 4) not in (2, 4) or
                getattr(src.image, "alpha_mode", "STRAIGHT") == "NONE"):
            return None
        tex = {"texture": file, "channel": "a"}
    else:
        # The Color output, as Blender reads it: in the image's colour space (an sRGB mask is
        # linearised), its grey (a colour mask's red stands in for Blender's luminance).
        tex = {"texture": file, "channel": "r", "space": _image_space(src.image)}
    tex.update(_texture_placement(src, warnings, what))
    return tex


def _alpha_toml(v):
    """The `alpha = ...` line of a material."""
    if not isinstance(v, dict):
        return f"alpha = {_toml_value(float(v))}"
    space = f", space = {_toml_string(v['space'])}" if "space" in v else ""
    return (f"alpha = {{ texture = {_toml_string(v['texture'])}, "
            f"channel = {_toml_string(v['channel'])}{space}{_placement_toml(v)} }}")


def material_entry(mat, flake_params, warnings):
    """(plugin, model, params, emission) for a Blender material; emission is (rgb or an image
    texture's table, intensity) or None."""
    if mat is None:
        return "smooth", "diffuse", {"albedo": (0.8, 0.8, 0.8)}, None
    flakes = getattr(mat, "spangle_flakes", None)
    if flakes is not None and flakes.enabled:
        params = {}
        if not flake_params:
            warnings.append(f"material '{mat.name}': its Spangle Flakes settings are not known "
                            "(the spangle module was not found when the add-on started; set its "
                            "Module folder in the add-on's preferences): the flake plugin's "
                            "defaults stand in")
        for p in flake_params:
            v = getattr(flakes, p["name"])
            # Blender keeps floats in single precision: a value within its rounding of the
            # default is the default (and is left out, as the plugin's default applies).
            if p["type"] == "color":
                v = tuple(float(c) for c in v)
                if all(abs(a - b) <= 1e-6 * max(1.0, abs(b)) for a, b in zip(v, p["default"])):
                    continue
            elif p["type"] == "float":
                v = float(v)
                if abs(v - p["default"]) <= 1e-6 * max(1.0, abs(p["default"])):
                    continue
            elif v == p["default"]:
                continue
            params[p["name"]] = v
        return "flake", "", params, None
    node = _principled(mat)
    what = f"material '{mat.name}'"
    if node is None:
        warnings.append(f"{what}: not a Principled BSDF; a diffuse of its viewport colour stands in")
        return "smooth", "diffuse", {"albedo": tuple(mat.diffuse_color)[:3]}, None
    base_sock = _input(node, "Base Color")
    base_src = base_sock.links[0].from_node if base_sock is not None and base_sock.is_linked else None
    if base_src is not None and base_src.type in ("VERTEX_COLOR", "ATTRIBUTE"):
        # A Color Attribute (or Attribute) node: the mesh's colours, which the export writes
        # into its PLY files (each mesh's render colour attribute, whichever one the node names).
        base = {"vertex_color": True}
    else:
        base = _unit_color(_socket_value(base_sock, warnings, what), warnings, what, "Base Color")
    metallic = _socket_value(_input(node, "Metallic"), warnings, what)
    roughness = _socket_value(_input(node, "Roughness"), warnings, what)
    ior = _socket_value(_input(node, "IOR"), warnings, what) or 1.5
    transmission = _socket_value(_input(node, "Transmission Weight", "Transmission"), warnings, what) or 0.0
    emission = None
    e_color = _socket_value(_input(node, "Emission Color", "Emission"), warnings, what)
    e_strength = _socket_value(_input(node, "Emission Strength"), warnings, what)
    if isinstance(e_strength, float) and e_strength < 0.0:
        warnings.append(f"{what}: a negative Emission Strength ({e_strength:g}) is not exported; "
                        "it emits nothing")
        e_strength = 0.0
    if isinstance(e_color, tuple) and e_strength and max(e_color) > 0.0:
        emission = (e_color, _bounded_light(e_color, float(e_strength), warnings, what))
    elif isinstance(e_color, dict) and e_strength:
        emission = (e_color, _bounded_light((1.0, 1.0, 1.0), float(e_strength), warnings, what))
    _dropped_inputs(node, transmission, warnings, what)
    surface = _surface_map(node, warnings, what)
    alpha = _alpha(node, warnings, what)
    if isinstance(transmission, float) and transmission > 0.5:
        params = {"ior": min(max(float(ior), 1.0), 10.0),
                  "roughness": float(roughness) ** 2 if isinstance(roughness, float) else 0.0}
        # Principled's Base Color tints the light its glass transmits (each crossing), as the
        # dielectric's transmission_color does; the reflection stays white in both.
        if isinstance(base, dict) or (isinstance(base, tuple) and
                                      any(abs(c - 1.0) > 1e-3 for c in base[:3])):
            params["transmission_color"] = base
        if surface is not None:
            params[surface[0]] = surface[1]
        if alpha is not None:
            params["alpha"] = alpha
        # Multiscatter GGX (Principled's default) keeps the light single scattering loses in
        # rough glass, as the dielectric's multiscatter does (off unless asked for); plain GGX
        # does not.
        if getattr(node, "distribution", "MULTI_GGX") != "GGX":
            params["multiscatter"] = True
        return "smooth", "dielectric", params, emission
    params = {}
    if surface is not None:
        params[surface[0]] = surface[1]  # written beside params, not in them
    if alpha is not None:
        params["alpha"] = alpha  # written beside params too
    params["base_color"] = base if base is not None else (0.8, 0.8, 0.8)
    # An image linked into Metallic or Roughness is a texture of the parameter (both are
    # texturable); it was left out, and the plugin's defaults (metallic 1, roughness 1) turned
    # a plastic with a black metallic map into a rough metal.
    if isinstance(metallic, float):
        params["metallic"] = min(max(metallic, 0.0), 1.0)
    elif isinstance(metallic, dict):
        params["metallic"] = metallic
    if isinstance(roughness, float):
        params["roughness"] = min(max(roughness, 0.0), 1.0)
    elif isinstance(roughness, dict):
        params["roughness"] = roughness
    params["ior"] = min(max(float(ior), 1.0), 10.0)
    # Sheen (weight x tint, roughness): metal_rough's sheen layer (KHR_materials_sheen's
    # Charlie sheen; Cycles' is a microfiber model of the same look).
    sheen_w = _socket_value(_input(node, "Sheen Weight", "Sheen"), warnings, what)
    if isinstance(sheen_w, float) and sheen_w > 0.0:
        tint = _socket_value(_input(node, "Sheen Tint"), warnings, what)
        t = tint[:3] if isinstance(tint, tuple) else (1.0, 1.0, 1.0)
        params["sheen_color"] = tuple(min(max(sheen_w * float(c), 0.0), 1.0) for c in t)
        sheen_r = _socket_value(_input(node, "Sheen Roughness"), warnings, what)
        if isinstance(sheen_r, float):
            params["sheen_roughness"] = min(max(sheen_r, 0.0), 1.0)
    # Specular IOR Level scales the dielectric's F0 by 2 level (0.5: as the IOR gives); above
    # 0.5 it brightens it, which KHR_materials_specular's specular_color carries (the level was
    # clamped to 0.5). Specular Tint colours F0 the same way.
    level = _socket_value(_input(node, "Specular IOR Level"), warnings, what)
    tint = _socket_value(_input(node, "Specular Tint"), warnings, what)
    boost = 1.0
    if isinstance(level, float):
        params["specular"] = min(max(2.0 * level, 0.0), 1.0)
        boost = min(max(2.0 * level, 1.0), 10.0)
    tint = tint if isinstance(tint, tuple) and len(tint) == 3 else (1.0, 1.0, 1.0)
    spec_color = tuple(min(t * boost, 10.0) for t in tint)
    if any(abs(c - 1.0) > 1e-6 for c in spec_color):
        params["specular_color"] = spec_color
    # Principled's default distribution, Multiscatter GGX, keeps the light single-scattering
    # GGX loses on rough metal: the plugin's multiscatter (on by default) does the same.
    if getattr(node, "distribution", "MULTI_GGX") == "GGX":
        params["multiscatter"] = False
    coat = _socket_value(_input(node, "Coat Weight"), warnings, what)
    if isinstance(coat, float) and coat > 0.0:
        params["clearcoat"] = min(coat, 1.0)
        coat_tint = _input(node, "Coat Tint")
        if coat_tint is not None and (coat_tint.is_linked or any(
                abs(c - 1.0) > 1e-6 for c in tuple(coat_tint.default_value)[:3])):
            warnings.append(f"{what}: Coat Tint is not exported; the coat is clear")
        coat_ior = _input(node, "Coat IOR")
        if coat_ior is not None and (coat_ior.is_linked or
                                     abs(float(coat_ior.default_value) - 1.5) > 1e-3):
            warnings.append(f"{what}: Coat IOR is not exported; the coat's index is 1.5")
        coat_r = _socket_value(_input(node, "Coat Roughness"), warnings, what)
        if isinstance(coat_r, float):
            params["clearcoat_roughness"] = min(max(coat_r, 0.0), 1.0)
    return "smooth", "metal_rough", params, emission


_SURFACE_MAPS = ("normal_map", "bump_map")


def _placement_toml(v):
    """A texture table's wrap and uv_transform entries (each after a comma), as written."""
    extra = ""
    if "wrap" in v:
        extra += f", wrap = {_toml_string(v['wrap'])}"
    if "uv_transform" in v:
        extra += f", uv_transform = {{ matrix = {_vec(v['uv_transform']['matrix'])} }}"
    return extra


def _param_toml(k, v):
    if isinstance(v, dict) and "texture" not in v:  # the meshes' vertex colours
        return f"{k} = {{ vertex_color = true }}"
    if isinstance(v, dict):
        space = v.get("space", "srgb_texture")
        channel = f", channel = {_toml_string(v['channel'])}" if "channel" in v else ""
        return (f'{k} = {{ texture = {_toml_string(v["texture"])}, '
                f'space = {_toml_string(space)}{channel}{_placement_toml(v)} }}')
    return f"{k} = {_toml_value(v)}"


def vertical_fov(cam, width, height):
    """Blender's camera as a vertical field of view in degrees for a width x height image."""
    aspect = width / height
    fit = cam.sensor_fit
    if fit == "AUTO":
        fit, sensor = ("HORIZONTAL" if width >= height else "VERTICAL"), cam.sensor_width
    else:
        sensor = cam.sensor_width if fit == "HORIZONTAL" else cam.sensor_height
    half = math.atan(sensor / (2.0 * cam.lens))
    if fit == "HORIZONTAL":
        return math.degrees(2.0 * math.atan(math.tan(half) / aspect))
    return math.degrees(2.0 * half)


def _full_equirectangular(cam):
    """Whether a panoramic camera is an equirectangular one over the whole sphere (Spangle's
    equirectangular camera): Blender 4 keeps the type and range on the camera, 3.x in cycles."""
    holder = cam if hasattr(cam, "panorama_type") else getattr(cam, "cycles", None)
    if holder is None or getattr(holder, "panorama_type", "") != "EQUIRECTANGULAR":
        return False
    full = ((getattr(holder, "latitude_min", -math.pi / 2), -math.pi / 2),
            (getattr(holder, "latitude_max", math.pi / 2), math.pi / 2),
            (getattr(holder, "longitude_min", -math.pi), -math.pi),
            (getattr(holder, "longitude_max", math.pi), math.pi))
    return all(abs(v - want) < 1e-4 for v, want in full)


def ortho_height(cam, width, height):
    """Blender's orthographic camera as the view's height in scene units for a width x height
    image: Ortho Scale spans the fitted side (the wider one under Auto)."""
    fit = cam.sensor_fit
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and width >= height)
    return cam.ortho_scale * height / width if horizontal else cam.ortho_scale


def shifted_window(cam, width, height):
    """Blender's lens shift as Spangle's screen window (x0, x1, y0, y1 in units of the tangent of
    half the vertical fov, y up), or None without a shift. Blender shifts by shift x the size of
    the sensor's fitted side (the wider one under Auto); it was dropped, silently."""
    if cam.shift_x == 0.0 and cam.shift_y == 0.0:
        return None
    aspect = width / height
    fit = cam.sensor_fit
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and width >= height)
    span = 2.0 * aspect if horizontal else 2.0
    dx, dy = cam.shift_x * span, cam.shift_y * span
    return (-aspect + dx, aspect + dx, -1.0 + dy, 1.0 + dy)


def _image_space(image):
    """The Spangle colour space of a Blender image's colour space."""
    name = image.colorspace_settings.name
    if name in ("sRGB",):
        return "srgb_texture"
    if name in ("Non-Color", "Raw"):
        return "raw"
    return "lin_rec709"


def _world_lines(world, warnings):
    """[environment] for Blender's world: its background colour, or its environment texture as a
    lat-long map. Blender's equirectangular layout (Cycles: u = 1/2 - atan2(y, x) / 2 pi, v =
    1/2 + elevation / pi) is pbrt-v3's z-up one (u = atan2(y, x) / 2 pi) with x mirrored: the
    map's frame flips x."""
    if world is None:
        return []
    if not world.use_nodes or world.node_tree is None:
        color, strength = tuple(world.color)[:3], 1.0
        return ["[environment]", f"color = {_vec(color)}", f"intensity = {_fmt(strength)}", ""]
    for node in world.node_tree.nodes:
        if node.type != "BACKGROUND":
            continue
        color = node.inputs["Color"]
        strength = float(node.inputs["Strength"].default_value)
        if strength <= 0.0:
            return []
        strength = _bounded_light((1.0, 1.0, 1.0), strength, warnings, "world")
        if color.is_linked:
            src = color.links[0].from_node
            if src.type == "TEX_ENVIRONMENT" and src.image is not None:
                path = _abspath(src.image.filepath)
                if src.inputs["Vector"].is_linked:
                    warnings.append("world: the environment texture's mapping is not exported")
                if src.projection == "EQUIRECTANGULAR" and path and os.path.isfile(path):
                    return ["[environment]", f"map = {_toml_string(path)}",
                            f"color_space = {_toml_string(_image_space(src.image))}",
                            'projection = "latlong_z_up"',
                            "frame = [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]",
                            f"intensity = {_fmt(strength)}", ""]
                px = np.empty(len(src.image.pixels), dtype=np.float32)
                src.image.pixels.foreach_get(px)
                mean = px.reshape(-1, src.image.channels)[:, :3].mean(axis=0)
                warnings.append("world: the environment texture is not an equirectangular image "
                                "file on disk; its mean colour lights the scene instead")
                return ["[environment]", f"color = {_vec(mean)}", f"intensity = {_fmt(strength)}", ""]
            warnings.append(f"world: its colour comes from a {src.type} node; its own value stands in")
        c = tuple(color.default_value)[:3]
        if max(c) <= 0.0:
            return []
        return ["[environment]", f"color = {_vec(c)}", f"intensity = {_fmt(strength)}", ""]
    return []


def _light_node_factor(obj, warnings):
    """(colour, strength) of a light's node tree: an Emission node into the Light Output scales
    the light's colour and power, as in Cycles (it was ignored); anything else is a warning."""
    light = obj.data
    if not getattr(light, "use_nodes", False) or light.node_tree is None:
        return (1.0, 1.0, 1.0), 1.0
    for node in light.node_tree.nodes:
        if node.type == "OUTPUT_LIGHT" and node.is_active_output:
            surf = node.inputs.get("Surface")
            if surf is None or not surf.is_linked:
                return (1.0, 1.0, 1.0), 1.0
            src = surf.links[0].from_node
            if src.type == "EMISSION" and not any(i.is_linked for i in src.inputs):
                return (tuple(src.inputs["Color"].default_value)[:3],
                        float(src.inputs["Strength"].default_value))
            warnings.append(f"light '{obj.name}': its node tree is not exported (an Emission node "
                            "with unlinked inputs is); its colour and power stand in")
            break
    return (1.0, 1.0, 1.0), 1.0


def _light_lines(obj, matrix, warnings):
    light = obj.data
    pos = matrix.translation
    tint, strength = _light_node_factor(obj, warnings)
    color = tuple(c * t * strength for c, t in zip(light.color, tint))
    lines = []
    what = f"light '{obj.name}'"
    if light.energy < 0.0 or min(color) < 0.0:
        # Cycles subtracts light where it is negative; Spangle's lights only add.
        warnings.append(f"{what}: negative power ({light.energy:g}) is not supported; it is left "
                        "out")
        return lines
    if light.energy == 0.0 or max(color) <= 0.0:
        return lines  # gives no light
    if getattr(light, "use_shadow", True) is False:
        warnings.append(f"{what}: Cast Shadow off is not exported; it casts shadows")
    linking = getattr(obj, "light_linking", None)
    if linking is not None and (getattr(linking, "receiver_collection", None) is not None or
                                getattr(linking, "blocker_collection", None) is not None):
        warnings.append(f"{what}: light linking is not exported; it lights everything")
    scale = matrix.to_scale()
    if light.type == "SPOT" and max(abs(scale.x), abs(scale.y)) > 1.0001 * min(abs(scale.x),
                                                                               abs(scale.y)):
        warnings.append(f"{what}: a spot's non-uniform scale is not exported; its cone stays round")
    if light.type in ("POINT", "SPOT"):
        # Blender's watts as radiant intensity, P / (4 pi) W/sr (as its glTF exporter converts).
        intensity = light.energy / (4.0 * math.pi)
        if light.shadow_soft_size > 1e-6:
            warnings.append(f"light '{obj.name}': its radius ({light.shadow_soft_size:g} m) is "
                            "not exported; a point light stands in")
        if light.type == "POINT":
            lines += ["[[light]]", 'type = "point"', f"position = {_vec(pos)}"]
        else:
            axis = matrix.to_3x3() @ mathutils.Vector((0.0, 0.0, -1.0))
            half = min(math.degrees(light.spot_size) / 2.0, 90.0)
            lines += ["[[light]]", 'type = "spot"', f"position = {_vec(pos)}",
                      f"look_at = {_vec(pos + axis)}", f"cone_angle = {_fmt(half)}",
                      f"cone_falloff = {_fmt(spot_falloff(half, light.spot_blend))}"]
        intensity = _bounded_light(color, intensity, warnings, what)
        lines += [f"color = {_vec(color)}", f"intensity = {_fmt(intensity)}"]
    elif light.type == "SUN":
        # A sun's strength (its `energy`) is irradiance in W/m^2.
        direction = matrix.to_3x3() @ mathutils.Vector((0.0, 0.0, 1.0))
        lines += ["[[light]]", 'type = "distant"', f"direction = {_vec(direction)}",
                  f"angular_radius = {_fmt(math.degrees(light.angle) / 2.0)}",
                  f"color = {_vec(color)}",
                  f"intensity = {_fmt(_bounded_light(color, light.energy, warnings, what))}"]
    elif light.type == "AREA":
        sx = light.size
        sy = light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size
        if light.shape in ("DISK", "ELLIPSE"):
            warnings.append(f"light '{obj.name}': a {light.shape.lower()} area light is exported as "
                            "the rectangle of the same area")
            sx, sy = sx * math.sqrt(math.pi) / 2.0, sy * math.sqrt(math.pi) / 2.0
        m3 = matrix.to_3x3()
        ex = m3 @ mathutils.Vector((sx, 0.0, 0.0))
        ey = m3 @ mathutils.Vector((0.0, sy, 0.0))
        corner = pos - 0.5 * ex - 0.5 * ey
        area = ex.cross(ey).length
        if not area > 0.0:
            # Cycles' light of no area gives no light.
            warnings.append(f"{what}: an area light of no area (size {sx:g} x {sy:g}, after its "
                            "scale) gives no light; it is left out")
            return lines
        # Power P of a one-sided Lambertian emitter: radiance P / (pi A). It emits along the
        # light's -Z: edge2 x edge1 order.
        radiance = _bounded_light(color, light.energy / (math.pi * area), warnings, what)
        if getattr(light, "spread", math.pi) < math.pi - 1e-4:
            warnings.append(f"{what}: its spread ({math.degrees(light.spread):g} degrees) is not "
                            "exported; it emits into the whole hemisphere")
        # As in Cycles, a light is not in the way: the camera does not see it (a black quad
        # from behind), it casts no shadow, and rays that meet it go on.
        if getattr(obj, "visible_camera", False):
            warnings.append(f"{what}: its camera visibility is not exported; the camera does "
                            "not see it")
        lines += ["[[light]]", 'type = "quad"', "transparent = true", f"corner = {_vec(corner)}", f"edge1 = {_vec(ey)}",
                  f"edge2 = {_vec(ex)}", f"color = {_vec(color)}", f"intensity = {_fmt(radiance)}"]
    else:
        warnings.append(f"light '{obj.name}': type {light.type} is not supported")
    return lines


def _object_warnings(obj, warnings):
    """Warnings for an object's Cycles settings that the export does not carry (they were
    dropped silently). A shadow catcher is carried over (Spangle's `shadow_catcher`)."""
    what = f"object '{obj.name}'"
    for attr, label in (("visible_camera", "camera"), ("visible_shadow", "shadow"),
                        ("visible_diffuse", "diffuse"), ("visible_glossy", "glossy"),
                        ("visible_transmission", "transmission")):
        if getattr(obj, attr, True) is False:
            warnings.append(f"{what}: its ray visibility ({label} off) is not exported; it is seen "
                            "by every ray")
    if getattr(obj, "is_holdout", False):
        warnings.append(f"{what}: holdout is not exported; the object renders as itself")
    linking = getattr(obj, "light_linking", None)
    if linking is not None and (getattr(linking, "receiver_collection", None) is not None or
                                getattr(linking, "blocker_collection", None) is not None):
        warnings.append(f"{what}: light linking is not exported; it lights and shadows everything")


def _pixel_filter(scene, warnings):
    """The [render] lines of Blender's pixel filter (Cycles' Film > Pixel Filter; without Cycles
    a Blackman-Harris of the render's filter size). Cycles' width w spans a Blackman-Harris over
    [-w, w] (its default 1.5: radius 1.5 here) and a Gaussian of sigma w / 4 out to 1.5 w (radius
    0.75 w here: Spangle's Gaussian has sigma radius / 3; beyond 3 sigma Cycles' keeps 0.3% of
    its weight); its box is one pixel whatever the width (Blender's sync sets width 1 for a box).
    Spangle's radius is at most 8 pixels (Cycles' width goes to 10)."""
    cycles = getattr(scene, "cycles", None)
    kind = getattr(cycles, "pixel_filter_type", "BLACKMAN_HARRIS") if cycles else "BLACKMAN_HARRIS"
    if kind == "BOX":
        return ['filter = "box"']
    width = float(getattr(cycles, "filter_width", 0.0) if cycles else 0.0) or \
        float(getattr(scene.render, "filter_size", 1.5))
    name, radius = ("gaussian", 0.75 * width) if kind == "GAUSSIAN" else ("blackman-harris", width)
    if radius > 8.0:
        warnings.append(f"pixel filter width {width:g}: Spangle's filter reaches at most 8 pixels "
                        "(radius 8 exported)")
    return [f'filter = "{name}"', f"filter_radius = {min(8.0, max(0.05, radius)):.6g}"]


def _clipping_warning(depsgraph, cam_obj, warnings):
    """A warning when the camera's clip start or end would cut geometry in Cycles: Spangle's
    camera does not clip (everything in front of it is seen)."""
    cam = cam_obj.data
    m = cam_obj.matrix_world
    eye = m.translation
    forward = (m.to_3x3() @ mathutils.Vector((0.0, 0.0, -1.0))).normalized()
    # Depth along the view for a perspective or orthographic camera; a panorama clips by distance.
    radial = cam.type == "PANO"
    near, far = math.inf, -math.inf
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type not in ("MESH", "CURVE", "SURFACE", "META", "FONT"):
            continue
        mw = inst.matrix_world
        for corner in obj.bound_box:
            v = mw @ mathutils.Vector(corner) - eye
            d = v.length if radial else v.dot(forward)
            near, far = min(near, d), max(far, d)
    if far < 0.0:
        return
    cut = []
    # Blender's default clip start (0.1 m) cuts nothing anyone frames; a larger one is a choice.
    if cam.clip_start > 0.1 + 1e-6 and near < cam.clip_start:
        cut.append(f"clip start {cam.clip_start:g} m")
    if far > cam.clip_end:
        cut.append(f"clip end {cam.clip_end:g} m")
    if cut:
        verb = "are" if len(cut) > 1 else "is"
        warnings.append(f"camera '{cam_obj.name}': its {' and '.join(cut)} {verb} not exported "
                        "(Spangle's camera does not clip): geometry Cycles cuts away is seen")


def export_scene(depsgraph, folder, size, spp, flake_params, max_depth=5):
    """Writes folder/scene.toml and its meshes; returns the warnings."""
    scene = depsgraph.scene
    warnings = []
    out = ["# Exported by Spangle's Blender add-on", "", "[render]",
           f"width = {size[0]}", f"height = {size[1]}", f"spp = {spp}", f"max_depth = {max_depth}",
           *_pixel_filter(scene, warnings),
           'working_space = "lin_rec709"', 'color_space = "lin_rec709"', ""]
    cam_obj = scene.camera
    if cam_obj is None:
        raise RuntimeError("the scene has no camera")
    cam = cam_obj.data
    # The frame's shape as Blender frames it: with non-square pixels (Pixel Aspect X/Y) the image
    # spans width x aspect_x by height x aspect_y, and the screen window stretches the pixels.
    framed = (size[0] * scene.render.pixel_aspect_x, size[1] * scene.render.pixel_aspect_y)
    equirect = cam.type == "PANO" and _full_equirectangular(cam)
    if cam.type not in ("PERSP", "ORTHO") and not equirect:
        what = cam.type.lower() if cam.type != "PANO" else \
            f"{getattr(cam, 'panorama_type', 'panoramic').lower()} panoramic"
        warnings.append(f"camera '{cam_obj.name}': {what} cameras are not supported (only full "
                        "equirectangular panoramas are); a perspective camera stands in")
    m = cam_obj.matrix_world
    eye = m.translation
    forward = m.to_3x3() @ mathutils.Vector((0.0, 0.0, -1.0))
    up = m.to_3x3() @ mathutils.Vector((0.0, 1.0, 0.0))
    out += ["[camera]", f"position = {_vec(eye)}", f"look_at = {_vec(eye + forward)}",
            f"up = {_vec(up)}",
            'projection = "equirectangular"' if equirect else
            f"ortho_height = {_fmt(ortho_height(cam, *framed))}" if cam.type == "ORTHO" else
            f"fov = {_fmt(vertical_fov(cam, *framed))}"]
    window = None if equirect else shifted_window(cam, *framed)
    if window is None and not equirect and framed[0] * size[1] != framed[1] * size[0]:
        window = (-framed[0] / framed[1], framed[0] / framed[1], -1.0, 1.0)
    if window is not None:
        out.append(f"screen_window = [{', '.join(_fmt(v) for v in window)}]")
    _clipping_warning(depsgraph, cam_obj, warnings)
    if cam.dof.use_dof and not equirect:
        focus = cam.dof.focus_distance
        if cam.dof.focus_object is not None:
            # Blender's distance along the view axis, whichever side the object is on (behind
            # the camera, a negative distance was clamped to 0.1 mm: all of the frame blurred).
            focus = abs((cam.dof.focus_object.matrix_world.translation - eye).dot(forward))
        out += [f"aperture = {_fmt(cam.lens / 1000.0 / (2.0 * cam.dof.aperture_fstop))}",
                f"focus_distance = {_fmt(max(focus, 1e-4))}"]
    out.append("")
    out += _world_lines(scene.world, warnings)

    materials = {}  # name -> (plugin, model, params, emission)
    meshes = {}  # evaluated object name -> [(ply file, material name)]
    objects = []
    names = {}  # object name -> how many instances took it (names are unique in the scene)
    mesh_dir = os.path.join(folder, "meshes")
    os.makedirs(mesh_dir, exist_ok=True)
    for inst in depsgraph.object_instances:
        obj = inst.object
        # An instancer shown only through its instances (a particle emitter with Show Emitter
        # off for render) is not drawn itself (it was).
        if not getattr(inst, "show_self", True):
            continue
        if obj.type == "LIGHT":
            out += _light_lines(obj, inst.matrix_world.copy(), warnings) + [""]
            continue
        if obj.type not in ("MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES"):
            continue
        _object_warnings(obj, warnings)
        # One mesh file per geometry: Geometry Nodes instances are objects named after their
        # instancer but hold the instanced mesh (keyed by name, every instance took the
        # instancer's own mesh, or an empty one).
        key = (obj.name, obj.data.as_pointer() if obj.data is not None else 0)
        if key not in meshes:
            meshes[key] = []
            try:
                mesh = obj.to_mesh(preserve_all_data_layers=False, depsgraph=depsgraph)
            except RuntimeError:
                mesh = None
            if mesh is None:
                continue
            positions, normals, uvs, colors, mat_index = mesh_arrays(mesh)
            slots = [s.material for s in obj.material_slots] or [None]
            for k, mat in enumerate(slots):
                sel = np.nonzero(np.clip(mat_index, 0, len(slots) - 1) == k)[0]
                if len(sel) == 0:
                    continue
                corners = (3 * sel[:, None] + np.arange(3)).reshape(-1)
                name = mat.name if mat is not None else "spangle_default"
                if name not in materials:
                    materials[name] = material_entry(mat, flake_params, warnings)
                ply = os.path.join("meshes", f"mesh_{sum(len(v) for v in meshes.values()):05d}.ply")
                write_ply(os.path.join(folder, ply), positions[corners], normals[corners],
                          uvs[corners], np.arange(len(corners), dtype=np.int32).reshape(-1, 3),
                          None if colors is None else colors[corners])
                meshes[key].append((ply, name))
            obj.to_mesh_clear()
        # An object scaled to nothing (the usual way to hide one in an animation) draws nothing:
        # left out (its matrix, not invertible, failed the whole scene).
        if abs(inst.matrix_world.to_3x3().determinant()) <= 1e-30:
            warnings.append(f"object '{obj.name}': scaled to nothing, so not exported")
            continue
        for ply, name in meshes[key]:
            k = names.get(obj.name, 0)
            names[obj.name] = k + 1
            unique = obj.name if k == 0 else f"{obj.name}.{k}"
            objects.append((ply, name, inst.matrix_world.copy(), unique,
                            bool(getattr(obj, "is_shadow_catcher", False))))

    for name, (plugin, model, params, _emission) in materials.items():
        out += ["[[material]]", f"name = {_toml_string(name)}", f"plugin = {_toml_string(plugin)}"]
        if model:
            out.append(f"model = {_toml_string(model)}")
        maps = {k: v for k, v in params.items() if k in _SURFACE_MAPS}
        plain = {k: v for k, v in params.items() if k not in _SURFACE_MAPS and k != "alpha"}
        out.append("params = { " + ", ".join(_param_toml(k, v) for k, v in plain.items()) + " }")
        for k, v in maps.items():  # keys of the material itself, applied by the engine
            out.append(f"{k} = {{ " + ", ".join(f"{a} = {_toml_value(b)}" for a, b in v.items())
                       + " }")
        if "alpha" in params:
            out.append(_alpha_toml(params["alpha"]))
        out.append("")
    for ply, name, mw, obj_name, catcher in objects:
        rows = [mw[r][c] for r in range(3) for c in range(4)]
        out += ["[[object]]", f"name = {_toml_string(obj_name)}", f"mesh = {_toml_string(ply)}",
                f"material = {_toml_string(name)}", "matrix = " + _vec(rows)]
        if catcher:
            out.append("shadow_catcher = true")
        emission = materials[name][3]
        if emission is not None:
            # Cycles' emission shines from both sides of a face (one-sided, an emitter whose
            # normals faced away was black).
            color = (_param_toml("emission", emission[0]) if isinstance(emission[0], dict)
                     else f"emission = {_vec(emission[0])}")
            out += [color, f"emission_intensity = {_fmt(emission[1])}",
                    "emission_two_sided = true"]
        out.append("")
    with open(os.path.join(folder, "scene.toml"), "w", encoding="utf-8") as f:
        f.write("\n".join(out) + "\n")
    return warnings
