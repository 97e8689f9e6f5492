"""Library materials made from a measured one with a recomputed reflectance spectrum: the skin
tones (:mod:`humv_usd.catalog.skin`) and hair colours (:mod:`humv_usd.catalog.hair`).

This module does not import :mod:`humv_usd.catalog.materials` (which imports the modules that
use it), so it works on any :class:`~humv_usd.catalog.materials.Material`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection


def variant_name(stem: str, key: str, value: str | None, allowed: Collection[str], default: str) -> str:
    """``<stem>_<value>``, the library name of a variant; None: ``default``. A value outside
    ``allowed`` raises ValueError naming the scenario ``key`` and the allowed values."""
    if value is None:
        return default
    if value not in allowed:
        raise ValueError(f"{key} = {value!r}: expected one of {list(allowed)}")
    return f"{stem}_{value}"


def spectral_variant(base, name: str, source: str, **spectrum):
    """``base`` named ``name`` with the new spectrum fields (``spectrum_reflectance``, optionally
    ``spectrum_wavelengths``); its solar absorptivity becomes that of the new spectrum under the
    reference sun (rounded to 4 digits: no per-variant literature value at hand) and ``source``
    is put before the base's."""
    made = dataclasses.replace(base, name=name, **spectrum)
    return dataclasses.replace(
        made, solar_absorptivity=round(made.spectral_solar_absorptivity, 4), source=source + base.source
    )
