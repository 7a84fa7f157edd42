"""A turntable of the room on a local Dask cluster: the camera circles the middle
sphere, each frame is rendered by a worker and written as it arrives.

    python examples/python/turntable.py --frames 60 --workers 2 --out turntable/
    ffmpeg -i turntable/frame_%04d.png turntable.mp4     # if you want a video
"""

import argparse
import math
import os
import time

import whitted
import whitted.distributed as wd
from distributed import Client, LocalCluster

HERE = os.path.dirname(os.path.abspath(__file__))
ROOM = os.path.join(HERE, "..", "..", "scenes", "room.toml")


def turntable(scene: whitted.Scene, frames: int, radius: float):
    """Frames circling the camera's look-at point at `radius`, starting from where the
    camera is; they share the scene's geometry, so the cluster receives it once."""
    cam = scene.camera
    cx, cy, cz = cam.look_at
    start = math.atan2(cam.position[0] - cx, cam.position[2] - cz)
    for i in range(frames):
        a = start + 2 * math.pi * i / frames
        yield scene.copy(position=(cx + radius * math.sin(a), cam.position[1], cz + radius * math.cos(a)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--size", type=int, default=400)
    ap.add_argument("--radius", type=float, default=35.0, help="orbit radius (the room is 80 wide)")
    ap.add_argument("--out", default="turntable")
    args = ap.parse_args()
    scene = whitted.load(ROOM, width=args.size, height=args.size)
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, host="127.0.0.1",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        start = time.perf_counter()
        paths = wd.render_many(list(turntable(scene, args.frames, args.radius)), client, args.out)
        took = time.perf_counter() - start
    print(f"{len(paths)} frames in {took:.1f} s -> {args.out}/")


if __name__ == "__main__":
    main()
