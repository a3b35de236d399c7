"""Derived results from runs: fragments, fracture tip and plastic zone, cracks, loading index."""

from .cracks import CrackAnalysis, CrackSettings, analyse_cracks
from .fracture_tip import FracturePlane, propagating_plastic_zone, tip_and_plastic_zone
from .fragments import Fragments, find_fragments
from .loading_index import loading_directions, loading_index, loading_index_of

__all__ = ["CrackAnalysis", "CrackSettings", "analyse_cracks", "loading_index_of", "FracturePlane", "Fragments", "find_fragments", "loading_directions", "loading_index", "propagating_plastic_zone", "tip_and_plastic_zone"]
