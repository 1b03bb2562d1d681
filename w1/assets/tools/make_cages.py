#!/usr/bin/env python3
"""Writes the Catmull-Clark control cages in assets/meshes/: a toy VW Beetle and a
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
# A toy VW Beetle, 4 m long (x forward, y up, z to the car's left), standing on y = 0: a round
# body whose roof line rises from a short, low hood to a domed cabin and falls in one curve to
# the engine lid; four separate round fenders over the wheels (the front ones carrying the round
# headlights), running boards between them, chrome bumper blades with overriders, chrome
# hubcaps, tail lights, and windows set into the cabin.

WHEEL_X, WHEEL_Y, WHEEL_Z = 1.2, 0.33, 0.70   # wheel centres (x = +-1.2: a 2.4 m wheelbase)

# The box faces as (axis, sign, u axis, v axis) with u x v pointing out.
BOX = [(0, 1, 1, 2), (0, -1, 2, 1), (1, 1, 2, 0), (1, -1, 0, 2), (2, 1, 0, 1), (2, -1, 1, 0)]


def box_lattice(counts, fn, tile0=0):
    """The surface of the box [-1, 1]^3 cut into counts = (nx, ny, nz) cells per axis, each
    lattice point P mapped to fn(P); each box face is its own uv tile."""
    c, index = Cage(), {}
    for fi, (ax, sign, ua, va) in enumerate(BOX):
        nu, nv = counts[ua], counts[va]
        uvid = {}
        for i in range(nu + 1):
            for j in range(nv + 1):
                key = [0, 0, 0]
                key[ax] = counts[ax] if sign > 0 else 0
                key[ua], key[va] = i, j
                key = tuple(key)
                if key not in index:
                    index[key] = c.vert(fn(tuple(2.0 * key[k] / counts[k] - 1.0 for k in range(3))))
                uvid[i, j] = c.uv((tile0 + fi + i / nu, j / nv))
        for i in range(nu):
            for j in range(nv):
                q = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
                vs = []
                for a, b in q:
                    key = [0, 0, 0]
                    key[ax] = counts[ax] if sign > 0 else 0
                    key[ua], key[va] = a, b
                    vs.append(index[tuple(key)])
                c.face(vs, [uvid[k] for k in q])
    return c


def rounded(p, power):
    """A point of the box surface pushed onto the rounded box |x|^p + |y|^p + |z|^p = 1."""
    n = sum(abs(x) ** power for x in p) ** (1.0 / power)
    return tuple(x / n for x in p)


def spline(points, x):
    """Catmull-Rom interpolation through (x, y) points sorted by x, clamped at the ends."""
    if x <= points[0][0]:
        return points[0][1]
    if x >= points[-1][0]:
        return points[-1][1]
    for k in range(len(points) - 1):
        x0, x1 = points[k][0], points[k + 1][0]
        if x0 <= x <= x1:
            t = (x - x0) / (x1 - x0)
            p0 = points[max(k - 1, 0)][1]
            p1, p2 = points[k][1], points[k + 1][1]
            p3 = points[min(k + 2, len(points) - 1)][1]
            return 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t * t
                          + (-p0 + 3 * p1 - 3 * p2 + p3) * t ** 3)


def smoothstep(t):
    t = min(1.0, max(0.0, t))
    return t * t * (3 - 2 * t)


# The roof line, front (x = 1.95) to rear (x = -2.0): nose, hood, windscreen, dome, engine lid.
ROOF = [(-2.0, 0.58), (-1.75, 0.84), (-1.35, 1.06), (-0.95, 1.30), (-0.5, 1.47), (-0.05, 1.52),
        (0.3, 1.45), (0.62, 1.08), (0.95, 1.0), (1.5, 0.92), (1.95, 0.70)]
BODY_X0, BODY_X1, FLOOR, BELT = -2.0, 1.95, 0.30, 0.97


def body_half_width(x, y):
    """Half the body's width at (x, y): narrower towards the nose and the tail (seen from above),
    and drawn in above the belt line towards the roof (the cabin's tumblehome)."""
    low = 0.64 - 0.12 * max(0.0, (x - 0.8) / 1.15) ** 2 - 0.07 * max(0.0, (-x - 0.9) / 1.1) ** 2
    top = max(spline(ROOF, x), BELT + 0.05)
    return low - (low - 0.47) * smoothstep((y - BELT) / (top - BELT)) ** 1.2


def body_point(p):
    """A point of the box lattice onto the body: rounded box, then the Beetle's profile."""
    q = rounded(p, 2.6)
    x = BODY_X0 + (q[0] + 1) / 2 * (BODY_X1 - BODY_X0)
    y = FLOOR + (q[1] + 1) / 2 * (spline(ROOF, x) - FLOOR)
    return (x, y, q[2] * body_half_width(x, y))


BODY_COUNTS = (12, 6, 6)


def on_body(face, target, lift):
    """The body point of box face `face` = (axis, sign) whose mapped coordinates on the two
    other axes equal `target` (a dict axis -> value), lifted by `lift` along the outward normal
    estimated from the mapping; solved by Newton's method with finite differences."""
    ax, sign = face
    free = [k for k in range(3) if k != ax]
    st = [0.0, 0.0]
    for _ in range(30):
        def mapped(s):
            p = [0.0, 0.0, 0.0]
            p[ax] = float(sign)
            p[free[0]], p[free[1]] = s
            return body_point(p)
        m = mapped(st)
        err = [m[k] - target[k] for k in free]
        if abs(err[0]) + abs(err[1]) < 1e-7:
            break
        h = 1e-5
        ja = [(mapped([st[0] + h, st[1]])[k] - m[k]) / h for k in free]
        jb = [(mapped([st[0], st[1] + h])[k] - m[k]) / h for k in free]
        det = ja[0] * jb[1] - jb[0] * ja[1]
        st = [min(1.0, max(-1.0, st[0] - (err[0] * jb[1] - jb[0] * err[1]) / det)),
              min(1.0, max(-1.0, st[1] - (ja[0] * err[1] - err[0] * ja[1]) / det))]
    m = mapped(st)
    h = 1e-4
    ta = [a - b for a, b in zip(mapped([st[0] + h, st[1]]), mapped([st[0] - h, st[1]]))]
    tb = [a - b for a, b in zip(mapped([st[0], st[1] + h]), mapped([st[0], st[1] - h]))]
    n = norm((ta[1] * tb[2] - ta[2] * tb[1], ta[2] * tb[0] - ta[0] * tb[2], ta[0] * tb[1] - ta[1] * tb[0]))
    out = [0.0, 0.0, 0.0]
    out[ax] = float(sign)
    if sum(a * b for a, b in zip(n, out)) < 0:
        n = scale(n, -1)
    return add(m, scale(n, lift))


def arch_point(p, wheel_x, side, front):
    """A point of a box lattice onto a fender: an arch over the wheel, thick at its crown and
    thin at its ends, bulging out sideways; the front fenders reach further forward and down
    (where the headlight and the bumper sit), the rear ones further back."""
    q = rounded(p, 2.4)
    t = (1 - q[0]) / 2                      # 0 at the fender's front end, 1 at its rear end
    a0, a1 = (-12.0, 192.0) if front else (-14.0, 196.0)
    ang = math.radians(a0 + t * (a1 - a0))
    crown = math.sin(math.pi * t)           # 0 at the ends, 1 over the wheel
    r_in = 0.40
    r_out = 0.44 + 0.15 * crown + (0.07 * (1 - t) if front else 0.07 * t)
    r = r_in + (q[1] + 1) / 2 * (r_out - r_in)
    half = 0.10 + 0.09 * crown ** 0.6
    x = wheel_x + r * math.cos(ang)
    y = WHEEL_Y + r * math.sin(ang)
    z = side * (WHEEL_Z - 0.05 + q[2] * half)
    return (x, max(y, 0.17), z)


def oriented(cage, origin, axis):
    """`cage`, built around the +y axis at the origin, turned so +y runs along unit `axis` and
    moved to `origin`."""
    d = norm(axis)
    s = norm((d[1], -d[0], 0.0) if abs(d[2]) < 0.9 else (0.0, d[2], -d[1]))
    t = (d[1] * s[2] - d[2] * s[1], d[2] * s[0] - d[0] * s[2], d[0] * s[1] - d[1] * s[0])
    return cage.transformed(lambda p: add(origin, add(scale(s, p[0]), add(scale(d, p[1]), scale(t, p[2])))))


def blade(x_centre, depth, half_span, y0, y1, curve):
    """A bumper blade across the car at x_centre, swept back by `curve` at its ends."""
    sgn = 1 if x_centre > 0 else -1

    def fn(p):
        q = rounded(p, 4.0)
        z = q[2] * half_span
        x = x_centre + sgn * (q[0] * depth - curve * (z / half_span) ** 2)
        return (x, y0 + (q[1] + 1) / 2 * (y1 - y0), z)
    return box_lattice((1, 2, 10), fn)


def beetle():
    body = box_lattice(BODY_COUNTS, body_point)
    body.write("beetle_body.obj", "beetle: body shell (glitter paint)")

    # Windows: quad grids on the cabin, each point solved onto the body and lifted 1.5 cm.
    glass = Cage()
    lift = 0.015
    for side in (-1, 1):
        def front_window(u, v, side=side):   # the door window: slanted front edge (A pillar)
            y = BELT + 0.07 + v * 0.33
            x = (0.52 - 0.2 * v) * (1 - u) + (-0.05) * u
            y = min(y, spline(ROOF, x) - 0.09)
            return on_body((2, side), {0: x, 1: y}, lift)

        def rear_window(u, v, side=side):    # the rear quarter window: curved rear edge
            y = BELT + 0.07 + v * 0.31
            x = (-0.15) * (1 - u) + (-0.86 + 0.26 * v ** 0.7) * u
            y = min(y, spline(ROOF, x) - 0.09)
            return on_body((2, side), {0: x, 1: y}, lift)
        glass.add(patch(front_window, 6, 3, flip=side < 0))
        glass.add(patch(rear_window, 6, 3, flip=side < 0))
    # The windscreen on the top face: x along the glass, z across; its corners rounded in.
    glass.add(patch(lambda u, v: on_body((1, 1), {0: 0.59 - 0.26 * v, 2: (2 * u - 1) * (0.43 - 0.05 * v)}, lift), 8, 3, flip=True))
    # The small oval rear window.
    glass.add(patch(lambda u, v: on_body((1, 1), {0: -0.84 - 0.2 * v, 2: (2 * u - 1) * 0.3 * (1 - 0.35 * (2 * v - 1) ** 2)}, lift), 6, 3))
    glass.write("beetle_windows.obj", "beetle: door and quarter windows, windscreen, rear window (open patches)")

    fenders = Cage()
    for wx, front in ((WHEEL_X, True), (-WHEEL_X, False)):
        for side in (-1, 1):
            f = box_lattice((8, 2, 3), lambda p, wx=wx, side=side, front=front: arch_point(p, wx, side, front))
            if side < 0:   # mirrored: reverse each face to keep it facing out
                f.f = [fc[::-1] for fc in f.f]
            fenders.add(f)
    fenders.write("beetle_fenders.obj", "beetle: four round fenders")

    boards = Cage()
    for side in (-1, 1):
        b = box_lattice((6, 1, 2), lambda p, side=side: (
            rounded(p, 5.0)[0] * 0.62, 0.235 + rounded(p, 5.0)[1] * 0.03, side * (0.73 + rounded(p, 5.0)[2] * 0.13)))
        if side < 0:
            b.f = [fc[::-1] for fc in b.f]
        boards.add(b)
    boards.write("beetle_boards.obj", "beetle: running boards")

    tyres, hubs, rims = Cage(), Cage(), Cage()
    for x in (-WHEEL_X, WHEEL_X):
        for side in (-1, 1):
            z = side * WHEEL_Z
            tyres.add(torus(0.235, 0.095, (x, WHEEL_Y, z), "z", nu=16, nv=8))
            rims.add(ellipsoid((0.2, 0.2, 0.07), (x, WHEEL_Y, z + side * 0.02), n=2))
            hubs.add(ellipsoid((0.12, 0.12, 0.055), (x, WHEEL_Y, z + side * 0.075), n=2))
    tyres.write("beetle_tyres.obj", "beetle: tyres")
    rims.write("beetle_rims.obj", "beetle: painted wheel rims")
    hubs.write("beetle_hubcaps.obj", "beetle: chrome hubcaps")

    chrome = Cage()
    chrome.add(blade(2.03, 0.035, 0.86, 0.36, 0.46, 0.16))       # front bumper
    chrome.add(blade(-2.06, 0.035, 0.86, 0.36, 0.46, 0.16))      # rear bumper
    for x in (2.0, -2.03):                                       # overriders
        for z in (-0.42, 0.42):
            chrome.add(ellipsoid((0.04, 0.13, 0.035), (x + (0.02 if x > 0 else -0.02), 0.47, z), n=2))
    lamp_axis = (1.0, 0.1, 0.0)
    lamps, buckets = Cage(), Cage()
    for side in (-1, 1):
        centre = (1.66, 0.80, side * 0.655)
        # The bucket, a round housing out of the fender's nose, in the body's paint.
        buckets.add(oriented(cylinder(0.14, -0.3, 0.0, (0, 0), n=12, rings=2, taper=0.92), centre, lamp_axis))
        chrome.add(oriented(torus(0.128, 0.024, (0, 0.0, 0), "y", nu=16, nv=6), centre, lamp_axis))
        lamps.add(oriented(ellipsoid((0.12, 0.05, 0.12), (0, 0.0, 0)), centre, lamp_axis))
    chrome.write("beetle_chrome.obj", "beetle: bumper blades, overriders and headlight rims")
    lamps.write("beetle_headlights.obj", "beetle: round headlight lenses")
    buckets.write("beetle_lamp_buckets.obj", "beetle: headlight housings on the front fenders")
    tail = Cage()
    for side in (-1, 1):
        tail.add(ellipsoid((0.05, 0.1, 0.06), (-1.72, 0.68, side * 0.68), n=2))
    tail.write("beetle_taillights.obj", "beetle: tail lights")


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    snowman()
    beetle()
