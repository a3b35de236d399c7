"""Derived results from runs: fragments, and more to come (crack speed, FPZ length...)."""

from .fracture_tip import FracturePlane, propagating_plastic_zone, tip_and_plastic_zone
from .fragments import Fragments, find_fragments

__all__ = ["FracturePlane", "Fragments", "find_fragments", "propagating_plastic_zone", "tip_and_plastic_zone"]
