"""Artificial light sources after dark: relative spectral power distributions (SPDs) by lamp type.

Each lamp type is a relative SPD over 0.36-2.5 um (peak 1; the render scales it to the lamp's
luminous flux or luminance with the CIE photopic efficiency, 683 lm W-1,
:func:`humv_usd.physics.nightsky.scale_to_photometric`). What the SPDs are:

- ``incandescent``: a blackbody at 2856 K, CIE standard illuminant A (CIE 015:2018, the
  tungsten-filament lamp; the filament's emissivity barely changes the shape);
- ``halogen``: a blackbody at 3200 K, the colour temperature of tungsten-halogen vehicle
  headlamp bulbs (H4/H7: 3100-3300 K; e.g. Schanda (ed.), *Colorimetry*, Wiley 2007, ch. 5 on
  light sources), halogen street and flood lights alike;
- ``led_3000k``, ``led_4000k``, ``led_5700k``: phosphor-converted white LEDs modelled as a blue
  InGaN peak (450 nm, 20 nm FWHM) plus a broad YAG:Ce phosphor band (Gaussians; Ohno 2005, Opt.
  Eng. 44:111302, the two-band model), the phosphor centre, width and blue share fitted here so
  that the correlated colour temperature is the nominal one within 1 % and |Duv| < 0.005
  (tests/test_lights.py checks both with colour-science's Ohno 2013 method). No emission beyond
  0.8 um: white LEDs are dark in the SWIR;
- ``hps``: high-pressure sodium (the orange street lamp): the pressure-broadened, self-reversed
  sodium D line (two lobes at 568 and 615 nm around the absorbed 589 nm core), weaker lines at
  498 nm, the 819 nm near-infrared doublet and the 1138 nm line; relative heights read from the
  measured HPS spectrum of Elvidge et al. (2010) Sensors 10:3961 (fig. 2; representative
  values, not data points).

The lamp's photometry comes from its USD light (:mod:`humv_usd.usd.lights`): luminous flux [lm]
for a lamp (street lamp, headlight), luminance [cd m-2] for a lit surface (a window).
Typical values (informative): a residential LED street luminaire 3000-8000 lm (EN 13201 road
classes P/M), a halogen low-beam headlamp ~1000 lm per lamp (H7: 1500 lm bulb, ECE R37), a
lit window at night 10-100 cd m-2 (Narisada & Schreuder, *Light Pollution Handbook*, 2004).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.physics import planck


def _gauss(wl_um, centre_nm, fwhm_nm):
    s = fwhm_nm / 2.354820045 / 1000.0
    return np.exp(-0.5 * ((np.asarray(wl_um, float) - centre_nm / 1000.0) / s) ** 2)


def _led(blue, centre_nm, fwhm_nm):
    return lambda wl: blue * _gauss(wl, 450.0, 20.0) + _gauss(wl, centre_nm, fwhm_nm)


def _planck(t_k):
    return lambda wl: planck.spectral_radiance(np.asarray(wl, float), t_k)


def _hps(wl):
    lines = (
        (568.0, 22.0, 1.0),
        (615.0, 30.0, 0.75),
        (498.0, 6.0, 0.15),
        (819.0, 6.0, 0.35),
        (1138.0, 8.0, 0.12),
    )
    return sum(h * _gauss(wl, c, f) for c, f, h in lines)


@dataclass(frozen=True)
class LampType:
    """A lamp type: ``relative_spd(wavelengths_um)`` (any scale) and what it is."""

    name: str
    description: str
    relative_spd: object

    def spd(self, wavelengths_um) -> np.ndarray:
        """Relative SPD at ``wavelengths_um`` [um], peak 1 on 0.36-2.5 um."""
        grid = np.linspace(0.36, 2.5, 2141)
        peak = float(np.max(self.relative_spd(grid)))
        return np.asarray(self.relative_spd(np.asarray(wavelengths_um, float)), float) / peak


LAMPS: dict[str, LampType] = {
    lamp.name: lamp
    for lamp in (
        LampType("incandescent", "tungsten filament, CIE illuminant A (2856 K blackbody)", _planck(2856.0)),
        LampType(
            "halogen", "tungsten-halogen (vehicle headlamp, flood light), 3200 K blackbody", _planck(3200.0)
        ),
        LampType("led_3000k", "phosphor-converted white LED, 3000 K", _led(0.66, 590.0, 110.0)),
        LampType(
            "led_4000k", "phosphor-converted white LED, 4000 K (street lighting)", _led(1.25, 580.0, 120.0)
        ),
        LampType(
            "led_5700k", "phosphor-converted white LED, 5700 K (LED headlamps)", _led(1.75, 565.0, 130.0)
        ),
        LampType("hps", "high-pressure sodium (orange street lamp), self-reversed Na D line", _hps),
    )
}
#: Nominal correlated colour temperatures [K] of the white lamps (checked in tests/test_lights.py).
NOMINAL_CCT_K = {
    "incandescent": 2856.0,
    "halogen": 3200.0,
    "led_3000k": 3000.0,
    "led_4000k": 4000.0,
    "led_5700k": 5700.0,
}
