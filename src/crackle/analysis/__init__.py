"""Derived results from runs: fragments, and more to come (crack speed, FPZ length...)."""

from .fragments import Fragments, find_fragments

__all__ = ["Fragments", "find_fragments"]
