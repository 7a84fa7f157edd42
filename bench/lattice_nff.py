#!/usr/bin/env python3
"""Writes a lattice as NFF, after the SPD's "lattice": spheres at the nodes of an N x N x N
grid, joined along the axes by thin cylinders (N = 9: 729 spheres and 1,944 cylinders),
two lights, seen from outside a corner so that rays cross many rods. A scene of
thousands of cylinders among spheres, for bench/compare-nff.sh. The grid, view and
lights are this script's own, not the SPD's.

    python3 bench/lattice_nff.py [N] > lattice.nff
"""
import sys


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 9
    mid = (n - 1) / 2
    out = ["b 0.1 0.1 0.1", "v", f"from {mid + 10} {mid + 6} {mid + 4}", f"at {mid} {mid} {mid}", "up 0 0 1",
           "angle 40", "hither 0.01", "resolution 512 512", "l 30 20 30", "l -10 30 20",
           "f 0.9 0.3 0.2 0.7 0.3 20 0 1"]
    nodes = [(x, y, z) for x in range(n) for y in range(n) for z in range(n)]
    out += [f"s {x} {y} {z} 0.2" for x, y, z in nodes]
    out.append("f 0.6 0.6 0.7 0.8 0.2 10 0 1")
    for x, y, z in nodes:
        for dx, dy, dz in ((1, 0, 0), (0, 1, 0), (0, 0, 1)):
            if max(x + dx, y + dy, z + dz) < n:
                out += ["c", f"{x} {y} {z} 0.08", f"{x + dx} {y + dy} {z + dz} 0.08"]
    print("\n".join(out))


if __name__ == "__main__":
    main()
