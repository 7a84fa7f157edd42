#!/usr/bin/env python3
"""Writes a Sierpinski tetrahedron as NFF polygons, after the SPD's "tetra": 4^level
tetrahedra of 4 triangles each (level 6: 16,384 triangles, 1.5 MB; level 7: 65,536
triangles, 6 MB), matte, two lights, for bench/compare-nff.sh. A scene of many small
polygons, where reading the file and building the tree weigh as much as rendering.
The view and lights are this script's own, not the SPD's.

    python3 bench/tetra_nff.py [LEVEL] > tetra.nff
"""
import sys

SIDE = 3 ** -0.5
CORNERS = [(SIDE, SIDE, SIDE), (SIDE, -SIDE, -SIDE), (-SIDE, SIDE, -SIDE), (-SIDE, -SIDE, SIDE)]
FACES = [(0, 1, 2), (0, 3, 1), (0, 2, 3), (1, 3, 2)]


def tetra(centre, size, level, out):
    if level == 0:
        v = [tuple(c + size * d for c, d in zip(centre, corner)) for corner in CORNERS]
        for face in FACES:
            out.append("p 3")
            out.extend("%.6f %.6f %.6f" % v[i] for i in face)
        return
    half = size / 2
    for corner in CORNERS:
        tetra(tuple(c + half * d for c, d in zip(centre, corner)), half, level - 1, out)


def main():
    level = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    out = ["b 0.078 0.361 0.753", "v", "from 1.022 -3.177 -2.015", "at -0.0462 -0.0277 0.0", "up 0 0 -1",
           "angle 45", "hither 1", "resolution 512 512", "l 1.86 -8.658 -8.248", "l 8.5 1.5 -4",
           "f 1 0.2 0.05 0.8 0 100000 0 1"]
    tetra((0.0, 0.0, 0.0), 1.0, level, out)
    print("\n".join(out))


if __name__ == "__main__":
    main()
