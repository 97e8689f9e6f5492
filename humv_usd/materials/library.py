"""Built-in material library: spectral emissivity/reflectance over 0.4-14 µm and thermal data.

Spectra are given at a few wavelength nodes [µm] and interpolated linearly between them. All
materials here are opaque, so in the infrared emissivity = 1 - directional-hemispherical
reflectance (Kirchhoff); in the visible the reflectance drives the EO render.
Every entry names its sources. This is the foundation's small set; the materials issue extends
it to the full library (fabrics, asphalt, grass, glass, ...) with measured spectra.
"""
from __future__ import annotations

from dataclasses import dataclass

WAVELENGTHS_UM = (0.4, 0.55, 0.7, 1.0, 2.5, 3.0, 5.0, 8.0, 11.0, 14.0)


@dataclass(frozen=True)
class Material:
    name: str
    reflectance: tuple[float, ...]      # at WAVELENGTHS_UM [0-1]
    conductivity: float                 # [W m-1 K-1]
    density: float                      # [kg m-3]
    specific_heat: float                # [J kg-1 K-1]
    thickness: float                    # [m] of the slab or layer
    solar_absorptivity: float           # [0-1]
    source: str
    label_class: str = "other"

    @property
    def emissivity(self) -> tuple[float, ...]:
        return tuple(round(1.0 - r, 6) for r in self.reflectance)

    @property
    def display_color(self) -> tuple[float, float, float]:
        """Rough sRGB-linear colour for DCC viewports (reflectance at 0.7, 0.55, 0.4 µm)."""
        r = self.reflectance
        return (r[2], r[1], r[0])


LIBRARY: dict[str, Material] = {m.name: m for m in (
    Material("skin",
             reflectance=(0.25, 0.35, 0.55, 0.6, 0.03, 0.02, 0.02, 0.02, 0.02, 0.02),
             conductivity=0.37, density=1109.0, specific_heat=3391.0, thickness=0.002,
             solar_absorptivity=0.62,
             source="IR emissivity 0.98 +- 0.01 over 2-14 µm: Steketee (1973) Phys. Med. Biol. "
                    "18, 686; visible/NIR reflectance of light skin: Jacques (1998) Oregon "
                    "Medical Laser Center skin optics; k, rho, c: IT'IS tissue database v4.1 "
                    "(skin)"),
    Material("concrete",
             reflectance=(0.25, 0.30, 0.33, 0.35, 0.3, 0.15, 0.10, 0.06, 0.05, 0.06),
             conductivity=1.4, density=2300.0, specific_heat=880.0, thickness=0.2,
             solar_absorptivity=0.65,
             source="LWIR emissivity 0.94-0.95: ECOSTRESS spectral library (Meerdink et al. "
                    "2019, concrete); k, rho, c: Incropera et al., Fundamentals of Heat and "
                    "Mass Transfer, 6th ed., Table A.3 (stone mix concrete)",
             label_class="ground"),
    Material("asphalt",
             reflectance=(0.05, 0.06, 0.07, 0.08, 0.1, 0.08, 0.07, 0.05, 0.04, 0.05),
             conductivity=0.75, density=2120.0, specific_heat=920.0, thickness=0.1,
             solar_absorptivity=0.93,
             source="LWIR emissivity 0.95: ECOSTRESS spectral library (asphalt); k, rho, c: "
                    "Incropera et al., 6th ed., Table A.3",
             label_class="ground"),
    Material("painted_metal",
             reflectance=(0.35, 0.40, 0.40, 0.45, 0.3, 0.15, 0.12, 0.10, 0.10, 0.10),
             conductivity=50.0, density=7850.0, specific_heat=470.0, thickness=0.0006,
             solar_absorptivity=0.6,
             source="paint emissivity 0.90 (8-14 µm): Incropera et al., 6th ed., Table A.11 "
                    "(paints 0.90-0.98, lower end for a weathered light siding); steel k, rho, c: "
                    "Table A.1 (plain carbon steel)",
             label_class="building"),
    Material("wood",
             reflectance=(0.2, 0.3, 0.4, 0.5, 0.3, 0.12, 0.1, 0.1, 0.08, 0.1),
             conductivity=0.12, density=510.0, specific_heat=1380.0, thickness=0.02,
             solar_absorptivity=0.6,
             source="LWIR emissivity 0.90-0.92: ECOSTRESS spectral library (construction wood); "
                    "k, rho, c: Incropera et al., 6th ed., Table A.3 (softwood)",
             label_class="prop"),
    Material("grass",
             reflectance=(0.04, 0.10, 0.05, 0.45, 0.15, 0.04, 0.03, 0.02, 0.02, 0.03),
             conductivity=0.5, density=1000.0, specific_heat=3000.0, thickness=0.05,
             solar_absorptivity=0.8,
             source="green grass spectrum: ECOSTRESS spectral library (Meerdink et al. 2019, "
                    "vegetation); LWIR emissivity 0.97-0.98; bulk properties of a wet sod layer "
                    "(order of magnitude)",
             label_class="vegetation"),
    Material("soil",
             reflectance=(0.1, 0.15, 0.2, 0.25, 0.3, 0.12, 0.1, 0.05, 0.06, 0.05),
             conductivity=0.52, density=2050.0, specific_heat=1840.0, thickness=0.3,
             solar_absorptivity=0.8,
             source="LWIR emissivity 0.94-0.95: ECOSTRESS spectral library (brown loam); "
                    "k, rho, c: Incropera et al., 6th ed., Table A.3 (soil)",
             label_class="ground"),
    Material("blackbody",
             reflectance=(0.03, 0.03, 0.03, 0.03, 0.03, 0.03, 0.03, 0.03, 0.03, 0.03),
             conductivity=200.0, density=2700.0, specific_heat=900.0, thickness=0.006,
             solar_absorptivity=0.97,
             source="extended-area blackbody panel, emissivity 0.97 (typical specification of "
                    "field calibration sources, e.g. CI Systems SR-800); aluminium plate k, rho, c: "
                    "Incropera et al., 6th ed., Table A.1",
             label_class="panel"),
)}
