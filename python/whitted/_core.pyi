"""Type stubs for the compiled part of whitted (python/src/lib.rs)."""

from typing import Callable, Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_V3 = Tuple[float, float, float]
_CameraArgs = Tuple[_V3, _V3, _V3, float, int, int]
# ("point", position, color, intensity, attenuation)
# ("directional", direction, color, intensity)
# ("spot", position, direction, inner_angle, outer_angle, color, intensity, attenuation)
# attenuation: (constant, linear, quadratic), (1, 0, 0) for none.
_LightArgs = Union[
    Tuple[Literal["point"], _V3, _V3, float, _V3],
    Tuple[Literal["directional"], _V3, _V3, float],
    Tuple[Literal["spot"], _V3, _V3, float, float, _V3, float, _V3],
]

MAX_RESOLUTION: int

class SceneError(Exception):
    """A scene that cannot be used; the message is the command line's
    (file:line:column: field: problem)."""

class CoreScene:
    @staticmethod
    def load(path: str, format: str) -> Tuple["CoreScene", Optional[str]]: ...
    @staticmethod
    def parse(text: str, name: str, base_dir: str, nff: bool) -> "CoreScene": ...
    @staticmethod
    def empty() -> "CoreScene": ...
    def camera(self) -> _CameraArgs: ...
    def settings(self) -> Tuple[_V3, int, int, float]: ...
    def color(self) -> Literal["linear", "srgb"]: ...
    def counts(self) -> Tuple[int, int, int]: ...
    def frames(self) -> Optional[Tuple[int, int]]: ...
    def at_frame(self, frame: int) -> "CoreScene": ...
    def camera_at(self, camera: _CameraArgs, frame: int) -> _CameraArgs: ...
    def extend(
        self,
        background: Optional[_V3],
        ambient: Optional[float],
        materials: Sequence[tuple],
        objects: Sequence[tuple],
        lights: Sequence[_LightArgs],
    ) -> "CoreScene": ...
    def render(
        self,
        camera: _CameraArgs,
        spp: Optional[int] = None,
        max_depth: Optional[int] = None,
        threads: Optional[int] = None,
        region: Optional[Tuple[int, int, int, int]] = None,
        progress: Optional[Callable[[int, int], object]] = None,
    ) -> npt.NDArray[np.float32]: ...

def write_png_array(image: npt.NDArray[np.float32], path: str, srgb: bool) -> None: ...
def encode_png(image: npt.NDArray[np.float32], srgb: bool) -> bytes: ...
