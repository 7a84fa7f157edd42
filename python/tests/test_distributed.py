"""whitted.distributed on Dask: tiles and frames on a LocalCluster, on a scheduler and
workers started as separate commands, and with a worker killed mid-render. All traffic
stays on 127.0.0.1; every process started here is stopped here."""

import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

import whitted
import whitted.distributed as wd
from conftest import ROOM, ROOT

import distributed  # noqa: E402  (a test dependency: a missing one fails, not skips)


def room(**kw):
    return whitted.load(ROOM, **kw)


@pytest.fixture(scope="module")
def local_client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None, processes=True
    )
    client = distributed.Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


@pytest.mark.parametrize("tile,spp", [(64, 1), (48, 4), (40, 1)])
def test_render_tiles_on_a_local_cluster_equals_the_local_render(local_client, tile, spp):
    scene = room(width=150, height=110, spp=spp)
    tiled = wd.render_tiles(scene, local_client, tile=tile)
    assert tiled.dtype == np.float32 and tiled.shape == (110, 150, 3) and tiled.flags.c_contiguous
    assert tiled.tobytes() == whitted.render(scene).tobytes()


def test_both_workers_render_tiles(local_client):
    scene = room(width=160, height=160)
    seen = set()
    futures = [local_client.submit(wd._render_region, scene, r, None, None, pure=False)
               for r in wd._tiles(160, 160, 32)]
    distributed.wait(futures)
    for f in futures:
        seen |= {w for w in local_client.who_has([f])[f.key]}
    assert len(seen) == 2


def test_render_many_writes_every_frame(local_client, tmp_path):
    base = room(width=48, height=40)
    frames = []
    for i in range(5):
        angle = 2 * np.pi * i / 5
        frames.append(base.copy(position=(60 * np.sin(angle), 0.0, -60 + 60 * np.cos(angle)), look_at=(0, 0, -60)))
    paths = wd.render_many(frames, local_client, tmp_path / "out", progress=False, in_flight=3)
    assert [os.path.basename(p) for p in paths] == [f"frame_{i:04d}.png" for i in range(5)]
    for frame, path in zip(frames, paths):
        with open(path, "rb") as f:
            assert f.read() == whitted.to_png_bytes(whitted.render(frame))
    assert sorted(os.listdir(tmp_path / "out")) == sorted(os.path.basename(p) for p in paths)
    # Different frames: the camera moved.
    assert len({open(p, "rb").read() for p in paths}) == 5
    # A scene whose file asks for sRGB output gets sRGB frames, as `whitted render` writes.
    srgb = tmp_path / "srgb.toml"
    srgb.write_text(ROOM.read_text().replace("[settings]\n", '[settings]\ncolor = "srgb"\n', 1))
    frame = whitted.load(srgb, width=48, height=40)
    (path,) = wd.render_many([frame], local_client, tmp_path / "srgb", progress=False)
    with open(path, "rb") as f:
        assert f.read() == whitted.to_png_bytes(whitted.render(frame), color="srgb")
    if os.name == "posix":  # a new file's usual mode, not mkstemp's private 0600
        mask = os.umask(0o022)
        os.umask(mask)
        assert {os.stat(p).st_mode & 0o777 for p in paths} == {0o666 & ~mask}


def test_render_many_packs_frames_into_tasks(local_client, tmp_path):
    """Several frames to a task, a task never mixing two geometries, single frames at
    the end: the same files as one frame a task, in order, each the local render."""
    a, b = room(width=24, height=20), whitted.load(ROOT / "scenes" / "shapes.toml", width=24, height=20)
    frames = [s.copy(position=(k, 5, 30)) for s in (a, b, a) for k in range(8)]

    class Spy:
        """The client, noting the frames of each task sent."""

        def __init__(self, client):
            self.client, self.tasks = client, []

        def map(self, func, bases, jobs, **kw):
            self.tasks += [(b, len(j)) for b, j in zip(bases, jobs)]
            return self.client.map(func, bases, jobs, **kw)

        def __getattr__(self, name):
            return getattr(self.client, name)

    spy = Spy(local_client)
    paths = wd.render_many(frames, spy, tmp_path / "out", progress=False, frames_per_task=3)
    sizes = [n for _, n in spy.tasks]
    # 24 frames on 2 threads, all sent at once: a task takes (frames left) / 8 of them,
    # at most 3, and ends where the scene changes (frame 8); never two scenes.
    assert sizes == [3, 2, 2, 1, 2] + [1] * 14, sizes
    assert len({b.key for b, _ in spy.tasks}) == 2
    assert [os.path.basename(p) for p in paths] == [f"frame_{i:04d}.png" for i in range(24)]
    for frame, path in zip(frames, paths):
        with open(path, "rb") as f:
            assert f.read() == whitted.to_png_bytes(whitted.render(frame))
    assert sorted(os.listdir(tmp_path / "out")) == sorted(os.path.basename(p) for p in paths)
    with pytest.raises(ValueError, match="frames_per_task"):
        wd.render_many(frames, local_client, tmp_path / "x", progress=False, frames_per_task=0)


def test_scenes_built_in_code_render_on_the_cluster(local_client):
    scene = whitted.Scene(whitted.Camera((0, 0, 5), (0, 0, 0), width=70, height=50))
    scene.add(whitted.Sphere((0, 0, 0), 1), whitted.Material(color=(1, 0.3, 0.1), reflectivity=0.2))
    scene.add(whitted.Mesh(np.array([[-2, -1, -1], [2, -1, -1], [0, 2, -2]]), [[0, 1, 2]]), whitted.Material())
    scene.add(whitted.PointLight((3, 4, 5)))
    assert wd.render_tiles(scene, local_client, tile=32).tobytes() == whitted.render(scene).tobytes()


def test_every_light_kind_and_glass_material_reach_the_workers(local_client):
    """The file's spot and directional lights, and lights and a Fresnel, absorbing glass
    added in code, survive the trip to the workers (pickled as text plus additions)."""
    scene = whitted.load(ROOT / "scenes" / "lights.toml", width=72, height=54)
    scene.add(whitted.SpotLight((-1, 4, 3), (0, -1, 0), 15, 25, color=(0, 1, 0), attenuation=(1, 0, 0.05)))
    scene.add(whitted.DirectionalLight((0, -1, -1), intensity=0.3))
    glass = whitted.Material(transparency=0.9, ior=1.5, fresnel=True, absorption=(0.8, 0.1, 0.6))
    scene.add(whitted.Sphere((0, 1, 2), 0.8), glass)
    assert "5 lights" in repr(scene)  # the file's three and two
    assert wd.render_tiles(scene, local_client, tile=32).tobytes() == whitted.render(scene).tobytes()


# -- a scheduler and workers started by hand ------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def dask_command() -> list:
    exe = os.path.join(os.path.dirname(sys.executable), "dask")
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "dask"]


class HandCluster:
    """`dask scheduler` and `dask worker` as separate processes, each in its own
    process group so that stopping it leaves nothing behind."""

    def __init__(self, workers: int):
        self.port = free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.procs = []
        # Without --dashboard-address, the HTTP server (health, metrics) would listen on
        # all interfaces (0.0.0.0:8787) even with --no-dashboard.
        local = ["--host", "127.0.0.1", "--no-dashboard", "--dashboard-address", "127.0.0.1:0"]
        self.start(["scheduler", "--port", str(self.port)] + local)
        for _ in range(workers):
            self.start(["worker", self.address, "--nthreads", "1", "--no-nanny", "--death-timeout", "30"] + local)

    def start(self, args):
        self.procs.append(subprocess.Popen(dask_command() + args, start_new_session=True,
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))

    def stop(self):
        for p in reversed(self.procs):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + 20
        for p in self.procs:
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        for p in self.procs:
            with pytest.raises(ProcessLookupError):
                os.killpg(p.pid, 0)  # no process of its group is left


def listening_addresses(pids):
    """The local addresses of the TCP sockets `pids` listen on (Linux: /proc)."""
    inodes = set()
    for pid in pids:
        for fd in os.listdir(f"/proc/{pid}/fd"):
            try:
                link = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if link.startswith("socket:["):
                inodes.add(link[8:-1])
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for row in list(f)[1:]:
                cols = row.split()
                if cols[3] == "0A" and cols[9] in inodes:  # LISTEN
                    found.append(cols[1].split(":")[0])
    return found


@pytest.fixture
def hand_cluster():
    cluster = HandCluster(workers=2)
    client = None
    try:
        client = distributed.Client(cluster.address, timeout=60)
        client.wait_for_workers(2, timeout=60)
        yield cluster, client
    finally:
        if client is not None:
            client.close()
        cluster.stop()


def test_render_tiles_on_a_scheduler_and_workers_started_by_hand(hand_cluster):
    cluster, client = hand_cluster
    workers = client.scheduler_info()["workers"]
    assert len(workers) == 2 and all(a.startswith("tcp://127.0.0.1:") for a in workers)
    if os.path.isdir("/proc/net"):
        # Every socket the scheduler and workers listen on is on the loopback address.
        found = listening_addresses([p.pid for p in cluster.procs])
        assert len(found) >= 3 and all(a in ("0100007F", "00000000000000000000000001000000") for a in found), found
    scene = room(width=130, height=90, spp=4)
    assert wd.render_tiles(scene, client, tile=32).tobytes() == whitted.render(scene).tobytes()


def test_a_worker_killed_during_render_tiles_costs_a_retry_not_the_image(hand_cluster):
    cluster, client = hand_cluster
    scene = room(width=320, height=320, spp=16)
    pids = client.run(os.getpid)  # worker address -> pid
    victim = sorted(pids.values())[0]
    killed = []

    def kill_after_first_tiles(done, total):
        if done == 2 and not killed:
            os.kill(victim, signal.SIGKILL)
            killed.append((done, total))

    image = wd.render_tiles(scene, client, tile=32, progress=kill_after_first_tiles)
    assert killed and killed[0][0] < killed[0][1], "the worker was not killed mid-render"
    assert cluster.procs[1 + [p.pid for p in cluster.procs[1:]].index(victim)].wait(timeout=10) == -signal.SIGKILL
    assert len(client.scheduler_info()["workers"]) == 1
    assert image.tobytes() == whitted.render(scene).tobytes()


def test_render_frames_writes_each_frame_of_an_animation(local_client, tmp_path):
    from test_render import ANIMATED

    scene = whitted.Scene.from_toml(ANIMATED, "anim.toml")
    paths = wd.render_frames(scene, local_client, tmp_path, frames=range(2, 5), progress=False)
    assert [os.path.basename(p) for p in paths] == ["frame_0002.png", "frame_0003.png", "frame_0004.png"]
    for f, p in zip(range(2, 5), paths):
        assert open(p, "rb").read() == whitted.to_png_bytes(whitted.render(scene, frame=f))
    # Without frames: the scene's own range.
    assert len(wd.render_frames(scene, local_client, tmp_path / "all", progress=False)) == 9
    with pytest.raises(ValueError):
        wd.render_frames(room(), local_client, tmp_path)
