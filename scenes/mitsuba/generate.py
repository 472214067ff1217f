#!/usr/bin/env python3
"""Writes the three scenes of scenes/mitsuba/ that plexus makes itself, as Mitsuba 0.6 XML with
their meshes (see LICENSES.md there):

- cornell-box/: the Cornell box from the measurements the Cornell University Program of Computer
  Graphics publishes (https://www.graphics.cornell.edu/online/box/data.html): its geometry in
  millimetres, the reflectance spectra of its white, red and green surfaces and its light's
  emission spectrum. As in the variant of Mueller, Gross and Novak ("Practical Path Guiding for
  Efficient Light-Transport Simulation", 2017), the light quad is turned over (it faces the
  ceiling, 77.6 mm below it, so the box is lit by the ceiling) and emits twice the measured
  spectrum; the blocks are closed by their bottom faces.
- torus/: caustics on a floor under the sun: a glass torus standing on the floor, a diffuse torus
  lying beside it and two aluminium rings, all smooth, under Mitsuba's sun and sky.
- veach-lamp/: a closed room lit only by two shaded lamps, after the bidirectional test scene of
  Veach's thesis (Veach, "Robust Monte Carlo Methods for Light Transport Simulation", 1997,
  Fig. 10.3): each lamp's light leaves through the open end of a metal shade, so most of what the
  camera sees is lit only after a bounce off the shade, the walls or the ceiling, which a path
  tracer finds only by hitting the small emitters; a glass egg stands on a wooden table.

Meshes are binary little-endian PLY (x y z, nx ny nz when smooth, u v when the mesh has a
parametrisation; faces as `list uchar int`); every number is written from the formulas below, so
running the script again rewrites the same bytes.

    python3 scenes/mitsuba/generate.py
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(path, text):
    with open(os.path.join(HERE, path), "w") as f:
        f.write(text)


def num(x):
    """A float as Mitsuba and plexus read it back exactly: the shortest round-trip text."""
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(float(x))


# ---------------------------------------------------------------------------------------------
# Meshes


class Mesh:
    def __init__(self):
        self.positions, self.normals, self.uvs, self.faces = [], [], [], []

    def vertex(self, p, n=None, uv=None):
        self.positions.append(tuple(p))
        if n is not None:
            self.normals.append(tuple(n))
        if uv is not None:
            self.uvs.append(tuple(uv))
        return len(self.positions) - 1

    def extend(self, other):
        base = len(self.positions)
        self.positions += other.positions
        self.normals += other.normals
        self.uvs += other.uvs
        self.faces += [tuple(base + i for i in f) for f in other.faces]
        return self

    def transformed(self, m):
        """The mesh under the affine 3x4 matrix m (rows), normals by the inverse transpose."""
        out = Mesh()
        inv_t = inverse_transpose(m)
        out.positions = [apply(m, p) for p in self.positions]
        out.normals = [normalize(apply_linear(inv_t, n)) for n in self.normals]
        out.uvs = list(self.uvs)
        out.faces = list(self.faces)
        if det3(m) < 0:
            out.faces = [(a, c, b) for a, b, c in out.faces]
        return out

    def flat(self):
        """The mesh without vertex normals (rendered with its faces' normals)."""
        self.normals = []
        return self

    def flipped(self):
        """The mesh facing the other way: faces wound the other way round, normals negated."""
        out = Mesh()
        out.positions, out.uvs = list(self.positions), list(self.uvs)
        out.normals = [tuple(-c for c in n) for n in self.normals]
        out.faces = [(a, c, b) for a, b, c in self.faces]
        return out

    def write_ply(self, path, comment):
        n = len(self.positions)
        smooth = len(self.normals) == n
        textured = len(self.uvs) == n
        assert self.normals == [] or smooth and (self.uvs == [] or textured)
        header = ["ply", "format binary_little_endian 1.0", f"comment {comment}", f"element vertex {n}",
                  "property float x", "property float y", "property float z"]
        if smooth:
            header += ["property float nx", "property float ny", "property float nz"]
        if textured:
            header += ["property float u", "property float v"]
        header += [f"element face {len(self.faces)}", "property list uchar int vertex_indices", "end_header"]
        body = bytearray("\n".join(header).encode() + b"\n")
        for i in range(n):
            values = list(self.positions[i])
            if smooth:
                values += self.normals[i]
            if textured:
                values += self.uvs[i]
            body += struct.pack(f"<{len(values)}f", *values)
        for f in self.faces:
            assert len(f) == 3 and all(0 <= i < n for i in f)
            body += struct.pack("<B3i", 3, *f)
        with open(os.path.join(HERE, path), "wb") as out:
            out.write(bytes(body))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def normalize(v):
    length = math.sqrt(dot(v, v))
    return tuple(x / length for x in v)


def apply(m, p):
    return tuple(m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3] for r in range(3))


def apply_linear(m, v):
    return tuple(m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2] for r in range(3))


def det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def inverse_transpose(m):
    """The inverse transpose of m's linear 3x3 part (cofactors over the determinant)."""
    d = det3(m)
    c = [[m[(r + 1) % 3][(k + 1) % 3] * m[(r + 2) % 3][(k + 2) % 3]
          - m[(r + 1) % 3][(k + 2) % 3] * m[(r + 2) % 3][(k + 1) % 3] for k in range(3)] for r in range(3)]
    return [[c[r][k] / d for k in range(3)] for r in range(3)]


def frame(origin, axis):
    """The affine matrix taking +z to the unit vector `axis` and the origin to `origin` (right-handed)."""
    w = normalize(axis)
    helper = (1.0, 0.0, 0.0) if abs(w[0]) < 0.9 else (0.0, 1.0, 0.0)
    u = normalize(cross(helper, w))
    v = cross(w, u)
    return [[u[0], v[0], w[0], origin[0]], [u[1], v[1], w[1], origin[1]], [u[2], v[2], w[2], origin[2]]]


def scale_translate(s, t):
    return [[s[0], 0.0, 0.0, t[0]], [0.0, s[1], 0.0, t[1]], [0.0, 0.0, s[2], t[2]]]


def torus(major, minor, rings, sides):
    """A torus about +z centred at the origin: u around the axis, v around the tube; smooth
    normals, outward. A seam column and row of vertices closes each parameter."""
    m = Mesh()
    for i in range(rings + 1):
        phi = 2 * math.pi * i / rings
        cp, sp = math.cos(phi), math.sin(phi)
        for j in range(sides + 1):
            theta = 2 * math.pi * j / sides
            ct, st = math.cos(theta), math.sin(theta)
            n = (ct * cp, ct * sp, st)
            p = ((major + minor * ct) * cp, (major + minor * ct) * sp, minor * st)
            m.vertex(p, n, (i / rings, j / sides))
    row = sides + 1
    for i in range(rings):
        for j in range(sides):
            a, b, c, d = i * row + j, (i + 1) * row + j, (i + 1) * row + j + 1, i * row + j + 1
            m.faces += [(a, b, c), (a, c, d)]
    return m


def sphere(rings, segments):
    """The unit sphere, poles on +-z, smooth outward normals, (u, v) = (longitude, latitude)."""
    m = Mesh()
    for i in range(rings + 1):
        theta = math.pi * i / rings
        for j in range(segments + 1):
            phi = 2 * math.pi * j / segments
            n = (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))
            m.vertex(n, n, (j / segments, 1.0 - i / rings))
    row = segments + 1
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = i * row + j, (i + 1) * row + j, (i + 1) * row + j + 1, i * row + j + 1
            if i > 0:
                m.faces.append((a, b, d))
            if i < rings - 1:
                m.faces.append((b, c, d))
    return m


def tube(radius, z0, z1, segments, inward=False):
    """An open cylinder of `radius` about +z from z0 to z1, smooth normals (outward, or inward)."""
    m = Mesh()
    s = -1.0 if inward else 1.0
    for j in range(segments + 1):
        phi = 2 * math.pi * j / segments
        c, si = math.cos(phi), math.sin(phi)
        for z in (z0, z1):
            m.vertex((radius * c, radius * si, z), (s * c, s * si, 0.0))
    for j in range(segments):
        a, b, c, d = 2 * j, 2 * j + 2, 2 * j + 3, 2 * j + 1
        m.faces += [(a, b, c), (a, c, d)] if not inward else [(a, c, b), (a, d, c)]
    return m


def annulus(r0, r1, z, segments, up=True):
    """The flat ring r0 <= r <= r1 in the plane z, facing +z (or -z); r0 = 0 gives a disk, a fan
    about one centre vertex."""
    m = Mesh()
    n = (0.0, 0.0, 1.0 if up else -1.0)
    if r0 == 0:
        m.vertex((0.0, 0.0, z), n)
        for j in range(segments):
            phi = 2 * math.pi * j / segments
            m.vertex((r1 * math.cos(phi), r1 * math.sin(phi), z), n)
        for j in range(segments):
            a, b = 1 + j, 1 + (j + 1) % segments
            m.faces.append((0, a, b) if up else (0, b, a))
        return m
    for j in range(segments + 1):
        phi = 2 * math.pi * j / segments
        c, s = math.cos(phi), math.sin(phi)
        m.vertex((r0 * c, r0 * s, z), n)
        m.vertex((r1 * c, r1 * s, z), n)
    for j in range(segments):
        a, b, c, d = 2 * j, 2 * j + 2, 2 * j + 3, 2 * j + 1
        m.faces += [(a, c, b), (a, d, c)] if up else [(a, b, c), (a, c, d)]
    return m


def box(lo, hi):
    """An axis-aligned box, each face its own four vertices, flat outward normals."""
    m = Mesh()
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    quads = [
        ((x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0), (0, 0, -1)),
        ((x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1), (0, 0, 1)),
        ((x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1), (0, -1, 0)),
        ((x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0), (0, 1, 0)),
        ((x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0), (-1, 0, 0)),
        ((x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1), (1, 0, 0)),
    ]
    for *corners, n in quads:
        base = len(m.positions)
        for p in corners:
            m.vertex(p, tuple(float(c) for c in n))
        m.faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return m


def quad(corners):
    """A planar quad given by its corners in counter-clockwise order seen from its front."""
    m = Mesh()
    for p in corners:
        m.vertex(p)
    m.faces = [(0, 1, 2), (0, 2, 3)]
    return m


def band_ring(radius, width, height, segments):
    """A closed metal band standing on z = 0: outer wall of `radius`, inner wall `width` less, the
    rims at z = 0 and z = `height`, each surface facing out of the band's solid."""
    inner = radius - width
    ring = tube(radius, 0.0, height, segments)
    ring.extend(tube(inner, 0.0, height, segments, inward=True))
    ring.extend(annulus(inner, radius, height, segments, up=True))
    return ring.extend(annulus(inner, radius, 0.0, segments, up=False))


def shade(radius, wall, length, segments, closed):
    """A lamp shade about +z: a thin-walled cylinder from z = 0 to `length` (walls `wall` thick),
    open at the top, and closed at the bottom by a wall of the same thickness when `closed` (else
    open there too); every surface faces out of the shell's solid."""
    inner = radius - wall
    bottom = wall if closed else 0.0
    m = tube(radius, 0.0, length, segments)
    m.extend(tube(inner, bottom, length, segments, inward=True))
    m.extend(annulus(inner, radius, length, segments, up=True))
    if closed:
        m.extend(annulus(0.0, radius, 0.0, segments, up=False))
        m.extend(annulus(0.0, inner, wall, segments, up=True))
    else:
        m.extend(annulus(inner, radius, 0.0, segments, up=False))
    return m


# ---------------------------------------------------------------------------------------------
# The Cornell box

# Reflectance spectra from the Cornell box data page, 400 to 700 nm in steps of 4 nm.
CORNELL_WAVELENGTHS = list(range(400, 701, 4))
CORNELL_WHITE = [
    0.343, 0.445, 0.551, 0.624, 0.665, 0.687, 0.708, 0.723, 0.715, 0.71, 0.745, 0.758, 0.739, 0.767, 0.777, 0.765,
    0.751, 0.745, 0.748, 0.729, 0.745, 0.757, 0.753, 0.75, 0.746, 0.747, 0.735, 0.732, 0.739, 0.734, 0.725, 0.721,
    0.733, 0.725, 0.732, 0.743, 0.744, 0.748, 0.728, 0.716, 0.733, 0.726, 0.713, 0.74, 0.754, 0.764, 0.752, 0.736,
    0.734, 0.741, 0.74, 0.732, 0.745, 0.755, 0.751, 0.744, 0.731, 0.733, 0.744, 0.731, 0.712, 0.708, 0.729, 0.73,
    0.727, 0.707, 0.703, 0.729, 0.75, 0.76, 0.751, 0.739, 0.724, 0.73, 0.74, 0.737]
CORNELL_GREEN = [
    0.092, 0.096, 0.098, 0.097, 0.098, 0.095, 0.095, 0.097, 0.095, 0.094, 0.097, 0.098, 0.096, 0.101, 0.103, 0.104,
    0.107, 0.109, 0.112, 0.115, 0.125, 0.14, 0.16, 0.187, 0.229, 0.285, 0.343, 0.39, 0.435, 0.464, 0.472, 0.476,
    0.481, 0.462, 0.447, 0.441, 0.426, 0.406, 0.373, 0.347, 0.337, 0.314, 0.285, 0.277, 0.266, 0.25, 0.23, 0.207,
    0.186, 0.171, 0.16, 0.148, 0.141, 0.136, 0.13, 0.126, 0.123, 0.121, 0.122, 0.119, 0.114, 0.115, 0.117, 0.117,
    0.118, 0.12, 0.122, 0.128, 0.132, 0.139, 0.144, 0.146, 0.15, 0.152, 0.157, 0.159]
CORNELL_RED = [
    0.04, 0.046, 0.048, 0.053, 0.049, 0.05, 0.053, 0.055, 0.057, 0.056, 0.059, 0.057, 0.061, 0.061, 0.06, 0.062,
    0.062, 0.062, 0.061, 0.062, 0.06, 0.059, 0.057, 0.058, 0.058, 0.058, 0.056, 0.055, 0.056, 0.059, 0.057, 0.055,
    0.059, 0.059, 0.058, 0.059, 0.061, 0.061, 0.063, 0.063, 0.067, 0.068, 0.072, 0.08, 0.09, 0.099, 0.124, 0.154,
    0.192, 0.255, 0.287, 0.349, 0.402, 0.443, 0.487, 0.513, 0.558, 0.584, 0.62, 0.606, 0.609, 0.651, 0.612, 0.61,
    0.65, 0.638, 0.627, 0.62, 0.63, 0.628, 0.642, 0.639, 0.657, 0.639, 0.635, 0.642]
# The light: its measured emission spectrum (doubled here) and its reflectance.
CORNELL_LIGHT_EMISSION = [(400, 0.0), (500, 8.0), (600, 15.6), (700, 18.4)]
CORNELL_LIGHT_REFLECTANCE = 0.78

# Geometry (mm), each polygon's corners in the order of the data page.
CORNELL_WALLS = {
    "floor": [(552.8, 0, 0), (0, 0, 0), (0, 0, 559.2), (549.6, 0, 559.2)],
    "ceiling": [(556, 548.8, 0), (556, 548.8, 559.2), (0, 548.8, 559.2), (0, 548.8, 0)],
    "back": [(549.6, 0, 559.2), (0, 0, 559.2), (0, 548.8, 559.2), (556, 548.8, 559.2)],
    "greenwall": [(0, 0, 559.2), (0, 0, 0), (0, 548.8, 0), (0, 548.8, 559.2)],
    "redwall": [(552.8, 0, 0), (549.6, 0, 559.2), (556, 548.8, 559.2), (556, 548.8, 0)],
    "luminaire": [(343, 548.8, 227), (343, 548.8, 332), (213, 548.8, 332), (213, 548.8, 227)],
}
# The blocks: the top corners A, B, C, D (the bottom ones are at y = 0), the height, and the sides
# in the data page's order, each as the pair of top corners it spans (from the bottom of the first
# corner up, along the top edge, down the second).
CORNELL_BLOCKS = {
    "smallbox": ([(130, 65), (82, 225), (240, 272), (290, 114)], 165, [(3, 2), (0, 3), (1, 0), (2, 1)]),
    "largebox": ([(423, 247), (265, 296), (314, 456), (472, 406)], 330, [(0, 3), (3, 2), (2, 1), (1, 0)]),
}


def spectrum(wavelengths, values):
    return ", ".join(f"{w}:{num(v)}" for w, v in zip(wavelengths, values))


def block_faces(corners, height, sides):
    """The block's faces, wound outward: the top, the four sides, then the bottom (D, C, B, A)."""
    top = [(x, height, z) for x, z in corners]
    bottom = [(x, 0, z) for x, z in corners]
    faces = [top] + [[bottom[i], top[i], top[j], bottom[j]] for i, j in sides]
    return faces + [[bottom[3], bottom[2], bottom[1], bottom[0]]]


def obj_number(x):
    return num(x)


def fixed6(x):
    """x with six decimals, never "-0.000000"."""
    text = f"{x:.6f}"
    return "0.000000" if text == "-0.000000" else text


def write_cornell_box():
    os.makedirs(os.path.join(HERE, "cornell-box", "meshes"), exist_ok=True)
    header = "# The Cornell box ({}), from the Cornell Program of Computer Graphics' data; see ../../LICENSES.md.\n"
    for name, corners in CORNELL_WALLS.items():
        lines = [header.format(name)] + [f"v {' '.join(obj_number(c) for c in p)}\n" for p in corners]
        write(f"cornell-box/meshes/cbox_{name}.obj", "".join(lines) + "f 1 2 3 4\n")
    for name, (corners, height, sides) in CORNELL_BLOCKS.items():
        lines = [header.format(name)]
        faces = block_faces(corners, height, sides)
        for f in faces:
            n = normalize(cross(sub(f[1], f[0]), sub(f[2], f[0])))
            lines.append("vn " + " ".join(fixed6(c) for c in n) + "\n")
            lines += [f"v {' '.join(obj_number(c) for c in p)}\n" for p in f]
        for k in range(len(faces)):
            a = 4 * k + 1
            lines.append(f"f {a}//{k + 1} {a + 1}//{k + 1} {a + 2}//{k + 1}\n")
            lines.append(f"f {a}//{k + 1} {a + 2}//{k + 1} {a + 3}//{k + 1}\n")
        write(f"cornell-box/meshes/cbox_{name}.obj", "".join(lines))
    bsdf = '\t<bsdf type="diffuse" id="{}">\n\t\t<spectrum name="reflectance" value="{}"/>\n\t</bsdf>\n'
    shape = '\t<shape type="obj">\n\t\t<string name="filename" value="meshes/cbox_{}.obj"/>\n{}\n\t\t<ref id="{}"/>\n\t</shape>\n'
    light_spectrum = ", ".join(f"{w}:{num(2 * e)}" for w, e in CORNELL_LIGHT_EMISSION)
    xml = ['<?xml version="1.0" encoding="utf-8"?>\n<!--\n'
           '\tThe Cornell box from the Cornell University Program of Computer Graphics\' published data\n'
           '\t(https://www.graphics.cornell.edu/online/box/data.html): geometry (mm), camera, reflectance\n'
           '\tspectra. The light quad is turned over to face the ceiling 77.6 mm below it and emits twice\n'
           '\tthe measured spectrum (the variant of Mueller et al. 2017). Written by generate.py.\n-->\n\n'
           '<scene version="0.5.0">\n'
           '\t<integrator type="path">\n\t\t<integer name="maxDepth" value="10"/>\n'
           '\t\t<integer name="rrDepth" value="10"/>\n\t</integrator>\n\n'
           '\t<sensor type="perspective">\n\t\t<string name="fovAxis" value="smaller"/>\n'
           '\t\t<transform name="toWorld">\n'
           '\t\t\t<lookAt origin="278, 273, -800" target="278, 273, -799" up="0, 1, 0"/>\n\t\t</transform>\n'
           # The data page's 35 mm focal length on a 25 mm film: 2 atan(12.5 / 35) = 39.3077 degrees.
           '\t\t<float name="fov" value="39.3077"/>\n\n'
           '\t\t<sampler type="independent">\n\t\t\t<integer name="sampleCount" value="128"/>\n'
           '\t\t\t<integer name="seed" value="1234"/>\n\t\t</sampler>\n\n'
           '\t\t<film type="hdrfilm">\n\t\t\t<integer name="width" value="512"/>\n'
           '\t\t\t<integer name="height" value="512"/>\n\n\t\t\t<rfilter type="box"/>\n\t\t</film>\n'
           '\t</sensor>\n\n']
    white = spectrum(CORNELL_WAVELENGTHS, CORNELL_WHITE)
    for name, values in [("box", white), ("white", white), ("red", spectrum(CORNELL_WAVELENGTHS, CORNELL_RED)),
                         ("green", spectrum(CORNELL_WAVELENGTHS, CORNELL_GREEN)),
                         ("light", spectrum([400, 500, 600, 700], [CORNELL_LIGHT_REFLECTANCE] * 4))]:
        xml.append(bsdf.format(name, values) + "\n")
    xml.append('\t<shape type="obj">\n\t\t<string name="filename" value="meshes/cbox_luminaire.obj"/>\n'
               '\t\t<transform name="toWorld">\n\t\t\t<rotate x="1" angle="180"/>\n'
               '\t\t\t<translate x="0" y="1020" z="550"/>\n\t\t</transform>\n\n\t\t<ref id="light"/>\n\n'
               f'\t\t<emitter type="area">\n\t\t\t<spectrum name="radiance" value="{light_spectrum}"/>\n'
               '\t\t</emitter>\n\t</shape>\n\n')
    for name, material in [("floor", "white"), ("ceiling", "white"), ("back", "white"), ("greenwall", "green"),
                           ("redwall", "red"), ("smallbox", "box"), ("largebox", "box")]:
        xml.append(shape.format(name, "", material) + ("\n" if name != "largebox" else ""))
    xml.append("</scene>\n")
    write("cornell-box/cbox.xml", "".join(xml))


# ---------------------------------------------------------------------------------------------
# The torus scene (z up, units of the sunsky scenes' centimetres)

# Mitsuba's sun and sky at 9 am on its default date and place, the sky turned so that z is up; the
# cross-check (scripts/crosscheck.py) replaces it in both renderers by a constant sky and a sun disk
# in the direction plexus's importer computes from these parameters.
SUNSKY = ('\t<emitter type="sunsky">\n\t\t<transform name="toWorld">\n\t\t\t<rotate y="1" angle="-30"/>\n'
          '\t\t\t<rotate x="1" angle="90"/>\n\t\t</transform>\n\t\t<float name="hour" value="9"/>\n'
          '\t\t<float name="turbidity" value="5"/>\n\t</emitter>\n')


def write_torus():
    os.makedirs(os.path.join(HERE, "torus"), exist_ok=True)
    note = "torus scene of plexus (scenes/mitsuba/generate.py)"
    quad([(-50.0, -30.0, 0.0), (50.0, -30.0, 0.0), (50.0, 70.0, 0.0), (-50.0, 70.0, 0.0)]).write_ply(
        "torus/floor.ply", note)
    # Standing upright on the floor: the torus about +z turned to the xz-plane (axis along y).
    upright = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 5.0]]
    torus(3.5, 1.5, 128, 64).transformed(upright).write_ply("torus/glass.ply", note)
    torus(3.5, 1.5, 96, 48).transformed(scale_translate((1, 1, 1), (-9.0, 4.0, 1.5))).write_ply(
        "torus/donut.ply", note)
    band_ring(3.0, 0.15, 1.2, 256).write_ply("torus/ring.ply", note)
    shape = '\t<shape type="ply">\n\t\t<string name="filename" value="{}"/>\n{}\t\t<ref id="{}"/>\n\t</shape>\n\n'
    rings = "".join(shape.format("ring.ply", f'\t\t<transform name="toWorld">\n\t\t\t<translate x="{x}" y="{y}"/>\n'
                                 '\t\t</transform>\n', "mat_metal") for x, y in [(9, -5), (10, 5)])
    xml = ('<?xml version="1.0" encoding="utf-8"?>\n<!--\n'
           '\tCaustics under the sun: a glass torus standing on the floor, a diffuse torus lying beside it\n'
           '\tand two aluminium bands. Written by generate.py; see ../LICENSES.md.\n-->\n\n'
           '<scene version="0.6.0">\n'
           '\t<integrator type="path">\n\t\t<integer name="maxDepth" value="9"/>\n\t</integrator>\n\n'
           '\t<bsdf type="diffuse" id="mat_donut">\n\t\t<rgb name="reflectance" value=".8, .8, .4"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="conductor" id="mat_metal">\n\t\t<string name="material" value="Al"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="dielectric" id="mat_glass">\n\t\t<float name="intIOR" value="1.5"/>\n'
           '\t\t<float name="extIOR" value="1.0"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="diffuse" id="mat_floor"/>\n\n'
           + SUNSKY + "\n"
           + shape.format("floor.ply", "", "mat_floor") + shape.format("donut.ply", "", "mat_donut")
           + shape.format("glass.ply", "", "mat_glass") + rings +
           '\t<sensor type="perspective">\n\t\t<float name="fov" value="35"/>\n'
           '\t\t<string name="fovAxis" value="x"/>\n\t\t<transform name="toWorld">\n'
           '\t\t\t<lookat origin="-24, -38, 30" target="1, 1, 2" up="0, 0, 1"/>\n\t\t</transform>\n\n'
           '\t\t<sampler type="independent">\n\t\t\t<integer name="sampleCount" value="100"/>\n\t\t</sampler>\n\n'
           '\t\t<film type="hdrfilm">\n\t\t\t<integer name="width" value="1024"/>\n'
           '\t\t\t<integer name="height" value="768"/>\n\t\t\t<rfilter type="box"/>\n\t\t</film>\n'
           '\t</sensor>\n</scene>\n')
    write("torus/scene.xml", xml)


# ---------------------------------------------------------------------------------------------
# The lamp scene (z up, metres)


def write_veach_lamp():
    os.makedirs(os.path.join(HERE, "veach-lamp"), exist_ok=True)
    note = "lamp scene of plexus (scenes/mitsuba/generate.py)"
    segments = 96
    # The room, seen from inside: floor z = 0, ceiling z = 2.8.
    box((-2.8, -6.5, 0.0), (2.2, 2.2, 2.8)).flat().flipped().write_ply("veach-lamp/room.ply", note)
    # The table: a top 1.4 x 0.9 m at 0.77 m on four legs.
    table = box((-0.2, -0.2, 0.72), (1.2, 0.7, 0.77)).flat()
    for x, y in [(-0.15, -0.15), (1.1, -0.15), (-0.15, 0.6), (1.1, 0.6)]:
        table.extend(box((x, y, 0.0), (x + 0.05, y + 0.05, 0.72)).flat())
    table.write_ply("veach-lamp/table.ply", note)
    # A glass egg on the table.
    sphere(48, 96).transformed(scale_translate((0.16, 0.16, 0.22), (0.3, 0.2, 0.99))).write_ply(
        "veach-lamp/egg.ply", note)
    # Lamp 1, by the left wall: a shade closed at its back, aimed at the far upper corner; its
    # emitter faces the open end from just inside the back.
    origin1, axis1 = (-2.1, 0.9, 1.75), (-0.55, 0.55, 0.63)
    to1 = frame(origin1, axis1)
    shade(0.18, 0.01, 0.36, segments, closed=True).transformed(to1).write_ply("veach-lamp/shade1.ply", note)
    annulus(0.0, 0.12, 0.06, segments, up=True).flat().transformed(to1).write_ply("veach-lamp/emitter1.ply", note)
    # Lamp 2, on the right: an upright shade open at both ends; its emitter, halfway up, faces the
    # ceiling.
    to2 = scale_translate((1, 1, 1), (1.7, 1.5, 1.25))
    shade(0.22, 0.01, 0.3, segments, closed=False).transformed(to2).write_ply("veach-lamp/shade2.ply", note)
    annulus(0.0, 0.1, 0.15, segments, up=True).flat().transformed(to2).write_ply("veach-lamp/emitter2.ply", note)
    # The lamps' stands: poles from the floor to each shade.
    stands = box((-2.12, 0.88, 0.0), (-2.08, 0.92, 1.72)).flat()
    stands.extend(box((1.68, 1.48, 0.0), (1.72, 1.52, 1.25)).flat())
    stands.write_ply("veach-lamp/stands.ply", note)

    def shape(file, inner):
        return f'\t<shape type="ply">\n\t\t<string name="filename" value="{file}"/>\n{inner}\t</shape>\n\n'

    def emitter(material, radiance):
        return (f'\t\t<ref name="bsdf" id="{material}"/>\n\t\t<emitter type="area">\n'
                f'\t\t\t<rgb name="radiance" value="{radiance}"/>\n\t\t</emitter>\n')

    xml = ('<?xml version="1.0" encoding="utf-8"?>\n<!--\n'
           '\tA closed room lit only by two shaded lamps (after the bidirectional test scene of Veach\'s\n'
           '\tthesis, 1997, Fig. 10.3), a glass egg on a wooden table. Written by generate.py; see\n'
           '\t../LICENSES.md.\n-->\n\n'
           '<scene version="0.6.0">\n'
           '\t<integrator type="path">\n\t\t<integer name="maxDepth" value="6"/>\n\t</integrator>\n\n'
           '\t<sensor type="perspective">\n\t\t<float name="fov" value="57"/>\n'
           '\t\t<string name="fovAxis" value="x"/>\n\t\t<transform name="toWorld">\n'
           '\t\t\t<lookat origin="-0.3, -5.8, 1.3" target="-0.2, 0, 1" up="0, 0, 1"/>\n\t\t</transform>\n\n'
           '\t\t<sampler type="independent">\n\t\t\t<integer name="sampleCount" value="256"/>\n\t\t</sampler>\n\n'
           '\t\t<film type="hdrfilm">\n\t\t\t<integer name="width" value="1024"/>\n'
           '\t\t\t<integer name="height" value="576"/>\n\t\t\t<rfilter type="box"/>\n\t\t</film>\n'
           '\t</sensor>\n\n'
           '\t<bsdf type="dielectric" id="Glass">\n\t\t<float name="extIOR" value="1.0"/>\n'
           '\t\t<float name="intIOR" value="1.5"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="ward" id="LampMaterial">\n\t\t<spectrum name="diffuseReflectance" value="0"/>\n'
           '\t\t<rgb name="specularReflectance" value="0.61600 0.47520 0.35200"/>\n'
           '\t\t<float name="alpha" value="0.4"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="diffuse" id="Diffuse">\n\t\t<rgb name="reflectance" value="0.5 0.5 0.5"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="diffuse" id="Luminaire">\n\t\t<rgb name="reflectance" value="0.5 0.5 0.5"/>\n\t</bsdf>\n\n'
           '\t<bsdf type="diffuse" id="Wood">\n\t\t<rgb name="reflectance" value="0.33 0.258 0.15"/>\n\t</bsdf>\n\n'
           + shape("room.ply", '\t\t<ref name="bsdf" id="Diffuse"/>\n')
           + shape("table.ply", '\t\t<ref name="bsdf" id="Wood"/>\n')
           + shape("egg.ply", '\t\t<ref name="bsdf" id="Glass"/>\n')
           + shape("shade1.ply", '\t\t<ref name="bsdf" id="LampMaterial"/>\n')
           + shape("emitter1.ply", emitter("Luminaire", "400 400 400"))
           + shape("shade2.ply", '\t\t<ref name="bsdf" id="LampMaterial"/>\n')
           + shape("emitter2.ply", emitter("Luminaire", "700 545 363"))
           + shape("stands.ply", '\t\t<bsdf type="diffuse"/>\n')
           + "</scene>\n")
    write("veach-lamp/scene.xml", xml.replace("\n\n</scene>", "\n</scene>"))


if __name__ == "__main__":
    write_cornell_box()
    write_torus()
    write_veach_lamp()
