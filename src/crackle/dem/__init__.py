"""Bonded-particle DEM for rock (paper 003, the JCFpm model): spheres from a random dense packing,
bonds between near neighbours that break in tension or shear and go on rubbing in compression,
frictional contacts, local non-viscous damping; the shared tools, supports, run control, outputs
and energy audit."""

from .setup import Scenario, build_simulation

__all__ = ["Scenario", "build_simulation"]
