"""Whitted: a fast recursive (Whitted-style) ray tracer, from Python.

    import whitted
    scene = whitted.load("scenes/room.toml", width=400, height=400)
    image = whitted.render(scene)          # numpy float32, (400, 400, 3), linear colour
    whitted.write_png(image, "room.png")

Rendering runs in Rust on all cores with the GIL released; Ctrl-C stops it. For many
frames or big images on a Dask cluster, see :mod:`whitted.distributed`.
"""

from __future__ import annotations

import os
from typing import Any, Callable, Optional, Tuple, Union

import numpy as np

from . import _core
from ._core import SceneError
from ._scene import (
    Camera,
    Checker,
    Cone,
    Cylinder,
    DirectionalLight,
    Material,
    Mesh,
    PointLight,
    Quad,
    Scene,
    Sphere,
    SpotLight,
    Stripes,
    Triangle,
    load,
)
from ._scene import _count

__all__ = [
    "Camera", "Checker", "Cone", "Cylinder", "DirectionalLight", "Material", "Mesh", "PointLight", "Quad",
    "Scene", "SceneError", "Sphere", "SpotLight", "Stripes", "Triangle", "load", "render", "write_png",
    "to_png_bytes", "show",
]

Region = Tuple[int, int, int, int]


def _region(region: Any, width: int, height: int) -> Optional[Region]:
    if region is None:
        return None
    if isinstance(region, (str, bytes)) or not hasattr(region, "__len__"):
        raise TypeError(f"region: expected (x0, y0, x1, y1), got {region!r}")
    if len(region) != 4:
        raise ValueError(f"region: expected four numbers (x0, y0, x1, y1), got {len(region)}")
    x0, y0, x1, y1 = (_count("region", v, 0, 1 << 31) for v in region)
    if not (x0 < x1 <= width and y0 < y1 <= height):
        raise ValueError(
            f"region {x0},{y0},{x1},{y1} is not a non-empty rectangle inside the {width} x {height} image "
            "(need x0 < x1 <= width, y0 < y1 <= height)"
        )
    return (x0, y0, x1, y1)


def _progress_callback(progress: Any) -> Optional[Callable[[int, int], Any]]:
    """A (done, total) callable from what the caller gave: a callable, a tqdm bar, or
    True for a new tqdm bar."""
    if progress is None or progress is False:
        return None
    if progress is True:
        try:
            from tqdm.auto import tqdm
        except ImportError:
            raise ImportError("progress=True shows a tqdm bar: pip install tqdm (or pass a callable)") from None
        progress = tqdm(unit="tile", leave=False)
    if hasattr(progress, "update") and hasattr(progress, "n") and hasattr(progress, "total"):
        bar = progress

        def to_bar(done: int, total: int) -> None:
            if bar.total != total:
                bar.total = total
            bar.update(done - bar.n)

        return to_bar
    if not callable(progress):
        raise TypeError(f"progress: expected a callable (done, total), a tqdm bar or True, got {type(progress).__name__}")
    return progress


def render(
    scene: Scene,
    spp: Optional[int] = None,
    threads: Optional[int] = None,
    region: Optional[Region] = None,
    progress: Any = None,
    max_depth: Optional[int] = None,
    frame: Optional[int] = None,
) -> np.ndarray:
    """Renders `scene` and returns a writable, C-contiguous float32 array of shape
    (height, width, 3) in linear colour (or the region's size).

    - `spp`, `max_depth`: override the scene's; `threads`: worker threads (all cores).
    - `region=(x0, y0, x1, y1)` (x1, y1 exclusive) renders just those pixels, exactly as
      they are in the full image.
    - `progress(done, total)` is called from this thread as tiles complete; a tqdm bar
      (or True, for a new one) works too.
    - `frame=N` renders frame N of an animated scene (``scene.at_frame(N)``).

    The GIL is released while rendering; Ctrl-C raises KeyboardInterrupt within a tile.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene: expected whitted.Scene, got {type(scene).__name__}")
    if frame is not None:
        scene = scene.at_frame(frame)
    spp = scene.spp if spp is None else _count("spp", spp, 1, 65536)
    max_depth = scene.max_depth if max_depth is None else _count("max_depth", max_depth, 1, 1000)
    if threads is not None:
        threads = _count("threads", threads, 1, 1024)
    region = _region(region, scene.width, scene.height)
    callback = _progress_callback(progress)
    core = scene._base.core()
    at = getattr(scene, "_frame", None)
    if at is not None:
        core = core.at_frame(at)
    return core.render(scene.camera._args(), spp, max_depth, threads, region, callback)


def _image(image: Any) -> np.ndarray:
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image: expected a numpy array, got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"image: expected shape (height, width, 3), got {image.shape}")
    if image.dtype.kind not in "fiu":
        raise TypeError(f"image: expected a numeric array, got dtype {image.dtype}")
    return np.ascontiguousarray(image, dtype=np.float32)


def _srgb(color: Any) -> bool:
    if not isinstance(color, str):
        raise TypeError(f"color: expected 'linear' or 'srgb', got {type(color).__name__}")
    if color not in ("linear", "srgb"):
        raise ValueError(f"color: expected 'linear' or 'srgb', got {color!r}")
    return color == "srgb"


def write_png(image: np.ndarray, path: Union[str, os.PathLike], *, color: str = "linear") -> None:
    """Writes a (height, width, 3) linear-colour array as 8-bit PNG, clamped and
    quantised as the command line does, whole or not at all (temporary file + rename).
    `color` is how the file encodes colour, as ``--color``: ``"linear"`` or ``"srgb"``;
    ``color=scene.color`` writes what ``whitted render`` writes for that scene."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected str or os.PathLike, got {type(path).__name__}")
    _core.write_png_array(_image(image), os.fspath(path), _srgb(color))


def to_png_bytes(image: np.ndarray, *, color: str = "linear") -> bytes:
    """The PNG file :func:`write_png` would write, as bytes."""
    return _core.encode_png(_image(image), _srgb(color))


def show(image: np.ndarray, *, color: str = "linear"):
    """Shows an image inline in Jupyter (returns an ``IPython.display.Image``)."""
    from IPython.display import Image

    return Image(data=to_png_bytes(image, color=color), format="png")
