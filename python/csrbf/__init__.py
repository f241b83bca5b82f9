"""csrbf: deformation and interpolation by compactly supported radial basis functions (Wendland).

``csrbf.Interpolator`` interpolates scattered data in 1-3 dimensions (the compact-support counterpart
of ``scipy.interpolate.RBFInterpolator``); ``csrbf.SpaceMap`` is the paper's space mapping of 3-D
points by control vectors. The file functions (``read_mesh``, ``morph``, ``Scene`` ...) are the
extension ``csrbf._io``, which links VTK, assimp and CGNS: it is imported on first use of one of its
names, so that ``import csrbf`` loads the core alone. docs/python.md is the tutorial.
"""

from ._core import DisplacementField, SpaceMap, __version__, estimate, suggest_radius
from ._interpolate import Interpolator

TYPE_CHECKING = False  # typing's costs 4 ms of a 4 ms import; type checkers take any TYPE_CHECKING
if TYPE_CHECKING:  # what type checkers see of the names imported on first use
    from ._io import (
        FileError,
        Scene,
        apply_deformation,
        morph,
        read_active_area,
        read_controls,
        read_deformation,
        read_mesh,
        write_deformation,
        write_mesh,
    )
del TYPE_CHECKING

#: The names of csrbf._io, reached as csrbf.NAME.
_IO_NAMES = (
    "FileError",
    "read_mesh",
    "write_mesh",
    "read_controls",
    "read_deformation",
    "read_active_area",
    "apply_deformation",
    "write_deformation",
    "morph",
    "Scene",
)


def _io_names() -> list[str]:
    """The file names this build has (csrbf.morph needs csrbf's morph library)."""
    from . import _core

    return [n for n in _IO_NAMES if n != "morph" or _core._HAVE_MORPH]


def __getattr__(name: str) -> object:
    """PEP 562: a file function is imported from csrbf._io on first use, then kept here."""
    if name not in _io_names():
        raise AttributeError(f"module 'csrbf' has no attribute '{name}'")
    try:
        from . import _io
    except ImportError as e:  # an AttributeError, so that hasattr is False; it says why
        raise AttributeError(
            f"csrbf.{name} is in csrbf's file extension csrbf._io, which could not be loaded: {e}"
        ) from e
    value = getattr(_io, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_io_names()))


# `from csrbf import *` takes the file functions too (through __getattr__, as any other use).
__all__ = sorted(
    ["DisplacementField", "Interpolator", "SpaceMap", "estimate", "suggest_radius"] + _io_names()
)
