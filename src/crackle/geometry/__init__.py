"""Tetrahedral meshes: structured and gmsh generation, import, checks, selections, face topology;
projectiles' surfaces."""

from . import meshes, projectile, walnut
from .meshes import *  # noqa: F403 - the package's names are those of its modules' __all__
from .projectile import *  # noqa: F403
from .walnut import *  # noqa: F403

__all__ = [*meshes.__all__, *projectile.__all__, *walnut.__all__]
