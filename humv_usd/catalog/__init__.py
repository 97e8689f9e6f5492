"""Catalogues as data that tools read: spectral/thermal materials, garments, sensor presets.

Nothing here reads or writes USD; the materials, clothing and sensors tools author these entries
into their layers, and downstream tools read them back from the stage (``humv_usd.usd``).
"""
