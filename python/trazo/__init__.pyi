from os import PathLike
from typing import Any, Callable, Dict, Literal, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

Image = npt.NDArray[np.float32]
Source = Union[str, PathLike[str], Mapping[str, Any]]

class TrazoError(Exception): ...

class Scene:
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def spp(self) -> int: ...
    @property
    def integrator(self) -> str: ...
    @property
    def warnings(self) -> list[str]: ...

def load(source: Optional[Source] = None, **params: Union[str, int, float, bool]) -> Scene: ...

Progress = Union[None, bool, Callable[[int, int], object]]

def render(
    scene: Union[Scene, Source],
    *,
    spp: Optional[int] = None,
    integrator: Optional[Literal["whitted", "path", "photon", "sppm", "volpath", "light", "ao"]] = None,
    sampling: Optional[Literal["uniform", "cosine", "bsdf", "nee", "nee-uniform", "mis"]] = None,
    seed: Optional[int] = None,
    threads: Optional[int] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    max_depth: Optional[int] = None,
    aovs: Sequence[Literal["albedo", "normal", "depth", "steps"]] = (),
    progress: Progress = None,
) -> Union[Image, Dict[str, Image]]: ...
def read(path: Union[str, PathLike[str]]) -> Image: ...
def write(
    path: Union[str, PathLike[str]],
    image: Image,
    tonemap: Literal["clamp", "reinhard", "aces"] = "clamp",
    exposure: float = 0.0,
) -> None: ...
