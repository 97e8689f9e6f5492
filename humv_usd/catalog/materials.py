"""Built-in material library: spectral reflectance/emissivity over 0.4-14 µm and thermal data.

Each material has its own wavelength grid [µm] (finer where the spectrum has features: the
water bands of skin and leaves at 1.45/1.94/2.8-3 µm, the chlorophyll red edge, the 8-10 µm
silicate reststrahlen bands of concrete, soil and glass) and is interpolated linearly between
nodes. Opaque materials obey Kirchhoff's law, emissivity = 1 - directional-hemispherical
reflectance; glass also carries a transmittance (emissivity = 1 - R - T). Every entry names its
sources; spectral values taken "after" a library are representative readings of the library's
curves for that class of material (shape and level), not its data points.

``Material.reflectance`` and ``Material.emissivity`` give the values at the common coarse grid
``WAVELENGTHS_UM`` (what the thermal tools use); ``spectrum_*`` is the full table that the
materials layer writes.

Common sources:
- ECOSTRESS spectral library v1.0: Meerdink, Hook, Roberts & Abbott (2019) Remote Sens.
  Environ. 230:111196 (0.35-15.4 µm directional-hemispherical reflectance).
- ASTER spectral library v2.0: Baldridge, Hook, Grove & Rivera (2009) Remote Sens. Environ.
  113:711-715.
- Salisbury & D'Aria (1992) "Emissivity of terrestrial materials in the 8-14 µm atmospheric
  window", Remote Sens. Environ. 42:83-106; (1994) "... in the 3-5 µm atmospheric window",
  Remote Sens. Environ. 47:345-361.
- Incropera, DeWitt, Bergman & Lavine, Fundamentals of Heat and Mass Transfer, 6th ed. (2007),
  Tables A.1 (metals), A.3 (building materials), A.11 (total emissivities).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from humv_usd.physics import snow as snow_optics
from humv_usd.physics.sun import solar_absorptivity

#: Common coarse grid of the thermal tools (and of the fabric entries).
WAVELENGTHS_UM = (0.4, 0.55, 0.7, 1.0, 2.5, 3.0, 5.0, 8.0, 11.0, 14.0)

#: Fine grid for spectra with features: visible every 50 nm, the water bands (1.45, 1.94,
#: 2.8-3.0 µm), the carbonate band (6.5-7 µm) and the silicate reststrahlen region (8-10 µm).
FINE_WAVELENGTHS_UM = (
    0.40,
    0.45,
    0.50,
    0.55,
    0.60,
    0.65,
    0.70,
    0.75,
    0.80,
    0.90,
    1.00,
    1.20,
    1.45,
    1.65,
    1.94,
    2.20,
    2.50,
    2.80,
    3.00,
    3.50,
    4.00,
    4.50,
    5.00,
    6.00,
    6.50,
    7.00,
    7.50,
    8.00,
    8.50,
    9.00,
    9.30,
    9.60,
    10.00,
    10.50,
    11.00,
    11.50,
    12.00,
    12.50,
    13.00,
    13.50,
    14.00,
)
_FINE = FINE_WAVELENGTHS_UM


@dataclass(frozen=True)
class Material:
    name: str
    spectrum_reflectance: tuple[float, ...]  # at spectrum_wavelengths [0-1]
    conductivity: float  # [W m-1 K-1]
    density: float  # [kg m-3]
    specific_heat: float  # [J kg-1 K-1]
    thickness: float  # [m] of the slab or layer
    solar_absorptivity: float  # [0-1] broadband literature value (see spectral_solar_absorptivity)
    source: str
    label_class: str = "other"
    spectrum_wavelengths: tuple[float, ...] = WAVELENGTHS_UM  # [µm], ascending
    spectrum_transmittance: tuple[float, ...] | None = None  # None: opaque

    def __post_init__(self):
        n = len(self.spectrum_wavelengths)
        if len(self.spectrum_reflectance) != n or (
            self.spectrum_transmittance is not None and len(self.spectrum_transmittance) != n
        ):
            raise ValueError(f"material {self.name}: one value per wavelength expected")

    @property
    def opaque(self) -> bool:
        return self.spectrum_transmittance is None

    @property
    def spectrum_emissivity(self) -> tuple[float, ...]:
        """Kirchhoff: emissivity = absorptivity = 1 - R - T at each node."""
        t = self.spectrum_transmittance or (0.0,) * len(self.spectrum_reflectance)
        return tuple(round(1.0 - r - tt, 6) for r, tt in zip(self.spectrum_reflectance, t))

    def at(self, wavelengths_um, what: str = "reflectance") -> np.ndarray:
        """Reflectance, emissivity or transmittance interpolated at wavelengths [µm]."""
        table = {
            "reflectance": self.spectrum_reflectance,
            "emissivity": self.spectrum_emissivity,
            "transmittance": self.spectrum_transmittance or (0.0,) * len(self.spectrum_wavelengths),
        }[what]
        return np.interp(wavelengths_um, self.spectrum_wavelengths, table)

    @property
    def reflectance(self) -> tuple[float, ...]:
        """Reflectance at the common grid WAVELENGTHS_UM."""
        return tuple(round(float(v), 6) for v in self.at(WAVELENGTHS_UM, "reflectance"))

    @property
    def emissivity(self) -> tuple[float, ...]:
        """Emissivity at the common grid WAVELENGTHS_UM."""
        return tuple(round(float(v), 6) for v in self.at(WAVELENGTHS_UM, "emissivity"))

    @property
    def spectral_solar_absorptivity(self) -> float:
        """Solar absorptivity of this material's own spectrum under the reference sun
        (:func:`humv_usd.physics.sun.solar_absorptivity`): the value the materials tool writes
        and the thermal solve uses. ``solar_absorptivity`` is the broadband literature value
        the spectrum was checked against (tests/test_material_consistency.py)."""
        return solar_absorptivity(
            self.spectrum_wavelengths, self.spectrum_reflectance, self.spectrum_transmittance
        )

    @property
    def display_color(self) -> tuple[float, float, float]:
        """Rough sRGB-linear colour for DCC viewports (reflectance at 0.65, 0.55, 0.45 µm)."""
        r, g, b = self.at([0.65, 0.55, 0.45], "reflectance")
        return (float(r), float(g), float(b))


def _fine(values) -> dict:
    values = tuple(float(v) for v in values)
    assert len(values) == len(_FINE), len(values)
    return {"spectrum_wavelengths": _FINE, "spectrum_reflectance": values}


_ECOSTRESS = "ECOSTRESS spectral library v1.0 (Meerdink et al. 2019, Remote Sens. Environ. 230:111196)"
_SD92 = "Salisbury & D'Aria (1992) Remote Sens. Environ. 42:83-106 (8-14 µm)"
_SD94 = "Salisbury & D'Aria (1994) Remote Sens. Environ. 47:345-361 (3-5 µm)"
_INCROPERA = "Incropera et al., Fundamentals of Heat and Mass Transfer, 6th ed., 2007"

LIBRARY: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "skin",
            **_fine(
                (
                    0.20,
                    0.25,
                    0.29,
                    0.30,
                    0.42,
                    0.54,
                    0.58,
                    0.60,
                    0.60,
                    0.58,
                    0.55,
                    0.45,
                    0.14,
                    0.36,
                    0.06,
                    0.16,
                    0.05,
                    0.02,
                    0.02,
                    0.03,
                    0.03,
                    0.03,
                    0.03,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                )
            ),
            conductivity=0.37,
            density=1109.0,
            specific_heat=3391.0,
            thickness=0.002,
            solar_absorptivity=0.62,
            source="IR emissivity 0.98 +- 0.01 over the measured 2-14 µm, independent of "
            "pigmentation: Steketee (1973) Phys. Med. Biol. 18:686-694 (reflectance "
            "0.02 here from 2.8 µm on; 0.97 in 3.5-5 µm where water absorbs least, "
            "estimate); visible/NIR reflectance of light skin with the haemoglobin dip "
            "at 0.54-0.58 µm and the water bands at 1.45 and 1.94 µm: Anderson & "
            "Parrish (1981) J. Invest. Dermatol. 77:13-19 (0.25-2.5 µm), Jacques (2013) "
            "Phys. Med. Biol. 58:R37; k, rho, c: IT'IS tissue database v4.1 (skin)",
            label_class="person",
        ),
        Material(
            "concrete",
            **_fine(
                (
                    0.20,
                    0.23,
                    0.26,
                    0.28,
                    0.30,
                    0.31,
                    0.32,
                    0.33,
                    0.34,
                    0.35,
                    0.36,
                    0.37,
                    0.33,
                    0.38,
                    0.30,
                    0.33,
                    0.30,
                    0.12,
                    0.08,
                    0.10,
                    0.11,
                    0.08,
                    0.07,
                    0.04,
                    0.06,
                    0.05,
                    0.04,
                    0.03,
                    0.06,
                    0.09,
                    0.08,
                    0.06,
                    0.05,
                    0.04,
                    0.03,
                    0.04,
                    0.03,
                    0.03,
                    0.03,
                    0.03,
                    0.03,
                )
            ),
            conductivity=1.4,
            density=2300.0,
            specific_heat=880.0,
            thickness=0.2,
            solar_absorptivity=0.65,
            source=f"construction concrete after {_ECOSTRESS}: grey, rising slowly through "
            f"the visible, bound-water bands at 1.45/1.94 µm and 2.8-3 µm, carbonate "
            f"(calcite) features at 6.5 and 11.3 µm, quartz-aggregate reststrahlen "
            f"peak at 8.5-9.3 µm; 8-14 µm emissivity 0.94-0.96 as {_SD92}; MWIR "
            f"0.89-0.93 as {_SD94}; k, rho, c: {_INCROPERA}, Table A.3 (stone mix "
            f"concrete)",
            label_class="ground",
        ),
        Material(
            "asphalt",
            **_fine(
                (
                    0.05,
                    0.05,
                    0.055,
                    0.06,
                    0.062,
                    0.065,
                    0.07,
                    0.072,
                    0.075,
                    0.078,
                    0.08,
                    0.085,
                    0.085,
                    0.10,
                    0.09,
                    0.10,
                    0.09,
                    0.08,
                    0.07,
                    0.06,
                    0.07,
                    0.065,
                    0.06,
                    0.05,
                    0.05,
                    0.05,
                    0.05,
                    0.05,
                    0.06,
                    0.07,
                    0.065,
                    0.06,
                    0.05,
                    0.045,
                    0.04,
                    0.04,
                    0.04,
                    0.04,
                    0.04,
                    0.045,
                    0.05,
                )
            ),
            conductivity=0.75,
            density=2120.0,
            specific_heat=920.0,
            thickness=0.1,
            solar_absorptivity=0.93,
            source=f"paving asphalt after {_ECOSTRESS} (construction asphalt): dark and "
            f"nearly flat, C-H absorption of the binder at 3.4 µm, weak aggregate "
            f"reststrahlen near 9 µm; 8-14 µm emissivity ~0.95; k, rho, c: "
            f"{_INCROPERA}, Table A.3 (asphalt)",
            label_class="ground",
        ),
        Material(
            "painted_metal",
            **_fine(
                (
                    0.30,
                    0.34,
                    0.37,
                    0.40,
                    0.41,
                    0.41,
                    0.42,
                    0.43,
                    0.44,
                    0.45,
                    0.45,
                    0.44,
                    0.40,
                    0.40,
                    0.32,
                    0.30,
                    0.25,
                    0.12,
                    0.10,
                    0.08,
                    0.12,
                    0.12,
                    0.10,
                    0.06,
                    0.06,
                    0.06,
                    0.06,
                    0.06,
                    0.08,
                    0.10,
                    0.10,
                    0.09,
                    0.08,
                    0.08,
                    0.08,
                    0.08,
                    0.09,
                    0.09,
                    0.10,
                    0.10,
                    0.10,
                )
            ),
            conductivity=50.0,
            density=7850.0,
            specific_heat=470.0,
            thickness=0.0006,
            solar_absorptivity=0.6,
            source=f"light grey/beige painted steel siding: 8-14 µm emissivity ~0.91 from "
            f"{_INCROPERA}, Table A.11 (paints 0.90-0.98, lower end for a weathered "
            f"light siding); spectral shape (TiO2-pigmented binder: bright visible/NIR, "
            f"C-H band at 3.4 µm, polymer C-O bands at 8-10 µm) typical of paint "
            f"spectra in {_ECOSTRESS} (manmade, paint), not a measurement of the NCMR "
            f"warehouse; steel k, rho, c: Table A.1 (plain carbon steel)",
            label_class="building",
        ),
        Material(
            "wood",
            **_fine(
                (
                    0.15,
                    0.20,
                    0.25,
                    0.30,
                    0.36,
                    0.40,
                    0.44,
                    0.47,
                    0.50,
                    0.53,
                    0.55,
                    0.55,
                    0.40,
                    0.50,
                    0.25,
                    0.40,
                    0.20,
                    0.04,
                    0.03,
                    0.05,
                    0.08,
                    0.07,
                    0.06,
                    0.04,
                    0.04,
                    0.04,
                    0.04,
                    0.05,
                    0.06,
                    0.04,
                    0.03,
                    0.03,
                    0.04,
                    0.05,
                    0.06,
                    0.06,
                    0.07,
                    0.07,
                    0.07,
                    0.08,
                    0.08,
                )
            ),
            conductivity=0.12,
            density=510.0,
            specific_heat=1380.0,
            thickness=0.02,
            solar_absorptivity=0.6,
            source=f"dry sawn pine after {_ECOSTRESS} (construction wood): rising visible/NIR "
            f"reflectance, water and cellulose bands at 1.45/1.94/2.1 µm, strong "
            f"cellulose C-O absorption at 9-10 µm; 8-14 µm emissivity 0.90-0.95; k, "
            f"rho, c: {_INCROPERA}, Table A.3 (softwood)",
            label_class="prop",
        ),
        Material(
            "grass",
            **_fine(
                (
                    0.04,
                    0.045,
                    0.06,
                    0.11,
                    0.07,
                    0.05,
                    0.15,
                    0.42,
                    0.47,
                    0.48,
                    0.47,
                    0.40,
                    0.18,
                    0.30,
                    0.08,
                    0.17,
                    0.05,
                    0.02,
                    0.02,
                    0.03,
                    0.04,
                    0.04,
                    0.04,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.025,
                    0.03,
                    0.03,
                    0.025,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                    0.02,
                )
            ),
            conductivity=0.5,
            density=1000.0,
            specific_heat=3000.0,
            thickness=0.05,
            solar_absorptivity=0.8,
            source=f"green lawn grass after {_ECOSTRESS} (vegetation, grass): green peak at "
            f"0.55 µm, chlorophyll absorption at 0.67 µm, red edge to the NIR plateau "
            f"~0.47, leaf-water bands at 1.45/1.94/2.8 µm; 8-14 µm emissivity 0.97-0.98 "
            f"as {_SD92} (green foliage); bulk properties of a wet sod layer (order of "
            f"magnitude)",
            label_class="vegetation",
        ),
        Material(
            "soil",
            **_fine(
                (
                    0.06,
                    0.08,
                    0.10,
                    0.12,
                    0.15,
                    0.18,
                    0.20,
                    0.22,
                    0.23,
                    0.25,
                    0.27,
                    0.30,
                    0.27,
                    0.33,
                    0.25,
                    0.29,
                    0.28,
                    0.10,
                    0.05,
                    0.08,
                    0.10,
                    0.09,
                    0.08,
                    0.04,
                    0.03,
                    0.03,
                    0.03,
                    0.04,
                    0.09,
                    0.10,
                    0.07,
                    0.05,
                    0.04,
                    0.03,
                    0.03,
                    0.03,
                    0.03,
                    0.035,
                    0.03,
                    0.03,
                    0.03,
                )
            ),
            conductivity=0.52,
            density=2050.0,
            specific_heat=1840.0,
            thickness=0.3,
            solar_absorptivity=0.8,
            source=f"brown loam after {_ECOSTRESS} / ASTER v2.0 (Baldridge et al. 2009, "
            f"Remote Sens. Environ. 113:711; soils, Inceptisol/Mollisol): reflectance "
            f"rising from the visible to 2.5 µm with clay OH bands at 1.4/1.9/2.2 µm, "
            f"water band at 2.8-3 µm, quartz reststrahlen doublet at 8.2-9.3 µm and "
            f"12.6 µm; 8-14 µm emissivity 0.94-0.96 as {_SD92}; k, rho, c: "
            f"{_INCROPERA}, Table A.3 (soil)",
            label_class="ground",
        ),
        Material(
            "glass",
            spectrum_wavelengths=_FINE,
            spectrum_reflectance=(
                0.08,
                0.08,
                0.08,
                0.08,
                0.08,
                0.08,
                0.08,
                0.08,
                0.08,
                0.08,
                0.075,
                0.075,
                0.075,
                0.075,
                0.075,
                0.075,
                0.075,
                0.07,
                0.07,
                0.06,
                0.055,
                0.05,
                0.045,
                0.04,
                0.03,
                0.02,
                0.03,
                0.06,
                0.10,
                0.22,
                0.28,
                0.25,
                0.15,
                0.08,
                0.06,
                0.05,
                0.05,
                0.05,
                0.05,
                0.06,
                0.06,
            ),
            spectrum_transmittance=(
                0.86,
                0.89,
                0.90,
                0.90,
                0.89,
                0.88,
                0.87,
                0.85,
                0.82,
                0.78,
                0.75,
                0.76,
                0.78,
                0.80,
                0.80,
                0.80,
                0.80,
                0.55,
                0.45,
                0.50,
                0.35,
                0.05,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            ),
            conductivity=1.4,
            density=2500.0,
            specific_heat=750.0,
            thickness=0.006,
            solar_absorptivity=0.12,
            source="6 mm clear soda-lime float glass: optical constants of soda-lime-silica "
            "glass from Rubin (1985) Solar Energy Materials 12:275-288 (0.3-50 µm): "
            "~4 % reflection per face in the visible, Fe2+ absorption near 1 µm, OH band "
            "at 2.8 µm, opaque beyond ~4.5 µm, silica reststrahlen reflectance peak "
            "~0.28 at 9.3 µm, 8-14 µm emissivity ~0.90 (broadband 0.84-0.92, "
            f"{_INCROPERA}, Table A.11, glass); transmittance in the visible 0.89, "
            "typical of clear float glass data sheets (EN 410); k, rho, c: "
            f"{_INCROPERA}, Table A.3 (glass, plate)",
            label_class="building",
        ),
        Material(
            "blackbody",
            spectrum_reflectance=(0.03,) * len(WAVELENGTHS_UM),
            conductivity=200.0,
            density=2700.0,
            specific_heat=900.0,
            thickness=0.006,
            solar_absorptivity=0.97,
            source="extended-area blackbody panel, emissivity 0.97 (typical specification of "
            "field calibration sources, e.g. CI Systems SR-800); aluminium plate k, rho, c: "
            f"{_INCROPERA}, Table A.1",
            label_class="panel",
        ),
    )
}

# ---------------------------------------------------------------------------- fabrics
# Garment fabrics (humv_usd.clothing). The layer is modelled as opaque (emissivity = 1 - R);
# real thin fabrics also transmit a few % in the LWIR and up to ~25 % in the NIR, which the
# opaque model folds into reflectance and absorptivity. Common sources:
_LWIR_FABRICS = (
    "LWIR (8-12 µm) emissivity of nylon 0.87, cotton 0.88, polyester 0.88 fabrics at "
    "40 °C: Belliveau et al. (2020) Forensic Chemistry 19:100242"
)
_KNITS = (
    "MIR reflection 6-14 %, NIR absorption 10-96 % / reflection 4-67 % of wool, cotton and "
    "polyester knits, colour mainly acting in the visible/NIR: Bauer, Gresser & Mark (2021) "
    "J. Textile Sci. Fashion Technol. 8(1)"
)
_CP = (
    "specific heat of dry fibres: Morton & Hearle (2008) Physical Properties of Textile Fibres, "
    "4th ed., Table 6.1 (cotton 1.22-1.35, wool 1.36, nylon 6.6 1.46, PET 1.03 J/(g K))"
)
_K = (
    "effective fibre+air conductivity of fabrics 0.03-0.07 W/(m K): Baxter (1946) Proc. Phys. "
    "Soc. 58:105 (wool felts vs bulk density); density = areal mass / thickness of a typical "
    "fabric of that kind"
)
_MWIR = "MWIR nodes (3 µm O-H/N-H absorption, ε ≈ 0.8 at 5 µm) are estimates, no measured spectrum at hand"

FABRICS: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "cotton_white",
            spectrum_reflectance=(0.72, 0.78, 0.78, 0.65, 0.35, 0.05, 0.18, 0.12, 0.12, 0.12),
            conductivity=0.05,
            density=250.0,
            specific_heat=1300.0,
            thickness=0.0006,
            solar_absorptivity=0.30,
            source=f"white cotton jersey (T-shirt, 150 g/m2, 0.6 mm). {_LWIR_FABRICS}; "
            f"visible/NIR of a white knit at the high-reflection end of {_KNITS}; {_CP}; "
            f"{_K}; {_MWIR}",
            label_class="person",
        ),
        Material(
            "cotton_black",
            spectrum_reflectance=(0.04, 0.04, 0.05, 0.30, 0.25, 0.05, 0.15, 0.12, 0.12, 0.12),
            conductivity=0.05,
            density=250.0,
            specific_heat=1300.0,
            thickness=0.0006,
            solar_absorptivity=0.88,
            source=f"black-dyed cotton jersey (150 g/m2, 0.6 mm). {_LWIR_FABRICS} (dye barely "
            f"changes the LWIR value); NIR reflectance of black dyes rises beyond 0.7 µm, "
            f"low end of {_KNITS}; {_CP}; {_K}; {_MWIR}",
            label_class="person",
        ),
        Material(
            "nylon",
            spectrum_reflectance=(0.05, 0.05, 0.06, 0.35, 0.30, 0.10, 0.18, 0.13, 0.13, 0.13),
            conductivity=0.05,
            density=370.0,
            specific_heat=1460.0,
            thickness=0.0006,
            solar_absorptivity=0.85,
            source=f"black nylon/elastane knit (leggings, 220 g/m2, 0.6 mm). {_LWIR_FABRICS}; "
            f"{_KNITS}; {_CP}; {_K}; {_MWIR}",
            label_class="person",
        ),
        Material(
            "polyester",
            spectrum_reflectance=(0.30, 0.32, 0.33, 0.50, 0.40, 0.15, 0.20, 0.12, 0.12, 0.12),
            conductivity=0.045,
            density=280.0,
            specific_heat=1030.0,
            thickness=0.0005,
            solar_absorptivity=0.60,
            source=f"mid-grey polyester knit (sportswear, 140 g/m2, 0.5 mm). {_LWIR_FABRICS}; "
            f"{_KNITS}; {_CP}; {_K}; {_MWIR}",
            label_class="person",
        ),
        Material(
            "wool",
            spectrum_reflectance=(0.08, 0.09, 0.10, 0.35, 0.25, 0.05, 0.15, 0.10, 0.10, 0.10),
            conductivity=0.04,
            density=200.0,
            specific_heat=1360.0,
            thickness=0.002,
            solar_absorptivity=0.80,
            source=f"charcoal wool knit (cap, 400 g/m2, 2 mm). LWIR emissivity 0.90 from the "
            f"6-14 % MIR reflection of {_KNITS}; {_CP}; {_K}; {_MWIR}",
            label_class="person",
        ),
        Material(
            "camouflage_nyco",
            spectrum_reflectance=(0.07, 0.12, 0.15, 0.45, 0.35, 0.06, 0.18, 0.12, 0.12, 0.12),
            conductivity=0.06,
            density=490.0,
            specific_heat=1380.0,
            thickness=0.00045,
            solar_absorptivity=0.70,
            source=f"50/50 nylon/cotton (NYCO) camouflage-printed ripstop of combat uniforms "
            f"(MIL-DTL-44436B cloth: dyes specified for a foliage-like NIR reflectance; "
            f"~220 g/m2, 0.45 mm); pattern-averaged visible reflectance of a woodland/OCP "
            f"print and NIR ~0.45 at 1 µm are representative values, not a measurement. "
            f"{_LWIR_FABRICS} (both fibres 0.87-0.88); specific heat = mass mean of "
            f"nylon and cotton, {_CP}; {_K}; {_MWIR}",
            label_class="person",
        ),
    )
}
LIBRARY.update(FABRICS)

# ---------------------------------------------------------------------------- worn equipment
# Not plain fabrics (thicker, stiffer), so kept out of FABRICS; used by the clothing catalogue's
# ``vest`` and ``rifle``.
EQUIPMENT: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "kevlar_vest",
            spectrum_reflectance=(0.05, 0.06, 0.07, 0.35, 0.30, 0.10, 0.18, 0.13, 0.13, 0.13),
            conductivity=0.045,
            density=650.0,
            specific_heat=1420.0,
            thickness=0.008,
            solar_absorptivity=0.85,
            source=f"soft body armour (NIJ Standard-0101.06 Level IIIA class) in a dark nylon "
            f"carrier, modelled as one 8 mm slab: aramid fibre specific heat 1.42 J/(g K) "
            f"and conductivity 0.04 W/(m K): DuPont Kevlar Aramid Fiber Technical Guide "
            f"(H-77848); panel areal density ~5.2 kg/m2 over ~8 mm (about 25 plies of "
            f"~200 g/m2 aramid plus the carrier) is a representative value of commercial "
            f"Level IIIA panels, not a measurement (density = areal mass / thickness); "
            f"the outer surface is the nylon carrier: {_LWIR_FABRICS}; visible/NIR of a "
            f"dark nylon as the 'nylon' entry, {_KNITS}; {_K} (the fibre+air value); "
            f"{_MWIR}",
            label_class="person",
        ),
        Material(
            "polymer_black",
            spectrum_reflectance=(0.05, 0.05, 0.05, 0.06, 0.06, 0.05, 0.06, 0.06, 0.06, 0.07),
            conductivity=0.30,
            density=1360.0,
            specific_heat=1500.0,
            thickness=0.003,
            solar_absorptivity=0.94,
            source="black glass-fibre-reinforced polyamide (PA6-GF30) of rifle furniture, "
            "standing in for the whole weapon (receiver and barrel are black-finished "
            "metal; one material keeps the prop simple): density 1.36 g/cm3 and "
            "conductivity ~0.3 W/(m K) from PA6-GF30 data sheets (e.g. BASF Ultramid "
            "B3WG6); specific heat ~1.5 J/(g K) (PA6 ~1.7, glass 0.8, mass mean, "
            "estimate); LWIR emissivity 0.93-0.95 of black plastics from thermographic "
            "emissivity tables (e.g. Optris / FLIR: plastic, black 0.95); carbon-black "
            "pigment keeps the visible and NIR reflectance at ~5 % (estimate); 3 mm wall",
            label_class="prop",
        ),
        Material(
            "leather_black",
            spectrum_reflectance=(0.05, 0.05, 0.06, 0.20, 0.20, 0.08, 0.10, 0.06, 0.06, 0.06),
            conductivity=0.159,
            density=998.0,
            specific_heat=1500.0,
            thickness=0.003,
            solar_absorptivity=0.88,
            source="black leather of shoe uppers and soles, modelled as one 3 mm layer: "
            "conductivity 0.159 W/(m K) and density 998 kg/m3 of sole leather, Incropera et al. "
            "(2007) Table A.3; specific heat ~1.5 J/(g K) (collagen, estimate); LWIR emissivity "
            "0.94 (dark finished leather, thermographic emissivity tables give 0.75-0.95 for "
            "leathers: a representative value, not a measurement); visible/NIR of a black "
            "dye with its NIR rise as the black fabrics (estimate)",
            label_class="person",
        ),
        Material(
            "rubber_black",
            spectrum_reflectance=(0.04, 0.04, 0.04, 0.05, 0.05, 0.05, 0.06, 0.06, 0.06, 0.06),
            conductivity=0.16,
            density=1190.0,
            specific_heat=2010.0,
            thickness=0.004,
            solar_absorptivity=0.95,
            source="black rubber of boots (4 mm): hard rubber k 0.160 W/(m K), 1190 kg/m3, "
            "2010 J/(kg K), Incropera et al. (2007) Table A.3; LWIR emissivity 0.94 (rubber "
            "0.86-0.95 in Incropera Table A.11 and thermographic tables; representative); "
            "carbon-black filled rubber reflects ~4-6 % from the visible to the LWIR "
            "(estimate)",
            label_class="person",
        ),
        Material(
            "hair_dark",
            spectrum_reflectance=(0.04, 0.05, 0.07, 0.20, 0.15, 0.05, 0.08, 0.05, 0.05, 0.05),
            conductivity=0.05,
            density=100.0,
            specific_heat=1500.0,
            thickness=0.005,
            solar_absorptivity=0.88,
            source="short dark head hair as a 5 mm fibre+air layer: effective conductivity "
            "0.05 W/(m K) of a fibre layer of ~8 % keratin by volume (as wool felts: Baxter "
            "(1946) Proc. Phys. Soc. 58:105; fur insulation, Scholander et al. (1950) Biol. "
            "Bull. 99:225), density = 8 % of keratin's ~1300 kg/m3; keratin specific heat "
            "~1.5 J/(g K) (wool, Morton & Hearle 2008 Table 6.1); LWIR emissivity 0.95 "
            "(keratin/skin-like, estimate); eumelanin-dark hair absorbs most visible light "
            "(reflectance a few %, rising in the NIR; representative values, not a "
            "measurement)",
            label_class="person",
        ),
    )
}
LIBRARY.update(EQUIPMENT)


# ---------------------------------------------------------------------------- insulating fabrics
# Thicker, lofted fabrics of sweaters, fleeces, denim and winter coats (issue 25: coats and
# jackets that insulate). Kept out of FABRICS (thin woven/knit shell fabrics); their insulation is
# mostly the air their fibres hold still, so the effective conductivity is near still air's
# (0.026 W/(m K)) plus fibre conduction and radiation through the batt. Common sources:
_BATTS = (
    "effective conductivity of fibrous batts and pile fabrics near still air, 0.03-0.05 W/(m K) "
    "at 5-50 kg/m3, rising at low density as radiation passes between fibres: Bankvall (1973) "
    "J. Testing Eval. 1(3):235-243; fabric thermal resistance set by thickness, not fibre: Rees "
    "(1941) J. Textile Inst. 32:T149-T165"
)

INSULATION: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "denim",
            spectrum_reflectance=(0.12, 0.10, 0.08, 0.45, 0.30, 0.05, 0.16, 0.12, 0.12, 0.12),
            conductivity=0.06,
            density=560.0,
            specific_heat=1300.0,
            thickness=0.0008,
            solar_absorptivity=0.78,
            source=f"indigo cotton denim of jeans (14 oz/yd2 = 475 g/m2, 0.8-0.9 mm; density = "
            f"areal mass / thickness); a dense twill conducts more than a knit: 0.06 W/(m K), "
            f"within the 0.04-0.07 of woven cottons in {_K}; indigo absorbs in the red and is "
            f"transparent in the NIR (reflectance rising to ~0.45 at 1 µm), representative "
            f"values after {_KNITS}, not a measurement; {_LWIR_FABRICS} (cotton 0.88); {_CP} "
            f"(cotton 1.3 J/(g K)); {_MWIR}",
            label_class="person",
        ),
        Material(
            "wool_knit_thick",
            spectrum_reflectance=(0.07, 0.08, 0.09, 0.35, 0.25, 0.05, 0.15, 0.10, 0.10, 0.10),
            conductivity=0.04,
            density=150.0,
            specific_heat=1360.0,
            thickness=0.003,
            solar_absorptivity=0.82,
            source=f"navy chunky wool knit of a thick sweater (450 g/m2 over 3 mm, density = areal "
            f"mass / thickness); conductivity 0.04 W/(m K) of wool at 100-200 kg/m3: Baxter "
            f"(1946) Proc. Phys. Soc. 58:105; {_BATTS}; LWIR emissivity 0.90 from the 6-14 % "
            f"MIR reflection of {_KNITS}; {_CP} (wool 1.36 J/(g K)); {_MWIR}",
            label_class="person",
        ),
        Material(
            "fleece",
            spectrum_reflectance=(0.06, 0.08, 0.07, 0.40, 0.35, 0.12, 0.18, 0.12, 0.12, 0.12),
            conductivity=0.038,
            density=75.0,
            specific_heat=1100.0,
            thickness=0.004,
            solar_absorptivity=0.81,
            source=f"olive polyester fleece ('300-weight', 300 g/m2, about 4 mm of brushed pile; "
            f"density = areal mass / thickness); conductivity 0.038 W/(m K) of a polyester pile "
            f"at 75 kg/m3, {_BATTS}; specific heat of PET 1.03-1.17 J/(g K), {_CP}; "
            f"{_LWIR_FABRICS} (polyester 0.88); dyed dark olive with the NIR rise of "
            f"synthetic dyes, representative after {_KNITS}; {_MWIR}",
            label_class="person",
        ),
        Material(
            "down_fill",
            spectrum_reflectance=(0.05, 0.05, 0.06, 0.35, 0.30, 0.10, 0.18, 0.13, 0.13, 0.13),
            conductivity=0.038,
            density=12.0,
            specific_heat=1450.0,
            thickness=0.012,
            solar_absorptivity=0.85,
            source=f"down-filled winter coat as one 12 mm layer: black nylon shell (2 x 40 g/m2) "
            f"around 650 fill-power down (about 60 g/m2 lofted to ~12 mm in wear), 140 g/m2 "
            f"over 12 mm = 12 kg/m3; down and feather batts at 5-20 kg/m3 conduct "
            f"0.035-0.045 W/(m K) with radiation (as fibre batts of that density, {_BATTS}); "
            f"specific heat mass mean of keratin (~1.5 J/(g K), wool in {_CP}) and nylon "
            f"(1.46); the outer surface is the nylon shell: {_LWIR_FABRICS}; visible/NIR as "
            f"the 'nylon' entry, {_KNITS}; {_MWIR}",
            label_class="person",
        ),
    )
}
LIBRARY.update(INSULATION)

# ------------------------------------------------------------------- warm clutter (issue 30)
# Tyres and animal coats of humv_usd.scene.objects. Coarse grid WAVELENGTHS_UM.
CLUTTER = {
    m.name: m
    for m in (
        Material(
            "rubber",
            spectrum_reflectance=(0.05, 0.05, 0.05, 0.05, 0.05, 0.05, 0.05, 0.06, 0.06, 0.06),
            conductivity=0.13,
            density=1190.0,
            specific_heat=2010.0,
            thickness=0.01,
            solar_absorptivity=0.95,
            source="carbon-black filled tyre rubber: black in the visible and NIR (reflectance "
            "~5 %), long-wave emissivity 0.94 (rubber 0.86-0.95: "
            f"{_INCROPERA}, Table A.11); k, rho, c: {_INCROPERA}, Table A.3 (rubber, hard)",
            label_class="vehicle",
        ),
        Material(
            "fur",
            spectrum_reflectance=(0.08, 0.14, 0.24, 0.34, 0.28, 0.05, 0.04, 0.02, 0.02, 0.02),
            conductivity=0.055,
            density=100.0,
            specific_heat=1700.0,
            thickness=0.01,
            solar_absorptivity=0.78,
            source="brown mammal coat (dog, cattle): visible/NIR reflectance rising from ~8 % "
            "(blue) to ~34 % (1 µm), keratin/water absorption from 2.8 µm, long-wave "
            "emissivity 0.98 (hair, Campbell & Norman (1998) Table 11.3); solar absorptivity "
            "0.78 (brown coats 0.7-0.85, Campbell & Norman ch. 12); effective conductivity of "
            "fur 0.055 W m-1 K-1 (Davis & Birkebak (1974) Biophys. J. 14:249: 0.04-0.07); "
            "bulk density and heat capacity of a hair coat, order of magnitude",
            label_class="animal",
        ),
    )
}
LIBRARY.update(CLUTTER)


@dataclass(frozen=True)
class SurfaceWater:
    """How a surface material evaporates (issue 30.2/30.4): transpiration through a surface
    resistance (vegetation, moist soil) and the water film rain or dew leaves on it.

    minimum_resistance_s_m : r_s,min = r_l / LAI of a well-watered canopy in full light
        [s m^-1] (:func:`humv_usd.physics.evaporation.surface_resistance`); None: the dry
        surface does not evaporate (paving, metal, glass).
    leaf_area_index : LAI [m^2 m^-2] of the light response.
    water_capacity_kg_m2 : water held on the surface before run-off [kg m^-2 = mm].
    leaf_dimension_m : see the field.
    """

    minimum_resistance_s_m: float | None
    leaf_area_index: float
    water_capacity_kg_m2: float
    source: str
    #: foliage: characteristic leaf dimension [m]; its faces exchange heat as leaves (both
    #: sides, :func:`humv_usd.physics.vegetation.leaf_heat_transfer_coefficient`); None: a
    #: flat surface (Watmuff)
    leaf_dimension_m: float | None = None
    #: the surface cannot warm above this (snow melts) [K]; None: no limit
    melts_at_k: float | None = None


_SUEWS = (
    "storage capacities of the SUEWS urban water balance (Grimmond & Oke 1991, J. Appl. "
    "Meteorol. 30:1141; Jarvi et al. 2011, J. Hydrol. 411:219, Table 1: paved 0.48 mm, "
    "buildings 0.25 mm, grass 1.9 mm, trees 1.3 mm, bare soil 1.9 mm)"
)
#: surface water per material name; materials not listed: dry, with the 0.25 mm film of a
#: building surface (:data:`DRY_SURFACE`)
SURFACE_WATER: dict[str, SurfaceWater] = {
    "grass": SurfaceWater(
        35.0,
        2.88,
        1.9,
        "r_s,min = 100 s/m (single leaf, FAO-56 eq. 5, Allen et al. 1998) / LAI 2.88 (FAO-56 "
        f"reference grass), Noilhan & Planton (1989) light response; {_SUEWS}",
    ),
    "soil": SurfaceWater(
        150.0,
        2.88,
        1.9,
        "bare moist soil as a surface resistance of 150 s/m at field capacity (soil "
        "evaporation resistances of 100-500 s/m of a drying top layer, van de Griend & Owe "
        f"1994, Water Resour. Res. 30:181; order of magnitude); {_SUEWS}",
    ),
    "asphalt": SurfaceWater(None, 1.0, 0.48, f"impervious paving; {_SUEWS}"),
    "concrete": SurfaceWater(None, 1.0, 0.48, f"impervious paving; {_SUEWS}"),
}
DRY_SURFACE = SurfaceWater(None, 1.0, 0.25, f"impervious surface (building); {_SUEWS}")


def surface_water(name: str) -> SurfaceWater:
    """:class:`SurfaceWater` of a material name (:data:`DRY_SURFACE` when not listed)."""
    return SURFACE_WATER.get(name, DRY_SURFACE)


# ------------------------------------------------------------------- skin tones (issue 29)
# skin_I ... skin_VI: the measured skin spectrum scaled by the skin-optics model per
# Fitzpatrick type (humv_usd.catalog.skin); IR and thermal data as "skin".
from humv_usd.catalog.skin import tone_materials  # noqa: E402  (needs LIBRARY["skin"])

LIBRARY.update(tone_materials(LIBRARY["skin"]))


#: specific surface area of the library's snow [m^2 kg^-1]: settled seasonal snow a few days
#: old (fresh snow 40-150, aged 10-30; Domine et al. 2007, J. Geophys. Res. 112:F02031)
SNOW_SPECIFIC_SURFACE_AREA = 20.0
#: density of the library's snow [kg m^-3] (settled seasonal snow 200-350, Sturm et al. 1997)
SNOW_DENSITY = 250.0
#: the library snow's solar nodes [µm]: the ice bands (1.03, 1.27, 1.5, 2.0 µm) and the
#: windows between them (1.1, 1.8, 2.25 µm) on top of the visible every 50 nm
SNOW_SOLAR_UM = (
    0.40,
    0.45,
    0.50,
    0.55,
    0.60,
    0.65,
    0.70,
    0.75,
    0.80,
    0.85,
    0.90,
    0.95,
    1.00,
    1.03,
    1.10,
    1.20,
    1.27,
    1.35,
    1.45,
    1.50,
    1.65,
    1.80,
    1.94,
    2.00,
    2.10,
    2.25,
    2.40,
    2.50,
)
#: reflectance of snow beyond 2.5 µm, where ice is opaque (imaginary index >= 1e-3, Warren &
#: Brandt 2008) and the grains reflect at their surfaces only: 8-14 µm emissivity 0.985-0.99,
#: falling to about 0.97 at 13-14 µm for coarser grains (Dozier & Warren 1982, Water Resour.
#: Res. 18:1424; Hori et al. 2006, Remote Sens. Environ. 100:486); 3-5 µm: a few percent, higher
#: at 3.5-4 µm where ice absorbs least (estimates from the ice's k, no measured snow spectrum
#: at hand)
SNOW_INFRARED = {
    2.8: 0.01,
    3.0: 0.01,
    3.5: 0.03,
    4.0: 0.03,
    4.5: 0.02,
    5.0: 0.02,
    6.0: 0.015,
    7.0: 0.015,
    8.0: 0.015,
    9.0: 0.01,
    10.0: 0.01,
    11.0: 0.01,
    12.0: 0.015,
    13.0: 0.025,
    14.0: 0.03,
}


def _snow_material() -> Material:
    """Clean settled snow: solar spectrum from the grain size and ice's optical constants
    (:func:`humv_usd.physics.snow.spherical_albedo`), infrared from :data:`SNOW_INFRARED`."""
    d = snow_optics.optical_diameter_m(SNOW_SPECIFIC_SURFACE_AREA)
    solar = snow_optics.spherical_albedo(np.asarray(SNOW_SOLAR_UM), d)
    return Material(
        "snow",
        spectrum_wavelengths=SNOW_SOLAR_UM + tuple(SNOW_INFRARED),
        spectrum_reflectance=tuple(round(float(v), 4) for v in solar) + tuple(SNOW_INFRARED.values()),
        conductivity=round(float(snow_optics.effective_conductivity(SNOW_DENSITY)), 4),
        density=SNOW_DENSITY,
        specific_heat=snow_optics.ICE_SPECIFIC_HEAT,
        thickness=0.1,
        solar_absorptivity=0.2,
        source=f"clean settled seasonal snow, 10 cm, specific surface area {SNOW_SPECIFIC_SURFACE_AREA:g} "
        f"m2/kg (optical grain diameter {d * 1e3:.2f} mm): 0.4-2.5 µm the spherical albedo of the "
        "asymptotic radiative transfer theory (Kokhanovsky & Zege 2004, Appl. Opt. 43:1589; B 1.6, "
        "g 0.845 after Libois et al. 2013) with the ice's optical constants of Warren & Brandt "
        "(2008, J. Geophys. Res. 113:D14220): visible 0.98-0.99, falling through the NIR with "
        "the ice bands at 1.03, 1.27, 1.5 and 2.0 µm, near 0 at 1.5 and 2.0 µm (Wiscombe & Warren "
        "1980, J. Atmos. Sci. 37:2712; Warren 1982, Rev. Geophys. 20:67); broadband albedo 0.8 "
        "(Warren 1982); 8-14 µm emissivity 0.97-0.99 (Dozier & Warren 1982, Water Resour. Res. "
        "18:1424; Hori et al. 2006, Remote Sens. Environ. 100:486), 3-5 µm estimates; effective "
        f"conductivity at {SNOW_DENSITY:g} kg/m3 (Sturm et al. 1997, J. Glaciol. 43:26, eq. 4); "
        "c of ice at 0 degC (Feistel & Wagner 2006). It melts at 0 degC "
        "(humv_usd.physics.snow: the surface is held there while its balance has a surplus)",
        label_class="ground",
    )


#: foliage, snow and water (issue 30.2/30.4)
NATURE: dict[str, Material] = {
    m.name: m
    for m in (
        Material(
            "leaf",
            spectrum_wavelengths=LIBRARY["grass"].spectrum_wavelengths,
            spectrum_reflectance=LIBRARY["grass"].spectrum_reflectance,
            conductivity=0.5,
            density=700.0,
            specific_heat=3500.0,
            thickness=0.0003,
            solar_absorptivity=0.8,
            source=f"green broadleaf foliage as a crown's outer surface: the green-vegetation "
            f"spectrum of the grass entry (after {_ECOSTRESS}; leaves and lawn share the "
            f"chlorophyll well, red edge, NIR plateau 0.45-0.5 and water bands); 8-14 µm "
            f"emissivity 0.97-0.98 ({_SD92}, green foliage); a 0.3 mm leaf of about 70 % water "
            f"(rho 700 kg/m3, c 3.5 kJ/(kg K), Jones 2014, Plants and Microclimate, ch. 9): its "
            f"heat capacity is negligible against its exchange, so it follows its energy balance; "
            f"broadband absorptivity of a crown 0.8-0.85 (deciduous canopy albedo 0.15-0.20, Oke "
            f"1987, Boundary Layer Climates, Table 1.1; one leaf alone absorbs about 0.5)",
            label_class="vegetation",
        ),
        _snow_material(),
        Material(
            "water",
            spectrum_reflectance=(0.02, 0.02, 0.02, 0.02, 0.03, 0.02, 0.02, 0.02, 0.01, 0.03),
            conductivity=0.6,
            density=1000.0,
            specific_heat=4186.0,
            thickness=0.02,
            solar_absorptivity=0.95,
            source="a 2 cm puddle on dark paving: Fresnel reflectance about 0.02 at normal "
            "incidence across the spectrum, 8-14 µm emissivity 0.98-0.99 (Masuda, Takashima & "
            "Takayama 1988, Remote Sens. Environ. 24:313); the sun it transmits is absorbed by "
            f"the water and the dark bottom (absorptivity 0.95); k, rho, c: {_INCROPERA}, "
            "Table A.6 (water at 300 K). Rendered diffuse: the render has no specular water yet",
            label_class="ground",
        ),
    )
}
LIBRARY.update(NATURE)
SURFACE_WATER.update(
    {
        "leaf": SurfaceWater(
            100.0,
            1.0,
            0.3,
            "stomatal resistance of a sunlit broad leaf r_l = 100 s/m (FAO-56 eq. 5, Allen et al. "
            "1998; Jones 2014, ch. 6: 50-200 s/m for open stomata), light response of Noilhan & "
            "Planton (1989) per unit leaf area; interception 0.3 mm per unit crown surface "
            f"(deciduous trees 0.3-0.8 mm, {_SUEWS})",
            leaf_dimension_m=0.05,
        ),
        "snow": SurfaceWater(
            None,
            1.0,
            0.0,
            "snow: sublimation not modelled; the surface melts at 0 degC (its depth not tracked)",
            melts_at_k=273.15,
        ),
        "water": SurfaceWater(
            0.0, 1.0, 20.0, "free water: no surface resistance; a 2 cm puddle holds 20 kg/m2"
        ),
    }
)

# ------------------------------------------------------ short-wave infrared detail (issue 24.3)
# The fabrics, hair, fur and leather above are tabulated on the coarse grid WAVELENGTHS_UM,
# which goes straight from 1.0 to 2.5 µm: a SWIR (0.9-2.5 µm) camera would see them without
# their molecular absorption bands. Nodes are added in 1.0-2.5 µm at the overtone and combination
# bands of each fibre's chemistry, the value there being the coarse table's (linear between 1.0
# and 2.5 µm) times a relative depth; the coarse nodes are unchanged. Band positions: Workman &
# Weyer (2008) Practical Guide to Interpretive Near-Infrared Spectroscopy, CRC Press, ch. 2-9
# (O-H first overtone 1.40-1.50 µm and O-H/water combination 1.90-1.94 µm; C-H second overtone
# 1.13-1.21 µm, first overtone 1.65-1.76 µm, combinations 2.10-2.35 µm; N-H first overtone
# 1.46-1.53 µm and N-H combination 2.05-2.06 µm). The depths (reflectance at the band over the
# continuum) are estimates representative of diffuse-reflectance spectra of dry fibres under
# ambient humidity (cellulose and keratin hold 8-15 % water by mass, polyester < 1 %), not
# measurements.
SWIR_DETAIL_UM = (1.2, 1.45, 1.65, 1.73, 1.94, 2.1, 2.3)
#: relative depth at SWIR_DETAIL_UM by fibre chemistry
SWIR_DEPTH = {
    "cellulose": (1.0, 0.85, 0.97, 0.97, 0.65, 0.85, 0.85),  # cotton: water/O-H, cellulose 2.1
    "polyester": (0.96, 0.97, 0.88, 0.94, 0.95, 0.9, 0.85),  # PET: C-H 1.13, 1.66, 2.13/2.25
    "polyamide": (0.97, 0.9, 0.92, 0.88, 0.85, 0.85, 0.82),  # nylon, aramid: N-H 1.5/2.05, C-H 1.73/2.3
    "keratin": (1.0, 0.85, 0.97, 0.9, 0.7, 0.8, 0.85),  # wool, hair, fur; collagen (leather) alike
}
#: fibre chemistry of the coarse-grid materials that get SWIR detail (carbon-black rubber and
#: plastics stay flat: the pigment absorbs the bands' contrast away; camouflage_nyco stays coarse:
#: its spectrum's solar absorptivity is already 0.066 above the literature value it was checked
#: against, and its NIR-specified dyes are not modelled)
SWIR_FIBRE = {
    "cotton_white": "cellulose",
    "cotton_black": "cellulose",
    "denim": "cellulose",
    "nylon": "polyamide",
    "kevlar_vest": "polyamide",
    "down_fill": "polyamide",  # the nylon shell is the surface
    "polyester": "polyester",
    "fleece": "polyester",
    "wool": "keratin",
    "wool_knit_thick": "keratin",
    "hair_dark": "keratin",
    "fur": "keratin",
    "leather_black": "keratin",
}


def with_swir_detail(material: Material, fibre: str) -> Material:
    """``material`` with nodes at :data:`SWIR_DETAIL_UM` whose reflectance is its own table's
    (linear) times the fibre's :data:`SWIR_DEPTH`; the other nodes and the source text stay,
    the source gains one sentence."""
    wl = np.asarray(material.spectrum_wavelengths, float)
    rho = np.asarray(material.spectrum_reflectance, float)
    add = np.asarray(SWIR_DETAIL_UM, float)
    added = np.interp(add, wl, rho) * np.asarray(SWIR_DEPTH[fibre], float)
    keep = ~np.isin(np.round(wl, 6), np.round(add, 6))
    grid = np.concatenate([wl[keep], add])
    values = np.concatenate([rho[keep], added])
    order = np.argsort(grid)
    tau = material.spectrum_transmittance
    if tau is not None:
        t = np.asarray(tau, float)
        tau = tuple(round(float(v), 6) for v in np.concatenate([t[keep], np.interp(add, wl, t)])[order])
    return dataclasses.replace(
        material,
        spectrum_wavelengths=tuple(round(float(v), 6) for v in grid[order]),
        spectrum_reflectance=tuple(round(float(v), 6) for v in values[order]),
        spectrum_transmittance=tau,
        source=f"{material.source}; SWIR {fibre} absorption bands at {', '.join(f'{v:g}' for v in add)} µm "
        "(positions Workman & Weyer 2008, depths estimated, see catalog.materials.SWIR_DEPTH)",
    )


for _name, _fibre in SWIR_FIBRE.items():
    LIBRARY[_name] = with_swir_detail(LIBRARY[_name], _fibre)
    for _table in (FABRICS, EQUIPMENT, CLUTTER):
        if _name in _table:
            _table[_name] = LIBRARY[_name]


# ------------------------------------------------------------------- hair colours (issue 29)
# hair_black ... hair_grey: hair_dark (with its SWIR bands) recomputed by the melanin model of
# humv_usd.physics.hair_optics per colour (humv_usd.catalog.hair); IR and thermal data as hair_dark.
from humv_usd.catalog.hair import hair_materials  # noqa: E402  (needs LIBRARY["hair_dark"])

LIBRARY.update(hair_materials(LIBRARY["hair_dark"]))
