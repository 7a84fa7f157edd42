#!/usr/bin/env python3
"""Writes a fractal mountain as NFF, after the SPD's "mount": a height field made by
midpoint displacement (2^level + 1 points a side; level 6: 8,192 triangles) as polygons,
with four glass spheres above it that reflect a little and refract most (index 1.5),
one light. A scene of thousands of small triangles with refraction, for
bench/compare-nff.sh. The terrain, view and lights are this script's own, not the SPD's;
the same seed gives the same file.

    python3 bench/mount_nff.py [LEVEL] > mount.nff
"""
import random
import sys


def terrain(level, rng):
    """Heights on a (2^level + 1)² grid, by the diamond-square midpoint displacement."""
    n = 2 ** level + 1
    h = [[0.0] * n for _ in range(n)]
    step, scale = n - 1, 0.5
    while step > 1:
        half = step // 2
        for y in range(half, n, step):
            for x in range(half, n, step):
                corners = h[y - half][x - half] + h[y - half][x + half] + h[y + half][x - half] + h[y + half][x + half]
                h[y][x] = corners / 4 + rng.uniform(-scale, scale)
        for y in range(0, n, half):
            for x in range((y + half) % step, n, step):
                near = [h[y + dy][x + dx] for dy, dx in ((-half, 0), (half, 0), (0, -half), (0, half))
                        if 0 <= y + dy < n and 0 <= x + dx < n]
                h[y][x] = sum(near) / len(near) + rng.uniform(-scale, scale)
        step, scale = half, scale * 0.55
    return h


def main():
    level = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    h = terrain(level, random.Random(4))
    n = len(h)
    out = ["b 0.2 0.3 0.6", "v", "from -1.6 -2.4 1.5", "at 0 0 0.1", "up 0 0 1", "angle 45", "hither 0.01",
           "resolution 512 512", "l -5 -8 10", "f 0.55 0.5 0.4 0.9 0 0 0 1"]

    def point(x, y):
        return "%.6f %.6f %.6f" % (-1 + 2 * x / (n - 1), -1 + 2 * y / (n - 1), 0.6 * h[y][x])

    for y in range(n - 1):
        for x in range(n - 1):
            for tri in (((x, y), (x + 1, y), (x + 1, y + 1)), ((x, y), (x + 1, y + 1), (x, y + 1))):
                out.append("p 3")
                out += [point(*p) for p in tri]
    out.append("f 1 1 1 0.05 0.1 50 0.85 1.5")
    for cx, cy in ((-0.4, -0.3), (0.2, -0.5), (0.5, 0.2), (-0.2, 0.4)):
        out.append("s %.3f %.3f %.3f 0.18" % (cx, cy, 0.5 + 0.1 * cx))
    print("\n".join(out))


if __name__ == "__main__":
    main()
