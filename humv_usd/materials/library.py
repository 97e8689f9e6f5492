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

# ---------------------------------------------------------------------------- fabrics
# Garment fabrics (humv_usd.clothing). The layer is modelled as opaque (emissivity = 1 - R);
# real thin fabrics also transmit a few % in the LWIR and up to ~25 % in the NIR, which the
# opaque model folds into reflectance and absorptivity. Common sources:
_LWIR_FABRICS = ("LWIR (8-12 µm) emissivity of nylon 0.87, cotton 0.88, polyester 0.88 fabrics at "
                 "40 °C: Belliveau et al. (2020) Forensic Chemistry 19:100242")
_KNITS = ("MIR reflection 6-14 %, NIR absorption 10-96 % / reflection 4-67 % of wool, cotton and "
          "polyester knits, colour mainly acting in the visible/NIR: Bauer, Gresser & Mark (2021) "
          "J. Textile Sci. Fashion Technol. 8(1)")
_CP = ("specific heat of dry fibres: Morton & Hearle (2008) Physical Properties of Textile Fibres, "
       "4th ed., Table 6.1 (cotton 1.22-1.35, wool 1.36, nylon 6.6 1.46, PET 1.03 J/(g K))")
_K = ("effective fibre+air conductivity of fabrics 0.03-0.07 W/(m K): Baxter (1946) Proc. Phys. "
      "Soc. 58:105 (wool felts vs bulk density); density = areal mass / thickness of a typical "
      "fabric of that kind")
_MWIR = ("MWIR nodes (3 µm O-H/N-H absorption, ε ≈ 0.8 at 5 µm) are estimates, no measured "
         "spectrum at hand")

FABRICS: dict[str, Material] = {m.name: m for m in (
    Material("cotton_white",
             reflectance=(0.72, 0.78, 0.78, 0.65, 0.35, 0.05, 0.18, 0.12, 0.12, 0.12),
             conductivity=0.05, density=250.0, specific_heat=1300.0, thickness=0.0006,
             solar_absorptivity=0.30,
             source=f"white cotton jersey (T-shirt, 150 g/m2, 0.6 mm). {_LWIR_FABRICS}; "
                    f"visible/NIR of a white knit at the high-reflection end of {_KNITS}; {_CP}; "
                    f"{_K}; {_MWIR}",
             label_class="person"),
    Material("cotton_black",
             reflectance=(0.04, 0.04, 0.05, 0.30, 0.25, 0.05, 0.15, 0.12, 0.12, 0.12),
             conductivity=0.05, density=250.0, specific_heat=1300.0, thickness=0.0006,
             solar_absorptivity=0.88,
             source=f"black-dyed cotton jersey (150 g/m2, 0.6 mm). {_LWIR_FABRICS} (dye barely "
                    f"changes the LWIR value); NIR reflectance of black dyes rises beyond 0.7 µm, "
                    f"low end of {_KNITS}; {_CP}; {_K}; {_MWIR}",
             label_class="person"),
    Material("nylon",
             reflectance=(0.05, 0.05, 0.06, 0.35, 0.30, 0.10, 0.18, 0.13, 0.13, 0.13),
             conductivity=0.05, density=370.0, specific_heat=1460.0, thickness=0.0006,
             solar_absorptivity=0.85,
             source=f"black nylon/elastane knit (leggings, 220 g/m2, 0.6 mm). {_LWIR_FABRICS}; "
                    f"{_KNITS}; {_CP}; {_K}; {_MWIR}",
             label_class="person"),
    Material("polyester",
             reflectance=(0.30, 0.32, 0.33, 0.50, 0.40, 0.15, 0.20, 0.12, 0.12, 0.12),
             conductivity=0.045, density=280.0, specific_heat=1030.0, thickness=0.0005,
             solar_absorptivity=0.60,
             source=f"mid-grey polyester knit (sportswear, 140 g/m2, 0.5 mm). {_LWIR_FABRICS}; "
                    f"{_KNITS}; {_CP}; {_K}; {_MWIR}",
             label_class="person"),
    Material("wool",
             reflectance=(0.08, 0.09, 0.10, 0.35, 0.25, 0.05, 0.15, 0.10, 0.10, 0.10),
             conductivity=0.04, density=200.0, specific_heat=1360.0, thickness=0.002,
             solar_absorptivity=0.80,
             source=f"charcoal wool knit (cap, 400 g/m2, 2 mm). LWIR emissivity 0.90 from the "
                    f"6-14 % MIR reflection of {_KNITS}; {_CP}; {_K}; {_MWIR}",
             label_class="person"),
    Material("camouflage_nyco",
             reflectance=(0.07, 0.12, 0.15, 0.45, 0.35, 0.06, 0.18, 0.12, 0.12, 0.12),
             conductivity=0.06, density=490.0, specific_heat=1380.0, thickness=0.00045,
             solar_absorptivity=0.70,
             source=f"50/50 nylon/cotton (NYCO) camouflage-printed ripstop of combat uniforms "
                    f"(MIL-DTL-44436B cloth: dyes specified for a foliage-like NIR reflectance; "
                    f"~220 g/m2, 0.45 mm); pattern-averaged visible reflectance of a woodland/OCP "
                    f"print and NIR ~0.45 at 1 µm are representative values, not a measurement. "
                    f"{_LWIR_FABRICS} (both fibres 0.87-0.88); specific heat = mass mean of "
                    f"nylon and cotton, {_CP}; {_K}; {_MWIR}",
             label_class="person"),
)}
LIBRARY.update(FABRICS)

# ---------------------------------------------------------------------------- worn equipment
# Not plain fabrics (thicker, stiffer), so kept out of FABRICS; used by the clothing catalogue's
# ``vest`` and ``rifle``.
EQUIPMENT: dict[str, Material] = {m.name: m for m in (
    Material("kevlar_vest",
             reflectance=(0.05, 0.06, 0.07, 0.35, 0.30, 0.10, 0.18, 0.13, 0.13, 0.13),
             conductivity=0.045, density=650.0, specific_heat=1420.0, thickness=0.008,
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
             label_class="person"),
    Material("polymer_black",
             reflectance=(0.05, 0.05, 0.05, 0.06, 0.06, 0.05, 0.06, 0.06, 0.06, 0.07),
             conductivity=0.30, density=1360.0, specific_heat=1500.0, thickness=0.003,
             solar_absorptivity=0.94,
             source="black glass-fibre-reinforced polyamide (PA6-GF30) of rifle furniture, "
                    "standing in for the whole weapon (receiver and barrel are black-finished "
                    "metal; one material keeps the prop simple): density 1.36 g/cm3 and "
                    "conductivity ~0.3 W/(m K) from PA6-GF30 data sheets (e.g. BASF Ultramid "
                    "B3WG6); specific heat ~1.5 J/(g K) (PA6 ~1.7, glass 0.8, mass mean, "
                    "estimate); LWIR emissivity 0.93-0.95 of black plastics from thermographic "
                    "emissivity tables (e.g. Optris / FLIR: plastic, black 0.95); carbon-black "
                    "pigment keeps the visible and NIR reflectance at ~5 % (estimate); 3 mm wall",
             label_class="prop"),
)}
LIBRARY.update(EQUIPMENT)
