"""The CIE tables of the EO render: :mod:`humv_usd.physics.cie` (the CIE 1931 colour-matching
functions and the sRGB matrix, frozen from colour-science), re-exported under the name the render
and its tests use. They moved to ``physics`` so that the atmosphere tool's sky texture, which sits
below the render in the package graph, reads the same tables."""

from __future__ import annotations

from humv_usd.physics.cie import CMF_WAVELENGTHS_NM, CMF_XYZ, XYZ_TO_SRGB, generate, main

__all__ = ["CMF_WAVELENGTHS_NM", "CMF_XYZ", "XYZ_TO_SRGB", "generate", "main"]
