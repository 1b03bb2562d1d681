"""Time to a clean image, Spangle against Blender's Cycles, on one scene built in Blender.

    /opt/spangle/bpy/bin/python tests/bench/cycles_time_to_quality.py BUILD_DIR OUT_DIR

(a Python with PyPI's bpy: scripts/install-deps.sh --tests makes /opt/spangle/bpy; PYTHONPATH
needs BUILD_DIR/python.) The scene is a car of our own, built here in Blender's Python: a
subdivided body in a red plastic paint under a clear coat (no flakes, so both renderers draw the
same kind of material), four wheels, windows, a grey ground, a sun and a sky colour. Spangle
renders it through the Blender add-on's export (integrations/blender) with
tests/bench/time_to_quality.sh (fixed spp with and without --denoise, adaptive, adaptive +
denoise); Cycles renders the same Blender scene with fixed samples (adaptive sampling off), with
its adaptive sampling at falling noise thresholds, and each with Open Image Denoise when the bpy
build has it. Each renderer is measured against its own reference of REF_SPP samples (their
materials are not the same BRDFs), relMSE = mean (x - r)^2 / (r^2 + 0.01) over RGB, as spangle
inspect computes it. A reference is rendered as two halves with their own seeds; their relMSE
against each other / 4 is the reference's own noise, and each run's relMSE is printed as
measured and less that noise, the targets judged on the latter (a renderer with noisier samples
has a noisier reference, which alone kept Cycles above 0.002 on the beetle). Cycles' time is
bpy.ops.render.render's (its scene sync included), Spangle's the whole `spangle render`
process. Each reference uses other seeds than the runs (a run of N samples would otherwise
share its first N samples with it). Both cap an indirect sample's value
alike: CLAMP (default 10, Cycles' own default; 0: no cap, both unbiased, and then the scene's
sun-chrome-ground caustics make fireflies that dominate relMSE for both). Both regularise paths
alike: FILTER_GLOSSY (default 1, Cycles' default "Filter Glossy"; Spangle's [render]
filter_glossy follows the same curve; 0: off for both). Environment: SIZE (320x180), REF_SPP
(2048), THREADS (2), CLAMP, FILTER_GLOSSY. SEEDS=N measures efficiency instead: fixed 16, 64
and 256 spp, each renderer over N seeds, the mean relMSE (one seed's figure is ruled by a few
pixels where the sun's highlight is caught or missed), the mean time and 1 / (relMSE x time),
Spangle's by its whole process and by its render phase (renderTimeSeconds). Time it on a quiet
machine.

SCENE=beetle, SCENE=interior (spangle bench's procedural room) or SCENE=path/to/scene.toml
measures one of Spangle's own scenes instead: Spangle renders the file (time_to_quality.sh),
Cycles the Blender scene tests/bench/spangle_to_blender.py builds from it (its flake paints as
Blender's usual Voronoi glitter: not the same BRDF, so again each against its own reference);
the scene's own max_depth, clamp_indirect, filter_glossy and pixel filter go to both.
RENDERERS=cycles (or spangle) measures one renderer only.
"""

import glob
import hashlib
import inspect
import math
import os
import statistics
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "integrations", "blender"))
import bpy  # noqa: E402  (first: it puts Blender's own modules on the path)
import addon_utils  # noqa: E402
import mathutils  # noqa: E402


# The cap on one indirect sample's value, for both renderers (Cycles' sample_clamp_indirect,
# whose default is 10, and Spangle's [render] clamp_indirect); 0: none (both unbiased).
CLAMP = float(os.environ.get("CLAMP", "10"))
# Path regularisation, for both renderers alike: Cycles' blur_glossy ("Filter Glossy", default 1)
# and Spangle's [render] filter_glossy, which follows the same curve; 0: off for both.
FILTER_GLOSSY = float(os.environ.get("FILTER_GLOSSY", "1"))


def principled(name, color, roughness, metallic=0.0, coat=0.0, transmission=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = (*color, 1.0)
    b.inputs["Roughness"].default_value = roughness
    b.inputs["Metallic"].default_value = metallic
    b.inputs["Coat Weight"].default_value = coat
    b.inputs["Transmission Weight"].default_value = transmission
    return m


def build_car(width, height):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("spangle_blender", default_set=True)
    scene = bpy.context.scene
    paint = principled("paint", (0.6, 0.03, 0.03), 0.3, coat=1.0)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, location=(0, 0, 0.75))
    body = bpy.context.active_object
    body.scale = (2.2, 0.95, 0.62)
    body.modifiers.new("subdivision", "SUBSURF").levels = 2
    bpy.ops.object.shade_smooth()
    body.data.materials.append(paint)
    glass = principled("glass", (0.02, 0.02, 0.03), 0.05, metallic=0.0)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, location=(-0.2, 0, 1.15))
    cabin = bpy.context.active_object
    cabin.scale = (1.1, 0.8, 0.45)
    bpy.ops.object.shade_smooth()
    cabin.data.materials.append(glass)
    rubber = principled("rubber", (0.02, 0.02, 0.02), 0.7)
    chrome = principled("chrome", (0.9, 0.9, 0.9), 0.15, metallic=1.0)
    for x in (-1.3, 1.3):
        for y in (-0.85, 0.85):
            bpy.ops.mesh.primitive_torus_add(location=(x, y, 0.38), rotation=(math.pi / 2, 0, 0),
                                             major_radius=0.28, minor_radius=0.11)
            bpy.ops.object.shade_smooth()
            bpy.context.active_object.data.materials.append(rubber)
            bpy.ops.mesh.primitive_cylinder_add(location=(x, y, 0.38), rotation=(math.pi / 2, 0, 0),
                                                radius=0.2, depth=0.16)
            bpy.context.active_object.data.materials.append(chrome)
    bpy.ops.mesh.primitive_plane_add(size=40)
    bpy.context.active_object.data.materials.append(principled("ground", (0.35, 0.35, 0.35), 0.5))
    bpy.ops.object.light_add(type="SUN", location=(0, 0, 10))
    sun = bpy.context.active_object
    sun.data.energy = 3.0
    sun.data.angle = math.radians(2.0)
    sun.rotation_euler = (math.radians(45.0), 0.0, math.radians(35.0))
    bpy.ops.object.camera_add(location=(6.5, -5.5, 2.6))
    cam = bpy.context.active_object
    cam.rotation_euler = (mathutils.Vector((0, 0, 0.7)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.world = bpy.data.worlds.new("sky")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.45, 0.55, 0.75, 1.0)
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.8
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    c = scene.cycles
    c.max_bounces = 5
    c.sample_clamp_indirect = CLAMP
    c.blur_glossy = FILTER_GLOSSY
    c.sample_clamp_direct = 0.0
    return scene


def read_rgb(path):
    img = bpy.data.images.load(path, check_existing=False)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], -1)[..., :3]
    bpy.data.images.remove(img)
    return px


def rel_mse(x, r):
    return float(np.mean((x - r) ** 2 / (r * r + 0.01)))


def cycles_render(scene, path, samples, threshold=None, denoise=False):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = threshold is not None
    if threshold is not None:
        c.adaptive_threshold = threshold
        c.adaptive_min_samples = 0  # Cycles' automatic minimum
    c.use_denoising = denoise
    if denoise:
        c.denoiser = "OPENIMAGEDENOISE"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    return time.time() - t0


def report(label, results):
    for target in (0.01, 0.002):
        for way in dict.fromkeys(r[0] for r in results):
            hits = [(t, s) for w, s, t, e, c in results if w == way and c <= target]
            if hits:
                t, s = min(hits)
                print(f"{label}: {way} reached relMSE {target} in {t:.2f} s ({s})")
            else:
                print(f"{label}: {way} never reached relMSE {target}")


def spangle_render_time(path):
    """The render phase's seconds, from the EXR header's renderTimeSeconds."""
    info = subprocess.run(["oiiotool", "--info", "-v", path], capture_output=True, text=True).stdout
    for line in info.splitlines():
        if "renderTimeSeconds" in line:
            return float(line.split(":")[-1])
    return float("nan")


def efficiency(scene, build, folder, out, w, h, threads, seeds, r_cy):
    """Error per unit time at fixed sample counts, each renderer over `seeds` seeds: the mean
    relMSE (one seed's figure is dominated by a few highlight pixels, a heavy tail), the mean
    time, and 1 / (relMSE x time) with Spangle's render phase and its whole process; then the
    same by the median relMSE, which one rare sample does not move (a single sun-bright sample
    near a highlight made one seed's relMSE 18x the median's at 64 spp: with 16 seeds the
    mean moved by a factor of two from it alone)."""
    spangle_ref = os.path.join(out, "spangle", "ref_car_seeded.exr")
    r_sp = read_rgb(spangle_ref)
    print(f"# car at {w}x{h}, {seeds} seeds: spp, renderer, mean relMSE (min..max), mean s, efficiency")
    for spp in (16, 64, 256):
        sp_e, sp_t, sp_r, cy_e, cy_t = [], [], [], [], []
        for seed in range(1, seeds + 1):
            text = open(os.path.join(folder, "car.toml")).read().replace(
                "[render]\n", f"[render]\nseed = {seed}\n", 1)
            toml = os.path.join(folder, f"car_seed{seed}.toml")
            with open(toml, "w") as f:
                f.write(text)
            exr = os.path.join(out, f"eff_spangle_{spp}_{seed}.exr")
            t0 = time.time()
            subprocess.run([os.path.join(build, "spangle"), "render", toml, "--size", f"{w}x{h}",
                            "--spp", str(spp), "--threads", str(threads), "-q", "--float",
                            "--no-preview", "-o", exr], check=True)
            sp_t.append(time.time() - t0)
            sp_r.append(spangle_render_time(exr))
            sp_e.append(rel_mse(read_rgb(exr), r_sp))
            scene.cycles.seed = seed
            p = os.path.join(out, f"eff_cycles_{spp}_{seed}.exr")
            cy_t.append(cycles_render(scene, p, spp))
            cy_e.append(rel_mse(read_rgb(p), r_cy))
        scene.cycles.seed = 0
        mean = lambda v: sum(v) / len(v)  # noqa: E731
        e_sp, e_cy = mean(sp_e), mean(cy_e)
        eff_whole, eff_render = 1 / (e_sp * mean(sp_t)), 1 / (e_sp * mean(sp_r))
        eff_cy = 1 / (e_cy * mean(cy_t))
        print(f"{spp} spangle {e_sp:.6f} ({min(sp_e):.6f}..{max(sp_e):.6f}) whole {mean(sp_t):.3f} s "
              f"render {mean(sp_r):.3f} s: efficiency {eff_whole:.0f} whole, {eff_render:.0f} render")
        print(f"{spp} cycles {e_cy:.6f} ({min(cy_e):.6f}..{max(cy_e):.6f}) {mean(cy_t):.3f} s: "
              f"efficiency {eff_cy:.0f}")
        print(f"{spp} spangle / cycles: {eff_whole / eff_cy:.2f}x whole process, "
              f"{eff_render / eff_cy:.2f}x render phase")
        m_sp, m_cy = statistics.median(sp_e), statistics.median(cy_e)
        print(f"{spp} median relMSE: spangle {m_sp:.6f}, cycles {m_cy:.6f}; spangle / cycles: "
              f"{(m_cy * mean(cy_t)) / (m_sp * mean(sp_t)):.2f}x whole process, "
              f"{(m_cy * mean(cy_t)) / (m_sp * mean(sp_r)):.2f}x render phase")
        sys.stdout.flush()


def main():
    build, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    os.makedirs(out, exist_ok=True)
    w, h = (int(v) for v in os.environ.get("SIZE", "320x180").split("x"))
    ref_spp = int(os.environ.get("REF_SPP", "2048"))
    threads = int(os.environ.get("THREADS", "2"))
    name = os.environ.get("SCENE", "car")
    if name != "car":
        main_scene(build, out, w, h, ref_spp, threads, spangle_scene(name, build, out))
        sys.stdout.flush()
        os._exit(0)
    scene = build_car(w, h)
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    # Spangle: the add-on's export, then the shell script's sweep.
    from spangle_blender import export, flake_parameters

    folder = os.path.join(out, "car")
    os.makedirs(folder, exist_ok=True)
    export.export_scene(bpy.context.evaluated_depsgraph_get(), folder, (w, h), 16,
                        flake_parameters())
    text = open(os.path.join(folder, "scene.toml")).read()
    if CLAMP > 0.0:
        text = text.replace("[render]\n", f"[render]\nclamp_indirect = {CLAMP}\n", 1)
    if FILTER_GLOSSY > 0.0:
        text = text.replace("[render]\n", f"[render]\nfilter_glossy = {FILTER_GLOSSY}\n", 1)
    with open(os.path.join(folder, "car.toml"), "w") as f:
        f.write(text)
    os.remove(os.path.join(folder, "scene.toml"))
    env = dict(os.environ, SIZE=f"{w}x{h}", REF_SPP=str(ref_spp), THREADS=str(threads))
    # Each reference with another seed than the runs measured against it: a run of N samples
    # would otherwise share its first N samples with the reference (for both renderers).
    spangle_out = os.path.join(out, "spangle")
    os.makedirs(spangle_out, exist_ok=True)
    # The cached reference holds for one scene text, size, sample count and build: another (a
    # filter exported differently, a plugin rebuilt) renders it again. It is SEEDS mode's, of
    # another seed than the runs; time_to_quality.sh keeps its own (ref_car.exr).
    key = hashlib.sha256(open(os.path.join(folder, "car.toml"), "rb").read())
    key.update(f"{w}x{h} {ref_spp}".encode())
    for f in [os.path.join(build, "spangle")] + sorted(glob.glob(os.path.join(build, "plugins", "*.so"))):
        st = os.stat(f)
        key.update(f"{f} {st.st_size} {st.st_mtime_ns}".encode())
    key_file = os.path.join(spangle_out, "ref_car_seeded.key")
    if not os.path.exists(key_file) or open(key_file).read() != key.hexdigest():
        for stale in (os.path.join(spangle_out, "ref_car_seeded.exr"), key_file):
            if os.path.exists(stale):
                os.remove(stale)
    if not os.path.exists(os.path.join(spangle_out, "ref_car_seeded.exr")):
        text = open(os.path.join(folder, "car.toml")).read().replace("[render]\n", "[render]\nseed = 977\n", 1)
        with open(os.path.join(folder, "car_ref.toml"), "w") as f:
            f.write(text)
        print(f"# spangle: rendering the reference ({ref_spp} spp)...", file=sys.stderr)
        subprocess.run([os.path.join(build, "spangle"), "render", os.path.join(folder, "car_ref.toml"),
                        "--size", f"{w}x{h}", "--spp", str(ref_spp), "--threads", str(threads),
                        "-q", "--float", "--no-preview", "-o", os.path.join(spangle_out, "ref_car_seeded.exr")],
                       check=True)
        with open(key_file, "w") as f:
            f.write(key.hexdigest())
    r_cy, noise = cycles_reference(scene, out, "car", ref_spp,
                                   inspect.getsource(build_car) + f" {CLAMP} {FILTER_GLOSSY}")
    seeds = int(os.environ.get("SEEDS", "0"))
    if seeds > 0:
        efficiency(scene, build, folder, out, w, h, threads, seeds, r_cy)
        sys.stdout.flush()
        os._exit(0)
    subprocess.run(["bash", os.path.join(ROOT, "tests", "bench", "time_to_quality.sh"), build,
                    spangle_out, os.path.join(folder, "car.toml")],
                   env=env, check=True)
    cycles_sweep(scene, out, "car", r_cy, noise, w, h)
    sys.stdout.flush()
    os._exit(0)  # bpy's exit handlers can crash once add-ons registered classes


def cycles_reference(scene, out, label, ref_spp, describe):
    """Cycles' reference: two halves of ref_spp / 2 samples with their own seeds (977, 978),
    averaged, and its own noise in relMSE (the halves' relMSE against each other / 4), which
    the sweep takes off each run's. Cached under a key of `describe` (the scene), the size, the
    sample count, this bpy and the importer."""
    key = hashlib.sha256(describe.encode())
    key.update(f"{scene.render.resolution_x}x{scene.render.resolution_y} {ref_spp} "
               f"{bpy.app.version_string}".encode())
    with open(os.path.join(ROOT, "tests", "bench", "spangle_to_blender.py"), "rb") as f:
        key.update(f.read())
    halves = [os.path.join(out, f"cycles_ref_{label}_{seed}.exr") for seed in (977, 978)]
    key_file = os.path.join(out, f"cycles_ref_{label}.key")
    cached = os.path.exists(key_file) and open(key_file).read() == key.hexdigest()
    if not (cached and all(os.path.exists(p) for p in halves)):
        print(f"# cycles: rendering the reference of {label} ({ref_spp} spp, two seeds)...",
              file=sys.stderr)
        for seed, p in zip((977, 978), halves):
            scene.cycles.seed = seed
            cycles_render(scene, p, max(1, ref_spp // 2))
        scene.cycles.seed = 0
        with open(key_file, "w") as f:
            f.write(key.hexdigest())
    a, b = read_rgb(halves[0]), read_rgb(halves[1])
    return 0.5 * (a + b), rel_mse(a, b) / 4.0


def cycles_sweep(scene, out, label, r, noise, w, h):
    """Cycles at fixed samples and at falling adaptive thresholds, each denoised too when this
    bpy has Open Image Denoise; prints every run (its relMSE, and that less the reference's
    noise) and the time each way reached the targets."""
    probe = os.path.join(out, "cycles_probe.exr")
    cycles_render(scene, probe, 4)
    plain = read_rgb(probe)
    cycles_render(scene, probe, 4, denoise=True)
    has_denoiser = not np.array_equal(read_rgb(probe), plain)
    if not has_denoiser:
        print("# cycles: this bpy build has no Open Image Denoise: no denoised runs", file=sys.stderr)
    prefix = "" if label == "car" else f"{label}_"
    results = []
    print(f"# {label} at {w}x{h}, cycles: reference noise (relMSE) {noise:.6f}")
    print(f"# {label} at {w}x{h}, cycles: way, setting, seconds, relMSE, relMSE - reference noise")
    for spp in (4, 8, 16, 32, 64, 128, 256, 512):
        for denoise in (False, True) if has_denoiser else (False,):
            p = os.path.join(out, f"cycles_{prefix}fixed_{spp}{'_dn' if denoise else ''}.exr")
            t = cycles_render(scene, p, spp, denoise=denoise)
            way = "fixed+denoise" if denoise else "fixed"
            e = rel_mse(read_rgb(p), r)
            results.append((way, spp, t, e, e - noise))
            print(f"{way} {spp} {t:.3f} {e:.6f} {e - noise:.6f}")
            sys.stdout.flush()
    for threshold in (0.2, 0.1, 0.05, 0.03, 0.02, 0.01, 0.005):
        for denoise in (False, True) if has_denoiser else (False,):
            p = os.path.join(out, f"cycles_{prefix}adaptive_{threshold}{'_dn' if denoise else ''}.exr")
            t = cycles_render(scene, p, 1024, threshold=threshold, denoise=denoise)
            way = "adaptive+denoise" if denoise else "adaptive"
            e = rel_mse(read_rgb(p), r)
            results.append((way, threshold, t, e, e - noise))
            print(f"{way} {threshold} {t:.3f} {e:.6f} {e - noise:.6f}")
            sys.stdout.flush()
    report(f"{label} (cycles)", results)


def spangle_scene(name, build, out):
    """The file of another scene than the car: SCENE is `beetle`, `interior` (spangle bench's
    procedural room, written into OUT) or a Spangle scene file; Cycles renders it as
    tests/bench/spangle_to_blender.py builds it, Spangle renders the file itself (its flakes
    included, which the Blender scene draws as a Voronoi glitter)."""
    if name == "beetle":
        return os.path.join(ROOT, "assets", "scenes", "beetle.toml")
    if name == "interior":
        folder = os.path.join(out, "interior")
        subprocess.run([os.path.join(build, "spangle"), "bench", "--write-scene", folder],
                       check=True, stdout=subprocess.DEVNULL)
        return os.path.join(folder, "interior.toml")
    return os.path.abspath(name)


def main_scene(build, out, w, h, ref_spp, threads, path):
    import spangle_to_blender

    label = os.path.splitext(os.path.basename(path))[0]
    levels = spangle_to_blender.subdivision_levels(os.path.join(build, "spangle"), path, w, h)
    scene = spangle_to_blender.build(path, w, h, levels)
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    env = dict(os.environ, SIZE=f"{w}x{h}", REF_SPP=str(ref_spp), THREADS=str(threads))
    spangle_out = os.path.join(out, "spangle")
    os.makedirs(spangle_out, exist_ok=True)
    with open(path) as f:
        describe = f.read() + repr(sorted(levels.items()))
    # RENDERERS=cycles or spangle measures one of them (the other's figures from an earlier
    # run stand).
    renderers = os.environ.get("RENDERERS", "spangle cycles").split()
    if "spangle" in renderers:
        subprocess.run(["bash", os.path.join(ROOT, "tests", "bench", "time_to_quality.sh"), build,
                        spangle_out, path], env=env, check=True)
    if "cycles" in renderers:
        r, noise = cycles_reference(scene, out, label, ref_spp, describe)
        cycles_sweep(scene, out, label, r, noise, w, h)


if __name__ == "__main__":
    main()
