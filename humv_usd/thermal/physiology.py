"""Human physiology: activity → heart rate, core and skin temperature over a time line.

The seed (HumV, section 2.2.1) drives USARIEM's ICDA model (Yokota & Berglund 2006) with a heart
rate obtained from the activity (Arts & Kuipers 1994) and the environment (air temperature, mean
radiant temperature, relative humidity, wind). ICDA itself is not public; two open models stand
in for it, chosen by ``model=`` in :func:`simulate_physiology`:

* ``"two_node"`` (:func:`two_node`): Gagge's two-node model (Gagge, Stolwijk & Nishi 1971;
  Gagge, Fobelets & Berglund 1986) — a core and a skin shell, thermoregulated by skin blood
  flow, sweating and shivering. ICDA is built on the same core/skin heat balance; the output is
  one mean skin temperature, applied to all 17 segments.
* ``"jos3"`` (:func:`jos3`): JOS-3 (Takahashi et al. 2021), 17 segments × 5 layers with
  arteries, veins and arteriovenous anastomoses, through pythermalcomfort's ``JOS3``. Gives a
  skin temperature per segment: cold hands and feet, warm trunk.

Both are transient over the input time line (metabolic rate and environment per step, held
constant over each step), start from a spin-up at the first step's conditions, and add the
heart rate of :func:`heart_rate`. Inputs and outputs are SI with temperatures in kelvin (the
project's convention); the models work in degrees Celsius internally.

All segment arrays use JOS-3's order (:data:`humv_usd.human.labels.JOS3_SEGMENTS`), the same
index the avatar writes per face as ``primvars:humv:label:jos3Segment``, so
:func:`skin_temperature_per_face` is a lookup.

References
----------
.. [1] Gagge, A. P., Stolwijk, J. A. J., Nishi, Y. (1971). An effective temperature scale based
   on a simple model of human physiological regulatory response. ASHRAE Trans. 77(1):247-262.
.. [2] Gagge, A. P., Fobelets, A. P., Berglund, L. G. (1986). A standard predictive index of human
   response to the thermal environment. ASHRAE Trans. 92(2B):709-731.
.. [3] ANSI/ASHRAE Standard 55-2020, Normative Appendix D (SET computer code: the two-node loop
   followed here, as also implemented in pythermalcomfort ``two_nodes_gagge``).
.. [4] Takahashi, Y., Nomoto, A., Yoda, S., Hisayama, R., Ogata, M., Ozeki, Y., Tanabe, S.
   (2021). Thermoregulation model JOS-3 with new open source code. Energy & Buildings
   231:110575.
.. [5] Tartarini, F., Schiavon, S. (2020). pythermalcomfort: A Python package for thermal comfort
   research. SoftwareX 12:100578.
.. [6] Arts, F. J. P., Kuipers, H. (1994). The relation between power output, oxygen uptake and
   heart rate in male athletes. Int. J. Sports Med. 15(5):228-231 (linear %Wmax–%VO2max–%HRmax;
   individual coefficients, not tabulated in the abstract).
.. [7] Swain, D. P., Leutholtz, B. C. (1997). Heart rate reserve is equivalent to %VO2 reserve,
   not to %VO2max. Med. Sci. Sports Exerc. 29(3):410-414.
.. [8] Tanaka, H., Monahan, K. D., Seals, D. R. (2001). Age-predicted maximal heart rate
   revisited. J. Am. Coll. Cardiol. 37(1):153-156.
.. [9] Yokota, M., Berglund, L. G. (2006). ICDA thermoregulatory model (USARIEM technical
   report; cited by the seed).
"""

from __future__ import annotations

import _imp
import contextlib
import importlib
import importlib.util
import math
import sys
from dataclasses import dataclass

import numpy as np

from humv_usd.human.body import body_fat_pct
from humv_usd.human.labels import JOS3_PYTHERMALCOMFORT, JOS3_SEGMENTS

N_SEGMENTS = len(JOS3_SEGMENTS)  # 17
ZERO_C = 273.15
MET_W_M2 = 58.2  # 1 met [W/m^2] (ASHRAE)
J_PER_ML_O2 = 20.1  # energy equivalent of oxygen [J/mL] (RER ~0.85-0.9; as avatar.motion)
VO2_REST_ML_KG_MIN = 3.5  # 1 MET [mL/kg/min]
LATENT_HEAT_J_G = 2418.0  # latent heat of sweat evaporation [J/g] (as JOS-3)
#: JOS-3 segment areas [m^2] for the standard body (1.72 m, 74.43 kg; Takahashi et al. 2021):
#: the weights of JOS-3's own mean skin temperature.
JOS3_STANDARD_AREAS_M2 = np.array(
    [
        0.110,
        0.029,
        0.175,
        0.161,
        0.221,
        0.096,
        0.063,
        0.050,
        0.096,
        0.063,
        0.050,
        0.209,
        0.112,
        0.056,
        0.209,
        0.112,
        0.056,
    ]
)

#: Fitness classes for :func:`heart_rate`: resting heart rate [bpm] and VO2max [mL/kg/min] of a
#: 30-year-old man. Assumed typical values (VO2max near the 20th / 50th / 80th percentiles of
#: ACSM's normative tables for men aged 30-39; resting HR of untrained ... trained adults).
FITNESS = {
    "low": {"resting_hr_bpm": 75.0, "vo2max_ml_kg_min": 34.0},
    "average": {"resting_hr_bpm": 68.0, "vo2max_ml_kg_min": 40.0},
    "high": {"resting_hr_bpm": 58.0, "vo2max_ml_kg_min": 48.0},
    # endurance-trained: VO2max below the 70-85 of elite distance runners (Bassett & Howley 2000,
    # Med. Sci. Sports Exerc. 32:70-84), resting bradycardia of trained athletes (~50 bpm;
    # D'Souza et al. 2014, Nat. Commun. 5:3775). Assumed typical values, as the classes above.
    "athlete": {"resting_hr_bpm": 50.0, "vo2max_ml_kg_min": 60.0},
}
FEMALE_VO2MAX_FACTOR = 0.82  # women's VO2max relative to men's (ACSM norms, ~18 % lower)
VO2MAX_DECLINE_PER_YEAR = 0.01  # ~1 %/year after 30 (Fleg et al. 2005, Circulation 112:674)


# ----------------------------------------------------------------------------- heart rate
def max_heart_rate(age_years) -> np.ndarray:
    """Age-predicted maximal heart rate [bpm]: HRmax = 208 - 0.7 age (Tanaka et al. 2001)."""
    return 208.0 - 0.7 * np.asarray(age_years, dtype=np.float64)


def heart_rate(
    metabolic_rate_w,
    mass_kg: float = 75.0,
    age_years: float = 30.0,
    fitness: str = "average",
    sex: str = "male",
    vo2max_ml_kg_min: float | None = None,
    resting_hr_bpm: float | None = None,
) -> np.ndarray:
    """Heart rate [bpm] from the metabolic rate, per frame.

    Parameters
    ----------
    metabolic_rate_w : numeric
        Metabolic rate [W] (e.g. ``Motion.metabolic_rate_w``).
    mass_kg : float
        Body mass [kg].
    age_years : float
        Age [years]; sets HRmax (Tanaka) and VO2max's decline with age.
    fitness : {'low', 'average', 'high', 'athlete'}
        Fitness class (:data:`FITNESS`): resting heart rate and VO2max when not given.
    sex : {'male', 'female'}
        Scales the class VO2max (:data:`FEMALE_VO2MAX_FACTOR`).
    vo2max_ml_kg_min, resting_hr_bpm : float, optional
        The person's own VO2max [mL/kg/min] and resting heart rate [bpm].

    Returns
    -------
    numeric
        Heart rate [bpm], between the resting and the maximal heart rate.

    Notes
    -----
    The seed maps power output to heart rate "for a given individual at a certain level of
    fitness" after Arts & Kuipers (1994), who found %Wmax, %VO2max and %HRmax linearly related
    but with individual coefficients (not reproduced here). We use the equivalent, widely used
    linear relation of Swain & Leutholtz (1997), %HRR = %VO2R:

    .. math:: HR = HR_{rest} + (HR_{max} - HR_{rest})
              \\frac{\\dot V O_2 - \\dot V O_{2,rest}}{\\dot V O_{2,max} - \\dot V O_{2,rest}}

    with VO2 = M / 20.1 J/mL, VO2rest = 3.5 mL/kg/min, HRmax = 208 - 0.7 age (Tanaka et al.
    2001) and VO2max from the fitness class, lowered 1 %/year after 30. The heart rate is
    instantaneous (no on/off kinetics beyond those of the metabolic schedule, which already
    decays after exercise) and has no thermal (cardiovascular drift) component.
    """
    if fitness not in FITNESS:
        raise ValueError(f"invalid fitness class {fitness!r}; expected one of {list(FITNESS)}")
    if sex not in ("male", "female"):
        raise ValueError(f"invalid sex {sex!r}; expected 'male' or 'female'")
    cls = FITNESS[fitness]
    if vo2max_ml_kg_min is None:
        vo2max_ml_kg_min = cls["vo2max_ml_kg_min"] * (FEMALE_VO2MAX_FACTOR if sex == "female" else 1.0)
        vo2max_ml_kg_min *= 1.0 - VO2MAX_DECLINE_PER_YEAR * max(age_years - 30.0, 0.0)
    hr_rest = cls["resting_hr_bpm"] if resting_hr_bpm is None else float(resting_hr_bpm)
    hr_max = float(max_heart_rate(age_years))
    vo2 = np.asarray(metabolic_rate_w, dtype=np.float64) * 60.0 / J_PER_ML_O2 / mass_kg
    reserve = (vo2 - VO2_REST_ML_KG_MIN) / (vo2max_ml_kg_min - VO2_REST_ML_KG_MIN)
    return hr_rest + (hr_max - hr_rest) * np.clip(reserve, 0.0, 1.0)


# ----------------------------------------------------------------------------- helpers
def dubois_area(height_m: float, mass_kg: float) -> float:
    """Body surface area [m^2], DuBois & DuBois (1916): 0.202 m^0.425 h^0.725."""
    return 0.202 * mass_kg**0.425 * height_m**0.725


def _series(value, n: int, name: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        return np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or {n} values, got shape {a.shape}")
    return a


def _segment_series(value, n: int, name: str) -> np.ndarray:
    """Scalar, (T,), (17,) or (T, 17) → (T, 17). A (17,) input with T == 17 is taken as (T,)."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0 or a.shape == (n,):
        return np.repeat(_series(a, n, name)[:, None], N_SEGMENTS, axis=1)
    if a.shape == (N_SEGMENTS,):
        return np.broadcast_to(a, (n, N_SEGMENTS)).copy()
    if a.shape == (n, N_SEGMENTS):
        return a
    raise ValueError(f"{name}: expected a scalar, ({n},), (17,) or ({n}, 17), got {a.shape}")


def _times(times_s) -> np.ndarray:
    t = np.asarray(times_s, dtype=np.float64)
    if t.ndim != 1 or len(t) < 1 or not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
        raise ValueError("times_s: expected a strictly increasing 1-D array of times [s]")
    return t


@dataclass(frozen=True)
class PhysiologyResult:
    """Physiology over a time line (T steps). Temperatures [K]."""

    model: str
    times_s: np.ndarray  # (T,) [s]
    core_temperature_k: np.ndarray  # (T,) core (two-node) / pelvis core ~ rectal (JOS-3)
    mean_skin_temperature_k: np.ndarray  # (T,) area-weighted mean skin temperature
    segment_skin_temperature_k: np.ndarray  # (T, 17) JOS-3 order; two-node: the mean skin
    skin_blood_flow_l_h: np.ndarray  # (T,) whole-body skin blood flow [L/h]
    sweat_rate_g_s: np.ndarray  # (T,) regulatory sweat rate [g/s]
    heart_rate_bpm: np.ndarray  # (T,) from the metabolic rate (heart_rate)
    cardiac_output_l_h: np.ndarray  # (T,) JOS-3's cardiac output [L/h]; NaN for two-node
    #: (T, 17) per unit segment area, at each output time's state under that output's inputs
    #: (those of the step that follows it; two-node: the body's value on every segment): sensible skin -> environment loss (T_sk - T_o) / R_t [W m^-2], the
    #: latent loss E_sk [W m^-2] (negative: condensation), the convective and linear radiative
    #: coefficients h_c, h_r and the dry resistance R_t skin -> environment (clothing included)
    #: [m^2 K W^-1] of that loss, and the core-to-skin conductance K + c_bl SKBF [W m^-2 K^-1]
    #: (Gagge et al. 1971; JOS-3: its own skin blood flow per segment).
    segment_sensible_w_m2: np.ndarray | None = None
    segment_latent_w_m2: np.ndarray | None = None
    segment_hc_w_m2_k: np.ndarray | None = None
    segment_hr_w_m2_k: np.ndarray | None = None
    segment_dry_resistance_m2_k_w: np.ndarray | None = None
    segment_skin_conductance_w_m2_k: np.ndarray | None = None
    wettedness: np.ndarray | None = None  # (T, 17) skin wettedness [0-1]
    #: (T, 17) core temperature of each segment [K] (JOS-3's core node of the segment; two-node:
    #: the body core on every segment): the upper bound of the segment's facet skin
    #: (:func:`local_skin_temperature`).
    segment_core_temperature_k: np.ndarray | None = None
    #: (17,) heat capacity of each segment's skin per unit area [J m^-2 K^-1] (JOS-3's skin node
    #: capacity / segment area, Takahashi et al. 2021; two-node: Gagge's 0.97 Wh/(kg K) x the
    #: skin mass fraction alpha x mass / area at the end of the spin-up): the time constant of a
    #: facet's departure from its segment's skin temperature.
    segment_skin_capacity_j_m2_k: np.ndarray | None = None


# ----------------------------------------------------------------------------- two-node
def _p_sat_kpa(t_c: float) -> float:
    """Saturation vapour pressure [kPa], Antoine form of the ASHRAE 55 SET code."""
    return math.exp(18.6686 - 4030.183 / (t_c + 235.0)) * 0.1333224  # mmHg → kPa


class _TwoNode:
    """State and one explicit step of Gagge's two-node model (ASHRAE 55-2020 App. D loop)."""

    T_SKIN_NEUTRAL = 33.7  # [°C]
    T_CORE_NEUTRAL = 36.8  # [°C]
    SKBF_NEUTRAL = 6.3  # [L/(m^2 h)]
    C_SW, C_DIL, C_STR = 170.0, 120.0, 0.5
    SKBF_MAX, SKBF_MIN, SWEAT_MAX = 90.0, 0.5, 500.0
    C_TISSUE = 0.97 * 3600.0  # body heat capacity [J/(kg K)]

    def __init__(
        self,
        mass_kg: float,
        area_m2: float,
        p_atm_pa: float,
        posture: str,
        t_core_c: float | None = None,
        t_skin_c: float | None = None,
    ):
        self.mass, self.area, self.posture = mass_kg, area_m2, posture
        self.p_atm = p_atm_pa / 101325.0
        self.t_core = self.T_CORE_NEUTRAL if t_core_c is None else t_core_c
        self.t_skin = self.T_SKIN_NEUTRAL if t_skin_c is None else t_skin_c
        self.alpha = 0.1
        self.t_body_neutral = 0.1 * self.T_SKIN_NEUTRAL + 0.9 * self.T_CORE_NEUTRAL
        self.skbf = self.SKBF_NEUTRAL
        self.sweat = 0.0  # regulatory sweat [g/(m^2 h)]
        self.e_skin = None  # evaporative heat loss [W/m^2]; set on the first step
        self.t_cl = None
        self.wettedness = 0.06
        self.coefficients = None  # (h_c, h_r, R_t) of the last substep

    K_TISSUE = 5.28  # core-skin conductance without blood flow [W/(m^2 K)]
    C_BLOOD = 1.163  # blood heat capacity [W h/(L K)]

    def step(self, dt: float, m_w_m2: float, tdb: float, tr: float, rh: float, v: float, clo: float) -> None:
        """Advance ``dt`` [s] at constant conditions by explicit Euler substeps, each no longer
        than the nodes' stability limit (:meth:`_euler`), so that no ``dt`` can drive the
        model unstable."""
        remaining = float(dt)
        while remaining > 1e-9 * max(float(dt), 1.0):
            remaining -= self._euler(remaining, m_w_m2, tdb, tr, rh, v, clo)

    def _euler(
        self, h_max: float, m_w_m2: float, tdb: float, tr: float, rh: float, v: float, clo: float
    ) -> float:
        """One explicit Euler substep of at most ``h_max`` [s]; returns the step taken.

        The step is at most C/G for each node (C its heat capacity, G its total conductance
        including the linearised sweating and evaporation feedbacks): half of explicit Euler's
        stability bound 2 C/G, so the substep cannot oscillate however long ``h_max`` is."""
        m_act = max(m_w_m2, 0.0)
        met = m_act / MET_W_M2
        p_a = rh * _p_sat_kpa(tdb)  # ambient vapour pressure [kPa]
        if self.e_skin is None:
            self.e_skin = 0.1 * met
        air_speed = max(v, 0.1)
        r_clo = 0.155 * clo  # [m^2 K/W]
        f_a_cl = 1.0 + 0.15 * clo
        lr = 2.2 / self.p_atm  # Lewis ratio [K/mmHg]
        i_cl = 0.45 if clo > 0 else 1.0
        w_max = 0.59 * air_speed**-0.08 if clo > 0 else 0.38 * air_speed**-0.29
        h_cc = max(3.0 * self.p_atm**0.53, 8.6 * (air_speed * self.p_atm) ** 0.53)
        if met > 0.85:
            h_cc = max(h_cc, 5.66 * (met - 0.85) ** 0.39)
        # clothing surface temperature and linear radiative coefficient (fixed point)
        area_ratio = 0.7 if self.posture == "sitting" else 0.73
        t_cl = self.t_skin if self.t_cl is None else self.t_cl
        for _ in range(50):
            h_r = 4.0 * 0.95 * 5.6697e-8 * ((t_cl + tr) / 2.0 + ZERO_C) ** 3 * area_ratio
            h_t = h_r + h_cc
            r_a = 1.0 / (f_a_cl * h_t)
            t_op = (h_r * tr + h_cc * tdb) / h_t
            t_cl_new = (r_a * self.t_skin + r_clo * t_op) / (r_a + r_clo)
            done = abs(t_cl_new - t_cl) <= 1e-3
            t_cl = t_cl_new
            if done:
                break
        self.t_cl = t_cl
        r_ea = 1.0 / (lr * f_a_cl * h_cc)
        r_ecl = r_clo / (lr * i_cl)
        self.coefficients = (h_cc, h_r, r_a + r_clo)
        # respiration (ASHRAE): latent 0.0023 M (44 - p_a[mmHg]), sensible 0.0014 M (34 - tdb)
        m_total = m_act + 19.4 * self._colds() * self._ccold()  # + shivering [W/m^2]
        q_res = 0.0023 * m_total * (44.0 - p_a / 0.1333224)
        c_res = 0.0014 * m_total * (34.0 - tdb)
        q_sensible = (self.t_skin - t_op) / (r_a + r_clo)
        self.q_sensible = q_sensible
        g_cs = self.K_TISSUE + self.C_BLOOD * self.skbf
        hf_cs = (self.t_core - self.t_skin) * g_cs  # core → skin [W/m^2]
        s_core = m_total - hf_cs - q_res - c_res
        s_skin = hf_cs - q_sensible - self.e_skin
        c_sk = self.C_TISSUE * self.alpha * self.mass / self.area  # [J/(m^2 K)]
        c_cr = self.C_TISSUE * (1.0 - self.alpha) * self.mass / self.area
        # stability: total conductances of the two nodes, feedbacks linearised
        warm_sk0 = max(self.t_skin - self.T_SKIN_NEUTRAL, 0.0)
        dpsat = _p_sat_kpa(self.t_skin) * 4030.183 / (self.t_skin + 235.0) ** 2 / 0.1333224  # [mmHg/K]
        g_sweat = 0.68 * self.C_SW * math.exp(warm_sk0 / 10.7) * (1.0 + warm_sk0 / 10.7)
        g_skin = g_cs + 1.0 / (r_a + r_clo) + max(w_max, 1.0) * dpsat / (r_ea + r_ecl) + g_sweat
        g_core = g_cs + self.C_BLOOD * self.C_DIL * max(self.t_core - self.t_skin, 0.0) + g_sweat
        limit = min(c_sk / g_skin, c_cr / g_core)
        h = h_max if h_max <= limit else h_max / math.ceil(h_max / limit)
        self.t_skin += s_skin * h / c_sk
        self.t_core += s_core * h / c_cr
        # thermoregulation (signals from the new temperatures)
        t_body = self.alpha * self.t_skin + (1.0 - self.alpha) * self.t_core
        warm_sk = max(self.t_skin - self.T_SKIN_NEUTRAL, 0.0)
        c_warm = max(self.t_core - self.T_CORE_NEUTRAL, 0.0)
        warm_b = max(t_body - self.t_body_neutral, 0.0)
        skbf = (self.SKBF_NEUTRAL + self.C_DIL * c_warm) / (1.0 + self.C_STR * self._colds())
        self.skbf = min(max(skbf, self.SKBF_MIN), self.SKBF_MAX)
        m_rsw = min(self.C_SW * warm_b * math.exp(warm_sk / 10.7), self.SWEAT_MAX)
        e_rsw = 0.68 * m_rsw  # [W/m^2]
        e_max = (_p_sat_kpa(self.t_skin) - p_a) / 0.1333224 / (r_ea + r_ecl)
        if e_max <= 0.0:
            # air more humid than the (wet) skin: no evaporation; vapour condenses on the
            # skin and releases its latent heat, E = E_max < 0; sweat drips
            self.e_skin = e_max
            self.wettedness = 1.0
            self.sweat = m_rsw
        else:
            w = 0.06 + 0.94 * e_rsw / e_max
            e_diff = w * e_max - e_rsw
            if w > w_max:
                p_rsw = (w_max - 0.06) / 0.94
                e_rsw = p_rsw * e_max
                e_diff = 0.06 * (1.0 - p_rsw) * e_max
                w = w_max
            self.e_skin = e_rsw + e_diff
            self.wettedness = w
            self.sweat = m_rsw
        self.alpha = 0.0417737 + 0.7451833 / (self.skbf + 0.585417)
        return h

    def _colds(self) -> float:
        return max(self.T_SKIN_NEUTRAL - self.t_skin, 0.0)

    def _ccold(self) -> float:
        return max(self.T_CORE_NEUTRAL - self.t_core, 0.0)


def two_node(
    times_s,
    metabolic_rate_w,
    air_temperature_k,
    mean_radiant_temperature_k,
    relative_humidity,
    air_speed_m_s,
    clothing_clo,
    *,
    height_m: float = 1.75,
    mass_kg: float = 75.0,
    age_years: float = 30.0,
    sex: str = "male",
    fitness: str = "average",
    posture: str = "standing",
    pressure_pa: float = 101325.0,
    spin_up_s: float = 3600.0,
    max_substep_s: float = 5.0,
) -> PhysiologyResult:
    """Gagge's two-node model (the ICDA-like option), transient over a time line.

    Parameters
    ----------
    times_s : array_like
        Strictly increasing output times [s], shape (T,).
    metabolic_rate_w : numeric
        Metabolic rate [W], scalar or (T,). Step i → i+1 uses the values at i.
    air_temperature_k, mean_radiant_temperature_k : numeric
        Air and mean radiant temperature [K], scalar or (T,).
    relative_humidity : numeric
        Relative humidity [0-1], scalar or (T,).
    air_speed_m_s : numeric
        Air speed relative to the body [m/s] (>= 0.1 used), scalar or (T,).
    clothing_clo : numeric
        Clothing insulation [clo] (1 clo = 0.155 m^2 K/W), scalar or (T,).
    height_m, mass_kg : float
        Body height [m] and mass [kg] (DuBois area, heat capacity).
    age_years, sex, fitness : optional
        For :func:`heart_rate`.
    posture : {'standing', 'sitting'}
        Radiating fraction of the body area (0.73 / 0.70).
    pressure_pa : float
        Atmospheric pressure [Pa].
    spin_up_s : float
        Time [s] run at the first step's conditions before ``times_s[0]``, from the neutral
        state (core 36.8 °C, skin 33.7 °C); 0 starts at the neutral state.
    max_substep_s : float
        Largest internal time step [s], > 0: each output step is split into equal substeps no
        longer than this (explicit Euler). Each substep is further limited to the nodes'
        stability bound (their heat capacity over their total conductance; the skin node's can
        fall to ~10 s in strong wind on wet skin), so any value is stable; smaller values are
        more accurate.

    Returns
    -------
    PhysiologyResult

    Notes
    -----
    Per unit body area [W/m^2] (ASHRAE 55-2020 App. D; Gagge et al. 1971, 1986):

    .. math:: c_{cr} \\frac{dT_{cr}}{dt} = M - (K + c_{bl} SKBF)(T_{cr} - T_{sk})
              - C_{res} - E_{res}

    .. math:: c_{sk} \\frac{dT_{sk}}{dt} = (K + c_{bl} SKBF)(T_{cr} - T_{sk})
              - \\frac{T_{sk} - T_o}{R_a + R_{cl}} - E_{sk}

    with K = 5.28 W/(m^2 K), c_bl = 1.163 Wh/(L K), capacities 0.97 Wh/(kg K) × mass split by
    the skin mass fraction alpha(SKBF); skin blood flow SKBF = (6.3 + 120 warm_cr) /
    (1 + 0.5 cold_sk) L/(m^2 h) in [0.5, 90]; regulatory sweating 170 warm_b exp(warm_sk/10.7)
    g/(m^2 h); shivering 19.4 cold_sk cold_cr W/m^2. Inputs are held constant over each step.
    """
    t = _times(times_s)
    n = len(t)
    _check_body(height_m, mass_kg, spin_up_s, max_substep_s)
    met = _series(metabolic_rate_w, n, "metabolic_rate_w")
    tdb = _series(air_temperature_k, n, "air_temperature_k") - ZERO_C
    tr = _series(mean_radiant_temperature_k, n, "mean_radiant_temperature_k") - ZERO_C
    rh = np.clip(_series(relative_humidity, n, "relative_humidity"), 0.0, 1.0)
    v = np.maximum(_series(air_speed_m_s, n, "air_speed_m_s"), 0.0)
    clo = np.maximum(_series(clothing_clo, n, "clothing_clo"), 0.0)
    area = dubois_area(height_m, mass_kg)
    body = _TwoNode(mass_kg, area, pressure_pa, posture)

    def advance(duration: float, i: int) -> None:
        k = max(1, math.ceil(duration / max_substep_s - 1e-9))
        h = duration / k
        args = (met[i] / area, tdb[i], tr[i], rh[i], v[i], clo[i])
        for _ in range(k):
            body.step(h, *args)

    if spin_up_s > 0:
        advance(float(spin_up_s), 0)
    core, skin, skbf, sweat, sens, lat, hc, hr, rt, cond, wet = (np.empty(n) for _ in range(11))
    for i in range(n):
        if i:
            advance(t[i] - t[i - 1], i - 1)
        if body.coefficients is None:  # no step yet (spin_up_s = 0): coefficients at t[0]
            probe = _TwoNode(mass_kg, area, pressure_pa, posture)
            probe._euler(0.0, met[0] / area, tdb[0], tr[0], rh[0], v[0], clo[0])
            body.coefficients = probe.coefficients
            body.e_skin = probe.e_skin
        core[i], skin[i] = body.t_core, body.t_skin
        skbf[i], sweat[i] = body.skbf * area, body.sweat * area / 3600.0
        j = i  # this output's conditions (those of the next step)
        hc[i], hr[i], rt[i] = body.coefficients
        t_op = (hr[i] * tr[j] + hc[i] * tdb[j]) / (hr[i] + hc[i])
        sens[i] = (body.t_skin - t_op) / rt[i]
        lat[i] = body.e_skin
        cond[i] = body.K_TISSUE + body.C_BLOOD * body.skbf
        wet[i] = body.wettedness
    return PhysiologyResult(
        model="two_node",
        times_s=t,
        core_temperature_k=core + ZERO_C,
        mean_skin_temperature_k=skin + ZERO_C,
        segment_skin_temperature_k=np.repeat(skin[:, None] + ZERO_C, N_SEGMENTS, axis=1),
        skin_blood_flow_l_h=skbf,
        sweat_rate_g_s=sweat,
        heart_rate_bpm=heart_rate(met, mass_kg, age_years, fitness, sex),
        cardiac_output_l_h=np.full(n, np.nan),
        segment_sensible_w_m2=_per_segment(sens),
        segment_latent_w_m2=_per_segment(lat),
        segment_hc_w_m2_k=_per_segment(hc),
        segment_hr_w_m2_k=_per_segment(hr),
        segment_dry_resistance_m2_k_w=_per_segment(rt),
        segment_skin_conductance_w_m2_k=_per_segment(cond),
        wettedness=_per_segment(wet),
        segment_core_temperature_k=_per_segment(core + ZERO_C),
        segment_skin_capacity_j_m2_k=np.full(N_SEGMENTS, body.C_TISSUE * body.alpha * mass_kg / area),
    )


def _per_segment(a: np.ndarray) -> np.ndarray:
    """(T,) body value → (T, 17), the same on every segment."""
    return np.repeat(np.asarray(a, dtype=np.float64)[:, None], N_SEGMENTS, axis=1)


def _check_body(height_m, mass_kg, spin_up_s, max_substep_s) -> None:
    """ValueError naming the argument for non-finite or non-physical body and step values."""
    for name, value, lo, hi in (
        ("height_m", height_m, 0.3, 3.0),
        ("mass_kg", mass_kg, 2.0, 500.0),
        ("spin_up_s", spin_up_s, 0.0, 30 * 86400.0),
        ("max_substep_s", max_substep_s, 1e-3, float("inf")),
    ):
        v = float(value)
        if not (math.isfinite(v) or (name == "max_substep_s" and v == float("inf"))) or not lo <= v <= hi:
            raise ValueError(f"{name} = {value!r}: expected a number in [{lo:g}, {hi:g}]")


# ----------------------------------------------------------------------------- JOS-3
#: JOS-3's pelvis core: the segment compared with rectal temperature (Takahashi et al. 2021).
JOS3_CORE_SEGMENT = JOS3_SEGMENTS.index("Pelvis")


def jos3(
    times_s,
    metabolic_rate_w,
    air_temperature_k,
    mean_radiant_temperature_k,
    relative_humidity,
    air_speed_m_s,
    clothing_clo,
    *,
    height_m: float = 1.75,
    mass_kg: float = 75.0,
    age_years: float = 30.0,
    sex: str = "male",
    fitness: str = "average",
    body_fat_percent: float | None = 15.0,
    posture: str = "standing",
    spin_up_s: float = 3600.0,
    max_substep_s: float = 60.0,
) -> PhysiologyResult:
    """JOS-3 (17 segments) through pythermalcomfort's ``JOS3``, transient over a time line.

    Parameters
    ----------
    times_s : array_like
        Strictly increasing output times [s], shape (T,).
    metabolic_rate_w : numeric
        Metabolic rate [W], scalar or (T,); fed to JOS-3 as its physical activity ratio
        PAR = M / BMR (JOS-3's Harris-Benedict basal rate), clipped to >= 1. A decaying
        post-exercise schedule gives the recovery.
    air_temperature_k, mean_radiant_temperature_k : numeric
        [K]: scalar, (T,), per segment (17,) or (T, 17) — e.g. a per-segment MRT from the
        radiation model.
    relative_humidity : numeric
        [0-1], same shapes.
    air_speed_m_s : numeric
        [m/s], same shapes.
    clothing_clo : numeric
        [clo], same shapes (per-segment insulation from the garments).
    height_m, mass_kg, age_years, sex, body_fat_percent : optional
        The body (JOS-3 parameters). ``age_years``, ``sex`` and ``fitness`` also go to
        :func:`heart_rate`. ``body_fat_percent`` None: the body's own, from BMI, age and sex
        (Deurenberg et al. 1991, :func:`humv_usd.human.body.body_fat_pct`, the value the avatar's
        mesh density uses; the thermal tool passes None); the default 15 % is JOS-3's reference
        man (Kobayashi & Tanabe 2013). JOS-3 uses body fat only to pick one of five tables of
        core-to-skin tissue conductance per segment (fat < 12.5, < 17.5, < 22.5, < 27.5,
        >= 27.5 %; pythermalcomfort ``jos3_functions.construction.conductance``): more fat, less
        conductance, so a warmer core and cooler skin in the cold; heat capacities and the basal
        rate do not depend on it. Outside JOS-3's validated body (toddlers, > 200 kg) see
        :func:`jos3_body`.
    posture : {'standing', 'sitting', 'lying'}
    spin_up_s : float
        Time [s] run at the first step's conditions before ``times_s[0]`` (JOS-3 starts from
        36 °C everywhere, so keep ~1 h).
    max_substep_s : float
        Largest internal step [s]; JOS-3's step is implicit (stable at any length).

    Returns
    -------
    PhysiologyResult
        ``core_temperature_k`` is the pelvis core (~ rectal), the mean skin temperature JOS-3's
        standard-area weighted mean, ``cardiac_output_l_h`` JOS-3's total blood flow.
    """
    t = _times(times_s)
    _check_body(height_m, mass_kg, spin_up_s, max_substep_s)
    with condensation_guard():
        return _jos3(
            t,
            metabolic_rate_w,
            air_temperature_k,
            mean_radiant_temperature_k,
            relative_humidity,
            air_speed_m_s,
            clothing_clo,
            height_m,
            mass_kg,
            age_years,
            sex,
            fitness,
            body_fat_percent,
            posture,
            spin_up_s,
            max_substep_s,
        )


def jos3_module():
    """pythermalcomfort's JOS-3 module (``pythermalcomfort.models.jos3``), imported without the
    rest of ``pythermalcomfort.models``: that package's ``__init__`` imports its ~40 models
    (heat indices, PMV, UTCI, ... with numba functions) for about 0.6 CPU-s of a one-shot compose
    (issue 31), of which JOS-3 needs none but its own. If the package is already imported its
    module is used; otherwise the submodule is loaded under a temporary package module that does
    not run the package's ``__init__``, removed again at once, so a later ``import
    pythermalcomfort.models`` runs the package as usual (and finds this same ``jos3``). The
    interpreter's import lock is held meanwhile: no other thread sees the temporary package."""
    name = "pythermalcomfort.models"
    if name + ".jos3" in sys.modules:
        return sys.modules[name + ".jos3"]
    _imp.acquire_lock()
    try:
        if name in sys.modules:
            return importlib.import_module(name + ".jos3")
        sys.modules[name] = importlib.util.module_from_spec(importlib.util.find_spec(name))
        try:
            return importlib.import_module(name + ".jos3")
        finally:
            del sys.modules[name]
    finally:
        _imp.release_lock()


#: pythermalcomfort's version whose JOS-3 evaporation :func:`condensation_guard` corrects
#: (the guard checks the formula's behaviour, not the version: see :func:`guarded_evaporation`).
PYTHERMALCOMFORT_CHECKED = "4.8.1"


def guarded_evaporation(evaporation):
    """JOS-3's evaporation (``pythermalcomfort.jos3_functions.thermoregulation.evaporation``)
    with vapour condensing instead of sweat evaporating when the air is more humid than the skin.

    Upstream (pythermalcomfort 4.8.1, and JOS-3's original code) computes the wettedness
    w = 0.06 + 0.94 E_sweat / E_max and the skin's evaporative loss E_sk = w E_max with
    E_max = (p_sk,s - p_a) / R_e,t. When the ambient vapour pressure p_a exceeds the saturation
    pressure at the skin, E_max < 0, w turns negative (-1.5 to -45 at 40 degC / 90 % RH) and
    E_sk = 0.06 E_max + 0.94 E_sweat keeps the regulatory sweat's evaporative *cooling*
    although no water can evaporate into that air. Here, on those segments: no evaporation,
    the skin is wet (w = 1) and vapour condenses on it, releasing its latent heat:
    E_sk = E_max < 0 (a heat gain; the same as Gagge's two-node model in :func:`two_node`),
    and the effective sweating E_sweat = 0 (the regulatory sweat drips). Elsewhere the upstream
    values are returned unchanged. Returns (w, E_sk, E_max, E_sweat) as upstream [-, W, W, W].

    References: Gagge, Stolwijk & Nishi (1971) (E_max, wettedness); ISO 7933:2023 (Predicted
    Heat Strain), section on the maximum evaporation rate: a negative E_max means condensation.
    """

    def evaporation_with_condensation(*args, **kwargs):
        wet, e_sk, e_max, e_sweat = evaporation(*args, **kwargs)
        condensing = np.asarray(e_max) < 0.0
        if not condensing.any():
            return wet, e_sk, e_max, e_sweat
        wet = np.where(condensing, 1.0, wet)
        e_sk = np.where(condensing, e_max, e_sk)
        e_sweat = np.where(condensing, 0.0, e_sweat)
        return wet, e_sk, e_max, e_sweat

    return evaporation_with_condensation


class _GuardedThermoregulation:
    """pythermalcomfort's thermoregulation module with :func:`guarded_evaporation`."""

    def __init__(self, module):
        self._module = module
        self.evaporation = guarded_evaporation(module.evaporation)

    def __getattr__(self, name):
        return getattr(self._module, name)


@contextlib.contextmanager
def condensation_guard():
    """While the block runs, pythermalcomfort's JOS-3 uses :func:`guarded_evaporation` (its
    module-level ``threg`` is swapped for a wrapper and restored afterwards)."""
    module = jos3_module()

    original = module.threg
    if isinstance(original, _GuardedThermoregulation):  # nested
        yield
        return
    module.threg = _GuardedThermoregulation(original)
    try:
        yield
    finally:
        module.threg = original


#: Heat capacity of blood in JOS-3 [W h L^-1 K^-1] (Takahashi et al. 2021).
JOS3_BLOOD_HEAT_CAPACITY = 1.067


def jos3_tissue_conductance(model) -> np.ndarray:
    """(17,) JOS-3's conductance [W K^-1] from each segment's core node to its skin node
    through its tissue layers in series (core-muscle-fat-skin for head and pelvis, core-skin
    elsewhere), from the model's own conductance matrix (Takahashi et al. 2021, after
    Stolwijk 1971 and the 65MN model)."""
    from pythermalcomfort.jos3_functions.matrix import IDICT

    c = model._cdt
    out = np.empty(N_SEGMENTS)
    for i, name in enumerate(JOS3_PYTHERMALCOMFORT):
        node = IDICT[name]
        if node.get("muscle") is not None:
            path = (
                (node["core"], node["muscle"]),
                (node["muscle"], node["fat"]),
                (node["fat"], node["skin"]),
            )
            out[i] = 1.0 / sum(1.0 / c[a, b] for a, b in path)
        else:
            out[i] = c[node["core"], node["skin"]]
    return out


def jos3_skin_capacity(model) -> np.ndarray:
    """(17,) heat capacity of each JOS-3 segment's skin node per unit segment area
    [J m^-2 K^-1], from the model's own capacities (Takahashi et al. 2021, Table 4, scaled to the
    body; e.g. the standard head 0.1885 Wh/K over 0.110 m^2: 6.2 kJ m^-2 K^-1, about 1.7 mm of
    tissue at 1,000 kg m^-3 and 3.6 kJ kg^-1 K^-1)."""
    from pythermalcomfort.jos3_functions.matrix import IDICT

    cap = np.asarray(model._cap, dtype=float)
    area = np.asarray(model._bsa, dtype=float)
    return np.array([cap[IDICT[name]["skin"]] for name in JOS3_PYTHERMALCOMFORT]) / area


def _jos3_state(model, bf_skin_l_h: np.ndarray, tissue_w_k: np.ndarray) -> dict:
    """Per-segment fluxes [W m^-2] and coefficients of a JOS3 model at its current state, by
    JOS-3's own formulas (``JOS3._run``): sensible (T_sk - T_o) / R_t, latent E_sk (guarded),
    h_c, h_r, R_t, and the core-skin conductance (tissue in series + blood heat capacity x skin
    blood flow) / segment area."""
    module = jos3_module()

    threg = module.threg
    tsk = np.asarray(model.t_skin, dtype=float)
    hc = threg.fixed_hc(threg.conv_coef(model._posture, model._v, model._tdb, tsk), model._v)
    hr = threg.fixed_hr(threg.rad_coef(model._posture))
    to = threg.operative_temp(model._tdb, model._tr, hc, hr)
    r_t = threg.dry_r(hc, hr, model._clo)
    wet, e_sk, _, _ = threg.evaporation(
        err_cr=model.t_core - model.cr_set_point,
        err_sk=tsk - model.sk_set_point,
        t_skin=tsk,
        tdb=model._tdb,
        rh=model._rh,
        ret=model.r_et,
        height=model._height,
        weight=model._weight,
        bsa_equation=model._bsa_equation,
        age=model._age,
    )
    area = np.asarray(model._bsa, dtype=float)
    return {
        "sensible": (tsk - to) / r_t,
        "latent": np.asarray(e_sk, dtype=float) / area,
        "hc": np.asarray(hc, dtype=float) * np.ones(N_SEGMENTS),
        "hr": np.asarray(hr, dtype=float) * np.ones(N_SEGMENTS),
        "rt": np.asarray(r_t, dtype=float) * np.ones(N_SEGMENTS),
        "conductance": (tissue_w_k + JOS3_BLOOD_HEAT_CAPACITY * bf_skin_l_h) / area,
        "wettedness": np.asarray(wet, dtype=float),
    }


#: JOS-3's validated body (pythermalcomfort ``validate_body_parameters``): height [m], mass
#: [kg], age [yr], body fat [%]
JOS3_BODY_RANGE = {
    "height_m": (0.5, 3.0),
    "mass_kg": (20.0, 200.0),
    "age_yr": (5, 100),
    "fat_pct": (1.0, 90.0),
}


def jos3_body(
    height_m, mass_kg, age_years, sex="male", body_fat_percent=None
) -> tuple[float, float, int, float]:
    """The body JOS-3 is run with: (height [m], mass [kg], age [whole yr], body fat [%]).

    Body fat None: :func:`humv_usd.human.body.body_fat_pct` of the person (Deurenberg et al.
    1991: adults 1.20 BMI + 0.23 age - 10.8 sex - 5.4, children 1.51 BMI - 0.70 age - 3.6 sex +
    1.4). Each value is then clipped to :data:`JOS3_BODY_RANGE`, the range pythermalcomfort's
    JOS-3 accepts.

    How JOS-3 treats age (Takahashi et al. 2021): the basal metabolic rate (Harris-Benedict,
    an adult regression, also used here for children) falls with age; from 60 yr the sweating,
    vasodilation and vasoconstriction signals are reduced per segment (its "signal decrement by
    aging"); the shivering limit depends on age and BMR. It has no child physiology: body size
    enters through the surface area and heat capacity only. Below 5 yr or 20 kg (toddlers) and
    above 200 kg the model is not defined: the body is run at the nearest valid age and mass (a
    2-yr-old of 12 kg as a 5-yr-old of 20 kg with the toddler's stature and body fat), i.e. its
    skin temperatures per segment are those of a small child, not a toddler's.
    """
    if body_fat_percent is None:
        body_fat_percent = body_fat_pct(sex, float(age_years), float(mass_kg) / float(height_m) ** 2)
    r = JOS3_BODY_RANGE
    return (
        float(np.clip(height_m, *r["height_m"])),
        float(np.clip(mass_kg, *r["mass_kg"])),
        int(np.clip(round(float(age_years)), *r["age_yr"])),
        float(np.clip(body_fat_percent, *r["fat_pct"])),
    )


def _jos3(
    t,
    metabolic_rate_w,
    air_temperature_k,
    mean_radiant_temperature_k,
    relative_humidity,
    air_speed_m_s,
    clothing_clo,
    height_m,
    mass_kg,
    age_years,
    sex,
    fitness,
    body_fat_percent,
    posture,
    spin_up_s,
    max_substep_s,
) -> PhysiologyResult:
    JOS3 = jos3_module().JOS3  # noqa: N806 (pythermalcomfort's class)

    n = len(t)
    met = _series(metabolic_rate_w, n, "metabolic_rate_w")
    tdb = _segment_series(air_temperature_k, n, "air_temperature_k") - ZERO_C
    tr = _segment_series(mean_radiant_temperature_k, n, "mean_radiant_temperature_k") - ZERO_C
    rh = np.clip(_segment_series(relative_humidity, n, "relative_humidity"), 0.0, 1.0) * 100.0
    v = np.maximum(_segment_series(air_speed_m_s, n, "air_speed_m_s"), 0.0)
    clo = np.maximum(_segment_series(clothing_clo, n, "clothing_clo"), 0.0)
    height_m, mass_kg, age, fat = jos3_body(height_m, mass_kg, age_years, sex, body_fat_percent)
    model = JOS3(height=height_m, weight=mass_kg, fat=fat, age=age, sex=sex)
    model.posture = posture
    bmr_w = model.bmr * float(np.sum(model.bsa))
    par = np.maximum(met / bmr_w, 1.0)
    last = {}

    def advance(duration: float, i: int) -> None:
        model.tdb, model.tr, model.rh, model.v, model.clo = tdb[i], tr[i], rh[i], v[i], clo[i]
        model.par = float(par[i])
        k = max(1, math.ceil(duration / max_substep_s - 1e-9))
        model.simulate(times=k, dtime=duration / k, output=True)
        # the newest output (JOS3 keeps all of them; drop the rest to bound memory)
        last["out"] = model._history[-1]
        del model._history[:-1]

    if spin_up_s > 0:
        advance(float(spin_up_s), 0)
    else:
        advance(1e-6, 0)  # an output record at the initial state
    tissue = jos3_tissue_conductance(model)
    skin_capacity = jos3_skin_capacity(model)
    seg_skin = np.empty((n, N_SEGMENTS))
    seg_core = np.empty((n, N_SEGMENTS))
    state = {
        k: np.empty((n, N_SEGMENTS))
        for k in ("sensible", "latent", "hc", "hr", "rt", "conductance", "wettedness")
    }
    core, skbf, sweat, co = (np.empty(n) for _ in range(4))
    for i in range(n):
        if i:
            advance(t[i] - t[i - 1], i - 1)
        out = last["out"]
        seg_skin[i] = model.t_skin
        seg_core[i] = model.t_core
        bf = np.array([getattr(out.bf_skin, s) for s in JOS3_PYTHERMALCOMFORT])
        # fluxes at this output under this output's conditions (those of the next step): so
        # that an input at step i sets the exchange reported at output i
        model.tdb, model.tr, model.rh, model.v, model.clo = tdb[i], tr[i], rh[i], v[i], clo[i]
        for k, value in _jos3_state(model, bf, tissue).items():
            state[k][i] = value
        core[i] = model.t_core[JOS3_CORE_SEGMENT]
        skbf[i] = sum(getattr(out.bf_skin, s) for s in JOS3_PYTHERMALCOMFORT) + 2.0 * (
            out.bf_ava_hand + out.bf_ava_foot
        )
        sweat[i] = sum(getattr(out.e_sweat, s) for s in JOS3_PYTHERMALCOMFORT) / LATENT_HEAT_J_G
        co[i] = out.cardiac_output
    mean_skin = seg_skin @ JOS3_STANDARD_AREAS_M2 / JOS3_STANDARD_AREAS_M2.sum()
    return PhysiologyResult(
        model="jos3",
        times_s=t,
        core_temperature_k=core + ZERO_C,
        mean_skin_temperature_k=mean_skin + ZERO_C,
        segment_skin_temperature_k=seg_skin + ZERO_C,
        skin_blood_flow_l_h=skbf,
        sweat_rate_g_s=sweat,
        heart_rate_bpm=heart_rate(met, mass_kg, age_years, fitness, sex),
        cardiac_output_l_h=co,
        segment_sensible_w_m2=state["sensible"],
        segment_latent_w_m2=state["latent"],
        segment_hc_w_m2_k=state["hc"],
        segment_hr_w_m2_k=state["hr"],
        segment_dry_resistance_m2_k_w=state["rt"],
        segment_skin_conductance_w_m2_k=state["conductance"],
        wettedness=state["wettedness"],
        segment_core_temperature_k=seg_core + ZERO_C,
        segment_skin_capacity_j_m2_k=skin_capacity,
    )


# ----------------------------------------------------------------------------- dispatch
MODELS = {"two_node": two_node, "jos3": jos3}


def simulate_physiology(
    times_s,
    metabolic_rate_w,
    air_temperature_k,
    mean_radiant_temperature_k,
    relative_humidity,
    air_speed_m_s,
    clothing_clo,
    model: str = "jos3",
    **kwargs,
) -> PhysiologyResult:
    """Physiology over a time line with the chosen ``model`` ('two_node' | 'jos3').

    Same inputs as :func:`two_node` / :func:`jos3` (keyword options are passed on). The
    two-node model takes per-segment environment arrays as their plain mean over segments.
    """
    if model not in MODELS:
        raise ValueError(f"invalid model selection {model}")
    args = [air_temperature_k, mean_radiant_temperature_k, relative_humidity, air_speed_m_s, clothing_clo]
    if model == "two_node":
        n = len(np.atleast_1d(times_s))
        per_segment = [np.ndim(a) == 2 or (np.shape(a) == (N_SEGMENTS,) and n != N_SEGMENTS) for a in args]
        args = [
            _segment_series(a, n, "input").mean(axis=1) if seg else a for a, seg in zip(args, per_segment)
        ]
    return MODELS[model](times_s, metabolic_rate_w, *args, **kwargs)


# ----------------------------------------------------------------------------- faces
def skin_temperature_per_face(segment_ids, segment_skin_k) -> np.ndarray:
    """Skin temperature [K] per face from the 17 JOS-3 segment temperatures.

    Parameters
    ----------
    segment_ids : array_like of int
        0-based JOS-3 segment index per face (``primvars:humv:label:jos3Segment``), (F,).
    segment_skin_k : array_like
        Segment skin temperatures [K] in JOS-3 order, (17,) or (T, 17).

    Returns
    -------
    numpy.ndarray
        (F,) or (T, F) [K].
    """
    ids = np.asarray(segment_ids)
    if ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer):
        raise ValueError("segment_ids: expected a 1-D integer array")
    if ids.size and (ids.min() < 0 or ids.max() >= N_SEGMENTS):
        raise ValueError(f"segment_ids: values must be in 0..{N_SEGMENTS - 1}")
    temps = np.asarray(segment_skin_k, dtype=np.float64)
    if temps.shape[-1:] != (N_SEGMENTS,) or temps.ndim > 2:
        raise ValueError(f"segment_skin_k: expected (17,) or (T, 17), got {temps.shape}")
    return temps[..., ids]


# ----------------------------------------------------------------------------- local skin
def local_skin_temperature(
    segment_skin_k,
    skin_conductance_w_m2_k,
    latent_w_m2,
    segment_ids,
    face_area_m2,
    flux_w_m2,
    flux_slope_w_m2_k,
    linearisation_k,
    segment_core_k=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Skin temperature per facet from each facet's own heat balance, bounded by the segment's
    core temperature (issue 14, deliverable 2; issue 25, deliverable 1).

    Every per-segment and per-facet argument may carry a leading frame axis ((T, 17) and
    (T, F)): the frames are then solved together, each exactly as alone (the same arithmetic,
    with the sums over a segment's facets taken per frame), and the results are (T, F).

    Parameters
    ----------
    segment_skin_k : array_like
        (17,) skin temperature of each segment from the physiology [K].
    skin_conductance_w_m2_k : array_like
        (17,) core-to-skin conductance K_s of each segment [W m^-2 K^-1]
        (``PhysiologyResult.segment_skin_conductance_w_m2_k``).
    latent_w_m2 : array_like
        (17,) latent (evaporative) loss E_s of each segment [W m^-2], spread evenly.
    segment_ids : array_like of int
        (F,) JOS-3 segment of each facet.
    face_area_m2 : array_like
        (F,) facet areas [m^2].
    flux_w_m2, flux_slope_w_m2_k, linearisation_k : array_like
        (F,) the facet's sensible loss to its surroundings q(T) [W m^-2] at the temperature
        ``linearisation_k`` and its slope dq/dT [W m^-2 K^-1] there: bare skin
        h (T - T_air) + eps sigma T^4 - q_abs (absorbed sun and long wave); under a garment the
        garment balance's skin-side flux q_in(T) (:func:`humv_usd.physics.garment.steady_state`).
    segment_core_k : array_like, optional
        (17,) core temperature of each segment [K] (``PhysiologyResult.segment_core_temperature_k``).
        Given, no facet of a segment whose skin is below its core is warmer than that core, and
        the inner temperature of the shell never exceeds it; omitted, the balance is unbounded
        (the model of issue 14).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        (F,) facet skin temperature [K] and (F,) its sensible loss q(T_f) on the linearisation
        [W m^-2].

    Notes
    -----
    Each segment is a core-skin shell: a conductance K_s [W m^-2 K^-1] between an inner
    temperature T_b,s and the skin surface, the tissue plus the skin blood flow's heat
    transport: with JOS-3 its own tissue conductances in series (core-muscle-fat-skin) plus
    1.067 Wh/(L K) x its skin blood flow, per segment area (Takahashi et al. 2021); with the
    two-node model Gagge's 5.28 + 1.163 SKBF (Gagge, Stolwijk & Nishi 1971). A facet f's
    surface balance is

    .. math:: K_s (T_{b,s} - T_f) = q_f(T_f) + E_s,  q_f(T) \\approx q_f^0 + g_f (T - T_f^0),

    so T_f = (K_s T_b,s + g_f T_f^0 - q_f^0 - E_s) / (K_s + g_f). T_b,s is chosen so that the
    area-weighted mean of T_f over the segment equals the physiology's segment skin temperature
    (closed form, the balance being linear in T_b,s); the segment's area-weighted heat flow
    K_s (T_b,s - T_f) then equals its sensible loss plus E_s, which the body-clothing coupling
    (:func:`humv_usd.thermal.human.human_temperatures`) makes equal to the physiology's own
    sensible loss. A sunlit facet absorbs more, so it is warmer than a shaded one of the same
    segment by Delta q_abs / (K_s + g_f).

    Physiological bound (issue 25). Heat reaches the skin from the core through the tissue and
    the skin's blood, whose temperature is at most the arterial (core) temperature; so neither
    the shell's inner temperature nor any facet can exceed the segment's core temperature T_c,s
    while the segment loses heat (its skin below its core; Stolwijk 1971, Takahashi et al. 2021:
    the skin node is fed by the core/artery node). The closed form above can break it when the
    facets' losses are larger than the segment's conductance carries at the physiology's skin
    temperature (a bare head at -15 degC needed T_b = 56 degC). With the bound:

    1. T_b,s <= T_c,s and every facet min(T_f, T_c,s); T_b,s is found by bisection so that the
       area mean of the clipped facets is the segment's skin temperature (a sunlit facet that
       would gain heat at the core temperature stays at the core: its extra heat is carried
       away by the skin's blood);
    2. if that needs T_b,s > T_c,s, the inner node is held at T_c,s and the shell's conductance
       is raised (K_s' >= K_s, by bisection in log K) until the clipped mean matches: the skin
       blood flow that carries the segment's heat loss from a core at T_c,s (vasodilation).
       The segment's heat flow to its facets stays the surface balance's, so the coupling with
       the physiology's sensible loss is unchanged.

    A segment whose physiological skin is at or above its core (air or radiant heat above about
    36 degC: heat flows into the body) is left to the unbounded closed form: there the skin is
    legitimately warmer than the core. Facet temperatures are then monotonic in the segment's
    skin and core temperatures and in each facet's loss (a larger q_f lowers T_f). Not
    modelled: lateral conduction between facets and a per-facet sweat distribution (E_s is even
    over the segment).
    """
    seg = np.asarray(segment_ids)
    area = np.asarray(face_area_m2, dtype=float)
    target = np.asarray(segment_skin_k, dtype=float)
    single = target.ndim == 1
    frames = 1 if single else target.shape[0]

    def per_frame(v, width):  # (width,) or (T, width) -> (T, width)
        return np.broadcast_to(np.asarray(v, dtype=float), (frames, width))

    target = per_frame(target, N_SEGMENTS)
    k = per_frame(skin_conductance_w_m2_k, N_SEGMENTS)[:, seg]
    e = per_frame(latent_w_m2, N_SEGMENTS)[:, seg]
    q0 = per_frame(flux_w_m2, len(seg))
    g = np.maximum(per_frame(flux_slope_w_m2_k, len(seg)), 0.0)
    t0 = per_frame(linearisation_k, len(seg))
    a = k / (k + g)  # dT_f / dT_b
    b = (g * t0 - q0 - e) / (k + g)
    n = N_SEGMENTS
    w = np.bincount(seg, area, n)
    w_safe = np.maximum(w, 1e-300)
    # a bin per (frame, segment): each bin sums its frame's facets in facet order, as one
    # frame's bincount over ``seg`` does
    bins = (np.arange(frames)[:, None] * n + seg).ravel()

    def segment_mean(values):  # (T, F) -> (T, 17) area-weighted mean per frame and segment
        return np.bincount(bins, (area * values).ravel(), frames * n).reshape(frames, n) / w_safe

    mean_a = segment_mean(a)
    mean_b = segment_mean(b)
    t_inner = (target - mean_b) / np.where(mean_a > 0, mean_a, 1.0)
    t_face = a * t_inner[:, seg] + b
    if segment_core_k is not None:
        t_face = _bounded_skin(
            t_face,
            t_inner,
            target,
            per_frame(segment_core_k, N_SEGMENTS),
            seg,
            bins,
            area,
            w_safe,
            k,
            g,
            t0,
            q0,
            e,
        )
    q = q0 + g * (t_face - t0)
    return (t_face[0], q[0]) if single else (t_face, q)


#: Bisection steps of the bounded skin model (the brackets shrink by 2^-48: below 1e-12 K
#: on a 100 K bracket, and 1e-13 of a decade in log K).
_BISECTIONS = 48
#: Largest factor on a segment's core-skin conductance in the bounded model (1e6 K_s puts
#: every facet within about 1e-5 K of the core).
_MAX_CONDUCTANCE_FACTOR = 1e6


def _bounded_skin(t_face, t_inner, target, core, seg, bins, area, w, k, g, t0, q0, e):
    """The core bound of :func:`local_skin_temperature` on the segments that need it: (T, F)
    facet arrays, (T, 17) segment arrays, ``bins`` the flat (frame, segment) bin of every facet
    of every frame; every (frame, segment) is bisected on its own."""
    frames, n = target.shape
    cap = core[:, seg]
    losing = target < core  # segments whose skin is below the core (heat leaves the body)
    over = np.bincount(bins, (t_face > cap).ravel().astype(float), frames * n).reshape(frames, n) > 0
    need = (losing & ((t_inner > core) | over)).ravel()
    if not need.any():
        return t_face
    sel = need[bins]
    s, ar, cf = bins[sel], np.broadcast_to(area, t_face.shape).ravel()[sel], cap.ravel()[sel]
    k, g, t0, q0, e = (v.ravel()[sel] for v in (k, g, t0, q0, e))
    core, target, w = core.ravel(), target.ravel(), np.tile(w, frames)
    a = k / (k + g)
    b = (g * t0 - q0 - e) / (k + g)

    def mean_clipped(values, bins_, weights, caps):  # over whole segments' facets
        return np.bincount(bins_, weights * np.minimum(values, caps), frames * n) / w

    # 1. the inner node below the core: T_b in [T_b free, T_c] (the clipped mean rises with T_b)
    inner_ok = need & (mean_clipped(a * core[s] + b, s, ar, cf) >= target)
    # each segment is bisected on its own facets: 1. where it holds, 2. where it does not
    one = inner_ok[s]
    r1, r2 = np.flatnonzero(one), np.flatnonzero(~one)
    s1, a1, b1, ar1, cf1 = s[r1], a[r1], b[r1], ar[r1], cf[r1]
    lo, hi = np.minimum(t_inner.ravel(), core), core.copy()
    for _ in range(_BISECTIONS if len(r1) else 0):
        mid = 0.5 * (lo + hi)
        high = mean_clipped(a1 * mid[s1] + b1, s1, ar1, cf1) > target
        hi, lo = np.where(high, mid, hi), np.where(high, lo, mid)
    t_b = 0.5 * (lo + hi)
    # 2. inner node at the core, conductance raised: K' = K 10^x, x in [0, 6]
    lo, hi = np.zeros(frames * n), np.full(frames * n, np.log10(_MAX_CONDUCTANCE_FACTOR))
    s2, k2, g2, ar2, cf2, core2 = s[r2], k[r2], g[r2], ar[r2], cf[r2], core[s[r2]]
    es = (g * t0 - q0 - e)[r2]

    def at_factor(x):
        kk = k2 * (10.0**x)[s2]  # the power once per (frame, segment)
        return (kk * core2 + es) / (kk + g2)

    for _ in range(_BISECTIONS if len(r2) else 0):
        mid = 0.5 * (lo + hi)
        high = mean_clipped(at_factor(mid), s2, ar2, cf2) > target
        hi, lo = np.where(high, mid, hi), np.where(high, lo, mid)
    inside = np.empty(len(s))
    inside[r1] = a1 * t_b[s1] + b1
    inside[r2] = at_factor(hi)
    out = t_face.copy().ravel()
    out[sel] = np.minimum(inside, cf)
    return out.reshape(t_face.shape)


def lagged_skin(
    steady_k,
    segment_skin_k,
    capacity_j_m2_k,
    conductance_w_m2_k,
    dt_s,
    segment_ids,
    face_area_m2,
    segment_core_k=None,
):
    """Facet skin temperatures over frames with the skin's heat capacity (issue 25, deliverable 4).

    Parameters
    ----------
    steady_k : array_like
        (T, F) each frame's steady facet temperature (:func:`local_skin_temperature`) [K].
    segment_skin_k : array_like
        (T, 17) the physiology's segment skin temperature [K] (its own heat capacities already
        make it evolve smoothly).
    capacity_j_m2_k : array_like
        (17,) skin heat capacity per unit area of each segment [J m^-2 K^-1].
    conductance_w_m2_k : array_like
        (T, F) a facet's total conductance K_s + dq/dT to its core and surroundings [W m^-2 K^-1].
    dt_s : float
        Time between frames [s].
    segment_ids, face_area_m2 : array_like
        (F,) JOS-3 segment and area [m^2] of each facet.
    segment_core_k : array_like, optional
        (T, 17) segment core temperatures [K]: the bound of :func:`local_skin_temperature`.

    Returns
    -------
    numpy.ndarray
        (T, F) facet temperatures [K]; frame 0 is the steady state (after the spin-up).

    Notes
    -----
    A facet's departure d_f = T_f - T_sk,s from its segment's skin temperature relaxes to the
    steady departure with the facet's own time constant tau_f = C_s / (K_s + g_f) (a lumped skin
    layer of capacity C_s between the core conductance and the surroundings): exactly, for a
    forcing held over the step, d_f(t + dt) = d_ss + (d_f(t) - d_ss) exp(-dt / tau_f). The
    departures are re-centred to a zero area mean per segment, so the segment keeps the
    physiology's skin temperature. With a skin capacity of 5-9 kJ m^-2 K^-1 (JOS-3) and
    K + g of 15-40 W m^-2 K^-1, tau is 2-10 min: radiation that changes at the second
    boundaries or air gaps that change each frame no longer make facets jump.
    """
    steady = np.asarray(steady_k, dtype=float)
    mean = np.asarray(segment_skin_k, dtype=float)
    seg = np.asarray(segment_ids)
    area = np.asarray(face_area_m2, dtype=float)
    w = np.maximum(np.bincount(seg, area, N_SEGMENTS), 1e-300)
    cap = np.asarray(capacity_j_m2_k, dtype=float)[seg]
    decay = np.exp(-float(dt_s) * np.asarray(conductance_w_m2_k, dtype=float) / cap)
    d_ss = steady - mean[:, seg]
    d = np.empty_like(d_ss)
    d[0] = d_ss[0]
    for n in range(1, len(d)):
        d[n] = d_ss[n] + (d[n - 1] - d_ss[n]) * decay[n]
        d[n] -= (np.bincount(seg, area * d[n], N_SEGMENTS) / w)[seg]
    out = mean[:, seg] + d
    if segment_core_k is not None:
        core = np.asarray(segment_core_k, dtype=float)
        losing = (mean < core)[:, seg]
        out = np.where(losing, np.minimum(out, core[:, seg]), out)
    return out


def radiant_temperature_for_sensible_loss(skin_k, sensible_w_m2, air_k, hc, hr, dry_resistance):
    """Mean radiant temperature [K] at which the physiology's sensible loss
    (T_sk - T_o) / R_t, T_o = (h_c T_a + h_r T_r) / (h_c + h_r), equals ``sensible_w_m2`` at the
    skin temperature ``skin_k`` (JOS-3's and Gagge's dry heat exchange; arrays broadcast)."""
    to = np.asarray(skin_k, dtype=float) - np.asarray(sensible_w_m2, dtype=float) * dry_resistance
    return (to * (hc + hr) - hc * np.asarray(air_k, dtype=float)) / hr
