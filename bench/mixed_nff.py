#!/usr/bin/env python3
"""Writes a test scene of thousands of mixed primitives as NFF, for
bench/compare-nff.sh: a smooth-shaded torus mesh (patches), spheres, cylinders and
cones on a floor, some reflective, one glass; three lights, as the SPD scenes have.
`--rings` writes instead 40 stacked rings of 25 spheres joined by thin tilted
cylinders (2,000 primitives, after the SPD's "rings"), whose long diagonal shapes
make loose bounding boxes.

    python3 bench/mixed_nff.py [--mesh 64] [--spheres 1000] [--rings] > mixed.nff
"""
import argparse
import math
import random


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", type=int, default=64, help="torus segments each way (2 n^2 triangles)")
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--sticks", type=int, default=300, help="cylinders and cones")
    ap.add_argument("--rings", action="store_true", help="the rings scene instead")
    a = ap.parse_args()
    if a.rings:
        print("\n".join(rings()))
        return
    rnd = random.Random(7)
    out = ["v", "from 0 -9 5", "at 0 0 0.8", "up 0 0 1", "angle 45", "hither 0.01", "resolution 512 512",
           "b 0.078 0.361 0.753", "l 4 -3 8", "l -6 -4 5", "l 1 6 7"]
    # Floor, matte.
    out += ["f 0.8 0.8 0.8 1 0 0 0 1", "p 4", "-12 -12 0", "12 -12 0", "12 12 0", "-12 12 0"]
    # Torus mesh, shiny, as smooth patches.
    out.append("f 0.9 0.5 0.2 0.6 0.4 30 0 1")
    n, big, small = a.mesh, 1.6, 0.5

    def torus(i, j):
        u, v = 2 * math.pi * i / n, 2 * math.pi * j / n
        c = (math.cos(u), math.sin(u))
        p = ((big + small * math.cos(v)) * c[0], (big + small * math.cos(v)) * c[1], 1.2 + small * math.sin(v))
        nrm = (math.cos(v) * c[0], math.cos(v) * c[1], math.sin(v))
        return "%.5f %.5f %.5f %.5f %.5f %.5f" % (p + nrm)

    for i in range(n):
        for j in range(n):
            a0, a1, b0, b1 = torus(i, j), torus(i + 1, j), torus(i, j + 1), torus(i + 1, j + 1)
            out += ["pp 3", a0, a1, b1, "pp 3", a0, b1, b0]
    # Spheres on the floor, matte or mirror-like.
    for k in range(a.spheres):
        x, y, r = rnd.uniform(-8, 8), rnd.uniform(-6, 10), rnd.uniform(0.05, 0.25)
        if k % 50 == 0:
            out.append("f %.2f %.2f %.2f 0.7 %.1f 20 0 1" % (rnd.random(), rnd.random(), rnd.random(), rnd.choice((0, 0.5))))
        out.append("s %.4f %.4f %.4f %.4f" % (x, y, r, r))
    # Cylinders and cones standing on it.
    out.append("f 0.3 0.7 0.3 0.8 0.2 10 0 1")
    for k in range(a.sticks):
        x, y, h, r = rnd.uniform(-8, 8), rnd.uniform(-6, 10), rnd.uniform(0.2, 1.0), rnd.uniform(0.03, 0.12)
        top = r if k % 2 else 0.0
        out += ["c", "%.4f %.4f 0 %.4f" % (x, y, r), "%.4f %.4f %.4f %.4f" % (x, y, h, top)]
    # A glass ball in front.
    out += ["f 1 1 1 0.1 0.5 100 0.85 1.5", "s 0 -3 0.8 0.8"]
    print("\n".join(out))


def rings():
    out = ["v", "from 2.1 1.3 1.7", "at 0 0 0", "up 0 0 1", "angle 45", "hither 0.01", "resolution 512 512",
           "b 0.078 0.361 0.753", "l 1.86 8.7 10.7", "l 5.5 -3.1 2.2", "l -8.4 -2 5.9",
           "f 1 0.75 0.33 0.8 0.2 10 0 1"]
    for ring in range(40):
        r, z = 0.2 + 0.02 * ring, -1.0 + 0.05 * ring
        cx, cy = 0.3 * math.cos(ring), 0.3 * math.sin(ring)
        angles = [2 * math.pi * k / 25 + ring * 0.3 for k in range(25)]
        pts = [(cx + r * math.cos(a), cy + r * math.sin(a), z + 0.05 * math.sin(3 * a)) for a in angles]
        for i, p in enumerate(pts):
            q = pts[(i + 1) % len(pts)]
            out += ["s %.4f %.4f %.4f 0.02" % p, "c", "%.4f %.4f %.4f 0.012" % p, "%.4f %.4f %.4f 0.012" % q]
    return out + ["f 0.8 0.8 0.8 1 0 0 0 0", "p 4", "-4 -4 -1.2", "4 -4 -1.2", "4 4 -1.2", "-4 4 -1.2"]


if __name__ == "__main__":
    main()
