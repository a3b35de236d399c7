"""Derived results from runs: fragments, and more to come (crack speed, FPZ length...)."""

from .fracture_tip import FracturePlane, propagating_plastic_zone, tip_and_plastic_zone
from .fragments import Fragments, find_fragments
from .loading_index import loading_directions, loading_index

__all__ = ["FracturePlane", "Fragments", "find_fragments", "loading_directions", "loading_index", "propagating_plastic_zone", "tip_and_plastic_zone"]
