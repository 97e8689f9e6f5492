"""Draw realistic people (sex, age, stature, mass, body shape, skin tone, hair) from cited statistics.

:func:`sample_people` returns ``[[human]]`` dictionaries (scenario keys, SI units) for ``n``
people from one seed, e.g. for a sweep or a crowd. Each person is drawn on its own stream
``numpy.random.default_rng([seed, i])``, so person ``i`` does not depend on how many are drawn.

Statistics
----------
Children and adolescents (2 <= age < 20 yr): CDC 2000 growth charts, LMS parameters of
stature-for-age (``statage.csv``) and BMI-for-age (``bmiagerev.csv``) for ages 2-20 yr
(Kuczmarski RJ et al. (2002) "2000 CDC Growth Charts for the United States: methods and
development", Vital Health Stat 11(246); data files at https://www.cdc.gov/growthcharts/
percentile_data_files.htm, public domain). The rows at whole years (24, 36.5, ..., 228.5,
240 months) are tabulated below and the L, M, S are interpolated linearly in age between them.
A value at z-score z is ``M (1 + L S z)^(1/L)`` (``M exp(S z)`` for L = 0; Cole 1990). The
stature z and the BMI z are drawn independently: BMI-for-age is built to be (nearly)
uncorrelated with stature, and ANSUR II shows the same for adults (below).

Adults (age >= 20 yr): ANSUR II, the 2012 Anthropometric Survey of U.S. Army Personnel
(Gordon CC et al. (2014) "2012 Anthropometric Survey of U.S. Army Personnel: Methods and
Summary Statistics", NATICK/TR-15/007; 4082 men, 1986 women, aged 17-58). Stature is normal,
BMI log-normal and independent of stature; the parameters are computed from the survey's public
data files (``ANSUR II MALE/FEMALE Public.csv``, stature [mm], weightkg [0.1 kg]):

===========  ===================  ===================  ==========================
             stature mean, SD      ln BMI mean, SD      corr(stature, ln BMI)
===========  ===================  ===================  ==========================
men          1756.2, 68.6 mm       3.3103, 0.1458       -0.001
women        1628.5, 64.2 mm       3.2293, 0.1354        0.056
===========  ===================  ===================  ==========================

(mass mean 85.52 +- 14.22 kg men, 67.76 +- 10.98 kg women; BMI 27.7 +- 4.0 and 25.5 +- 3.5.)
ANSUR II is a military population: fitter and younger than the general one (no one over 58).

Older adults (age > 58 yr): the U.S. National Health and Nutrition Examination Survey, August
2021-August 2023 (Fryar CD, Gu Q, Afful J, Carroll MD, Ogden CL (2025) "Anthropometric reference
data for children and adults: United States, August 2021-August 2023", Vital Health Stat 3(50),
Table 7 standing height [cm] and Table 10 BMI [kg m-2]; public domain). Per age group the mean
stature and the 10th / 50th / 90th percentiles are typed in :data:`NHANES_STATURE_CM` and
:data:`NHANES_BMI`; stature is drawn normal with the group's mean and SD = (P90 - P10) / (2 *
1.2816), ln BMI normal with ln P50 and SD = ln(P90 / P10) / (2 * 1.2816) (P10/P90 because the
80+ group has no 95th percentile of stature). The groups are placed at their mid-ages 64.5,
74.5 and 85 yr (80+: an assumption), and each parameter is linear in age from ANSUR II's value
at 58 yr to the 60-69 group's at 64.5 yr and on, constant beyond 85 yr. The survey is
cross-sectional: the old are shorter both because stature declines with age and because they
were born earlier (secular trend); both are what a population seen today shows.

=========  ==============================  ==============================
           men: stature mean, SD; BMI P50   women: stature mean, SD; BMI P50
=========  ==============================  ==============================
60-69 yr   174.7, 7.37 cm; 28.3             160.5, 6.94 cm; 28.8
70-79 yr   172.4, 7.41 cm; 28.8             158.3, 6.05 cm; 28.0
80+ yr     170.5, 7.49 cm; 27.2             156.8, 7.65 cm; 26.9
=========  ==============================  ==============================

ANSUR II's women (BMI median 25.3) are leaner than NHANES's 60-69 yr women (28.8): the draw
moves from one to the other between 58 and 64.5 yr.

BMI is clipped to [BMI_MIN, BMI_MAX] = [15, 45] for adults. Children's BMI has no lower clip
inside the growth charts (only a floor, CHILD_BMI_MIN = 11, below CDC's z = -3 at every age: a
clip at 15 had put ~40 % of 4-8-year-olds at BMI 15 exactly), and children's z-scores are
limited to +-3 (the charts' published range is the 3rd-97th percentile). Above the 97th
percentile the CDC 2000 BMI-for-age LMS curves are not to be used (their L is strongly negative,
so the curve rises without bound: z = 3 gives BMI 131 for a 10-yr-old boy; the reason for the
CDC's 2022 extended BMI-for-age charts, Hales CM et al. (2022) NCHS Vital Health Stat 2(197));
the draw continues the curve linearly in z beyond z97 = 1.881 with its slope there (a design
choice: the extended charts' parameters were not at hand), e.g. BMI 32 at z = 3 for that boy.

Leg length (adults): the sitting-height ratio (sitting height / stature) from ANSUR II's public
data files, a least-squares line on stature plus a normal residual (taller people have
relatively longer legs: r = -0.34 men, -0.37 women; independent of BMI: |r| < 0.07):

===========  ==================================  ==========
             ratio = a + b * stature [m]          residual SD
===========  ==================================  ==========
men          0.6402 - 0.0667 * stature            0.0127
women        0.6588 - 0.0814 * stature            0.0131
===========  ==================================  ==========

(mean ratio 0.5231 +- 0.0135 men, 0.5262 +- 0.0141 women.) Drawn for ages >= 20 yr. Children
(< 20 yr) draw theirs from the Fourth Dutch Growth Study's LMS references (Fredriks et al. 2005,
Arch Dis Child 90:807-812; :func:`humv_usd.human.proportions.child_sitting_height_ratio`: median
0.604 at 2 yr, 0.546 at 5, 0.520 / 0.522 at 10 (boys / girls), 0.508 / 0.518 at 14), a z-score
of its own, independent of stature; drawn last, after the hair colour. Each was drawn after the
traits before it, so adding it left every earlier draw of a seed unchanged. (Between the two
sources the median steps at 20 yr: Dutch 0.516 / 0.526, ANSUR II 0.523 / 0.526 at 1.75 / 1.63 m.)

Other traits (no population statistic at hand; stated as design choices, not data):

* sex: male with probability ``p_male`` (default 0.5);
* age: uniform in ``age_yr`` (default 18-65 yr);
* build (MakeHuman muscle macro): uniform over slim / average / muscular;
* proportions (MakeHuman proportions macro): uniform in [0.25, 0.75];
* skin tone: Fitzpatrick type uniform over I-VI unless ``skin_tones`` is given;
* hair: long or tied hair with probability 0.6 for women and 0.1 for men, else short; men
  above 16 yr get a beard with probability 0.25;
* hair colour (``hair_color``, :mod:`humv_usd.physics.hair_optics`): grey with probability
  min(0.8, (age - 40 yr) / 40 yr) from 40 yr on (Panhard, Lozano & Loussouarn (2012) Br J
  Dermatol 167:865 found some grey hair in 74 % of people aged 45-65; the ramp is a design
  choice shaped by that figure, not a fit), else uniform over black, dark brown, brown, blond
  and red. Drawn last, so adding it left every earlier draw of a seed unchanged.
"""

from __future__ import annotations

import numpy as np

from humv_usd.human.proportions import child_sitting_height_ratio

#: BMI range of drawn adults [kg m-2] (the issue's 16-45, with ANSUR II's 1st percentile).
BMI_MIN, BMI_MAX = 15.0, 45.0
#: children's BMI floor [kg m-2]: below the CDC 2000 BMI-for-age at z = -3 at every age 2-20 yr
CHILD_BMI_MIN = 11.0
#: children's z-scores are limited to +-CHILD_Z_MAX (the growth charts' published range)
CHILD_Z_MAX = 3.0
#: the 97th percentile's z: above it children's BMI-for-age continues linearly (module doc)
Z97 = 1.8807936081512509
AGE_MIN, AGE_MAX = 2.0, 90.0
ADULT_AGE = 20.0
SKIN_TONES = ("I", "II", "III", "IV", "V", "VI")
BUILDS = ("slim", "average", "muscular")
#: hair colours drawn below the greying age (= humv_usd.physics.hair_optics.HAIR_COLOURS less grey)
PIGMENTED_HAIR = ("black", "dark_brown", "brown", "blond", "red")

#: ANSUR II (Gordon et al. 2014), computed from the public data files (see the module doc):
#: sex -> (stature mean [m], stature SD [m], ln BMI mean, ln BMI SD)
ANSUR2 = {
    "male": (1.7562, 0.0686, 3.3103, 0.1458),
    "female": (1.6285, 0.0642, 3.2293, 0.1354),
}

#: ANSUR II sitting height / stature against stature (module doc): sex -> (a, b [1/m], residual SD)
ANSUR2_SITTING_HEIGHT_RATIO = {"male": (0.6402, -0.0667, 0.0127), "female": (0.6588, -0.0814, 0.0131)}

#: NHANES August 2021-August 2023 (Fryar et al. 2025, Vital Health Stat 3(50)), age groups of
#: older adults: (first age, last age, mid-age used [yr])
NHANES_AGE_GROUPS = ((60, 69, 64.5), (70, 79, 74.5), (80, None, 85.0))
#: Table 7, standing height [cm]: sex -> per age group (mean, P10, P50, P90)
NHANES_STATURE_CM = {
    "male": ((174.7, 165.2, 175.0, 184.1), (172.4, 162.6, 172.7, 181.6), (170.5, 160.1, 169.9, 179.3)),
    "female": ((160.5, 151.6, 160.4, 169.4), (158.3, 150.7, 157.9, 166.2), (156.8, 145.9, 156.9, 165.5)),
}
#: Table 10, BMI [kg m-2]: sex -> per age group (mean, P10, P50, P90)
NHANES_BMI = {
    "male": ((29.2, 22.7, 28.3, 36.0), (29.4, 22.9, 28.8, 36.5), (27.8, 22.8, 27.2, 32.6)),
    "female": ((30.1, 22.0, 28.8, 40.0), (29.5, 22.0, 28.0, 38.3), (27.7, 21.1, 26.9, 34.7)),
}
#: the ANSUR II population's oldest age [yr]: the NHANES trend starts here
ANSUR2_AGE_MAX = 58.0
_Z90 = 1.2815515655446004  # standard normal 90th percentile


def adult_stature_bmi_params(sex: str, age_yr: float) -> tuple[float, float, float, float]:
    """(stature mean [m], stature SD [m], ln BMI mean, ln BMI SD) of adults at an age: ANSUR II up
    to 58 yr, then linear in age to the NHANES 2021-2023 groups at 64.5, 74.5 and 85 yr (module doc)."""
    ages = [ANSUR2_AGE_MAX] + [g[2] for g in NHANES_AGE_GROUPS]
    rows = [ANSUR2[sex]]
    for (h_mean, h10, _h50, h90), (_b_mean, b10, b50, b90) in zip(NHANES_STATURE_CM[sex], NHANES_BMI[sex]):
        rows.append(
            (
                h_mean / 100.0,
                (h90 - h10) / (200.0 * _Z90),
                float(np.log(b50)),
                float(np.log(b90 / b10)) / (2 * _Z90),
            )
        )
    rows = np.asarray(rows)
    return tuple(float(np.interp(float(age_yr), ages, rows[:, k])) for k in range(4))


#: CDC 2000 growth charts at whole years: age [months] of the rows used
CDC_AGE_MONTHS = (
    24.0, 36.5, 48.5, 60.5, 72.5, 84.5, 96.5, 108.5, 120.5, 132.5,
    144.5, 156.5, 168.5, 180.5, 192.5, 204.5, 216.5, 228.5, 240.0,
)  # fmt: skip
#: stature-for-age (statage.csv) L, M [cm], S per row of CDC_AGE_MONTHS
CDC_STATURE = {
    "male": (
        (0.941523967, 86.45220101, 0.040321528),
        (-0.390918369, 95.27359106, 0.04053412),
        (0.827636736, 102.5104735, 0.041344257),
        (1.266367398, 109.1751441, 0.042593311),
        (1.137442868, 115.6608862, 0.043673359),
        (0.753244292, 122.0305342, 0.044403374),
        (0.455267507, 128.1237104, 0.045127088),
        (0.415687443, 133.7344759, 0.046217028),
        (0.505564115, 138.8234114, 0.047610108),
        (0.487939275, 143.7303663, 0.048937694),
        (0.420919142, 149.3088178, 0.049947823),
        (0.816239713, 156.4098858, 0.050333444),
        (1.670433444, 164.1418486, 0.04894519),
        (2.205180153, 170.139255, 0.045889585),
        (2.113023423, 173.6100518, 0.043085685),
        (1.724738292, 175.340954, 0.041408129),
        (1.399999187, 176.1850208, 0.04064364),
        (1.229163362, 176.6178621, 0.040391101),
        (1.167279219, 176.8492322, 0.040369574),
    ),
    "female": (
        (1.07244896, 84.97555512, 0.040791394),
        (0.54198094, 94.21335709, 0.042017509),
        (0.225705996, 101.033927, 0.043259907),
        (-0.057729947, 107.9566031, 0.044276588),
        (-0.219069129, 115.0054978, 0.044963636),
        (-0.210210748, 121.7616844, 0.045460702),
        (-0.079283065, 127.8262759, 0.045968169),
        (0.08414848, 133.1303527, 0.04688401),
        (0.284748919, 138.2111552, 0.048704503),
        (0.744289752, 144.2609497, 0.050524236),
        (1.303044695, 151.4865636, 0.048599314),
        (1.242968236, 157.3436995, 0.043859135),
        (0.95657215, 160.4776996, 0.041022401),
        (0.895569834, 161.8979913, 0.040083845),
        (0.941145943, 162.5689958, 0.039820663),
        (0.999505539, 162.9238449, 0.039732048),
        (1.047571238, 163.1307866, 0.039687311),
        (1.083315329, 163.2590052, 0.039657339),
        (1.108046193, 163.338251, 0.039636316),
    ),
}
#: BMI-for-age (bmiagerev.csv) L, M [kg m-2], S per row of CDC_AGE_MONTHS
CDC_BMI = {
    "male": (
        (-2.01118107, 16.57502768, 0.080592465),
        (-1.419991255, 16.00030401, 0.072634432),
        (-1.714869347, 15.62817269, 0.071889214),
        (-2.61516595, 15.41914163, 0.07599225),
        (-3.21170511, 15.38353217, 0.083048178),
        (-3.323188896, 15.51286936, 0.092131305),
        (-3.18305795, 15.78231007, 0.102091189),
        (-2.971148225, 16.16712234, 0.111720691),
        (-2.765648008, 16.64613844, 0.120112464),
        (-2.590560148, 17.20088732, 0.126734613),
        (-2.447426113, 17.81463359, 0.131389042),
        (-2.3294571, 18.47179706, 0.13414147),
        (-2.227362173, 19.15758672, 0.135251083),
        (-2.132344989, 19.85766121, 0.135110159),
        (-2.039015385, 20.5576474, 0.134198323),
        (-1.949134561, 21.24247982, 0.13305669),
        (-1.874670324, 21.8958685, 0.132286382),
        (-1.835138046, 22.50071778, 0.132566359),
        (-1.84233016, 23.02029424, 0.134539365),
    ),
    "female": (
        (-0.98660853, 16.42339664, 0.085451785),
        (-2.096828937, 15.69924188, 0.078605255),
        (-3.018521987, 15.29854897, 0.078713325),
        (-3.35007771, 15.15188405, 0.084300139),
        (-3.225606516, 15.21690296, 0.093803033),
        (-2.926186592, 15.45356545, 0.105325289),
        (-2.617192204, 15.82699517, 0.117158667),
        (-2.360920527, 16.30609316, 0.128013515),
        (-2.171295888, 16.86231366, 0.137057004),
        (-2.045235058, 17.46906585, 0.143868341),
        (-1.975521156, 18.10148804, 0.148361495),
        (-1.954977947, 18.73643338, 0.150705138),
        (-1.977073595, 19.35257209, 0.151255713),
        (-2.034893091, 19.9305662, 0.150511645),
        (-2.119156972, 20.45325617, 0.14909006),
        (-2.215737645, 20.90575839, 0.147723315),
        (-2.303687802, 21.27532239, 0.14726877),
        (-2.355677743, 21.55082155, 0.148723546),
        (-2.34495843, 21.71699934, 0.152974718),
    ),
}


def lms_value(L, M, S, z):
    """Cole's LMS method: the measurement at z-score ``z``, M (1 + L S z)^(1/L) (M e^(S z) at L = 0).

    Cole TJ (1990) "The LMS method for constructing normalized growth standards", Eur J Clin
    Nutr 44:45-60.
    """
    L, M, S, z = (np.asarray(a, dtype=float) for a in (L, M, S, z))
    small = np.abs(L) < 1e-9
    safe_l = np.where(small, 1.0, L)
    base = np.maximum(1.0 + safe_l * S * z, 1e-9)  # the LMS curve ends where 1 + LSz = 0
    return np.where(small, M * np.exp(S * z), M * base ** (1.0 / safe_l))


def lms_at(table: dict, sex: str, age_yr: float) -> tuple[float, float, float]:
    """L, M, S of a CDC table (:data:`CDC_STATURE` or :data:`CDC_BMI`) at an age, linear in age."""
    months = np.clip(12.0 * float(age_yr), CDC_AGE_MONTHS[0], CDC_AGE_MONTHS[-1])
    rows = np.asarray(table[sex])
    return tuple(float(np.interp(months, CDC_AGE_MONTHS, rows[:, k])) for k in range(3))


def stature_bmi(sex: str, age_yr: float, z_stature: float, z_bmi: float) -> tuple[float, float]:
    """Stature [m] and BMI [kg m-2] of a person at the given z-scores (children: CDC 2000, z
    limited to +-CHILD_Z_MAX; adults: ANSUR II, older adults the NHANES trend), before the BMI clip."""
    if age_yr < ADULT_AGE:
        z_stature, z_bmi = (float(np.clip(z, -CHILD_Z_MAX, CHILD_Z_MAX)) for z in (z_stature, z_bmi))
        stature = float(lms_value(*lms_at(CDC_STATURE, sex, age_yr), z_stature)) / 100.0
        lms = lms_at(CDC_BMI, sex, age_yr)
        if z_bmi <= Z97:
            return stature, float(lms_value(*lms, z_bmi))
        top = float(lms_value(*lms, Z97))
        slope = (top - float(lms_value(*lms, Z97 - 0.05))) / 0.05
        return stature, top + slope * (z_bmi - Z97)
    mu_h, sd_h, mu_b, sd_b = adult_stature_bmi_params(sex, age_yr)
    return mu_h + sd_h * z_stature, float(np.exp(mu_b + sd_b * z_bmi))


def bmi_range(age_yr: float) -> tuple[float, float]:
    """The clip of a drawn BMI [kg m-2]: adults [BMI_MIN, BMI_MAX], children [CHILD_BMI_MIN, BMI_MAX]."""
    return (CHILD_BMI_MIN if age_yr < ADULT_AGE else BMI_MIN), BMI_MAX


def _check_range(name: str, value, lo: float, hi: float) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {value!r}: expected [low, high]") from None
    if not lo <= a <= b <= hi:
        raise ValueError(f"{name} = {value!r}: expected {lo:g} <= low <= high <= {hi:g}")
    return a, b


def sample_person(
    rng: np.random.Generator,
    *,
    age_yr=(18.0, 65.0),
    p_male: float = 0.5,
    skin_tones=SKIN_TONES,
) -> dict:
    """One person's ``[[human]]`` keys (without ``id``) drawn with ``rng``; see the module doc."""
    lo, hi = _check_range("age_yr", age_yr, AGE_MIN, AGE_MAX)
    sex = "male" if rng.random() < p_male else "female"
    age = float(rng.uniform(lo, hi))
    z_h, z_b = rng.standard_normal(2)
    stature, bmi = stature_bmi(sex, age, z_h, z_b)
    bmi = float(np.clip(bmi, *bmi_range(age)))
    build = BUILDS[int(rng.integers(len(BUILDS)))]
    proportions = float(rng.uniform(0.25, 0.75))
    tone = skin_tones[int(rng.integers(len(skin_tones)))]
    p_long = 0.6 if sex == "female" else 0.1
    u = rng.random()
    hair = "hair_short" if u >= p_long else ("hair_long" if u < p_long / 2 else "hair_tied")
    clothing = [hair]
    if sex == "male" and age > 16.0 and rng.random() < 0.25:
        clothing.append("beard")
    person = {
        "sex": sex,
        "age_yr": round(age, 2),
        "stature_m": round(stature, 4),
        "mass_kg": round(bmi * stature**2, 2),
        "build": build,
        "proportions": round(proportions, 3),
        "skin_tone": tone,
        "clothing": clothing,
    }
    if age >= ADULT_AGE:
        a, b, sd = ANSUR2_SITTING_HEIGHT_RATIO[sex]
        ratio = a + b * stature + sd * rng.standard_normal()
        person["sitting_height_ratio"] = round(float(np.clip(ratio, 0.45, 0.60)), 4)
    if rng.random() < min(0.8, max(0.0, (age - 40.0) / 40.0)):
        person["hair_color"] = "grey"
    else:
        person["hair_color"] = PIGMENTED_HAIR[int(rng.integers(len(PIGMENTED_HAIR)))]
    if age < ADULT_AGE:  # drawn last: every earlier draw of a seed unchanged
        z = float(rng.standard_normal())
        person["sitting_height_ratio"] = round(child_sitting_height_ratio(sex, age, z), 4)
    return person


def sample_people(
    n: int, seed: int = 0, *, age_yr=(18.0, 65.0), p_male: float = 0.5, skin_tones=SKIN_TONES
) -> list[dict]:
    """``n`` people, person ``i`` drawn with ``numpy.random.default_rng([seed, i])``; ids p0, p1, ..."""
    if int(n) != n or n < 0:
        raise ValueError(f"n = {n!r}: expected a whole number >= 0")
    if not 0.0 <= float(p_male) <= 1.0:
        raise ValueError(f"p_male = {p_male!r}: expected a number in [0, 1]")
    bad = [t for t in skin_tones if t not in SKIN_TONES]
    if bad or not skin_tones:
        raise ValueError(f"skin_tones = {list(skin_tones)!r}: expected some of {list(SKIN_TONES)}")
    people = []
    for i in range(int(n)):
        rng = np.random.default_rng([int(seed), i])
        people.append(
            {"id": f"p{i}", **sample_person(rng, age_yr=age_yr, p_male=p_male, skin_tones=tuple(skin_tones))}
        )
    return people
