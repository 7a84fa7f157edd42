"""Scaling of whitted.distributed on this machine: 1 and 2 single-threaded Dask workers.

    python bench/distributed.py [--frames 60] [--size 800] [--rounds 3] [--json out.json]

Measures (all on 127.0.0.1, a LocalCluster of worker processes):
- a turntable of the room (60 frames, 800x800) through render_many, 1 worker then 2;
- one 3840x2160 room through render_tiles (256-pixel tiles), 1 worker then 2;
- each in --rounds rounds (default 3), 1 and 2 workers alternating, the best taken;
- per-task overhead: the wall time of many empty tasks per task, and for the tiles, the
  workers' busy time beyond the renders' own time, per task;
- the serial part on the client: loading the scene, scattering it, assembling the tiles.
Then projects the speed-up to N workers (Amdahl, with the per-task overhead); the
figures go into docs/distributed.md. Build the package with `maturin develop --release`.
"""

import argparse
import json
import math
import os
import sys
import time

# This file's folder goes first on sys.path, where its name would hide Dask's package.
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != HERE]

import numpy as np  # noqa: E402
from distributed import Client, LocalCluster, as_completed  # noqa: E402

import whitted  # noqa: E402
import whitted.distributed as wd  # noqa: E402

ROOM = os.path.join(HERE, "..", "scenes", "room.toml")


def turntable(scene, frames, radius=35.0):
    """The camera circling the middle sphere inside the room (80 wide)."""
    cam = scene.camera
    cx, _, cz = cam.look_at
    start = math.atan2(cam.position[0] - cx, cam.position[2] - cz)
    for i in range(frames):
        a = start + 2 * math.pi * i / frames
        yield scene.copy(position=(cx + radius * math.sin(a), cam.position[1], cz + radius * math.cos(a)))


def timed_region(scene, region):
    """The tile, its wall time and the worker process's CPU time for it (the render's
    own threads included): on a shared machine, CPU time is the work, wall time what
    the worker got of the cores."""
    t, c = time.perf_counter(), time.process_time()
    image = whitted.render(scene, region=region, threads=1)
    return image, time.perf_counter() - t, time.process_time() - c


def tiles_run(client, scene, tile):
    """render_tiles' steps, timed: scatter, tasks (with their own render time), assembly."""
    t0 = time.perf_counter()
    [remote] = client.scatter([scene], broadcast=True, hash=False)
    t_scatter = time.perf_counter() - t0
    regions = wd._tiles(scene.width, scene.height, tile)
    futures = {client.submit(timed_region, remote, r, pure=False): r for r in regions}
    image = np.empty((scene.height, scene.width, 3), np.float32)
    busy, cpu, assemble = 0.0, 0.0, 0.0
    for f in as_completed(futures):
        part, took, used = f.result()
        busy += took
        cpu += used
        x0, y0, x1, y1 = futures[f]
        t = time.perf_counter()
        image[y0:y1, x0:x1] = part
        assemble += time.perf_counter() - t
        f.release()
    wall = time.perf_counter() - t0
    remote.release()
    return dict(wall=wall, scatter=t_scatter, busy=busy, cpu=cpu, assemble=assemble, tasks=len(regions)), image


def empty_tasks(client, n=400):
    def nothing(i):
        return i

    client.gather(client.map(nothing, range(20), pure=False))  # warm up
    t = time.perf_counter()
    client.gather(client.map(nothing, range(n), pure=False))
    return (time.perf_counter() - t) / n


def one_config(workers, args, scene):
    out = {"workers": workers}
    with LocalCluster(n_workers=workers, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                      processes=True) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        client.run(lambda: __import__("whitted").render(scene.copy(width=16, height=16)))  # warm the import
        out["empty_task_s"] = empty_tasks(client)
        # The turntable: frames written as they arrive.
        frames = list(turntable(scene, args.frames))
        t = time.perf_counter()
        paths = wd.render_many(frames, client, args.out_dir, progress=False)
        out["turntable_s"] = time.perf_counter() - t
        assert len(paths) == args.frames
        # One 4K frame in tiles.
        big = scene.copy(width=3840, height=2160)
        stats, image = tiles_run(client, big, args.tile)
        out["tiles"] = stats
        out["tiles_mean"] = float(image.mean())
    return out


def main():
    ap = argparse.ArgumentParser(description="whitted.distributed scaling on this machine")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--size", type=int, default=800)
    ap.add_argument("--tile", type=int, default=256)
    ap.add_argument("--out-dir", default="/tmp/whitted-bench-frames")
    ap.add_argument("--rounds", type=int, default=3, help="runs of each configuration, alternating; best taken")
    ap.add_argument("--json")
    args = ap.parse_args()

    t = time.perf_counter()
    scene = whitted.load(ROOM, width=args.size, height=args.size)
    load_s = time.perf_counter() - t
    # One frame and one 4K frame on one thread in this process: the work to share out.
    t = time.perf_counter()
    whitted.render(scene, threads=1)
    frame_s = time.perf_counter() - t

    # Rounds alternate 1 and 2 workers; each figure below is the best of its rounds
    # (this host is shared: a run's wall time says as much about other jobs as about us).
    rounds = []
    for k in range(args.rounds):
        r = [one_config(w, args, scene) for w in (1, 2)]
        rounds.append(r)
        print(f"round {k + 1}: turntable 1 worker {r[0]['turntable_s']:.2f} s, 2 workers "
              f"{r[1]['turntable_s']:.2f} s ({r[0]['turntable_s'] / r[1]['turntable_s']:.2f}x); 4K tiles "
              f"{r[0]['tiles']['wall']:.2f} s, {r[1]['tiles']['wall']:.2f} s", flush=True)

    def best(w, key):
        return min((r[w] for r in rounds), key=key)

    one = dict(best(0, lambda r: r["tiles"]["wall"]))
    two = dict(best(1, lambda r: r["tiles"]["wall"]))
    one["turntable_s"] = best(0, lambda r: r["turntable_s"])["turntable_s"]
    two["turntable_s"] = best(1, lambda r: r["turntable_s"])["turntable_s"]
    runs = [one, two]
    result = dict(load_s=load_s, frame_1thread_s=frame_s, cpus=os.cpu_count(), runs=runs, rounds=rounds,
                  load_avg=os.getloadavg(), python=sys.version.split()[0])

    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the end")
    print(f"scene load (client, serial): {load_s * 1e3:.1f} ms; one {args.size}x{args.size} frame, "
          f"1 thread, in-process: {frame_s * 1e3:.1f} ms")
    print(f"turntable, {args.frames} frames {args.size}x{args.size}, best of {args.rounds}: 1 worker {one['turntable_s']:.2f} s, "
          f"2 workers {two['turntable_s']:.2f} s, speed-up {one['turntable_s'] / two['turntable_s']:.2f}x")
    for r in runs:
        s = r["tiles"]
        per_task = (r["workers"] * s["wall"] - s["busy"]) / s["tasks"]
        r["tile_overhead_s"] = per_task
        print(f"3840x2160 in {s['tasks']} tiles, {r['workers']} worker(s): {s['wall']:.2f} s "
              f"(renders {s['busy']:.2f} s of worker wall time, {s['cpu']:.2f} s CPU; scatter {s['scatter'] * 1e3:.1f} ms, "
              f"assembly {s['assemble'] * 1e3:.1f} ms); overhead per tile task {per_task * 1e3:.1f} ms; "
              f"empty task {r['empty_task_s'] * 1e3:.2f} ms")
    print(f"tiles speed-up 2 vs 1 worker: {one['tiles']['wall'] / two['tiles']['wall']:.2f}x")

    # Amdahl with the measured overhead, from the one-worker run (least disturbed by the
    # second worker competing for this machine's cores):
    #   4K frame:   T(N) = serial + (work + tasks * overhead) / N
    #   turntable:  T(N) = load + ceil(frames / N) * (time per frame, overhead included)
    s = one["tiles"]
    serial = load_s + s["scatter"] + s["assemble"]
    work, overhead = s["busy"], max(one["tile_overhead_s"], 0.0)
    per_frame = (one["turntable_s"]) / args.frames
    t1 = serial + work + s["tasks"] * overhead
    tt1 = load_s + args.frames * per_frame
    print(f"projection (one-worker figures): 4K serial {serial:.3f} s, work {work:.2f} s, "
          f"{s['tasks']} tasks x {overhead * 1e3:.1f} ms; turntable {per_frame * 1e3:.0f} ms a frame")
    print("  N     4K T(N) s  speed-up   turntable T(N) s  speed-up")
    proj = []
    for n in (1, 2, 4, 8, 16, 32, 64):
        tn = serial + (work + s["tasks"] * overhead) / n
        ttn = load_s + math.ceil(args.frames / n) * per_frame
        proj.append(dict(n=n, tiles_s=tn, tiles_speedup=t1 / tn, turntable_s=ttn, turntable_speedup=tt1 / ttn))
        print(f"  {n:<5} {tn:9.3f}  {t1 / tn:8.1f}   {ttn:16.3f}  {tt1 / ttn:8.1f}")
    result["projection"] = proj
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
