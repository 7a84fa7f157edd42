"""The binding: arrays, equality with the command line, regions, errors, the GIL,
interrupts, progress, scenes built in code and pickling."""

import os
import pickle
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import whitted
from conftest import ROOM


def room(**kw):
    kw.setdefault("width", 64)
    kw.setdefault("height", 48)
    return whitted.load(ROOM, **kw)


def test_render_returns_a_writable_c_contiguous_float32_array():
    image = whitted.render(room(spp=1))
    assert isinstance(image, np.ndarray)
    assert image.dtype == np.float32 and image.shape == (48, 64, 3)
    assert image.flags.c_contiguous and image.flags.writeable
    assert 0.05 < image.mean() < 1.0  # the room, not a black frame
    image[0, 0] = 7.0  # writable in place


def test_equals_the_command_lines_png_and_its_region(tmp_path, whitted_bin):
    cli, part = tmp_path / "cli.png", tmp_path / "part.png"
    args = [whitted_bin, "render", str(ROOM), "--width", "96", "--height", "80", "--spp", "4", "-q"]
    subprocess.run(args + ["-o", str(cli)], check=True)
    subprocess.run(args + ["--region", "21,9,77,63", "-o", str(part)], check=True)
    image = whitted.render(room(width=96, height=80, spp=4))
    # The same quantisation and encoder: the PNG files are byte for byte the same.
    assert whitted.to_png_bytes(image) == cli.read_bytes()
    assert whitted.to_png_bytes(image[9:63, 21:77]) == part.read_bytes()
    ours = tmp_path / "ours.png"
    whitted.write_png(image, ours)
    assert ours.read_bytes() == cli.read_bytes()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".whitted-")] == []
    # And the quantisation itself, written out in numpy: clamp, scale, round half up.
    q = (np.clip(image, 0, 1) * np.float32(255) + np.float32(0.5)).astype(np.uint8)
    assert q.shape == (80, 96, 3) and q.max() > 200


@pytest.mark.parametrize("spp", [1, 4, 5])
def test_a_region_is_that_part_of_the_full_render_bit_for_bit(spp):
    scene = room(width=100, height=70, spp=spp)
    full = whitted.render(scene)
    for r in [(0, 0, 100, 70), (16, 16, 48, 64), (3, 5, 97, 31), (50, 69, 51, 70), (99, 0, 100, 70)]:
        part = whitted.render(scene, region=r)
        assert part.shape == (r[3] - r[1], r[2] - r[0], 3)
        assert part.tobytes() == np.ascontiguousarray(full[r[1]:r[3], r[0]:r[2]]).tobytes(), r


def test_overrides_and_thread_counts():
    scene = room(width=40, height=30, spp=4, max_depth=3, fov=30.0)
    assert (scene.width, scene.height, scene.spp, scene.max_depth, scene.camera.fov) == (40, 30, 4, 3, 30.0)
    one = whitted.render(scene, threads=1)
    assert one.shape == (30, 40, 3)
    assert one.tobytes() == whitted.render(scene, threads=3).tobytes()
    assert one.tobytes() != whitted.render(scene, max_depth=1).tobytes()
    assert whitted.render(scene, spp=1).tobytes() != one.tobytes()


def test_scene_errors_carry_the_command_lines_message(tmp_path, whitted_bin):
    bad = tmp_path / "bad.toml"
    text = ROOM.read_text().replace("radius = ", "radius = -", 1)
    assert text != ROOM.read_text()
    bad.write_text(text)
    with pytest.raises(whitted.SceneError) as err:
        whitted.load(bad)
    msg = str(err.value)
    assert msg.startswith(f"{bad}:") and "radius: must be > 0" in msg, msg
    line = int(msg.split(":")[1])
    assert "radius = -" in text.splitlines()[line - 1]
    cli = subprocess.run([whitted_bin, "render", str(bad), "-o", str(tmp_path / "x.png")], capture_output=True, text=True)
    assert cli.returncode != 0 and cli.stderr.strip() == f"error: {msg}"
    with pytest.raises(whitted.SceneError, match="cannot read the scene"):
        whitted.load(tmp_path / "missing.toml")
    with pytest.raises(whitted.SceneError, match=r"^<string>:2:12: position: "):
        whitted.Scene.from_toml("[camera]\nposition = 1\n")
    assert issubclass(whitted.SceneError, Exception)


def test_bad_arguments_raise_value_and_type_errors(tmp_path):
    scene = room()
    for kw, exc in [
        (dict(spp=0), ValueError), (dict(spp="4"), TypeError), (dict(spp=2.5), TypeError),
        (dict(threads=0), ValueError), (dict(region=(0, 0, 65, 10)), ValueError),
        (dict(region=(10, 0, 10, 5)), ValueError), (dict(region=(0, 0, 1)), ValueError),
        (dict(region="0,0,1,1"), TypeError), (dict(progress=3), TypeError), (dict(max_depth=-1), ValueError),
    ]:
        with pytest.raises(exc):
            whitted.render(scene, **kw)
    with pytest.raises(TypeError):
        whitted.render("scenes/room.toml")
    with pytest.raises(TypeError, match="unexpected keyword"):
        whitted.load(ROOM, widht=10)
    with pytest.raises(ValueError):
        whitted.load(ROOM, width=0)
    with pytest.raises(ValueError):
        whitted.load(ROOM, format="ply")
    image = whitted.render(scene)
    with pytest.raises(ValueError, match="only PNG"):
        whitted.write_png(image, tmp_path / "x.jpg")
    with pytest.raises(OSError):
        whitted.write_png(image, tmp_path / "no" / "such" / "dir.png")
    with pytest.raises(ValueError):
        whitted.write_png(image[:, :, :2], tmp_path / "x.png")
    with pytest.raises(TypeError):
        whitted.write_png([[1, 2, 3]], tmp_path / "x.png")
    with pytest.raises(ValueError, match="color: expected 'linear' or 'srgb'"):
        whitted.write_png(image, tmp_path / "x.png", color="gamma")
    with pytest.raises(TypeError):
        whitted.to_png_bytes(image, color=True)
    with pytest.raises(ValueError):
        whitted.Sphere((0, 0, 0), -1)
    with pytest.raises(TypeError):
        whitted.Sphere("abc", 1)
    # Numbers the core's float32 cannot hold are refused here, as a scene file's reader
    # refuses them, rather than turned into an infinity or a zero.
    for make in (lambda: whitted.Sphere((0, 0, 0), 1e39), lambda: whitted.Sphere((1e39, 0, 0), 1),
                 lambda: whitted.Sphere((0, 0, 0), 1e-50), lambda: whitted.Material(shininess=1e39)):
        with pytest.raises(ValueError, match="float32"):
            make()
    tri = ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    for normal in (np.nan, 1e39):
        with pytest.raises(ValueError, match="mesh.normals: must be finite"):
            whitted.Mesh(*tri, normals=[[0, 0, normal]] * 3, smooth=True)
    with pytest.raises(ValueError):
        whitted.Material(reflectivity=0.6, transparency=0.6)
    with pytest.raises(ValueError):
        whitted.Camera((0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError):
        whitted.Mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(TypeError):
        scene.add("sphere")
    with pytest.raises(ValueError, match="camera: up"):
        whitted.render(scene.copy(up=(0, 0, -1), position=(0, 0, 0), look_at=(0, 0, -5)))
    assert not list(tmp_path.iterdir())


def long_scene():
    return room(width=1200, height=1200, spp=64)


def test_the_gil_is_released_while_rendering():
    scene = room(width=320, height=320, spp=16)
    ticks, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            ticks[0] += 1

    t = threading.Thread(target=count)
    t.start()
    try:
        time.sleep(0.05)
        before = ticks[0]
        start = time.perf_counter()
        whitted.render(scene, threads=1)
        took = time.perf_counter() - start
        during = ticks[0] - before
    finally:
        stop.set()
        t.join()
    # A Python loop runs about a million rounds a second even on a busy machine; held
    # GIL would leave it a few 20 ms slices at most.
    assert took > 0.1, f"render too quick to tell ({took:.3f} s)"
    assert during > 20_000 * took, f"{during} rounds in {took:.2f} s"


def test_ctrl_c_stops_a_long_render_within_a_second():
    scene = long_scene()
    sent = []

    def interrupt():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    # A process started in the background by a shell without job control (as CI may
    # be) inherits SIGINT ignored, and Python then installs no KeyboardInterrupt
    # handler: Ctrl-C could never reach any Python code. Install Python's own here.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, interrupt)
    timer.start()
    start = time.perf_counter()
    raised = False
    try:
        whitted.render(scene)
    except KeyboardInterrupt:
        raised = True
    finally:
        stopped = time.perf_counter()
        timer.join()
        signal.signal(signal.SIGINT, previous)
    sent_at = f"{sent[0] - start:.2f} s" if sent else "never"
    when = f"interrupt sent at {sent_at}, render returned at {stopped - start:.2f} s"
    assert sent, f"the render ended before the interrupt ({when})"
    assert raised, f"the render did not raise KeyboardInterrupt ({when})"
    assert stopped - sent[0] < 1.0, f"took {stopped - sent[0]:.2f} s to stop ({when})"
    assert stopped - start < 5.0
    # The renderer is usable afterwards.
    assert whitted.render(room()).shape == (48, 64, 3)


def test_progress_reaches_the_total_and_an_exception_in_it_stops_the_render():
    calls = []
    whitted.render(room(width=200, height=150), progress=lambda d, t: calls.append((d, t)))
    assert calls and calls[-1][0] == calls[-1][1] == 13 * 10
    assert [d for d, _ in calls] == sorted(d for d, _ in calls)

    def boom(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        whitted.render(long_scene(), progress=boom)


def test_progress_drives_a_tqdm_bar():
    tqdm = pytest.importorskip("tqdm")
    bar = tqdm.tqdm(disable=False, file=open(os.devnull, "w"))
    whitted.render(room(width=100, height=100), progress=bar)
    assert bar.n == bar.total == 7 * 7
    bar.close()
    assert whitted.render(room(), progress=True).shape == (48, 64, 3)  # a bar of its own


SPHERE_TOML = """
[camera]
position = [0, 0.5, 5]
look_at = [0, 0, 0]
fov = 40
width = 60
height = 40
[settings]
background = [0.1, 0.1, 0.2]
[[light]]
position = [4, 5, 6]
color = [1, 1, 1]
[material.red]
color = [1, 0.2, 0.1]
reflectivity = 0.3
[material.floor]
color = [0.8, 0.8, 0.8]
specular = 0
[[sphere]]
center = [0, 0, 0]
radius = 1
material = "red"
[[quad]]
corner = [-3, -1, 3]
edge_u = [6, 0, 0]
edge_v = [0, 0, -6]
material = "floor"
"""


def code_scene():
    scene = whitted.Scene(whitted.Camera((0, 0.5, 5), (0, 0, 0), fov=40, width=60, height=40),
                          background=(0.1, 0.1, 0.2))
    scene.add(whitted.Sphere((0, 0, 0), 1), whitted.Material(color=(1, 0.2, 0.1), reflectivity=0.3))
    scene.add(whitted.Quad((-3, -1, 3), (6, 0, 0), (0, 0, -6)), whitted.Material(color=(0.8, 0.8, 0.8), specular=0))
    scene.add(whitted.PointLight((4, 5, 6)))
    return scene


def test_a_scene_built_in_code_renders_as_the_same_scene_file():
    from_file = whitted.Scene.from_toml(SPHERE_TOML)
    assert whitted.render(code_scene()).tobytes() == whitted.render(from_file).tobytes()


def test_every_shape_and_a_numpy_mesh():
    scene = code_scene()
    glass = whitted.Material(color=(0.2, 0.5, 0.9), transparency=0.8, ior=1.5)
    scene.add(whitted.Cylinder((1.5, -1, 0), (0, 1, 0), 0.3, 1.2), glass)
    scene.add(whitted.Cone((-1.5, -1, 0), (0, 1, 0), 0.5, 1.5), whitted.Material(color=(0, 1, 0)))
    scene.add(whitted.Triangle((-1, 1, -1), (0, 2, -1), (1, 1, -1)),
              whitted.Material(texture=whitted.Checker(0.25)))
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64) * 0.6 + [0.8, 0.2, 1.0]
    tris = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    scene.add(whitted.Mesh(positions, tris), whitted.Material(color=(1, 1, 0)))
    image = whitted.render(scene)
    plain = whitted.render(code_scene())
    changed = np.any(image != plain, axis=2)
    assert changed.sum() > 200  # the new shapes show
    assert "6 objects" in repr(scene)
    # Adding to one scene leaves copies made before alone.
    before = code_scene()
    copy = before.copy()
    before.add(whitted.Sphere((0, 2, 0), 0.5))
    assert whitted.render(copy).tobytes() == plain.tobytes()


def test_scenes_pickle_as_their_source_and_render_the_same():
    for scene in [room(spp=4), code_scene(), whitted.Scene.from_toml(SPHERE_TOML)]:
        data = pickle.dumps(scene)
        back = pickle.loads(data)
        assert back._base._core is None  # rebuilt from the recipe, not shipped
        assert whitted.render(back).tobytes() == whitted.render(scene).tobytes()
    # A mesh scene pickles its arrays.
    scene = code_scene()
    scene.add(whitted.Mesh(np.eye(3), [[0, 1, 2]]), whitted.Material())
    assert whitted.render(pickle.loads(pickle.dumps(scene))).tobytes() == whitted.render(scene).tobytes()


def test_a_scenes_colour_encoding_writes_what_the_command_line_writes(tmp_path, whitted_bin):
    srgb = tmp_path / "srgb.toml"
    srgb.write_text(ROOM.read_text().replace("[settings]\n", '[settings]\ncolor = "srgb"\n', 1))
    for path, color in [(ROOM, "linear"), (srgb, "srgb")]:
        cli, ours = tmp_path / f"cli-{color}.png", tmp_path / f"ours-{color}.png"
        subprocess.run([whitted_bin, "render", str(path), "--width", "40", "--height", "30", "-q", "-o", str(cli)],
                       check=True)
        scene = whitted.load(path, width=40, height=30)
        assert scene.color == color
        image = whitted.render(scene)
        whitted.write_png(image, ours, color=scene.color)
        assert ours.read_bytes() == cli.read_bytes()
    # sRGB brightens the dark tones: the two files differ.
    assert (tmp_path / "cli-linear.png").read_bytes() != (tmp_path / "cli-srgb.png").read_bytes()
    assert whitted.Scene(whitted.Camera((0, 0, 1), (0, 0, 0))).color == "linear"


@pytest.mark.parametrize("name", ["torus.obj", "model.glb"])
def test_obj_and_gltf_files_load_as_the_command_line_reads_them(tmp_path, whitted_bin, name):
    path = ROOM.parent / name
    cli = tmp_path / "cli.png"
    args = [whitted_bin, "render", str(path), "--width", "64", "--height", "48", "-q", "-o", str(cli)]
    subprocess.run(args, check=True)
    scene = whitted.load(path, width=64, height=48)
    image = whitted.render(scene)
    assert image.mean() > 0.02  # the model in its default view and light, not a black frame
    assert whitted.to_png_bytes(image, color=scene.color) == cli.read_bytes()
    # Pickled as the file's path, read again on the other side.
    back = pickle.loads(pickle.dumps(scene))
    assert back._base._core is None
    assert whitted.render(back).tobytes() == image.tobytes()
    # A broken file raises the command line's message.
    broken = tmp_path / ("broken" + path.suffix)
    broken.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 3])
    with pytest.raises(whitted.SceneError, match=str(broken)):
        whitted.load(broken)


def test_show_makes_an_ipython_image(monkeypatch):
    try:
        import IPython.display  # noqa: F401
    except ImportError:
        # Without IPython installed, a stand-in for IPython.display.Image checks what
        # show hands it.
        import sys
        import types

        display = types.ModuleType("IPython.display")
        display.Image = lambda data, format: types.SimpleNamespace(data=data, format=format)
        monkeypatch.setitem(sys.modules, "IPython", types.ModuleType("IPython"))
        monkeypatch.setitem(sys.modules, "IPython.display", display)
    image = whitted.render(room())
    shown = whitted.show(image)
    assert shown.data[:8] == b"\x89PNG\r\n\x1a\n"
    assert shown.data == whitted.to_png_bytes(image)


ANIMATED = """
[settings]
frames = [0, 8]

[camera]
position = [0, 1, 6]
look_at = [0, 0, 0]
fov = 40
width = 40
height = 30
keys = [{ frame = 0, position = [0, 1, 6] }, { frame = 8, position = [3, 2, 5], fov = 55 }]

[[light]]
position = [5, 5, 5]
keys = [{ frame = 0, position = [5, 5, 5] }, { frame = 8, position = [-5, 4, 3] }]

[[sphere]]
center = [0, 0, 0]
radius = 1
material = { color = [1, 0.2, 0.2] }
keys = [{ frame = 0, transform = { translate = [-1, 0, 0] } }, { frame = 8, transform = { translate = [1, 0, -1] } }]

[[quad]]
corner = [-4, -1, 4]
edge_u = [8, 0, 0]
edge_v = [0, 0, -8]
material = { color = [0.8, 0.8, 0.8] }
"""

LAST = """
[camera]
position = [3, 2, 5]
look_at = [0, 0, 0]
fov = 55
width = 40
height = 30

[[light]]
position = [-5, 4, 3]

[[sphere]]
center = [0, 0, 0]
radius = 1
material = { color = [1, 0.2, 0.2] }
transform = { translate = [1, 0, -1] }

[[quad]]
corner = [-4, -1, 4]
edge_u = [8, 0, 0]
edge_v = [0, 0, -8]
material = { color = [0.8, 0.8, 0.8] }
"""


def test_frames_of_an_animated_scene_equal_the_scene_written_with_their_values(tmp_path, whitted_bin):
    scene = whitted.Scene.from_toml(ANIMATED, "anim.toml")
    assert scene.frames == (0, 8)
    assert room().frames is None
    last = whitted.render(whitted.Scene.from_toml(LAST, "last.toml"))
    assert whitted.render(scene, frame=8).tobytes() == last.tobytes()
    assert whitted.render(scene.at_frame(8)).tobytes() == last.tobytes()
    assert whitted.render(scene).tobytes() != last.tobytes()
    # Frame 4 as the command line renders it, and through a pickle (as Dask sends it).
    path = tmp_path / "anim.toml"
    path.write_text(ANIMATED)
    out = tmp_path / "f-##.png"
    subprocess.run([whitted_bin, "render", str(path), "--frames", "3..4", "-o", str(out), "-q"], check=True)
    image = whitted.render(whitted.load(path), frame=4)
    assert whitted.to_png_bytes(image) == (tmp_path / "f-04.png").read_bytes()
    again = pickle.loads(pickle.dumps(whitted.load(path).at_frame(4)))
    assert whitted.render(again).tobytes() == image.tobytes()
    with pytest.raises(ValueError):
        scene.at_frame(-1)
