"""Physics models: one flat module per domain, pure numpy, SI units, wavelengths in um.

``planck`` (blackbody spectral/band radiance, brightness temperature), ``sky`` (effective sky
temperature).
"""
