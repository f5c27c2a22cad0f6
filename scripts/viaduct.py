#!/usr/bin/env python3
"""A multi-span girder viaduct as a Wavefront OBJ (z up, metres) for the
simulator: a 10 m deck on three girders, a 2 m square pier every 25 m. At
125 m long, a 120-frame flight leaves over 10,000 gap voxels: the replan
benchmark's large instance (scripts/bench-stages).

Run: python3 scripts/viaduct.py LENGTH_M OUT.obj
"""

import sys


def boxes(length):
    """(x0, y0, z0, x1, y1, z1) of every part."""
    parts = [(0.0, -5.0, 8.0, length, 5.0, 8.5)]  # deck
    parts += [(0.0, y - 0.3, 6.5, length, y + 0.3, 8.0) for y in (-3.5, 0.0, 3.5)]  # girders
    for k in range(int(length // 25) + 1):  # piers, the end ones inside the span
        x = min(max(k * 25.0, 1.0), length - 1.0)
        parts.append((x - 1.0, -2.0, 0.0, x + 1.0, 2.0, 6.5))
    return parts


def mesh(parts):
    """Vertices and triangles (1-based) of boxes, faces wound outwards."""
    vertices, triangles = [], []
    # Corner k of a box is (x[k >> 2], y[(k >> 1) & 1], z[k & 1]).
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    for x0, y0, z0, x1, y1, z1 in parts:
        base = len(vertices) + 1
        vertices += [(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)]
        for a, b, c, d in quads:
            triangles += [(base + a, base + b, base + c), (base + a, base + c, base + d)]
    return vertices, triangles


def main():
    length, out = float(sys.argv[1]), sys.argv[2]
    vertices, triangles = mesh(boxes(length))
    with open(out, "w") as f:
        f.write(f"# postflight benchmark viaduct, {length:g} m\n")
        f.writelines("v %g %g %g\n" % v for v in vertices)
        f.writelines("f %d %d %d\n" % t for t in triangles)


if __name__ == "__main__":
    main()
