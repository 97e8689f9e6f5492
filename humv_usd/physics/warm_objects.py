"""Surface temperatures of warm clutter: vehicles, animals, street lamps, HVAC units, fires.

Pure numpy, SI units. These are held (prescribed) temperatures for the parts of an object that
carry their own heat source; the object's passive parts (a car's body panels, a lamp's pole)
are slabs of their material in the thermal layer, as any scene surface.

Models
------
* :func:`lumped_response`: first-order (lumped-capacitance) heating towards a steady excess
  over air while running and exponential cooling after stopping, Incropera et al. (2007)
  section 5.2 (Biot << 1): T - T_a = dT_run exp(-t_off / tau_cool) with
  dT_run = dT_ss (1 - exp(-t_run / tau_heat)).
* :func:`engine_temperature`: the coolant warms towards the thermostat's set point (regulated:
  a temperature, not an excess), Heywood (1988) ch. 12.
* :func:`sheet_temperature`: a thin panel between a warm inner air space and the outside
  (the hood over the engine bay, a lamp's housing): steady balance of inner convection, outer
  convection and long-wave exchange with surroundings at air temperature,
  h_i (T_i - T) = h_o (T - T_a) + eps sigma (T^4 - T_a^4) (Incropera Eq. 1.9, 3.1).
* :func:`vehicle_part_temperatures`: engine bay, hood, grille, exhaust, tyres, cabin glass.
* :func:`coat_surface_temperature`: an animal's coat surface, conduction from the skin through
  the coat (effective conductivity of fur, Davis & Birkebak 1974) against convection
  (cylinder, Churchill-Bernstein) and radiation, as in Campbell & Norman (1998) ch. 12-13.

References
----------
.. [1] Incropera, F. P., DeWitt, D. P., Bergman, T. L., Lavine, A. S. (2007). Fundamentals of
   Heat and Mass Transfer, 6th ed., Wiley.
.. [2] Heywood, J. B. (1988). Internal Combustion Engine Fundamentals, McGraw-Hill, ch. 12
   (coolant at 80-100 °C when the thermostat regulates).
.. [3] Fournier, E., Bayne, T. (2007). Under Hood Temperature Measurements. SAE Technical Paper
   2007-01-1393 (engine-bay air and component temperatures, idle and driving).
.. [4] mygolfmk7 (2023). Engine Compartment Temps: RTD above the engine, ~54 °C (130 °F) after
   about 15 min of driving (https://mygolfmk7.com/2023/01/engine-compartment-temps/).
.. [5] Harrison, R. (1970). Danger of ignition of ground cover fuels by vehicle exhaust
   systems. USDA Forest Service ED&T Report 5100-15 (exhaust surface temperatures, idle and load).
.. [6] Gent, A. N., Walter, J. D. (2006). The Pneumatic Tire. NHTSA DOT HS 810 561, ch. 7
   (tread and carcass warm-up in service).
.. [7] McLaren, C., Null, J., Quinn, J. (2005). Heat stress from enclosed vehicles: moderate
   ambient temperatures cause significant temperature rise in enclosed vehicles. Pediatrics
   116(1):e109-e112 (mean rise 22 K in 60 min, 80 % of it in the first 30 min).
.. [8] Horak, J., Schmerold, I., Wimmer, K., Schauberger, G. (2017). Cabin air temperature of
   parked vehicles in summer conditions. Theor. Appl. Climatol. 130:107-118.
.. [9] Davis, L. B., Birkebak, R. C. (1974). On the transfer of energy in layers of fur.
   Biophys. J. 14:249-268 (effective conductivity of fur 0.04-0.07 W m-1 K-1).
.. [10] Campbell, G. S., Norman, J. M. (1998). An Introduction to Environmental Biophysics,
   2nd ed., Springer, ch. 12-13 (animal coats and energy budgets).
.. [11] ASHRAE (2020). Handbook -- HVAC Systems and Equipment, ch. 39 (air-cooled condensers:
   air temperature rise across the coil 8-17 K, i.e. 15-30 °F).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics.convection import churchill_bernstein, watmuff

#: Thermostat-regulated coolant temperature of a warm engine [K] (90 °C; Heywood 1988 ch. 12).
ENGINE_COOLANT_K = 363.15
#: Coolant warm-up time constant [s]: idle (little load) and driving (Heywood ch. 12: a few
#: minutes to the thermostat's opening under load, about twice that at idle).
ENGINE_WARMUP_S = {"idle": 600.0, "drive": 300.0}
#: Engine cool-down time constant after stopping [s] (~1.5 h: a 12 h soak is a "cold start",
#: by then the excess is below 0.1 %).
ENGINE_COOLDOWN_S = 5400.0
#: Engine-bay air: share of the coolant's excess over air (idle: no ram air; driving: the
#: grille's flow dilutes it). 0.55 at idle puts the bay at ~58 °C for 20 °C air, driving
#: 0.45 at ~52 °C, as the 54 °C logged above the engine while driving [4]; [3] reports
#: 50-80 °C bay air in normal service.
BAY_AIR_SHARE = {"idle": 0.55, "drive": 0.45}
#: Hood's inner conductance [W m-2 K-1]: bay-side convection and radiation through a thin
#: hood insulator (felt ~10 mm over steel).
HOOD_INNER_W_M2K = 8.0
#: Exhaust tailpipe surface: steady excess over air [K] and heat-up / cool-down time constants
#: [s] (thin steel pipe: minutes; [5]: idle surfaces far below load temperatures, cooling by
#: ~200 K within 3 min of stopping at the manifold).
EXHAUST_EXCESS_K = {"idle": 70.0, "drive": 150.0}
EXHAUST_TAU_S = (180.0, 300.0)
#: Tyre tread excess over air while driving [K] and time constants [s]: [6] tread 15-30 K
#: above ambient in steady highway service, reached in ~20 min; no heating at idle.
TYRE_EXCESS_K = {"idle": 0.0, "drive": 20.0}
TYRE_TAU_S = (1200.0, 1800.0)
#: Cabin air set point while running (HVAC) [K] and the parked cabin's excess per unit global
#: irradiance [K per W m-2] with its time constant [s]: [7] 22 K in 60 min under clear sky
#: (~900 W m-2), 80 % in 30 min (tau ~ 18 min); [8] the same first-order form.
CABIN_SET_POINT_K = 295.15
CABIN_SOLAR_K_PER_W_M2 = 22.0 / 900.0
CABIN_TAU_S = 1080.0
#: Inside and outside film coefficients of a car window [W m-2 K-1] (6 mm glass: conduction
#: negligible): the glass sits at the weighted mean of cabin and outside air.
GLASS_INNER_W_M2K = 8.0
GLASS_OUTER_STILL_W_M2K = 2.8  # Watmuff at 0 m/s
#: Effective conductivity of an animal's coat [W m-1 K-1] (Davis & Birkebak 1974: 0.04-0.07).
FUR_CONDUCTIVITY_W_MK = 0.055


def lumped_response(run_s, off_s, steady_excess_k, tau_heat_s, tau_cool_s):
    """Excess over air [K] of a lumped body that has run ``run_s`` and stopped ``off_s`` ago.

    Parameters
    ----------
    run_s : numeric
        How long the heat source ran [s] (>= 0).
    off_s : numeric
        How long ago it stopped [s] (0: still running).
    steady_excess_k : numeric
        Excess over air it reaches after a long run [K].
    tau_heat_s, tau_cool_s : numeric
        Time constants of warming and cooling [s] (rho V c / h A).

    Returns
    -------
    numeric
        dT = dT_ss (1 - exp(-t_run / tau_h)) exp(-t_off / tau_c) [K].

    Notes
    -----
    Lumped capacitance, valid for Biot number h L / k < 0.1 (thin metal parts, well-mixed
    coolant) [1] section 5.2.
    """
    run = np.maximum(np.asarray(run_s, dtype=float), 0.0)
    off = np.maximum(np.asarray(off_s, dtype=float), 0.0)
    return steady_excess_k * (1.0 - np.exp(-run / tau_heat_s)) * np.exp(-off / tau_cool_s)


def engine_temperature(air_k, run_s, off_s=0.0, mode="idle"):
    """Coolant temperature [K] of an engine that ran ``run_s`` and stopped ``off_s`` ago.

    The thermostat regulates the coolant at :data:`ENGINE_COOLANT_K` ([2]); warm-up with the
    mode's time constant (:data:`ENGINE_WARMUP_S`), cool-down with :data:`ENGINE_COOLDOWN_S`.
    ``mode``: 'idle' or 'drive' (ValueError otherwise).
    """
    if mode not in ENGINE_WARMUP_S:
        raise ValueError(f"invalid model selection {mode}")
    air = np.asarray(air_k, dtype=float)
    excess = np.maximum(ENGINE_COOLANT_K - air, 0.0)
    return air + lumped_response(run_s, off_s, excess, ENGINE_WARMUP_S[mode], ENGINE_COOLDOWN_S)


def sheet_temperature(inner_k, air_k, h_inner, h_outer, emissivity=0.9, iterations=30):
    """Steady temperature [K] of a thin sheet between an inner air space and the outside.

    Parameters
    ----------
    inner_k : numeric
        Air temperature on the inner side [K].
    air_k : numeric
        Outside air temperature, also that of the long-wave surroundings [K].
    h_inner, h_outer : numeric
        Inner and outer convective conductances [W m-2 K-1].
    emissivity : numeric
        Long-wave emissivity of the outer face.

    Returns
    -------
    numeric
        T solving h_i (T_i - T) = h_o (T - T_a) + eps sigma (T^4 - T_a^4) [K] (fixed point on
        the radiative coefficient 4 eps sigma T_m^3 ... exact to 1e-9 K after a few passes).

    Notes
    -----
    Closed form without radiation: T = (h_i T_i + h_o T_a) / (h_i + h_o) [1] Eq. 3.1 (series
    resistances). No sun: the sheet's solar gain belongs to its slab in the thermal layer.
    """
    ti = np.asarray(inner_k, dtype=float)
    ta = np.asarray(air_k, dtype=float)
    t = (h_inner * ti + h_outer * ta) / (h_inner + h_outer)
    for _ in range(iterations):
        # eps sigma (T^4 - Ta^4) = h_r (T - Ta), h_r = eps sigma (T + Ta)(T^2 + Ta^2): exact
        h_r = emissivity * STEFAN_BOLTZMANN * (t + ta) * (t * t + ta * ta)
        t = (h_inner * ti + (h_outer + h_r) * ta) / (h_inner + h_outer + h_r)
    return t


@dataclass(frozen=True)
class VehicleState:
    """How a vehicle has been used: ``run_s`` its engine ran, ``off_s`` since it stopped (0:
    running), ``speed_m_s`` its speed now (0: idling or parked)."""

    run_s: float = 0.0
    off_s: float = 0.0
    speed_m_s: float = 0.0

    @property
    def mode(self) -> str:
        """How the engine ran: 'drive' when driving now or stopped (a parked car arrived
        driving), 'idle' when running at standstill."""
        return "drive" if self.speed_m_s > 0.5 or self.off_s > 0.0 else "idle"

    @property
    def bay_mode(self) -> str:
        """Engine-bay ventilation now: ram air only while driving."""
        return "drive" if self.speed_m_s > 0.5 and self.off_s <= 0.0 else "idle"


def vehicle_part_temperatures(air_k, state: VehicleState, wind_m_s=1.0, global_w_m2=0.0) -> dict:
    """Held temperatures [K] of a car's heat-carrying parts.

    Keys: ``engine`` (coolant), ``bay`` (engine-bay air), ``hood`` (outer face, over the bay),
    ``grille`` (radiator face: bay air), ``exhaust`` (tailpipe surface), ``tyre`` (tread),
    ``cabin`` (cabin air), ``glass`` (window, weighted mean of cabin and outside air).

    The hood is :func:`sheet_temperature` between the bay air and the outside, with the outer
    coefficient of Watmuff at the air speed over it (wind plus driving speed); cool-down
    follows the engine's. Exhaust and tyres are :func:`lumped_response` with the excesses and
    time constants of :data:`EXHAUST_EXCESS_K` and :data:`TYRE_EXCESS_K`. The cabin: running,
    the HVAC set point (reached with the engine's warm-up); parked, the solar rise of
    McLaren et al. [7] relaxing from the last cabin value. ``global_w_m2``: global irradiance
    on the car [W m-2] (0 at night).
    """
    air = float(air_k)
    mode = state.mode
    running = state.off_s <= 0.0
    engine = float(engine_temperature(air, state.run_s, state.off_s, mode))
    bay = air + BAY_AIR_SHARE[state.bay_mode] * (engine - air)
    speed = max(wind_m_s, 0.0) + (state.speed_m_s if running else 0.0)
    hood = float(sheet_temperature(bay, air, HOOD_INNER_W_M2K, watmuff(speed)))
    exhaust = air + float(lumped_response(state.run_s, state.off_s, EXHAUST_EXCESS_K[mode], *EXHAUST_TAU_S))
    tyre = air + float(lumped_response(state.run_s, state.off_s, TYRE_EXCESS_K[mode], *TYRE_TAU_S))
    solar_excess = CABIN_SOLAR_K_PER_W_M2 * max(global_w_m2, 0.0)
    if running:
        warm = 1.0 - np.exp(-state.run_s / ENGINE_WARMUP_S[mode])
        cabin = air + (CABIN_SET_POINT_K - air) * warm  # HVAC holds the set point, sun or not
    else:  # parked: from the set point towards air + solar excess, first order [7], [8]
        start = CABIN_SET_POINT_K if state.run_s > 0.0 else air + solar_excess
        target = air + solar_excess
        cabin = target + (start - target) * np.exp(-state.off_s / CABIN_TAU_S)
    h_out = float(watmuff(speed))
    glass = (GLASS_INNER_W_M2K * cabin + h_out * air) / (GLASS_INNER_W_M2K + h_out)
    return {
        "engine": engine,
        "bay": bay,
        "hood": hood,
        "grille": bay,
        "exhaust": exhaust,
        "tyre": tyre,
        "cabin": float(cabin),
        "glass": float(glass),
    }


@dataclass(frozen=True)
class Animal:
    """An animal's thermal and shape data: skin temperature [K], coat depth [m], trunk
    diameter [m] (the cylinder of the convection correlation), body length, height [m]."""

    name: str
    skin_k: float
    coat_depth_m: float
    trunk_diameter_m: float
    length_m: float
    height_m: float
    source: str


#: Dog (medium, ~25 kg) and cattle (adult, summer coat). Skin: mean skin temperature at
#: thermoneutral air; coat depths: typical of the breeds' short/medium coats.
ANIMALS = {
    "dog": Animal(
        "dog",
        308.15,
        0.012,
        0.28,
        0.9,
        0.6,
        "skin 35 °C, coat ~12 mm: Campbell & Norman (1998) ch. 12; fur k: Davis & Birkebak (1974)",
    ),
    "cattle": Animal(
        "cattle",
        307.15,
        0.006,
        0.75,
        2.3,
        1.4,
        "skin 34 °C, summer coat ~6 mm: Campbell & Norman (1998) ch. 12-13 (cattle coat data)",
    ),
}


def coat_surface_temperature(
    skin_k, air_k, coat_depth_m, diameter_m, wind_m_s=1.0, emissivity=0.98, conductivity=FUR_CONDUCTIVITY_W_MK
):
    """Coat surface temperature [K] of an animal: skin -> coat conduction -> convection and
    long-wave exchange with surroundings at air temperature.

    Parameters
    ----------
    skin_k, air_k : numeric
        Skin and air temperatures [K].
    coat_depth_m : numeric
        Coat (fur) depth [m]; 0 gives the skin temperature.
    diameter_m : numeric
        Trunk diameter [m] for forced convection over a cylinder (Churchill-Bernstein).
    wind_m_s : numeric
        Wind speed [m/s].
    emissivity : numeric
        Coat emissivity (hair ~0.98, Campbell & Norman Table 11.3).
    conductivity : numeric
        Effective conductivity of the coat [W m-1 K-1] (:data:`FUR_CONDUCTIVITY_W_MK`).

    Returns
    -------
    numeric
        T_s solving (T_skin - T_s) k / d = h_c (T_s - T_a) + eps sigma (T_s^4 - T_a^4) [K].

    Notes
    -----
    Sheet form of :func:`sheet_temperature` with the coat's conductance k/d as the inner
    coefficient; h_c = Nu k_air / D (Churchill-Bernstein, air k = 0.026 W m-1 K-1, nu =
    1.5e-5 m2 s-1) with a natural-convection floor of 2.5 W m-2 K-1 [10] ch. 7.
    """
    depth = max(float(coat_depth_m), 1e-9)
    speed = max(float(wind_m_s), 0.0)
    reynolds = speed * diameter_m / 1.5e-5
    h_c = max(float(churchill_bernstein(reynolds)) * 0.026 / diameter_m, 2.5)
    return sheet_temperature(skin_k, air_k, conductivity / depth, h_c, emissivity)


#: LED street-lamp luminaire: heat-sink housing excess over air when lit [K] and its time
#: constant [s] (LED drivers/heat sinks run 20-35 K above ambient; aluminium casting ~15 min).
LAMP_HOUSING_EXCESS_K = 25.0
LAMP_TAU_S = 900.0
#: Air-cooled condenser (HVAC outdoor unit): discharge-grille excess over air in cooling mode
#: [K] ([11]: 8-17 K air rise across the coil) and heating mode (heat pump: the outdoor coil
#: is colder than air, about -5 K); compressor casing runs warm (~+15 K).
HVAC_DISCHARGE_K = {"cooling": 12.0, "heating": -5.0, "off": 0.0}
HVAC_CASING_EXCESS_K = 15.0
HVAC_TAU_S = 300.0
#: Barbecue/fire: glowing charcoal 800-1000 K (a charcoal bed's surface; radiant grilling
#: literature), a kettle's enamelled lid ~150-250 °C while cooking; a small wood fire's ember
#: bed ~900 K.
EMBERS_K = 900.0
GRILL_LID_K = 470.0
#: Surface of burning logs around the ember bed [K] (charring wood surfaces 600-800 K).
LOGS_K = 650.0
