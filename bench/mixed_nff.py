#!/usr/bin/env python3
"""Writes a test scene of thousands of mixed primitives as NFF, for
bench/compare-nff.sh: a smooth-shaded torus mesh (patches), spheres, cylinders and
cones on a floor, some reflective, one glass; three lights, as the SPD scenes have.

    python3 bench/mixed_nff.py [--mesh 64] [--spheres 1000] > mixed.nff
"""
import argparse
import math
import random


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", type=int, default=64, help="torus segments each way (2 n^2 triangles)")
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--sticks", type=int, default=300, help="cylinders and cones")
    a = ap.parse_args()
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


if __name__ == "__main__":
    main()
