"""Spangle for Blender: a render engine that renders the Blender scene with Spangle.

The scene is exported (export.py) to a Spangle TOML scene with binary PLY meshes in a temporary
folder and rendered through the `spangle` Python module; progressive passes update the render
result as they arrive, and the render layers become Blender render passes (Glints, Spangle
Albedo, and Depth and Normal when the view layer asks for them). A "Spangle Flakes" panel on
materials carries every parameter of the flake plugin (read from the plugin's own schema), and
Blender's glTF exporter writes it as the SPANGLE_materials_flakes extension.

The `spangle` module must be importable: installed with `pip install .` into Blender's Python,
on PYTHONPATH, or in the folder named by $SPANGLE_PYTHONPATH or the add-on's preferences.
"""

bl_info = {
    "name": "Spangle",
    "author": "Spangle developers",
    "version": (0, 1, 0),
    "blender": (4, 2, 0),
    "location": "Render Properties > Render Engine > Spangle",
    "description": "Render with Spangle, the glitter renderer",
    "category": "Render",
}

import os
import shutil
import sys
import tempfile
import threading
import time

import bpy
import numpy as np

from . import export

ENGINE = "SPANGLE"


def _import_spangle():
    try:
        import spangle  # noqa: F401
    except ImportError:
        extra = os.environ.get("SPANGLE_PYTHONPATH", "")
        prefs = bpy.context.preferences.addons.get(__name__)
        if prefs is not None and getattr(prefs.preferences, "module_path", ""):
            extra = prefs.preferences.module_path + os.pathsep + extra
        for p in extra.split(os.pathsep):
            if p and p not in sys.path:
                sys.path.append(p)
    import spangle

    return spangle


_FLAKE_PARAMS = None


def flake_parameters():
    """The flake plugin's parameters, from its schema (once per Blender session: once found)."""
    global _FLAKE_PARAMS
    if _FLAKE_PARAMS is None:
        try:
            _FLAKE_PARAMS = _import_spangle().Session().parameters("flake")
        except Exception as e:  # no module: the panel stays empty, the engine says why
            print(f"Spangle: the flake parameters are not available: {e}")
            _FLAKE_PARAMS = []
    return _FLAKE_PARAMS


def _module_path_changed(prefs, context):
    """The module folder was set: when the flake parameters were not found before (the module
    was not importable when the add-on started), they are read now and the materials' Spangle
    Flakes settings get their fields (without them every flake paint rendered as the plugin's
    default grey, its settings silently dropped)."""
    global _FLAKE_PARAMS
    if _FLAKE_PARAMS:
        return
    _FLAKE_PARAMS = None
    if flake_parameters():
        _register_flake_settings()


class SpanglePreferences(bpy.types.AddonPreferences):
    bl_idname = __name__
    module_path: bpy.props.StringProperty(
        name="Module folder", subtype="DIR_PATH", update=_module_path_changed,
        description="Folder holding the spangle package (e.g. build/python of a Spangle build)")

    def draw(self, context):
        self.layout.prop(self, "module_path")


class SpangleRenderSettings(bpy.types.PropertyGroup):
    spp: bpy.props.IntProperty(name="Samples", default=64, min=1, max=1 << 20,
                               description="Samples per pixel")
    max_depth: bpy.props.IntProperty(name="Max bounces", default=5, min=1, max=1024)
    threads: bpy.props.IntProperty(name="Threads", default=0, min=0, max=1024,
                                   description="Render threads; 0: all cores")


def _flake_settings_class():
    """A PropertyGroup with a property per flake parameter, made from the plugin's schema."""
    ann = {"enabled": bpy.props.BoolProperty(
        name="Spangle Flakes", default=False,
        description="Render this material as Spangle's flake material")}
    for p in flake_parameters():
        name, doc = p["name"], p["doc"][:500]
        label = name.replace("_", " ").capitalize()
        if p["type"] == "float":
            hi = p["max"] if p["max"] < 3.0e38 else 3.0e38
            ann[name] = bpy.props.FloatProperty(name=label, description=doc, default=p["default"],
                                                min=p["min"], max=hi)
        elif p["type"] == "int":
            ann[name] = bpy.props.IntProperty(name=label, description=doc, default=p["default"],
                                              min=int(p["min"]), max=int(min(p["max"], 2**31 - 1)))
        elif p["type"] == "bool":
            ann[name] = bpy.props.BoolProperty(name=label, description=doc, default=p["default"])
        elif p["type"] == "color":
            ann[name] = bpy.props.FloatVectorProperty(name=label, description=doc, subtype="COLOR",
                                                      size=3, default=p["default"], min=p["min"],
                                                      max=p["max"])
        elif p["choices"]:
            ann[name] = bpy.props.EnumProperty(name=label, description=doc,
                                               items=[(c, c, "") for c in p["choices"]],
                                               default=p["default"])
        else:
            ann[name] = bpy.props.StringProperty(name=label, description=doc, default=p["default"])
    return type("SpangleFlakeSettings", (bpy.types.PropertyGroup,), {"__annotations__": ann})


class _SpanglePanel:
    """A properties-editor panel shown while Spangle is the render engine."""

    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class SPANGLE_PT_flakes(_SpanglePanel, bpy.types.Panel):
    bl_label = "Spangle Flakes"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.material is not None

    def draw_header(self, context):
        self.layout.prop(context.material.spangle_flakes, "enabled", text="")

    def draw(self, context):
        flakes = context.material.spangle_flakes
        col = self.layout.column()
        col.active = flakes.enabled
        for p in flake_parameters():
            col.prop(flakes, p["name"])


class SPANGLE_PT_render(_SpanglePanel, bpy.types.Panel):
    bl_label = "Spangle"
    bl_context = "render"

    def draw(self, context):
        s = context.scene.spangle
        for name in ("spp", "max_depth", "threads"):
            self.layout.prop(s, name)


def _rect(array):
    """An H x W x C image (row 0 at the top) as Blender's pass rect (rows bottom-up)."""
    return np.ascontiguousarray(array[::-1].reshape(-1, array.shape[2]), dtype=np.float32)


class SpangleRenderEngine(bpy.types.RenderEngine):
    bl_idname = ENGINE
    bl_label = "Spangle"
    bl_use_preview = False
    bl_use_postprocess = True

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        self.register_pass(scene, renderlayer, "Glints", 3, "RGB", "COLOR")
        self.register_pass(scene, renderlayer, "Spangle Albedo", 3, "RGB", "COLOR")
        if renderlayer.use_pass_z:
            self.register_pass(scene, renderlayer, "Depth", 1, "Z", "VALUE")
        if renderlayer.use_pass_normal:
            self.register_pass(scene, renderlayer, "Normal", 3, "XYZ", "VECTOR")

    def render(self, depsgraph):
        scene = depsgraph.scene
        settings = scene.spangle
        scale = scene.render.resolution_percentage / 100.0
        w = max(1, int(scene.render.resolution_x * scale))
        h = max(1, int(scene.render.resolution_y * scale))
        try:
            spangle = _import_spangle()
        except ImportError as e:
            self.report({"ERROR"}, f"Spangle: the spangle Python module is not found ({e})")
            return
        with tempfile.TemporaryDirectory(prefix="spangle-blender-") as folder:
            t0 = time.time()
            self.update_stats("Spangle", "exporting the scene")
            try:
                warnings = export.export_scene(depsgraph, folder, (w, h), settings.spp,
                                               flake_parameters(), settings.max_depth)
            except Exception as e:  # a scene it cannot export: say so, never take Blender down
                self.report({"ERROR"}, f"Spangle: the scene could not be exported: {e}")
                return
            self.export_seconds = time.time() - t0
            for msg in warnings:
                self.report({"WARNING"}, f"Spangle: {msg}")
            session = spangle.Session(threads=settings.threads)
            try:
                session.load(os.path.join(folder, "scene.toml"))
            except spangle.SceneError as e:
                # The error names a line of the exported scene: kept (the temporary folder goes
                # when the render ends), so that the line can be read.
                kept = tempfile.mkdtemp(prefix="spangle-blender-failed-")
                shutil.copytree(folder, kept, dirs_exist_ok=True)
                self.report({"ERROR"}, f"Spangle: {str(e).replace(folder, kept)} (the exported "
                            f"scene is kept in {kept})")
                return
            try:
                self._render(session, w, h, settings.spp, scene.render.film_transparent,
                             scene.render)
            except Exception as e:  # reported in the info area, never raised into Blender
                self.report({"ERROR"}, f"Spangle: {e}")

    def _render(self, session, w, h, spp, transparent=False, render_settings=None):
        state = {"pass": None, "progress": 0.0, "image": None, "error": None}

        def run():
            try:
                # Film > Transparent: the sky leaves the beauty (premultiplied, alpha = coverage);
                # otherwise the beauty keeps the sky and every pixel is opaque, as in Cycles.
                state["image"] = session.render(
                    spp=spp, size=(w, h), layers=True, background_apart=transparent,
                    progress=lambda done, total: state.__setitem__("progress", done / max(total, 1)),
                    on_pass=lambda beauty, n: state.__setitem__("pass", (beauty, n)))
            except Exception as e:  # raised once the render thread has ended
                state["error"] = e

        result = self.begin_result(0, 0, w, h)
        # A render region (Render > Region): Blender's result holds only the region's pixels;
        # the whole frame is rendered and the region cut out of it (it failed: "array length
        # cannot be changed").
        rw = getattr(result, "resolution_x", w) or w
        rh = getattr(result, "resolution_y", h) or h
        x0 = y0 = 0
        if (rw, rh) != (w, h) and render_settings is not None:
            x0 = min(max(0, int(render_settings.border_min_x * w)), w - rw)
            y0 = min(max(0, int(render_settings.border_min_y * h)), h - rh)

        def region(a):
            return a[h - (y0 + rh):h - y0, x0:x0 + rw] if (rw, rh) != (w, h) else a
        worker = threading.Thread(target=run, name="spangle-render")
        worker.start()
        # Blender's API from this thread only: the render thread just records what it has.
        while worker.is_alive():
            worker.join(0.1)
            self.update_progress(state["progress"])
            if self.test_break():
                session.stop()
            p, state["pass"] = state["pass"], None
            if p is not None:
                beauty, n = p
                rgba = np.concatenate([beauty, np.ones(beauty.shape[:2] + (1,), np.float32)], axis=2)
                result.layers[0].passes["Combined"].rect = _rect(region(rgba))
                self.update_result(result)
                self.update_stats("Spangle", f"{n} samples per pixel")
        if state["error"] is not None:
            self.report({"ERROR"}, f"Spangle: {state['error']}")
            self.end_result(result)
            return
        img = state["image"]
        layers = img.layers
        opaque = np.ones(img.beauty.shape[:2] + (1,), np.float32)
        alpha = layers.get("A", opaque) if transparent else opaque
        passes = result.layers[0].passes
        passes["Combined"].rect = _rect(region(np.concatenate([img.beauty, alpha], axis=2)))
        if "Glints" in passes and "glints" in layers:
            passes["Glints"].rect = _rect(region(layers["glints"]))
        if "Spangle Albedo" in passes and "albedo" in layers:
            passes["Spangle Albedo"].rect = _rect(region(layers["albedo"]))
        if "Depth" in passes and "Z" in layers:
            # Where no ray hit anything Cycles writes 1e10 (far), which Z-defocus and mist
            # expect; Spangle's layer holds 0 there.
            z = layers["Z"].copy()
            if "A" in layers:
                z[layers["A"][..., 0] <= 0.0] = 1e10
            passes["Depth"].rect = _rect(region(z))
        if "Normal" in passes and "N" in layers:
            passes["Normal"].rect = _rect(region(layers["N"]))
        self.end_result(result)
        self.update_stats("Spangle", f"done: {img.spp} samples per pixel in {img.seconds:.1f} s")


class glTF2ExportUserExtension:
    """Blender's glTF exporter calls this for every material: a material whose Spangle Flakes
    panel is on gets the SPANGLE_materials_flakes extension (docs/gltf.md), so that Spangle reads
    the exported file with the same flake paint."""

    def __init__(self):
        from io_scene_gltf2.io.com.gltf2_io_extensions import Extension

        self.Extension = Extension

    def gather_material_hook(self, gltf2_material, blender_material, export_settings):
        flakes = getattr(blender_material, "spangle_flakes", None)
        if flakes is None or not flakes.enabled:
            return
        _, _, params, _ = export.material_entry(blender_material, flake_parameters(), [])
        if gltf2_material.extensions is None:
            gltf2_material.extensions = {}
        gltf2_material.extensions["SPANGLE_materials_flakes"] = self.Extension(
            name="SPANGLE_materials_flakes", extension=params, required=False)


def _compatible_panels():
    """Blender's own material, light, camera and world panels that apply to Spangle too."""
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is not None and "BLENDER_EEVEE_NEXT" in engines:
            yield panel


_classes = []
_flake_class = None


def _register_flake_settings():
    """(Re)makes the materials' Spangle Flakes settings from the flake parameters known now.
    The values a .blend holds are kept by name, so settings saved before reappear."""
    global _flake_class
    if _flake_class is not None:
        del bpy.types.Material.spangle_flakes
        bpy.utils.unregister_class(_flake_class)
    _flake_class = _flake_settings_class()
    bpy.utils.register_class(_flake_class)
    bpy.types.Material.spangle_flakes = bpy.props.PointerProperty(type=_flake_class)


def register():
    global _classes
    # The preferences first: the module folder they name is where the flake parameters (read
    # by _register_flake_settings) may come from.
    _classes = [SpanglePreferences, SpangleRenderSettings, SPANGLE_PT_flakes, SPANGLE_PT_render,
                SpangleRenderEngine]
    for c in _classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.spangle = bpy.props.PointerProperty(type=SpangleRenderSettings)
    _register_flake_settings()
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE)


def unregister():
    global _flake_class
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE)
    if _flake_class is not None:
        del bpy.types.Material.spangle_flakes
        bpy.utils.unregister_class(_flake_class)
        _flake_class = None
    del bpy.types.Scene.spangle
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
