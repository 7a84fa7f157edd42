#!/usr/bin/env python3
"""Writes a branching tree as NFF, after the SPD's "tree": tapered branches (truncated
cones), each splitting into three shorter, thinner ones, spheres for leaves at the tips,
on a ground polygon, two lights. Level 7: 3,280 cones and 2,187 spheres. A scene of
thousands of cones among spheres, for bench/compare-nff.sh. The shape, view and lights
are this script's own, not the SPD's.

    python3 bench/tree_nff.py [LEVEL] > tree.nff
"""
import math
import sys


def add(a, b, s=1.0):
    return tuple(x + s * y for x, y in zip(a, b))


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return tuple(x / n for x in v)


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def branch(base, direction, length, radius, level, spin, out):
    tip = add(base, direction, length)
    out.append("c")
    out.append("%.6f %.6f %.6f %.6f" % (*base, radius))
    out.append("%.6f %.6f %.6f %.6f" % (*tip, radius * 0.7))
    if level == 0:
        out.append("s %.6f %.6f %.6f %.6f" % (*tip, length * 0.45))
        return
    # Three children, 40 degrees off this branch, a third of a turn apart, each level
    # turned a little further so that the crown does not line up.
    side = unit(cross(direction, (0.3, 0.5, 0.81) if abs(direction[2]) < 0.9 else (1.0, 0.0, 0.0)))
    other = cross(direction, side)
    for k in range(3):
        a = spin + k * 2 * math.pi / 3
        around = add(tuple(math.cos(a) * x for x in side), other, math.sin(a))
        child = unit(add(tuple(math.cos(math.radians(40)) * x for x in direction), around,
                         math.sin(math.radians(40))))
        branch(tip, child, length * 0.72, radius * 0.7, level - 1, spin + 0.7, out)


def main():
    level = int(sys.argv[1]) if len(sys.argv) > 1 else 7
    out = ["b 0.078 0.361 0.753", "v", "from 4.5 -5.5 2.6", "at 0 0 1.4", "up 0 0 1", "angle 45",
           "hither 0.01", "resolution 512 512", "l 6 -3 9", "l -4 -6 5",
           "f 0.55 0.4 0.25 0.9 0 0 0 1"]  # the branches' colour
    parts = []
    branch((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 0.12, level, 0.0, parts)
    # Branches (three lines each) in brown first, then the leaves in green.
    body, leaves, i = [], [], 0
    while i < len(parts):
        if parts[i] == "c":
            body.extend(parts[i:i + 3])
            i += 3
        else:
            leaves.append(parts[i])
            i += 1
    out.extend(body)
    out.append("f 0.2 0.6 0.15 0.7 0.3 20 0 1")
    out.extend(leaves)
    out.append("f 0.6 0.55 0.45 0.8 0.2 10 0.3 1")
    out.extend(["p 4", "-12 -12 0", "12 -12 0", "12 12 0", "-12 12 0"])
    print("\n".join(out))


if __name__ == "__main__":
    main()
