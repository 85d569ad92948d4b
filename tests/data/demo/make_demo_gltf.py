#!/usr/bin/env python3
"""Writes the authored demo level (tests/data/demo/loft.gltf, loft.bin and its PNG textures).

The demo room of demo.json authored the way a level comes out of a DCC tool: glTF 2.0, +Y up,
metres, with its own materials (base-colour factors and sRGB textures), a cutout (a trellis
screen with an alpha-masked texture, double-sided) and a KHR_lights_punctual lamp. The job file
(demo-gltf.json) maps +Y up to probebake's +Z up with the mesh transform and adds the sky and the
sun. Run by hand from the repository root (the outputs are committed):

    python3 tests/data/demo/make_demo_gltf.py

Standard library only; the same bytes on every run.
"""
import json
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def png(path, width, height, rgba):
    """An 8-bit RGBA PNG of `rgba` (rows top to bottom, 4 bytes a pixel)."""
    raw = b"".join(b"\x00" + bytes(rgba[4 * width * y:4 * width * (y + 1)]) for y in range(height))

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def wood():
    """Floor planks: 8 boards across a 64 x 64 tile, alternating tones, a darker seam and grain."""
    size, out = 64, []
    tones = [(150, 104, 64), (128, 86, 50), (160, 114, 72), (138, 94, 58)]
    for y in range(size):
        board = y // 8
        for x in range(size):
            r, g, b = tones[(board + (x // 32) * 2) % 4]
            if y % 8 == 0:  # seam
                r, g, b = r * 0.6, g * 0.6, b * 0.6
            grain = 0.9 + 0.1 * math.sin(x * 0.9 + board * 2.1 + math.sin(x * 0.23) * 3)
            out += [int(r * grain), int(g * grain), int(b * grain), 255]
    return size, size, out


def wallpaper():
    """Pale vertical stripes with a thin rule, 32 x 32."""
    size, out = 32, []
    for y in range(size):
        for x in range(size):
            if x < 16:
                c = (214, 206, 186)
            else:
                c = (196, 190, 176)
            if x in (0, 1):
                c = (168, 150, 120)
            out += [*c, 255]
    return size, size, out


def trellis():
    """A garden trellis: green-stained slats on a 4 x 4 lattice, alpha 0 in the openings (about
    56% open), 64 x 64."""
    size, out = 64, []
    for y in range(size):
        for x in range(size):
            slat = (x % 16) < 4 or (y % 16) < 4
            out += [70, 110, 60, 255] if slat else [0, 0, 0, 0]
    return size, size, out


def to_gltf(p):
    """probebake (x, y, z), +Z up, to glTF (x, z, -y), +Y up."""
    return (p[0], p[2], -p[1])


class Builder:
    def __init__(self):
        self.bin = bytearray()
        self.accessors, self.views, self.meshes, self.nodes = [], [], [], []

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data),
                           "target": target})
        self.bin += data
        return len(self.views) - 1

    def _accessor(self, values, kind, count, component, target, bounds=False):
        fmt = "<" + ("f" if component == 5126 else "H") * len(values)
        view = self._view(struct.pack(fmt, *values), target)
        a = {"bufferView": view, "componentType": component, "count": count, "type": kind}
        if bounds:
            a["min"] = [min(values[i::3]) for i in range(3)]
            a["max"] = [max(values[i::3]) for i in range(3)]
        self.accessors.append(a)
        return len(self.accessors) - 1

    def mesh(self, name, material, quads=(), triangles=None, uv_scale=1.0):
        """A mesh of probebake-frame quads (corners counter-clockwise seen from the front) or
        (positions, indices); texture coordinates from the two longest axes of each quad, in
        metres times uv_scale."""
        positions, uvs, indices = [], [], []
        if triangles:
            points, tri = triangles
            for p in points:
                positions += to_gltf(p)
                uvs += [p[0] * uv_scale, p[2] * uv_scale]
            indices = list(tri)
        for quad in quads:
            base = len(positions) // 3
            spans = [max(c[a] for c in quad) - min(c[a] for c in quad) for a in range(3)]
            axes = sorted(range(3), key=lambda a: -spans[a])[:2]
            axes.sort()
            for c in quad:
                positions += to_gltf(c)
                uvs += [c[axes[0]] * uv_scale, c[axes[1]] * uv_scale]
            indices += [base, base + 1, base + 2, base, base + 2, base + 3]
        count = len(positions) // 3
        primitive = {
            "attributes": {
                "POSITION": self._accessor(positions, "VEC3", count, 5126, 34962, bounds=True),
                "TEXCOORD_0": self._accessor(uvs, "VEC2", count, 5126, 34962),
            },
            "indices": self._accessor(indices, "SCALAR", len(indices), 5123, 34963),
            "material": material,
        }
        self.meshes.append({"name": name, "primitives": [primitive]})
        self.nodes.append({"name": name, "mesh": len(self.meshes) - 1})


def box_quads(lo, hi):
    """The six outward faces of an axis-aligned box, counter-clockwise from outside."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return [
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],  # bottom
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],  # top
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],  # -y
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],  # +y
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],  # -x
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],  # +x
    ]


def main():
    images = {"wood.png": wood(), "wallpaper.png": wallpaper(), "trellis.png": trellis()}
    for name, (w, h, rgba) in images.items():
        png(os.path.join(HERE, name), w, h, rgba)

    b = Builder()
    # Materials: 0 plaster, 1 red paint, 2 green paint, 3 floor planks, 4 wallpaper, 5 slate,
    # 6 crate (planks), 7 trellis (cutout).
    materials = [
        {"name": "plaster", "pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.75, 0.72, 1],
                                                     "metallicFactor": 0}},
        {"name": "red paint", "pbrMetallicRoughness": {"baseColorFactor": [0.65, 0.12, 0.08, 1],
                                                       "metallicFactor": 0}},
        {"name": "green paint", "pbrMetallicRoughness": {
            "baseColorFactor": [0.12, 0.5, 0.18, 1], "metallicFactor": 0}},
        {"name": "floor planks", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                          "metallicFactor": 0}},
        {"name": "wallpaper", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1},
                                                       "metallicFactor": 0}},
        {"name": "slate", "pbrMetallicRoughness": {"baseColorFactor": [0.35, 0.4, 0.55, 1],
                                                   "metallicFactor": 0}},
        {"name": "crate", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                   "baseColorFactor": [0.9, 0.9, 0.9, 1],
                                                   "metallicFactor": 0}},
        {"name": "trellis", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True,
         "pbrMetallicRoughness": {"baseColorTexture": {"index": 2}, "metallicFactor": 0}},
    ]
    # The room, 8 x 6 x 3 m, faces toward its inside.
    b.mesh("floor", 3, quads=[[(-4, -3, 0), (4, -3, 0), (4, 3, 0), (-4, 3, 0)]], uv_scale=0.5)
    b.mesh("ceiling", 0, quads=[[(-4, -3, 3), (-4, 3, 3), (4, 3, 3), (4, -3, 3)]])
    b.mesh("west wall", 1, quads=[[(-4, -3, 0), (-4, 3, 0), (-4, 3, 3), (-4, -3, 3)]])
    b.mesh("east wall", 2, quads=[[(4, -3, 0), (4, -3, 3), (4, 3, 3), (4, 3, 0)]])
    b.mesh("south wall", 4, quads=[[(-4, -3, 0), (-4, -3, 3), (4, -3, 3), (4, -3, 0)]],
           uv_scale=2.0)
    north = [(-4, 3, 0), (4, 3, 0), (4, 3, 3), (-4, 3, 3),
             (-1.5, 3, 0.8), (1.5, 3, 0.8), (1.5, 3, 2.3), (-1.5, 3, 2.3)]
    b.mesh("north wall with a window", 0, triangles=(
        north, [0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7]))
    b.mesh("tall box", 5, quads=box_quads((-2.6, -2.2, 0), (-1.6, -1.2, 1.4)))
    b.mesh("low box", 5, quads=box_quads((0.8, -1, 0), (1.8, 0, 0.6)))
    b.mesh("crate", 6, quads=box_quads((2.2, 0.6, 0), (3.2, 1.8, 0.9)), uv_scale=0.5)
    # A trellis screen 0.6 m inside the window, as wide as it and standing on the floor: the sun
    # through the window falls through its openings.
    b.mesh("trellis", 7, quads=[[(-1.5, 2.4, 0), (1.5, 2.4, 0), (1.5, 2.4, 2.4), (-1.5, 2.4, 2.4)]],
           uv_scale=1 / 0.4)
    # A lamp under the ceiling over the middle of the room: a point light of 3074 cd (4.5 W/sr at
    # 683 lm/W, the flux of the 1.5 m^2 ceiling panel of demo.json), warm white.
    b.nodes.append({"name": "lamp", "translation": list(to_gltf((0, -0.75, 2.6))),
                    "extensions": {"KHR_lights_punctual": {"light": 0}}})

    gltf = {
        "asset": {"version": "2.0", "generator": "probebake make_demo_gltf.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "lamp", "type": "point", "color": [1.0, 0.917, 0.792], "intensity": 3074}]}},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(b.nodes)))}],
        "nodes": b.nodes,
        "meshes": b.meshes,
        "materials": materials,
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0},
                     {"source": 2, "sampler": 0}],
        "images": [{"uri": "wood.png"}, {"uri": "wallpaper.png"}, {"uri": "trellis.png"}],
        "samplers": [{"wrapS": 10497, "wrapT": 10497}],
        "buffers": [{"uri": "loft.bin", "byteLength": len(b.bin)}],
        "bufferViews": b.views,
        "accessors": b.accessors,
    }
    with open(os.path.join(HERE, "loft.bin"), "wb") as f:
        f.write(b.bin)
    with open(os.path.join(HERE, "loft.gltf"), "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
