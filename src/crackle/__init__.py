"""crackle: dynamic fracture of brittle solids and thin-walled shells."""

__version__ = "0.1.0"
