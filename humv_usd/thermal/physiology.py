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

import math
from dataclasses import dataclass

import numpy as np

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
    fitness : {'low', 'average', 'high'}
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

    def step(self, dt: float, m_w_m2: float, tdb: float, tr: float, rh: float, v: float, clo: float) -> None:
        """Advance ``dt`` [s] (explicit Euler; keep dt <= ~10 s) at constant conditions."""
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
        # respiration (ASHRAE): latent 0.0023 M (44 - p_a[mmHg]), sensible 0.0014 M (34 - tdb)
        m_total = m_act + 19.4 * self._colds() * self._ccold()  # + shivering [W/m^2]
        q_res = 0.0023 * m_total * (44.0 - p_a / 0.1333224)
        c_res = 0.0014 * m_total * (34.0 - tdb)
        q_sensible = (self.t_skin - t_op) / (r_a + r_clo)
        hf_cs = (self.t_core - self.t_skin) * (5.28 + 1.163 * self.skbf)  # core → skin [W/m^2]
        s_core = m_total - hf_cs - q_res - c_res
        s_skin = hf_cs - q_sensible - self.e_skin
        c_sk = self.C_TISSUE * self.alpha * self.mass / self.area  # [J/(m^2 K)]
        c_cr = self.C_TISSUE * (1.0 - self.alpha) * self.mass / self.area
        self.t_skin += s_skin * dt / c_sk
        self.t_core += s_core * dt / c_cr
        # thermoregulation (signals from the new temperatures)
        t_body = self.alpha * self.t_skin + (1.0 - self.alpha) * self.t_core
        warm_sk = max(self.t_skin - self.T_SKIN_NEUTRAL, 0.0)
        c_warm = max(self.t_core - self.T_CORE_NEUTRAL, 0.0)
        warm_b = max(t_body - self.t_body_neutral, 0.0)
        skbf = (self.SKBF_NEUTRAL + self.C_DIL * c_warm) / (1.0 + self.C_STR * self._colds())
        self.skbf = min(max(skbf, self.SKBF_MIN), self.SKBF_MAX)
        m_rsw = min(self.C_SW * warm_b * math.exp(warm_sk / 10.7), self.SWEAT_MAX)
        e_rsw = 0.68 * m_rsw  # [W/m^2]
        r_ea = 1.0 / (lr * f_a_cl * h_cc)
        r_ecl = r_clo / (lr * i_cl)
        e_max = (_p_sat_kpa(self.t_skin) - p_a) / 0.1333224 / (r_ea + r_ecl)
        if e_max <= 0.0:  # air more humid than the skin: no evaporation
            self.e_skin = 0.0
            self.sweat = m_rsw  # dripping, not evaporating
        else:
            w = 0.06 + 0.94 * e_rsw / e_max
            e_diff = w * e_max - e_rsw
            if w > w_max:
                p_rsw = (w_max - 0.06) / 0.94
                e_rsw = p_rsw * e_max
                e_diff = 0.06 * (1.0 - p_rsw) * e_max
            self.e_skin = e_rsw + e_diff
            self.sweat = m_rsw
        self.alpha = 0.0417737 + 0.7451833 / (self.skbf + 0.585417)

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
        Largest internal time step [s]: each output step is split into equal substeps no longer
        than this (explicit Euler; the skin node's time constant can fall to ~20 s).

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
    core, skin, skbf, sweat = (np.empty(n) for _ in range(4))
    for i in range(n):
        if i:
            advance(t[i] - t[i - 1], i - 1)
        core[i], skin[i] = body.t_core, body.t_skin
        skbf[i], sweat[i] = body.skbf * area, body.sweat * area / 3600.0
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
    )


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
    body_fat_percent: float = 15.0,
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
        :func:`heart_rate`.
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
    from pythermalcomfort.models import JOS3  # numba compiles on the first call (~10 s)

    t = _times(times_s)
    n = len(t)
    met = _series(metabolic_rate_w, n, "metabolic_rate_w")
    tdb = _segment_series(air_temperature_k, n, "air_temperature_k") - ZERO_C
    tr = _segment_series(mean_radiant_temperature_k, n, "mean_radiant_temperature_k") - ZERO_C
    rh = np.clip(_segment_series(relative_humidity, n, "relative_humidity"), 0.0, 1.0) * 100.0
    v = np.maximum(_segment_series(air_speed_m_s, n, "air_speed_m_s"), 0.0)
    clo = np.maximum(_segment_series(clothing_clo, n, "clothing_clo"), 0.0)
    model = JOS3(height=height_m, weight=mass_kg, fat=body_fat_percent, age=int(round(age_years)), sex=sex)
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
    seg_skin = np.empty((n, N_SEGMENTS))
    core, skbf, sweat, co = (np.empty(n) for _ in range(4))
    for i in range(n):
        if i:
            advance(t[i] - t[i - 1], i - 1)
        out = last["out"]
        seg_skin[i] = model.t_skin
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


def bench_time_steps(
    model: str = "jos3", steps_s=None, reference_step_s=None, duration_s: float = 3600.0
) -> list[dict]:
    """Mean-skin-temperature error against the internal time step (an exercise bout and rest).

    The schedule: 100 W standing, 450 W from 10 to 30 min, 100 W after, at 20 degC, MRT 20 degC,
    RH 50 %, 0.5 m/s, 0.6 clo; outputs every 5 min. Each run uses ``max_substep_s`` = step;
    the error is the largest |mean skin - reference| over the outputs, the reference being the
    same model at ``reference_step_s``.

    Returns a list of dicts: model, step_s, max_error_k, seconds (run time).
    """
    import time as _time

    if steps_s is None:
        steps_s = (30.0, 60.0, 120.0, 300.0) if model == "jos3" else (5.0, 10.0, 30.0, 60.0)
    if reference_step_s is None:
        reference_step_s = 10.0 if model == "jos3" else 1.0
    times = np.arange(0.0, duration_s + 1.0, 300.0)
    rate = np.where((times >= 600.0) & (times < 1800.0), 450.0, 100.0)
    args = (times, rate, 293.15, 293.15, 0.5, 0.5, 0.6)

    def run(step):
        t0 = _time.perf_counter()
        r = simulate_physiology(*args, model=model, spin_up_s=0.0, max_substep_s=step)
        return np.asarray(r.mean_skin_temperature_k, dtype=float), _time.perf_counter() - t0

    ref, _ = run(reference_step_s)
    rows = []
    for step in steps_s:
        t, sec = run(step)
        err = float(np.max(np.abs(t - ref))) if np.all(np.isfinite(t)) else float("inf")
        rows.append({"model": model, "step_s": float(step), "max_error_k": err, "seconds": sec})
    return rows
