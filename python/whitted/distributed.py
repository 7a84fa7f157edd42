"""Rendering on a Dask cluster: one image as tiles, or many frames.

Works with any ``distributed.Client``: a ``LocalCluster``, ``dask-jobqueue`` on an HPC
cluster, Kubernetes, or a scheduler and workers started by hand (docs/distributed.md).
Workers need ``whitted`` installed and, for scenes that name files (textures, meshes),
those files at the same absolute paths.

- The scene goes to the workers once (``client.scatter``, to every worker, so losing one
  loses no copy), not with every task; frames that share geometry share that copy.
- Each tile is a region render (:func:`whitted.render` with ``region=``) on the full
  image's tile grid, so the assembled image equals the local render bit for bit.
- A worker that dies takes only its running tasks with it: the scheduler reruns them
  elsewhere (``retries`` also covers exceptions inside a task).
"""

from __future__ import annotations

import itertools
import os
import secrets
from typing import Any, Iterable, List, Optional, Sequence

import numpy as np

import whitted
from ._scene import MAX_FRAME, Scene, _Base, _count


def _tiles(width: int, height: int, tile: int):
    return [
        (x, y, min(x + tile, width), min(y + tile, height))
        for y in range(0, height, tile)
        for x in range(0, width, tile)
    ]


# One render thread per task: a worker runs as many tasks at once as it has threads
# (``dask worker --nthreads``), so give workers as many threads as cores.
def _render_region(scene: Scene, region, spp, max_depth) -> np.ndarray:
    return whitted.render(scene, spp=spp, max_depth=max_depth, region=region, threads=1)


def _render_frame(base: _Base, camera, spp, max_depth, frame=None) -> bytes:
    scene = Scene.__new__(Scene)
    scene._base, scene.camera, scene.spp, scene.max_depth = base, camera, spp, max_depth
    scene._frame = frame
    image = whitted.render(scene, threads=1)
    return whitted.to_png_bytes(image, color=scene.color)


def _render_frames(base: _Base, frames) -> List[bytes]:
    """One task of :func:`render_many`: frames (camera, spp, max_depth, frame) of one
    geometry, one after the other, as PNG bytes."""
    return [_render_frame(base, *frame) for frame in frames]


def _bar(progress: Any, total: Optional[int], unit: str):
    """A tqdm bar for progress=True; none if tqdm is not installed (it is optional)."""
    if progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            return None
        return tqdm(total=total, unit=unit)
    return None


def render_tiles(
    scene: Scene,
    client,
    tile: int = 256,
    spp: Optional[int] = None,
    max_depth: Optional[int] = None,
    retries: int = 2,
    progress: Any = None,
) -> np.ndarray:
    """Renders `scene` as tiles of `tile` pixels on the cluster behind `client` and
    returns the assembled image, identical bit for bit to ``whitted.render(scene)``.

    `tile` should be a multiple of 16 (the renderer's own tile grid), so no pixel is
    traced twice. `progress`: True for a tqdm bar, or a callable (done, total).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene: expected whitted.Scene, got {type(scene).__name__}")
    tile = _count("tile", tile, 1, 1 << 20)
    from distributed import as_completed

    width, height = scene.width, scene.height
    regions = _tiles(width, height, tile)
    [remote] = client.scatter([scene], broadcast=True, hash=False)
    futures = {
        client.submit(_render_region, remote, r, spp, max_depth, retries=retries, pure=False): r for r in regions
    }
    image = np.empty((height, width, 3), dtype=np.float32)
    bar = _bar(progress, len(regions), "tile")
    try:
        for done, future in enumerate(as_completed(futures), 1):
            x0, y0, x1, y1 = futures[future]
            image[y0:y1, x0:x1] = future.result()
            future.release()
            if bar is not None:
                bar.update(1)
            elif callable(progress):
                progress(done, len(regions))
    finally:
        if bar is not None:
            bar.close()
        for f in futures:
            f.cancel()
        remote.release()
    return image


def _write_atomically(path: str, data: bytes) -> None:
    folder = os.path.dirname(path) or "."
    # Not mkstemp: it makes the file private (0600), and an image should get a new
    # file's usual mode (0666 less the umask), as open() gives it.
    tmp = os.path.join(folder, f".whitted-{os.getpid()}-{secrets.token_hex(8)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def render_many(
    scenes: Iterable[Scene],
    client,
    out_dir: os.PathLike,
    name: str = "frame_{:04d}.png",
    spp: Optional[int] = None,
    max_depth: Optional[int] = None,
    retries: int = 2,
    in_flight: Optional[int] = None,
    progress: Any = True,
    numbers: Optional[Sequence[int]] = None,
    frames_per_task: Optional[int] = None,
) -> List[str]:
    """Renders each scene (frames of an animation, say) on the cluster to a numbered PNG
    file in `out_dir` (``name.format(i)``), each written (atomically) as it arrives.

    Workers send back PNG bytes, not float images, and at most `in_flight` frames are
    out at a time (default: four times the cluster's threads times `frames_per_task`,
    sent in batches), so memory stays bounded however many frames there are. A task
    renders up to `frames_per_task` frames one after the other (default: enough that
    each thread still gets eight tasks, at most 4; 1 when the number of scenes is
    unknown), fewer as the last frames go out: every task costs the scheduler and the
    client some milliseconds of CPU, which on a small cluster comes out of the
    rendering. Scenes that share geometry (made with ``scene.copy(...)`` or
    ``scene.at_frame(...)``) send it once. `numbers`, if given, numbers the files
    instead of the scenes' positions. Returns the paths in frame order.
    """
    from distributed import as_completed

    out_dir = os.fspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    threads = sum(client.nthreads().values()) or 1
    total = len(scenes) if hasattr(scenes, "__len__") else None
    if frames_per_task is None:
        frames_per_task = 1 if total is None else max(1, min(4, total // (8 * threads)))
    per_task = _count("frames_per_task", frames_per_task, 1, 1 << 20)
    if in_flight is None:
        in_flight = 4 * threads * per_task
    in_flight = _count("in_flight", in_flight, 1, 1 << 20)
    bar = _bar(progress, total, "frame")
    shared = {}  # id(base) -> (base, future): geometry sent once
    tasks: dict = {}  # future key -> (future, [(i, path), ...])
    out = 0  # frames in flight
    pending = as_completed(with_results=True)
    frames = enumerate(scenes)

    def task_size(i: int) -> int:
        """Frames for the task that frame `i` would start: `per_task`, tapering to one
        as the last frames go out (guided scheduling), so that the workers finish
        together instead of one waiting on another's last long task."""
        if total is None:
            return per_task
        return max(1, min(per_task, (total - i) // (4 * threads)))

    def submit(n: int) -> None:
        """Sends the next `n` frames, up to `task_size` to a task (fewer where the
        geometry changes), in one message: a round trip to the scheduler per task would
        cost the client several ms of CPU a task."""
        nonlocal out
        bases, jobs, files, limit = [], [], [], 0
        for i, scene in itertools.islice(frames, n):
            if not isinstance(scene, Scene):
                raise TypeError(f"scenes[{i}]: expected whitted.Scene, got {type(scene).__name__}")
            key = id(scene._base)
            if key not in shared:
                [remote] = client.scatter([scene._base], broadcast=True, hash=False)
                shared[key] = (scene._base, remote)
            s = scene.spp if spp is None else spp
            d = scene.max_depth if max_depth is None else max_depth
            number = i if numbers is None else numbers[i]
            job = (scene.camera, s, d, getattr(scene, "_frame", None))
            path = os.path.join(out_dir, name.format(number))
            if not bases or bases[-1] is not shared[key][1] or len(jobs[-1]) >= limit:
                bases.append(shared[key][1])
                jobs.append([])
                files.append([])
                limit = task_size(i)
            jobs[-1].append(job)
            files[-1].append((i, path))
        if not jobs:
            return
        futures = client.map(_render_frames, bases, jobs, retries=retries, pure=False)
        for future, chunk in zip(futures, files):
            tasks[future.key] = (future, chunk)
            out += len(chunk)
        pending.update(futures)

    try:
        submit(in_flight)
        written = []
        # Refill in batches when half the frames in flight have come back.
        for batch in pending.batches():
            for future, images in batch:
                _, chunk = tasks.pop(future.key)
                for (i, path), data in zip(chunk, images):
                    _write_atomically(path, data)
                    written.append((i, path))
                    if bar is not None:
                        bar.update(1)
                    elif callable(progress):
                        progress(len(written), total)
                out -= len(chunk)
                future.release()
            if out <= in_flight // 2:
                submit(in_flight - out)
    finally:
        if bar is not None:
            bar.close()
        if tasks:  # stopped early (an error, Ctrl-C): the frames still out are not wanted
            client.cancel([future for future, _ in tasks.values()])
        for _, remote in shared.values():
            remote.release()
    return [p for _, p in sorted(written)]


def render_frames(
    scene: Scene,
    client,
    out_dir: os.PathLike,
    frames: Optional[Iterable[int]] = None,
    name: str = "frame_{:04d}.png",
    **options: Any,
) -> List[str]:
    """Renders frames of an animated scene (a TOML file with ``keys``) on the cluster,
    one task per frame, each to ``name.format(frame)`` in `out_dir`. `frames` defaults
    to the scene's own range (``scene.frames``, both ends included). The scene's
    geometry goes to the workers once; each worker applies its frame's values. Other
    options are :func:`render_many`'s. Returns the paths in frame order.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene: expected whitted.Scene, got {type(scene).__name__}")
    if frames is None:
        span = scene.frames
        if span is None:
            raise ValueError("the scene has no keys: give frames=range(first, last + 1)")
        frames = range(span[0], span[1] + 1)
    numbers = [_count("frames", f, 0, MAX_FRAME) for f in frames]
    return render_many([scene.at_frame(f) for f in numbers], client, out_dir, name=name, numbers=numbers, **options)
