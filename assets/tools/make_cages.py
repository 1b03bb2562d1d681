#!/usr/bin/env python3
"""Writes the Catmull-Clark control cages in assets/meshes/: a toy VW-Beetle-like car and a
snowman, each as several OBJ files (one per material), with face-varying uvs.

    python3 assets/tools/make_cages.py

Every part is built from a few cage primitives: cube-spheres (a cube of n x n quads per face whose
vertices are pushed onto a shape; each cube face is its own uv tile, so uv seams run along the
cube's edges), tori, capped cylinders (n-gon caps: extraordinary vertices) and cones. Faces wind
counter-clockwise seen from outside.
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "meshes")

# Cube faces as (normal, u axis, v axis) with u x v = normal.
CUBE = [((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
        ((0, 1, 0), (0, 0, 1), (1, 0, 0)), ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
        ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (0, 1, 0), (1, 0, 0))]


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def scale(a, s):
    return tuple(x * s for x in a)


def norm(a):
    n = math.sqrt(sum(x * x for x in a))
    return tuple(x / n for x in a)


class Cage:
    def __init__(self):
        self.v, self.vt, self.f = [], [], []

    def vert(self, p):
        self.v.append(tuple(p))
        return len(self.v) - 1

    def uv(self, t):
        self.vt.append(tuple(t))
        return len(self.vt) - 1

    def face(self, vs, ts):
        self.f.append(list(zip(vs, ts)))

    def add(self, other):
        ov, ot = len(self.v), len(self.vt)
        self.v += other.v
        self.vt += other.vt
        self.f += [[(a + ov, b + ot) for a, b in face] for face in other.f]
        return self

    def transformed(self, fn):
        c = Cage()
        c.v, c.vt, c.f = [tuple(fn(p)) for p in self.v], list(self.vt), [list(f) for f in self.f]
        return c

    def write(self, name, comment):
        with open(os.path.join(OUT, name), "w") as out:
            out.write(f"# {comment}\n# {len(self.v)} vertices, {len(self.f)} faces; made by assets/tools/make_cages.py\n")
            for p in self.v:
                out.write("v %.5f %.5f %.5f\n" % p)
            for t in self.vt:
                out.write("vt %.5f %.5f\n" % t)
            for face in self.f:
                out.write("f " + " ".join(f"{a + 1}/{b + 1}" for a, b in face) + "\n")


def cube_sphere(n, shape, keep=None, tile0=0):
    """A cube of n x n quads per face, its lattice points mapped by shape(direction)."""
    c, index = Cage(), {}
    for fi, (nrm, u, v) in enumerate(CUBE):
        grid_uv = {}
        for a in range(n + 1):
            for b in range(n + 1):
                p = add(nrm, add(scale(u, 2 * a / n - 1), scale(v, 2 * b / n - 1)))
                key = tuple(round(x * n) for x in p)
                if key not in index:
                    index[key] = c.vert(shape(norm(p)))
                grid_uv[a, b] = c.uv((tile0 + fi + a / n, b / n))
        for a in range(n):
            for b in range(n):
                corners = [(a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)]
                centre = norm(add(nrm, add(scale(u, (2 * a + 1) / n - 1), scale(v, (2 * b + 1) / n - 1))))
                if keep and not keep(centre):
                    continue
                vs = [index[tuple(round(x * n) for x in add(nrm, add(scale(u, 2 * i / n - 1), scale(v, 2 * j / n - 1))))]
                      for i, j in corners]
                c.face(vs, [grid_uv[k] for k in corners])
    if keep:  # drop vertices no kept face uses, so the open shell has no strays
        used = sorted({a for f in c.f for a, _ in f})
        remap = {old: new for new, old in enumerate(used)}
        c.v = [c.v[i] for i in used]
        c.f = [[(remap[a], b) for a, b in f] for f in c.f]
    return c


def sphere(r, centre, n=3):
    return cube_sphere(n, lambda d: add(centre, scale(d, r)))


def ellipsoid(radii, centre, n=3):
    return cube_sphere(n, lambda d: add(centre, tuple(x * k for x, k in zip(d, radii))))


def torus(R, r, centre, axis="y", nu=16, nv=8):
    """A torus around `axis` through `centre`."""
    c = Cage()
    idx = {}
    for i in range(nu):
        for j in range(nv):
            a, b = 2 * math.pi * i / nu, 2 * math.pi * j / nv
            x, y, z = (R + r * math.cos(b)) * math.cos(a), r * math.sin(b), (R + r * math.cos(b)) * math.sin(a)
            p = {"y": (x, y, z), "z": (x, z, y), "x": (y, x, z)}[axis]
            idx[i, j] = c.vert(add(centre, p))
    uvs = {(i, j): c.uv((i / nu, j / nv)) for i in range(nu + 1) for j in range(nv + 1)}
    flip = axis == "z"  # swapping two axes mirrors the surface: keep faces outward
    for i in range(nu):
        for j in range(nv):
            q = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)]
            if flip:
                q = q[::-1]
            c.face([idx[a % nu, b % nv] for a, b in q], [uvs[a, b] for a, b in q])
    return c


def cylinder(radius, y0, y1, centre_xz, n=12, rings=2, taper=1.0):
    """A capped cylinder along +y, radius scaled by `taper` at the top; n-gon caps."""
    c = Cage()
    ring = []
    for k in range(rings + 1):
        t = k / rings
        r = radius * (1 + (taper - 1) * t)
        y = y0 + (y1 - y0) * t
        ring.append([c.vert((centre_xz[0] + r * math.cos(2 * math.pi * i / n), y, centre_xz[1] + r * math.sin(2 * math.pi * i / n)))
                     for i in range(n)])
    uvs = {(i, k): c.uv((i / n, 0.25 + 0.5 * k / rings)) for i in range(n + 1) for k in range(rings + 1)}
    for k in range(rings):
        for i in range(n):
            q = [(i, k), (i, k + 1), (i + 1, k + 1), (i + 1, k)]
            c.face([ring[b][a % n] for a, b in q], [uvs[a, b] for a, b in q])
    cap = [c.uv((0.5 + 0.2 * math.cos(2 * math.pi * i / n), 0.1 + 0.08 * math.sin(2 * math.pi * i / n))) for i in range(n)]
    c.face(list(ring[0]), cap)                        # bottom, seen from below: counter-clockwise
    c.face(list(reversed(ring[rings])), cap[::-1])    # top
    return c


def cone(radius, length, base, direction, n=8):
    """A cone from `base` along unit `direction`, with an n-gon base and a triangle fan."""
    c = Cage()
    d = norm(direction)
    s = norm((d[1], -d[0], 0.0) if abs(d[2]) < 0.9 else (0.0, d[2], -d[1]))
    t = (d[1] * s[2] - d[2] * s[1], d[2] * s[0] - d[0] * s[2], d[0] * s[1] - d[1] * s[0])
    ring = [c.vert(add(base, add(scale(s, radius * math.cos(2 * math.pi * i / n)), scale(t, radius * math.sin(2 * math.pi * i / n)))))
            for i in range(n)]
    tip = c.vert(add(base, scale(d, length)))
    uvs = [c.uv((i / n, 0.0)) for i in range(n + 1)]
    top = c.uv((0.5, 1.0))
    for i in range(n):
        c.face([ring[i], ring[(i + 1) % n], tip], [uvs[i], uvs[i + 1], top])
    c.face(list(reversed(ring)), [uvs[i] for i in reversed(range(n))])
    return c


def patch(fn, nu, nv, flip=False):
    """A rectangular grid of nu x nv quads at points fn(u, v), u, v in [0, 1]; uv = (u, v)."""
    c = Cage()
    vid = {(i, j): c.vert(fn(i / nu, j / nv)) for i in range(nu + 1) for j in range(nv + 1)}
    tid = {(i, j): c.uv((i / nu, j / nv)) for i in range(nu + 1) for j in range(nv + 1)}
    for i in range(nu):
        for j in range(nv):
            q = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
            if flip:
                q = q[::-1]
            c.face([vid[k] for k in q], [tid[k] for k in q])
    return c


# ------------------------------------------------------------------------------------ snowman

def snowman():
    body = sphere(0.75, (0, 0.72, 0)).add(sphere(0.55, (0, 1.78, 0))).add(sphere(0.38, (0, 2.55, 0)))
    body.write("snowman_body.obj", "snowman: three snowballs")
    hat = cylinder(0.42, 2.83, 2.87, (0, 0), n=16, rings=1).add(cylinder(0.26, 2.85, 3.3, (0, 0), n=16, rings=3, taper=1.05))
    hat.write("snowman_hat.obj", "snowman: top hat (brim and crown)")
    cone(0.055, 0.38, (0, 2.56, 0.34), (0, -0.08, 1)).write("snowman_nose.obj", "snowman: carrot nose")
    coal = Cage()
    for x in (-0.13, 0.13):
        coal.add(sphere(0.045, (x, 2.66, 0.33), n=1))
    for y, z in ((1.95, 0.52), (1.72, 0.55), (1.49, 0.5)):
        coal.add(sphere(0.05, (0, y, z), n=1))
    coal.write("snowman_coal.obj", "snowman: coal eyes and buttons")
    scarf = torus(0.36, 0.085, (0, 2.22, 0), "y", nu=20, nv=8)
    scarf.add(ellipsoid((0.09, 0.32, 0.035), (0.22, 1.98, 0.36), n=2))
    scarf.write("snowman_scarf.obj", "snowman: scarf around the neck and its hanging end")


# ------------------------------------------------------------------------------------ beetle

def beetle_shape(d):
    """The body: one rounded shell whose roof line rises from a low hood to a high cabin and falls
    to the rear (the Beetle's arc), with a flat floor and sides drawn in towards the roof."""
    x, y, z = d
    length, half_width, floor = 2.0, 0.82, 0.75
    px = length * x
    if y < 0:
        py = 0.3 * y
    else:
        roof = 0.32 + 0.78 * math.exp(-((x + 0.12) / 0.62) ** 2)  # height of the arc along the car
        py = roof * y
    pz = half_width * z * (1.0 - 0.34 * max(0.0, y) ** 2)
    return (px, floor + py, pz)


def beetle():
    body = cube_sphere(6, beetle_shape)
    body.write("beetle_body.obj", "beetle: body shell (car paint)")
    # Windows: the cabin part of a slightly larger shell, an open surface with a boundary.
    # Windows: four curved rectangles on the cabin (two sides, windscreen, rear window). Each is
    # a quad grid in its own parameters, mapped onto the body and lifted 1.2% off it, so its
    # border is a smooth curve rather than the staircase of whole cage faces.
    c = (0.0, 0.75, 0.0)
    lift = lambda d: add(c, scale(add(beetle_shape(norm(d)), scale(c, -1)), 1.012))
    glass = Cage()
    for side in (-1, 1):  # side windows: x along the cabin, y up the side
        glass.add(patch(lambda u, v, s=side: lift((-0.52 + 0.7 * u, 0.36 + 0.44 * v, s * 0.9)), 8, 3, flip=side < 0))
    glass.add(patch(lambda u, v: lift((0.3 + 0.24 * v, 0.52 + 0.3 * v, -0.7 + 1.4 * u)), 8, 3))   # windscreen
    glass.add(patch(lambda u, v: lift((-0.62 - 0.2 * v, 0.42 + 0.3 * v, 0.6 - 1.2 * u)), 8, 3))    # rear window
    glass.write("beetle_windows.obj", "beetle: side windows, windscreen and rear window (open patches)")
    fenders = Cage()
    for x in (-1.25, 1.25):
        for z in (-0.7, 0.7):
            fenders.add(ellipsoid((0.56, 0.42, 0.24), (x, 0.66, z), n=3))
    fenders.write("beetle_fenders.obj", "beetle: four fenders")
    boards = Cage()
    for z in (-0.82, 0.82):
        boards.add(ellipsoid((0.75, 0.045, 0.12), (0.0, 0.47, z), n=2))
    boards.write("beetle_boards.obj", "beetle: running boards")
    tyres, hubs = Cage(), Cage()
    for x in (-1.25, 1.25):
        for z in (-0.72, 0.72):
            tyres.add(torus(0.25, 0.11, (x, 0.36, z), "z", nu=16, nv=8))
            hubs.add(ellipsoid((0.16, 0.16, 0.05), (x, 0.36, z + (0.06 if z > 0 else -0.06)), n=2))
    tyres.write("beetle_tyres.obj", "beetle: tyres")
    hubs.write("beetle_hubcaps.obj", "beetle: hubcaps")
    lamps = Cage()
    for z in (-0.68, 0.68):
        lamps.add(ellipsoid((0.08, 0.12, 0.12), (1.7, 0.86, z), n=2))
    lamps.write("beetle_headlights.obj", "beetle: round headlights")


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    snowman()
    beetle()
