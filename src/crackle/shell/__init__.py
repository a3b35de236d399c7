"""Kirchhoff-Love shells on triangulated mid-surfaces with J-integral fracture mechanics (paper 002)."""
