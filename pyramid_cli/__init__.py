"""Pyramid filters based on bilinear interpolation (Kraus & Strengert, GRAPP 2007)."""

__version__ = "0.1.0"
