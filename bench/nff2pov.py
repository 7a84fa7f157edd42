#!/usr/bin/env python3
"""Writes an NFF scene as POV-Ray 3.7 reads it, the way Eric Haines' SPD generator
writes its POV-Ray files (the sphereflake.pov of the POV-Ray harness): camera vectors
from the view, lights (1/sqrt(n) each where the file gives no colour), one texture per
`f` line (diffuse Kd; Ks as phong with phong_size Shine and as reflection; T and the
index as refraction), spheres, cylinders and cones (open), polygons as triangle fans,
patches as smooth triangles. For timing Whitted against POV-Ray on any NFF scene
(bench/compare-nff.sh); the colours need not match Whitted's to the level, the work
(rays, objects, depth) does.

    python3 bench/nff2pov.py scene.nff > scene.pov
"""
import math
import sys


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def vec(v):
    return "<%s>" % ", ".join("%g" % x for x in v)


def convert(lines, out):
    view, lights, textures = {}, [], 0
    it = iter(lines)
    for raw in it:
        w = raw.split()
        if not w or w[0].startswith("#"):
            continue
        k = w[0]
        if k == "v":
            for _ in range(6):
                f = next(it).split()
                view[f[0]] = [float(x) for x in f[1:]]
            fr, at, up = view["from"], view["at"], view["up"]
            d = unit([a - b for a, b in zip(at, fr)])
            scale = 2 * math.tan(math.radians(view["angle"][0]) / 2)
            right = unit(cross(d, up))
            upv = unit(cross(right, d))
            res = view.get("resolution", [512, 512])
            aspect = res[0] / res[1]
            out.write("camera {\n    location %s\n    direction %s\n    right %s\n    up %s\n}\n\n"
                      % (vec(fr), vec(d), vec([x * scale * aspect for x in right]), vec([x * scale for x in upv])))
        elif k == "b":
            out.write("background { color rgb %s }\n\n" % vec([float(x) for x in w[1:4]]))
        elif k == "l":
            lights.append(([float(x) for x in w[1:4]], [float(x) for x in w[4:7]] if len(w) >= 7 else None))
        elif k == "f":
            if lights is not None:
                for pos, col in lights:
                    c = col or [1 / math.sqrt(len(lights))] * 3
                    out.write("light_source { %s color rgb %s }\n\n" % (vec(pos), vec(c)))
                lights = None
            r, g, b, kd, ks, shine, t, ior = (float(x) for x in w[1:9])
            textures += 1
            fin = ["ambient %g" % (0.2 if ks == 0 else 0), "diffuse %g" % kd]
            if ks:
                fin += ["phong %g phong_size %g" % (ks, shine), "reflection %g" % ks]
            if t:
                fin += ["refraction 1 ior %g" % ior]
            pig = "color rgbf <%g, %g, %g, %g>" % (r, g, b, t) if t else "color rgb <%g, %g, %g>" % (r, g, b)
            out.write("#declare txt%03d = texture { pigment { %s } finish { %s } }\n\n" % (textures, pig, " ".join(fin)))
        elif k == "s":
            x, y, z, rad = (float(v) for v in w[1:5])
            out.write("sphere { %s, %g texture { txt%03d } }\n" % (vec([x, y, z]), rad, textures))
        elif k == "c":
            b4 = [float(x) for x in next(it).split()[:4]]
            a4 = [float(x) for x in next(it).split()[:4]]
            base, br, apex, ar = b4[:3], b4[3], a4[:3], a4[3]
            if abs(br) == abs(ar):
                out.write("cylinder { %s, %s, %g open texture { txt%03d } }\n" % (vec(base), vec(apex), abs(br), textures))
            else:
                out.write("cone { %s, %g, %s, %g open texture { txt%03d } }\n"
                          % (vec(base), abs(br), vec(apex), abs(ar), textures))
        elif k in ("p", "pp"):
            n = int(w[1])
            pts = [[float(x) for x in next(it).split()] for _ in range(n)]
            for i in range(1, n - 1):
                a, b_, c = pts[0], pts[i], pts[i + 1]
                if k == "p":
                    out.write("triangle { %s, %s, %s texture { txt%03d } }\n" % (vec(a[:3]), vec(b_[:3]), vec(c[:3]), textures))
                else:
                    out.write("smooth_triangle { %s, %s, %s, %s, %s, %s texture { txt%03d } }\n"
                              % (vec(a[:3]), vec(a[3:6]), vec(b_[:3]), vec(b_[3:6]), vec(c[:3]), vec(c[3:6]), textures))


if __name__ == "__main__":
    with open(sys.argv[1]) as f:
        convert(f.read().splitlines(), sys.stdout)
