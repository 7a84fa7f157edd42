"""Scenes: read from files or built in code, and picklable so Dask can ship them.

A :class:`Scene` is a light part (camera, samples, depth) over a shared heavy part
(:class:`_Base`: the source text it was read from plus what was added in code). The
heavy part pickles as that recipe, not as geometry, and is built once per process:
frames of a turntable share it, so a cluster receives it once.
"""

from __future__ import annotations

import dataclasses
import math
import os
import threading
from typing import Any, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core

Vec3 = Tuple[float, float, float]

MAX_RESOLUTION = _core.MAX_RESOLUTION
# Frame numbers run from 0 to this (the scene reader's limit).
MAX_FRAME = 1_000_000


def _vec3(field: str, value: Any) -> Vec3:
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{field}: expected three numbers, got {value!r}")
    try:
        items = [float(v) for v in value]
    except TypeError:
        raise TypeError(f"{field}: expected three numbers, got {value!r}") from None
    except ValueError:
        raise TypeError(f"{field}: expected three numbers, got {value!r}") from None
    if len(items) != 3:
        raise ValueError(f"{field}: expected three numbers, got {len(items)}")
    if not all(math.isfinite(v) for v in items):
        raise ValueError(f"{field}: must be three finite numbers (got {items})")
    for v in items:
        _f32(field, v)
    return (items[0], items[1], items[2])


def _number(field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{field}: expected a number, got {type(value).__name__}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{field}: must be a finite number (got {v})")
    # The core holds float32, as a scene file's reader does: past its range is an error
    # here too, not an infinity later.
    _f32(field, v)
    return v


def _positive(field: str, value: Any) -> float:
    v = _number(field, value)
    if not np.float32(v) > 0:
        raise ValueError(f"{field}: must be > 0 (got {v}{', 0 in float32' if v > 0 else ''})")
    return v


def _share(field: str, value: Any) -> float:
    v = _number(field, value)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{field}: must be in [0, 1] (got {v})")
    return v


def _color(field: str, value: Any) -> Vec3:
    c = _vec3(field, value)
    if min(c) < 0:
        raise ValueError(f"{field}: colour components must be >= 0 (got {list(c)})")
    return c


def _count(field: str, value: Any, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{field}: expected a whole number, got {type(value).__name__}")
    v = int(value)
    if not lo <= v <= hi:
        raise ValueError(f"{field}: must be between {lo} and {hi} (got {v})")
    return v


def _bool(field: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{field}: expected True or False, got {type(value).__name__}")
    return bool(value)


@dataclasses.dataclass(frozen=True)
class Camera:
    """A pinhole camera: `fov` is the vertical field of view in degrees."""

    position: Vec3
    look_at: Vec3
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: float = 45.0
    width: int = 640
    height: int = 480

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "position", _vec3("camera.position", self.position))
        set_(self, "look_at", _vec3("camera.look_at", self.look_at))
        set_(self, "up", _vec3("camera.up", self.up))
        fov = _number("camera.fov", self.fov)
        if not 0 < fov < 180:
            raise ValueError(f"camera.fov: must be in (0, 180) degrees (got {fov})")
        set_(self, "fov", fov)
        set_(self, "width", _count("camera.width", self.width, 1, MAX_RESOLUTION))
        set_(self, "height", _count("camera.height", self.height, 1, MAX_RESOLUTION))
        if self.position == self.look_at:
            raise ValueError("camera: look_at is the camera position: no viewing direction")

    def replace(self, **changes: Any) -> "Camera":
        """A copy with some fields changed: ``cam.replace(position=(1, 2, 3))``."""
        return dataclasses.replace(self, **changes)

    def _args(self):
        return (self.position, self.look_at, self.up, self.fov, self.width, self.height)


@dataclasses.dataclass(frozen=True)
class Checker:
    """A 3-D checkerboard of cubes of edge `size` (looked up at p + offset)."""

    size: float
    colors: Tuple[Vec3, Vec3] = ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    offset: Vec3 = (0.0, 0.0, 0.0)

    def _args(self):
        size = _positive("checker.size", self.size)
        a, b = (_color("checker.colors", c) for c in self.colors)
        return ("checker", size, _vec3("checker.offset", self.offset), a, b)


@dataclasses.dataclass(frozen=True)
class Stripes:
    """Bands of `width` across `axis`, alternating the two colours."""

    width: float
    axis: Vec3 = (1.0, 0.0, 0.0)
    colors: Tuple[Vec3, Vec3] = ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))

    def _args(self):
        width = _positive("stripes.width", self.width)
        a, b = (_color("stripes.colors", c) for c in self.colors)
        return ("stripes", _vec3("stripes.axis", self.axis), width, a, b)


@dataclasses.dataclass(frozen=True)
class Material:
    """Phong shading plus mirror reflection and transmission, as in scene files.

    - `fresnel=True` splits `transparency` at each hit by the Fresnel equations, the
      reflected part joining `reflectivity` (glass: 4 % reflected head-on, all at
      grazing angles);
    - `absorption=(r, g, b)` per unit length inside the object (Beer-Lambert: light
      travelling d inside keeps ``exp(-absorption*d)``); numbers >= 0, and anything but
      (0, 0, 0) needs `transparency` > 0.
    """

    color: Vec3 = (1.0, 1.0, 1.0)
    diffuse: float = 1.0
    specular: float = 1.0
    shininess: float = 50.0
    reflectivity: float = 0.0
    transparency: float = 0.0
    ior: float = 1.0
    texture: Optional[Union[Checker, Stripes]] = None
    fresnel: bool = False
    absorption: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "color", _color("material.color", self.color))
        for f in ("diffuse", "specular", "shininess"):
            v = _number(f"material.{f}", getattr(self, f))
            if v < 0:
                raise ValueError(f"material.{f}: must be >= 0 (got {v})")
            set_(self, f, v)
        set_(self, "reflectivity", _share("material.reflectivity", self.reflectivity))
        set_(self, "transparency", _share("material.transparency", self.transparency))
        set_(self, "fresnel", _bool("material.fresnel", self.fresnel))
        set_(self, "absorption", _color("material.absorption", self.absorption))
        # As the scene reader decides it, in float32.
        if any(np.float32(v) != 0 for v in self.absorption) and np.float32(self.transparency) == 0:
            raise ValueError("material.absorption: needs transparency > 0: nothing travels inside to be absorbed")
        if self.reflectivity + self.transparency > 1.0:
            raise ValueError(
                "material: reflectivity + transparency must be at most 1 "
                f"(got {self.reflectivity} + {self.transparency})"
            )
        set_(self, "ior", _positive("material.ior", self.ior))
        if self.texture is not None and not isinstance(self.texture, (Checker, Stripes)):
            raise TypeError(f"material.texture: expected Checker, Stripes or None, got {type(self.texture).__name__}")
        if self.texture is not None:
            self.texture._args()  # checks it

    def _args(self):
        tex = None if self.texture is None else self.texture._args()
        return (self.color, self.diffuse, self.specular, self.shininess, self.reflectivity,
                self.transparency, self.ior, tex, self.fresnel, self.absorption)


@dataclasses.dataclass(frozen=True)
class Sphere:
    center: Vec3
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3("sphere.center", self.center))
        object.__setattr__(self, "radius", _positive("sphere.radius", self.radius))

    def _args(self):
        return ("sphere", self.center, self.radius)


@dataclasses.dataclass(frozen=True)
class Quad:
    """The parallelogram corner + s·edge_u + t·edge_v for s, t in [0, 1]."""

    corner: Vec3
    edge_u: Vec3
    edge_v: Vec3

    def __post_init__(self) -> None:
        for f in ("corner", "edge_u", "edge_v"):
            object.__setattr__(self, f, _vec3(f"quad.{f}", getattr(self, f)))
        if not np.linalg.norm(np.cross(self.edge_u, self.edge_v)) > 0:
            raise ValueError("quad: edge_u and edge_v must not be parallel or zero")

    def _args(self):
        return ("quad", self.corner, self.edge_u, self.edge_v)


@dataclasses.dataclass(frozen=True)
class Triangle:
    a: Vec3
    b: Vec3
    c: Vec3

    def __post_init__(self) -> None:
        for f in ("a", "b", "c"):
            object.__setattr__(self, f, _vec3(f"triangle.{f}", getattr(self, f)))

    def _args(self):
        return ("triangle", self.a, self.b, self.c)


@dataclasses.dataclass(frozen=True)
class Cylinder:
    """From `base` along `axis` for `height`; `caps` closes both ends."""

    base: Vec3
    axis: Vec3
    radius: float
    height: float
    caps: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "base", _vec3("cylinder.base", self.base))
        object.__setattr__(self, "axis", _vec3("cylinder.axis", self.axis))
        if self.axis == (0.0, 0.0, 0.0):
            raise ValueError("cylinder.axis: must not be zero")
        object.__setattr__(self, "radius", _positive("cylinder.radius", self.radius))
        object.__setattr__(self, "height", _positive("cylinder.height", self.height))
        object.__setattr__(self, "caps", _bool("cylinder.caps", self.caps))

    def _args(self):
        return ("cylinder", self.base, self.axis, self.radius, self.height, self.caps)


@dataclasses.dataclass(frozen=True)
class Cone:
    """From `base` (radius `radius`) along `axis` for `height` to a top of `top_radius`
    (0: pointed)."""

    base: Vec3
    axis: Vec3
    radius: float
    height: float
    top_radius: float = 0.0
    cap: bool = True
    top_cap: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "base", _vec3("cone.base", self.base))
        object.__setattr__(self, "axis", _vec3("cone.axis", self.axis))
        if self.axis == (0.0, 0.0, 0.0):
            raise ValueError("cone.axis: must not be zero")
        object.__setattr__(self, "radius", _positive("cone.radius", self.radius))
        object.__setattr__(self, "height", _positive("cone.height", self.height))
        top = _number("cone.top_radius", self.top_radius)
        if top < 0:
            raise ValueError(f"cone.top_radius: must be >= 0 (got {top})")
        object.__setattr__(self, "top_radius", top)
        object.__setattr__(self, "cap", _bool("cone.cap", self.cap))
        object.__setattr__(self, "top_cap", _bool("cone.top_cap", self.top_cap))

    def _args(self):
        return ("cone", self.base, self.axis, self.radius, self.top_radius, self.height, self.cap, self.top_cap)


class Mesh:
    """A triangle mesh from numpy arrays: `positions` (N, 3) floats, `triangles` (M, 3)
    vertex indices, optional `normals` (N, 3) (with `smooth`; computed if absent)."""

    def __init__(self, positions: Any, triangles: Any, normals: Any = None, smooth: bool = False) -> None:
        self.positions = self._array("mesh.positions", positions, np.float32)
        tris = np.asarray(triangles)
        if tris.dtype.kind not in "iu":
            raise TypeError(f"mesh.triangles: expected integer indices, got dtype {tris.dtype}")
        if tris.size and (tris.min() < 0 or tris.max() >= len(self.positions)):
            raise ValueError(
                f"mesh.triangles: indices must be in [0, {len(self.positions)}) (got {tris.min()}..{tris.max()})"
            )
        self.triangles = self._array("mesh.triangles", tris, np.uint32)
        if len(self.triangles) == 0:
            raise ValueError("mesh.triangles: the mesh has no triangles")
        if not np.isfinite(self.positions).all():
            raise ValueError("mesh.positions: must be finite")
        self.normals = None if normals is None else self._array("mesh.normals", normals, np.float32)
        if self.normals is not None and self.normals.shape != self.positions.shape:
            raise ValueError(f"mesh.normals: expected shape {self.positions.shape}, got {self.normals.shape}")
        if self.normals is not None and not np.isfinite(self.normals).all():
            raise ValueError("mesh.normals: must be finite")
        self.smooth = _bool("mesh.smooth", smooth)

    @staticmethod
    def _array(field: str, value: Any, dtype) -> np.ndarray:
        try:
            # Past float32's range is reported as not finite below, without a numpy warning.
            with np.errstate(over="ignore"):
                a = np.ascontiguousarray(value, dtype=dtype)
        except (TypeError, ValueError) as e:
            raise TypeError(f"{field}: expected an (N, 3) array: {e}") from None
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"{field}: expected shape (N, 3), got {a.shape}")
        return a

    def _args(self):
        # An array unpickled from a stream (as Dask sends scenes) may sit at any byte
        # offset; the Rust side reads only aligned, contiguous arrays, so realign here.
        def ready(a):
            return None if a is None else np.require(a, requirements=["C_CONTIGUOUS", "ALIGNED"])

        return ("mesh", ready(self.positions), ready(self.triangles), ready(self.normals), self.smooth)

    def __repr__(self) -> str:
        return f"Mesh({len(self.positions)} vertices, {len(self.triangles)} triangles)"


def _f32(field: str, value: float) -> float:
    """`value` as the core will hold it (float32), which must still be finite."""
    # Too big for float32 is an error raised below, not a numpy warning as well.
    with np.errstate(over="ignore"):
        v = float(np.float32(value))
    if not math.isfinite(v):
        raise ValueError(f"{field}: must be a finite float32 number (got {value})")
    return v


def _direction(field: str, value: Any) -> Vec3:
    """Three finite numbers, not the zero vector (in float32, as the core normalises it)."""
    d = _vec3(field, value)
    x, y, z = (np.float32(v) for v in d)
    with np.errstate(over="ignore", under="ignore"):
        length_squared = x * x + y * y + z * z
    if not length_squared > 0:
        raise ValueError(f"{field}: must not be the zero vector")
    return d


def _attenuation(field: str, value: Any) -> Vec3:
    """`(constant, linear, quadratic)`: finite, >= 0, not all zero; (1, 0, 0) is none."""
    a = _vec3(field, value)
    if min(a) < 0:
        raise ValueError(f"{field}: must be three finite numbers >= 0 (got {list(a)})")
    if not any(np.float32(v) > 0 for v in a):
        raise ValueError(f"{field}: must not be all zero (1 / 0 light); (1, 0, 0) is none")
    return a


def _non_negative(field: str, value: Any) -> float:
    v = _number(field, value)
    if v < 0:
        raise ValueError(f"{field}: must be >= 0 (got {v})")
    return v


def _angle(field: str, value: Any) -> float:
    v = _number(field, value)
    if not 0 < _f32(field, v) < 90:
        raise ValueError(f"{field}: must be between 0 and 90 degrees, both excluded (got {v})")
    return v


NO_ATTENUATION: Vec3 = (1.0, 0.0, 0.0)


@dataclasses.dataclass(frozen=True)
class PointLight:
    """A light at `position` shining equally every way, as ``[[light]]`` (``kind =
    "point"``) in a scene file.

    - `color` times `intensity` is the light's colour (components >= 0);
    - `attenuation=(constant, linear, quadratic)`: at distance d the light is divided by
      ``constant + linear*d + quadratic*d**2``; numbers >= 0, not all zero; the default
      (1, 0, 0) is no falloff.
    """

    position: Vec3
    color: Vec3 = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    attenuation: Vec3 = NO_ATTENUATION

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "position", _vec3("light.position", self.position))
        set_(self, "color", _color("light.color", self.color))
        set_(self, "intensity", _non_negative("light.intensity", self.intensity))
        set_(self, "attenuation", _attenuation("light.attenuation", self.attenuation))

    def _args(self):
        return ("point", self.position, self.color, self.intensity, self.attenuation)


@dataclasses.dataclass(frozen=True)
class DirectionalLight:
    """A light infinitely far away (the sun): parallel rays travelling along
    `direction` (need not be unit; not zero), no falloff, shadows to infinity. As
    ``[[light]]`` with ``kind = "directional"`` in a scene file."""

    direction: Vec3
    color: Vec3 = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "direction", _direction("light.direction", self.direction))
        set_(self, "color", _color("light.color", self.color))
        set_(self, "intensity", _non_negative("light.intensity", self.intensity))

    def _args(self):
        return ("directional", self.direction, self.color, self.intensity)


@dataclasses.dataclass(frozen=True)
class SpotLight:
    """A light at `position` shining into a cone around `direction` (the way its axis
    points; not zero), as ``[[light]]`` with ``kind = "spot"`` in a scene file.

    `inner_angle` and `outer_angle` are half-angles from the axis in degrees, ``0 <
    inner_angle <= outer_angle < 90``: full light within the inner one, none past the
    outer one, a smooth falloff between. `color`, `intensity` and `attenuation` are as
    for :class:`PointLight`.
    """

    position: Vec3
    direction: Vec3
    inner_angle: float
    outer_angle: float
    color: Vec3 = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    attenuation: Vec3 = NO_ATTENUATION

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "position", _vec3("light.position", self.position))
        set_(self, "direction", _direction("light.direction", self.direction))
        inner = _angle("light.inner_angle", self.inner_angle)
        outer = _angle("light.outer_angle", self.outer_angle)
        if _f32("light.inner_angle", inner) > _f32("light.outer_angle", outer):
            raise ValueError(f"light.inner_angle: must be at most outer_angle (got {inner} > {outer})")
        set_(self, "inner_angle", inner)
        set_(self, "outer_angle", outer)
        set_(self, "color", _color("light.color", self.color))
        set_(self, "intensity", _non_negative("light.intensity", self.intensity))
        set_(self, "attenuation", _attenuation("light.attenuation", self.attenuation))

    def _args(self):
        return ("spot", self.position, self.direction, self.inner_angle, self.outer_angle, self.color,
                self.intensity, self.attenuation)


Light = Union[PointLight, DirectionalLight, SpotLight]
_LIGHTS = (PointLight, DirectionalLight, SpotLight)


Shape = Union[Sphere, Quad, Triangle, Cylinder, Cone, Mesh]
_SHAPES = (Sphere, Quad, Triangle, Cylinder, Cone, Mesh)


class _Base:
    """The heavy part of a scene: where it came from and what was added. Never changed
    once made (a change makes a new one), so scenes and threads can share it."""

    def __init__(self, source=None, background=None, ambient=None, materials=(), objects=(), lights=(), core=None):
        self.source = source  # None or (kind, text or None, name, base_dir)
        self.background = background
        self.ambient = ambient
        self.materials = tuple(materials)
        self.objects = tuple(objects)  # (shape, index into materials)
        self.lights = tuple(lights)
        self._core = core
        self._lock = threading.Lock()

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k not in ("_core", "_lock")}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._core = None
        self._lock = threading.Lock()

    def plain(self):
        if self.source is None:
            return _core.CoreScene.empty()
        kind, text, name, base_dir = self.source
        if text is None:  # OBJ and glTF: read from the file again
            return _core.CoreScene.load(name, kind)[0]
        return _core.CoreScene.parse(text, name, base_dir, kind == "nff")

    def core(self):
        """The scene built in Rust, built on first use in this process."""
        with self._lock:
            if self._core is None:
                core = self.plain()
                if self.background is not None or self.ambient is not None or self.objects or self.lights:
                    core = core.extend(
                        self.background,
                        self.ambient,
                        [m._args() for m in self.materials],
                        [(s._args()[0], i) + s._args()[1:] for s, i in self.objects],
                        [light._args() for light in self.lights],
                    )
                self._core = core
            return self._core

    def changed(self, **kw) -> "_Base":
        fields = dict(source=self.source, background=self.background, ambient=self.ambient,
                      materials=self.materials, objects=self.objects, lights=self.lights)
        fields.update(kw)
        return _Base(**fields)


class Scene:
    """What to render: a camera, settings, shapes with materials, and lights.

    Read one with :func:`whitted.load` or :meth:`Scene.from_toml`, or build one::

        scene = whitted.Scene(whitted.Camera((0, 0, 4), (0, 0, 0), width=320, height=240))
        scene.add(whitted.Sphere((0, 0, 0), 1), whitted.Material(color=(1, 0.2, 0.1)))
        scene.add(whitted.PointLight((5, 5, 5)))

    Scenes pickle as their source and additions (not as geometry), so Dask can send them.
    """

    def __init__(self, camera: Camera, *, background: Vec3 = (0.0, 0.0, 0.0), ambient: float = 0.2,
                 spp: int = 1, max_depth: int = 10) -> None:
        if not isinstance(camera, Camera):
            raise TypeError(f"camera: expected whitted.Camera, got {type(camera).__name__}")
        self.camera = camera
        self.spp = spp
        self.max_depth = max_depth
        self._base = _Base(background=_color("background", background), ambient=_share("ambient", ambient))
        self._frame: Optional[int] = None

    @classmethod
    def _from_core(cls, core, source) -> "Scene":
        position, look_at, up, fov, width, height = core.camera()
        _, max_depth, samples, _ = core.settings()
        scene = cls.__new__(cls)
        scene.camera = Camera(position, look_at, up, fov, width, height)
        scene.spp = samples
        scene.max_depth = max_depth
        scene._base = _Base(source=source, core=core)
        scene._frame = None
        return scene

    @classmethod
    def from_toml(cls, text: str, name: str = "<string>", base_dir: Union[str, os.PathLike] = ".") -> "Scene":
        """A scene from TOML text; `name` appears in error messages, relative paths in it
        resolve against `base_dir`."""
        if not isinstance(text, str):
            raise TypeError(f"text: expected str, got {type(text).__name__}")
        base_dir = os.path.abspath(os.fspath(base_dir))
        core = _core.CoreScene.parse(text, name, base_dir, False)
        return cls._from_core(core, ("toml", text, name, base_dir))

    @classmethod
    def from_nff(cls, text: str, name: str = "<string>") -> "Scene":
        """A scene from NFF text (Eric Haines' Neutral File Format)."""
        if not isinstance(text, str):
            raise TypeError(f"text: expected str, got {type(text).__name__}")
        core = _core.CoreScene.parse(text, name, ".", True)
        return cls._from_core(core, ("nff", text, name, "."))

    # -- settings ------------------------------------------------------------------

    @property
    def spp(self) -> int:
        """Samples per pixel."""
        return self._spp

    @spp.setter
    def spp(self, value: int) -> None:
        self._spp = _count("spp", value, 1, 65536)

    @property
    def max_depth(self) -> int:
        """Longest chain of rays; the camera ray is 1."""
        return self._max_depth

    @max_depth.setter
    def max_depth(self, value: int) -> None:
        self._max_depth = _count("max_depth", value, 1, 1000)

    @property
    def camera(self) -> Camera:
        return self._camera

    @camera.setter
    def camera(self, value: Camera) -> None:
        if not isinstance(value, Camera):
            raise TypeError(f"camera: expected whitted.Camera, got {type(value).__name__}")
        self._camera = value

    @property
    def width(self) -> int:
        return self.camera.width

    @property
    def height(self) -> int:
        return self.camera.height

    @property
    def background(self) -> Vec3:
        return self._base.background if self._base.background is not None else self._base.core().settings()[0]

    @background.setter
    def background(self, value: Vec3) -> None:
        self._base = self._base.changed(background=_color("background", value))

    @property
    def ambient(self) -> float:
        return self._base.ambient if self._base.ambient is not None else self._base.core().settings()[3]

    @ambient.setter
    def ambient(self, value: float) -> None:
        self._base = self._base.changed(ambient=_share("ambient", value))

    @property
    def color(self) -> str:
        """How the scene file says output files encode colour (``[settings] color``):
        ``"linear"`` or ``"srgb"`` (glTF files: ``"srgb"``; scenes built in code:
        ``"linear"``). Give it to :func:`whitted.write_png` to write what ``whitted
        render`` writes."""
        return self._base.core().color()

    # -- building ------------------------------------------------------------------

    def add(self, item: Union[Shape, Light], material: Optional[Material] = None) -> "Scene":
        """Adds a shape with its material, or a light (:class:`PointLight`,
        :class:`DirectionalLight`, :class:`SpotLight`). Returns the scene."""
        if isinstance(item, _LIGHTS):
            if material is not None:
                raise TypeError("a light takes no material")
            self._base = self._base.changed(lights=self._base.lights + (item,))
            return self
        if not isinstance(item, _SHAPES):
            raise TypeError(f"add: expected a shape or a light, got {type(item).__name__}")
        if material is None:
            material = Material()
        if not isinstance(material, Material):
            raise TypeError(f"material: expected whitted.Material, got {type(material).__name__}")
        materials = self._base.materials
        index = next((i for i, m in enumerate(materials) if m is material), None)
        if index is None:
            materials, index = materials + (material,), len(materials)
        self._base = self._base.changed(materials=materials, objects=self._base.objects + ((item, index),))
        return self

    def add_light(self, light: Light) -> "Scene":
        """Adds a light; ``scene.add(light)`` does the same."""
        if not isinstance(light, _LIGHTS):
            kind = type(light).__name__
            raise TypeError(f"add_light: expected a PointLight, DirectionalLight or SpotLight, got {kind}")
        return self.add(light)

    def copy(self, **changes: Any) -> "Scene":
        """A copy sharing the geometry, with `camera`, `spp` or `max_depth` changed; for
        a camera field, give it directly: ``scene.copy(position=(x, y, z))``."""
        new = Scene.__new__(Scene)
        new._base = self._base
        new._frame = getattr(self, "_frame", None)
        new.camera = changes.pop("camera", self.camera)
        new.spp = changes.pop("spp", self.spp)
        new.max_depth = changes.pop("max_depth", self.max_depth)
        if changes:
            new.camera = new.camera.replace(**changes)
        return new

    # -- animation -----------------------------------------------------------------

    @property
    def frames(self) -> Optional[Tuple[int, int]]:
        """``(first, last)`` of an animated scene (a TOML file with ``keys``): its
        ``[settings] frames``, else 0 to its last key; None for a scene without keys."""
        return self._base.core().frames()

    def at_frame(self, frame: int) -> "Scene":
        """This scene at `frame` of its animation: the camera fields, light positions and
        object transforms its keys animate take that frame's values (frames beyond the
        keys hold them). It shares the geometry, so Dask sends it once for all frames;
        the frame is applied where the scene renders. A scene without keys is the same
        at every frame."""
        frame = _count("frame", frame, 0, MAX_FRAME)
        new = self.copy()
        new._frame = frame
        new.camera = Camera(*self._base.core().camera_at(self.camera._args(), frame))
        return new

    def __repr__(self) -> str:
        materials, objects, lights = self._base.core().counts()
        src = self._base.source[2] if self._base.source else "code"
        return (f"<whitted.Scene from {src}: {objects} objects, {lights} lights, "
                f"{self.width}x{self.height}, {self.spp} spp>")


_OVERRIDES = ("width", "height", "spp", "max_depth", "fov", "position", "look_at", "up", "background", "ambient")


# File extensions of the formats other than TOML, for :func:`load`.
_FORMATS = {".nff": "nff", ".obj": "obj", ".gltf": "gltf", ".glb": "gltf"}


def load(path: Union[str, os.PathLike], *, format: Optional[str] = None, **overrides: Any) -> Scene:
    """Reads a scene file: TOML, NFF (``.nff``), a Wavefront OBJ mesh (``.obj``) or glTF
    (``.gltf``, ``.glb``), by its extension or ``format=`` (``"toml"``, ``"nff"``,
    ``"obj"``, ``"gltf"``), as ``whitted render`` does: an OBJ or glTF file without a
    camera or lights gets the command line's default view and light.

    Overrides: ``width``, ``height``, ``spp``, ``max_depth``, ``fov``, ``position``,
    ``look_at``, ``up``, ``background``, ``ambient``. Problems in the file raise
    :class:`whitted.SceneError` with the command line's message (file:line:column: field).
    A scene pickles as its file's text, or for OBJ and glTF as the file's absolute path,
    read again where it is unpickled.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected str or os.PathLike, got {type(path).__name__}")
    path = os.fspath(path)
    if format is None:
        kind = _FORMATS.get(os.path.splitext(path)[1].lower(), "toml")
    elif format in ("toml", "nff", "obj", "gltf"):
        kind = format
    else:
        raise ValueError(f"format: expected 'toml', 'nff', 'obj' or 'gltf', got {format!r}")
    for key in overrides:
        if key not in _OVERRIDES:
            raise TypeError(f"load() got an unexpected keyword argument {key!r} (overrides: {', '.join(_OVERRIDES)})")
    core, text = _core.CoreScene.load(path, kind)
    base_dir = os.path.abspath(os.path.dirname(path) or ".")
    name = path if text is not None else os.path.abspath(path)
    scene = Scene._from_core(core, (kind, text, name, base_dir))
    cam = {k: overrides.pop(k) for k in ("width", "height", "fov", "position", "look_at", "up") if k in overrides}
    if cam:
        scene.camera = scene.camera.replace(**cam)
    for key, value in overrides.items():
        setattr(scene, key, value)
    return scene
