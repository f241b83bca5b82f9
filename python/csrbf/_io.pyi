# Type stubs of csrbf._io, csrbf's file functions (python/module_io.cpp), reached as csrbf.NAME.
# csrbf's tests check that these name every public name of the module (tests/python/test_package.py).
import os
from typing import Any, Optional, Union

import numpy as np
import numpy.typing as npt

from ._core import SpaceMap

_Path = Union[str, os.PathLike[str]]

class FileError(OSError): ...

class Scene:
    def __init__(self, path: _Path) -> None: ...
    def positions(self, t: float) -> list[npt.NDArray[np.float64]]: ...
    def faces(self, object: int) -> list[list[int]]: ...
    @property
    def duration(self) -> float: ...
    @property
    def fps(self) -> float: ...
    @property
    def objects(self) -> list[str]: ...

def apply_deformation(path: _Path, positions: npt.ArrayLike, phase: float = 1.0) -> npt.NDArray[np.float64]: ...
def read_active_area(path: _Path) -> Any: ...
def read_controls(path: _Path) -> tuple[Any, ...]: ...
def read_deformation(path: _Path) -> SpaceMap: ...
def write_deformation(path: _Path, map: SpaceMap) -> None: ...
def read_mesh(path: _Path) -> tuple[Any, ...]: ...
def write_mesh(template: _Path, positions: npt.ArrayLike, path: _Path) -> None: ...
def morph(
    mesh: Any,
    motion: Any,
    output: Optional[_Path] = None,
    in_place: bool = False,
    radius: Union[float, str, None] = None,
    kernel: Optional[str] = None,
    polynomial: Optional[str] = None,
    greedy: Optional[float] = None,
    phase: float = 1.0,
    solver: str = "auto",
    force: bool = False,
    memory_limit: float = 4.0,
    patches: Optional[dict[str, Any]] = None,
    greedy_budget: Any = None,
    time: Any = None,
    levels: Any = "auto",
) -> tuple[Any, ...]: ...
