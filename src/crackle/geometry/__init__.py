"""Tetrahedral meshes: structured and gmsh generation, import, checks, selections, face topology."""

from . import meshes, walnut
from .meshes import *  # noqa: F403 - the package's names are those of its modules' __all__
from .walnut import *  # noqa: F403

__all__ = [*meshes.__all__, *walnut.__all__]
