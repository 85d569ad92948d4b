#!/usr/bin/python3
"""Reads a probe volume file with pyopenvdb and checks it against expectations from the C++ test.

Usage: read_volume.py VOLUME.vdb EXPECTATIONS.json

EXPECTATIONS.json:
  {"grids": {"radiance_sh_00": "Vec3SGrid", ...},   every grid of the file and its class
   "activeVoxels": N,                                 in every grid
   "voxels": [[grid, i, j, k, [values]], ...],        values as float32 (1 or 3 of them)
   "world": [[i, j, k, [x, y, z]], ...],              indexToWorld, exact doubles
   "metadata": {key: [kind, value]}}                  kind: int, bool, str, vec3i, vec3d, float
Prints one line per failed check and exits 1 on any failure, 0 otherwise.
"""
import json
import struct
import sys

import pyopenvdb as vdb


def f32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def main():
    path, expectations_path = sys.argv[1], sys.argv[2]
    with open(expectations_path) as f:
        want = json.load(f)
    failures = []

    grids, metadata = vdb.readAll(path)
    by_name = {g.name: g for g in grids}
    if sorted(by_name) != sorted(want["grids"]):
        failures.append("grid names: expected %s, got %s" % (sorted(want["grids"]), sorted(by_name)))
    for name, cls in want["grids"].items():
        g = by_name.get(name)
        if g is None:
            continue
        if type(g).__name__ != cls:
            failures.append("%s: class %s, expected %s" % (name, type(g).__name__, cls))
        if g.activeVoxelCount() != want["activeVoxels"]:
            failures.append("%s: %d active voxels, expected %d"
                            % (name, g.activeVoxelCount(), want["activeVoxels"]))

    for name, i, j, k, values in want["voxels"]:
        g = by_name[name]
        acc = g.getConstAccessor()
        if not acc.isValueOn((i, j, k)):
            failures.append("%s(%d,%d,%d): not active" % (name, i, j, k))
        got = acc.getValue((i, j, k))
        got = list(got) if isinstance(got, tuple) else [got]
        if [f32(v) for v in got] != [f32(v) for v in values]:
            failures.append("%s(%d,%d,%d): expected %r, got %r" % (name, i, j, k, values, got))

    transform = by_name["validity"].transform
    for i, j, k, xyz in want["world"]:
        got = list(transform.indexToWorld((i, j, k)))
        if got != xyz:
            failures.append("indexToWorld(%d,%d,%d): expected %r, got %r" % (i, j, k, xyz, got))

    kinds = {"int": int, "bool": bool, "str": str, "float": float, "vec3i": tuple, "vec3d": tuple}
    for key, (kind, value) in want["metadata"].items():
        if key not in metadata:
            failures.append("metadata %s: missing" % key)
            continue
        got = metadata[key]
        if type(got) is not kinds[kind]:
            failures.append("metadata %s: Python type %s, expected %s"
                            % (key, type(got).__name__, kinds[kind].__name__))
            continue
        if kind in ("vec3i", "vec3d"):
            got = list(got)
        if got != value:
            failures.append("metadata %s: expected %r, got %r" % (key, value, got))
    # settings and stats are JSON strings.
    for key in ("settings", "stats"):
        try:
            json.loads(metadata.get(key, ""))
        except ValueError as e:
            failures.append("metadata %s: not JSON: %s" % (key, e))

    for line in failures:
        print(line)
    print("read_volume.py: %d grids, %d metadata keys, %d failures"
          % (len(grids), len(metadata), len(failures)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
