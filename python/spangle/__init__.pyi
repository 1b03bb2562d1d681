"""Type hints of the spangle module (python/module.cpp)."""

import os
from typing import Callable, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

Vec3 = Sequence[float]
ParamValue = Union[bool, int, float, str, Sequence[float]]

class SceneError(RuntimeError):
    """A mistake in a scene or an edit; file, line and column say where (None, 0, 0 when the
    message names no place)."""

    file: Optional[str]
    line: int
    column: int

class Image:
    """A rendered image."""

    @property
    def beauty(self) -> npt.NDArray[np.float32]: ...
    @property
    def layers(self) -> dict[str, npt.NDArray[np.float32]]: ...
    @property
    def glints(self) -> Optional[npt.NDArray[np.float32]]: ...
    @property
    def spp(self) -> int: ...
    @property
    def spp_mean(self) -> float: ...
    @property
    def denoised(self) -> bool: ...
    @property
    def stopped(self) -> bool: ...
    @property
    def seconds(self) -> float: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...

class Session:
    """A live scene to edit and render; edits rebuild only what they change."""

    def __init__(
        self,
        plugin_path: Sequence[str] = ...,
        ocio: str = "",
        threads: int = 0,
        verbose: bool = False,
    ) -> None: ...
    def load(
        self, path: Union[str, os.PathLike], time: float = 0.0,
        size: Optional[tuple[int, int]] = None
    ) -> None: ...
    @property
    def materials(self) -> list[str]: ...
    def material(self, name: str) -> dict: ...
    def set_material(self, name: str, **params: ParamValue) -> None: ...
    @property
    def objects(self) -> list[str]: ...
    def transform(self, name: str) -> dict: ...
    def set_transform(
        self,
        name: str,
        *,
        translate: Optional[Vec3] = None,
        rotate: Optional[Vec3] = None,
        scale: Optional[Union[Vec3, float]] = None,
        matrix: Optional[Union[Sequence[Sequence[float]], Sequence[float]]] = None,
    ) -> None: ...
    @property
    def camera(self) -> dict: ...
    def set_camera(
        self,
        *,
        position: Optional[Vec3] = None,
        look_at: Optional[Vec3] = None,
        up: Optional[Vec3] = None,
        fov: Optional[float] = None,
        aperture: Optional[float] = None,
        focus_distance: Optional[float] = None,
        ortho_height: Optional[float] = None,
        projection: Optional[str] = None,
    ) -> None: ...
    @property
    def lights(self) -> list[dict]: ...
    def set_light(
        self,
        index: int,
        *,
        intensity: Optional[float] = None,
        color: Optional[Vec3] = None,
        position: Optional[Vec3] = None,
        radius: Optional[float] = None,
    ) -> None: ...
    def render(
        self,
        *,
        spp: Optional[int] = None,
        size: Optional[tuple[int, int]] = None,
        layers: bool = True,
        progress: Optional[Callable[[int, int], None]] = None,
        on_pass: Optional[Callable[[npt.NDArray[np.float32], int], None]] = None,
        background_apart: Optional[bool] = None,
        noise_threshold: Optional[float] = None,
        min_spp: Optional[int] = None,
        max_spp: Optional[int] = None,
        denoise: bool = False,
        denoise_glints: Optional[str] = None,
    ) -> Image: ...
    def parameters(self, plugin: str, model: str = "") -> list[dict]: ...
    def stop(self) -> None: ...
    def write(
        self,
        image: Image,
        path: Union[str, os.PathLike[str]],
        *,
        preview: Optional[Union[str, os.PathLike[str]]] = None,
        float: bool = False,
        compression: str = "zip",
    ) -> None: ...
