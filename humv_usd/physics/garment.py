"""Energy balance of a fabric layer over skin with an air gap, per facet (seed Eq. 5-9).

Heat flows from the skin across the air gap (conduction through still air, natural convection
in wide gaps, grey-body radiation between skin and fabric), through the fabric (conduction),
and leaves the outer surface by convection and emission, while the outer surface absorbs
``absorbed_radiation`` (short + long wave, computed elsewhere, seed Eq. 3-4)::

    q_in(T_in) + q_rad = h (T_out - T_air) + eps_f sigma T_out^4        (seed Eq. 5, 8, 9)
    q_in = q_fabric = k_f / l_f (T_in - T_out)                          (seed Eq. 6, R2)

The unknown is the outer fabric temperature T_out per facet; the inner temperature follows
from the fabric conduction, T_in = T_out + l_f / k_f q_out(T_out), so the balance is one
strictly decreasing scalar function of T_out per facet, solved by a bracketed (safeguarded)
Newton iteration that cannot leave its bracket. All functions are vectorized over facets.

A wet fabric (sweat wicked into it) also loses latent heat from its outer surface,
q_evap = w LR h (p_sat(T_out) - RH p_sat(T_air)) (Lewis relation, ASHRAE Fundamentals ch. 9),
which keeps the residual strictly decreasing.

Layered garments (:func:`stack_steady_state`, :func:`stack_transient_step`): layers 0 (on the
skin) .. n-1 (outermost) in series; the outermost layer's outer surface meets the environment,
each layer's inner surface exchanges with the next inner layer's outer surface across its own
air gap (conduction, Hollands convection, grey-plate radiation), layer 0's with the skin. The
unknowns are every layer's inner and outer surface temperature, solved together by Newton on
the layers' node balances (a small block-tridiagonal system per facet, :func:`_stack_newton`);
a facet it leaves is solved by shooting from the outermost temperature: the flux carried inward
layer by layer (fabric conduction, storage, the gap inverted for the warm side by
:func:`gap_temperature_for_flux`), the residual what the skin delivers minus what the stack
needs, again strictly decreasing, in a bracket.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics.checks import require
from humv_usd.physics.convection import mitchell
from humv_usd.physics.sky import effective_sky_temperature, water_vapour_pressure

GRAVITY = 9.80665  # [m s^-2]
_HOLLANDS_RA_CRITICAL = 1708.0  # onset of Rayleigh-Benard convection, rigid plates
_T_PROPERTY_MIN = 100.0  # [K], air properties are clamped below (outside any physical state)
#: Lewis ratio h_e / h_c of the evaporative to the convective coefficient at sea level
#: [K Pa^-1] (16.5 K kPa^-1, ASHRAE Handbook Fundamentals 2017, ch. 9 eq. 34).
LEWIS_RATIO_K_PA = 16.5e-3
_EPS = float(np.finfo(float).eps)  # unit round-off of float64 [-]


def air_conductivity(temperature_k):
    """Thermal conductivity of dry air at 1 atm.

    Parameters
    ----------
    temperature_k : numeric
        Air temperature [K].

    Returns
    -------
    numeric
        Thermal conductivity [W m^-1 K^-1].

    Notes
    -----
    k = 0.0263 (T / 300 K)^0.87, a power-law fit to Incropera Table A.4 (250-350 K within 1 %).

    References
    ----------
    .. [1] Incropera, F. P., DeWitt, D. P. et al. (2007). Fundamentals of Heat and Mass Transfer,
       6th ed., Wiley, Table A.4.
    """
    t = np.maximum(np.asarray(temperature_k, dtype=float), _T_PROPERTY_MIN)
    return 0.0263 * (t / 300.0) ** 0.87


def air_kinematic_viscosity(temperature_k):
    """Kinematic viscosity of dry air at 1 atm, nu = 15.89e-6 (T / 300 K)^1.79 [m^2 s^-1].

    Parameters
    ----------
    temperature_k : numeric
        Air temperature [K].

    Returns
    -------
    numeric
        Kinematic viscosity [m^2 s^-1].

    References
    ----------
    .. [1] Incropera et al. (2007), Table A.4 (power-law fit, 250-350 K within 1 %).
    """
    t = np.maximum(np.asarray(temperature_k, dtype=float), _T_PROPERTY_MIN)
    return 15.89e-6 * (t / 300.0) ** 1.79


def air_thermal_diffusivity(temperature_k):
    """Thermal diffusivity of dry air at 1 atm, alpha = 22.5e-6 (T / 300 K)^1.87 [m^2 s^-1].

    Parameters
    ----------
    temperature_k : numeric
        Air temperature [K].

    Returns
    -------
    numeric
        Thermal diffusivity [m^2 s^-1].

    References
    ----------
    .. [1] Incropera et al. (2007), Table A.4 (power-law fit, 250-350 K within 1.5 %).
    """
    t = np.maximum(np.asarray(temperature_k, dtype=float), _T_PROPERTY_MIN)
    return 22.5e-6 * (t / 300.0) ** 1.87


def grey_plates_exchange_factor(emissivity_1, emissivity_2):
    """Radiative exchange factor of two infinite parallel grey plates.

    Parameters
    ----------
    emissivity_1, emissivity_2 : numeric
        Hemispherical emissivities of the facing surfaces [0-1].

    Returns
    -------
    numeric
        F with q = F sigma (T1^4 - T2^4) [-]; 0 if either emissivity is 0.

    Notes
    -----
    F = 1 / (1/eps_1 + 1/eps_2 - 1) = eps_1 eps_2 / (eps_1 + eps_2 - eps_1 eps_2).

    References
    ----------
    .. [1] Incropera et al. (2007), Table 13.3.
    """
    e1 = np.asarray(emissivity_1, dtype=float)
    e2 = np.asarray(emissivity_2, dtype=float)
    den = e1 + e2 - e1 * e2
    return np.where(den > 0.0, e1 * e2 / np.where(den > 0.0, den, 1.0), 0.0)


def _t4(t):
    # sign(T) T^4: identical to T^4 for T > 0 and monotonic everywhere, so the residual stays
    # monotonic even at bracket ends far outside the physical range
    return t * t * t * np.abs(t)


def saturation_vapour_pressure(temperature_k):
    """Saturation vapour pressure over water [Pa] (Magnus form, Alduchov & Eskridge 1996).

    Parameters
    ----------
    temperature_k : numeric
        Temperature [K]; clamped to -100..200 degC so that solver brackets far outside the
        physical range stay finite and monotonic.

    Returns
    -------
    numeric
        e_s = 610.94 exp(17.625 t / (t + 243.04)) [Pa], t in degC.

    References
    ----------
    .. [1] Alduchov, O. A., Eskridge, R. E. (1996). Improved Magnus form approximation of
       saturation vapor pressure. J. Appl. Meteorol. 35, 601-609.
    """
    t = np.clip(np.asarray(temperature_k, dtype=float), 173.15, 473.15)
    return water_vapour_pressure(t, 1.0)


def fabric_evaporation(
    outer_temperature_k, air_temperature_k, relative_humidity, h_convective, wetted_fraction, limit=np.inf
):
    """Latent heat flux from a wet fabric surface to the air [W m^-2] (Lewis relation).

    Parameters
    ----------
    outer_temperature_k : numeric
        Fabric outer-surface temperature [K].
    air_temperature_k : numeric
        Air temperature [K].
    relative_humidity : numeric
        Air relative humidity [0-1].
    h_convective : numeric
        Convective coefficient of the surface [W m^-2 K^-1].
    wetted_fraction : numeric
        Wetted fraction of the fabric's outer surface [0-1] (0: dry).
    limit : numeric, default inf
        Largest evaporation [W m^-2]: the latent heat of the sweat that reaches the fabric
        (a fabric cannot evaporate more water than the skin supplies).

    Returns
    -------
    numeric
        q_evap = min(w LR h_c (p_sat(T_out) - RH p_sat(T_air)), limit) [W m^-2] with
        LR = 16.5 K kPa^-1; negative for condensation on a wet surface below the dew point.

    Notes
    -----
    The evaporative coefficient follows from the convective one by the Lewis relation
    h_e = LR h_c (ASHRAE Fundamentals 2017 ch. 9; Gagge & Nishi 1977). A fully wet surface
    (w = 1) with no other heat source settles at the temperature T_w that solves
    e_a = p_sat(T_w) - (T_a - T_w) / LR, the psychrometric wet-bulb temperature of a
    psychrometer constant 1 / LR = 0.061 kPa K^-1 (the sea-level thermodynamic value is
    0.066 kPa K^-1: about 0.3 K apart at 30 degC, 40 %).

    References
    ----------
    .. [1] ASHRAE (2017). Handbook - Fundamentals, ch. 9 Thermal Comfort, eq. 34 (Lewis
       relation) and ch. 1 Psychrometrics.
    .. [2] Gagge, A. P., Nishi, Y. (1977). Heat exchange between human skin surface and thermal
       environment. Handbook of Physiology, sect. 9, 69-92.
    """
    w = np.asarray(wetted_fraction, dtype=float)
    dp = saturation_vapour_pressure(outer_temperature_k) - np.asarray(
        relative_humidity, dtype=float
    ) * saturation_vapour_pressure(air_temperature_k)
    return np.minimum(w * LEWIS_RATIO_K_PA * np.asarray(h_convective, dtype=float) * dp, limit)


def hollands_nusselt(rayleigh):
    """Nusselt number of an enclosed air layer heated from below (Hollands et al. 1976).

    Parameters
    ----------
    rayleigh : numeric
        Rayleigh number g beta dT d^3 / (nu alpha) of the layer [-].

    Returns
    -------
    numeric
        Nusselt number [-], exactly 1 (pure conduction) below Ra = 1708.

    Notes
    -----
    Nu = 1 + 1.44 [1 - 1708/Ra]^+ + [(Ra/5830)^(1/3) - 1]^+ for a horizontal layer heated from
    below, 0 < Ra < 1e8. This orientation convects most; a vertical layer (ElSherbiny et al.
    1982) gives Nu within about 20 % for Ra < 1e5, so it is used as the upper bound for all
    facets. A layer heated from above (fabric warmer than skin) is stable: Nu = 1.

    References
    ----------
    .. [1] Hollands, K. G. T., Unny, T. E., Raithby, G. D., Konicek, L. (1976). Free convective
       heat transfer across inclined air layers. J. Heat Transfer 98(2), 189-193.
    """
    ra = np.maximum(np.asarray(rayleigh, dtype=float), 0.0)
    onset = np.where(
        ra > _HOLLANDS_RA_CRITICAL, 1.0 - _HOLLANDS_RA_CRITICAL / np.maximum(ra, _HOLLANDS_RA_CRITICAL), 0.0
    )
    return 1.0 + 1.44 * onset + np.maximum(np.cbrt(ra / 5830.0) - 1.0, 0.0)


def air_gap_flux(
    skin_temperature_k,
    inner_temperature_k,
    air_gap_m,
    skin_emissivity=0.98,
    fabric_emissivity=0.9,
    model="hollands",
):
    """Heat flux from skin across an air gap to the fabric's inner surface.

    Parameters
    ----------
    skin_temperature_k : numeric
        Skin temperature [K].
    inner_temperature_k : numeric
        Fabric inner-surface temperature [K].
    air_gap_m : numeric
        Air-gap thickness [m]; must be > 0 (a gap of 0 is contact, handled by the solver).
    skin_emissivity, fabric_emissivity : numeric
        Emissivities of skin and of the fabric's inner surface [0-1].
    model : str, default 'hollands'
        'hollands' (conduction up to the onset of convection, Ra = 1708, then the Hollands et al.
        1976 Nusselt number) or 'conduction' (still air, Nu = 1).

    Returns
    -------
    tuple of numeric
        (conduction + convection flux, radiation flux) [W m^-2], positive from skin to fabric.

    Notes
    -----
    q_cd = Nu k_air(T_m) / d (T_skin - T_in), Ra = g (1/T_m) (T_skin - T_in)^+ d^3 / (nu alpha),
    properties at T_m = (T_skin + T_in) / 2; q_r = F sigma (T_skin^4 - T_in^4) with F of two
    grey parallel plates. This replaces the seed's Eq. 7 (R1 with k_a / l_a and a linearized
    radiation term at (T_a + T_skin) / 2) by the exact terms at the gap's own temperatures.

    Raises
    ------
    ValueError
        If ``model`` is not one of the above.
    """
    if model not in ("hollands", "conduction"):
        raise ValueError(f"invalid model selection {model}")
    f_rad = grey_plates_exchange_factor(skin_emissivity, fabric_emissivity)
    return _air_gap_flux(skin_temperature_k, inner_temperature_k, air_gap_m, f_rad, model)


def _air_gap_flux(skin_temperature_k, inner_temperature_k, air_gap_m, f_rad, model, gap_cubed=None):
    """:func:`air_gap_flux` with the grey plates' exchange factor ``f_rad`` given (the gap
    solve evaluates the flux many times for the same surfaces), and optionally ``gap_cubed``
    = ``air_gap_m ** 3``. The air properties are those of :func:`air_conductivity`,
    :func:`air_kinematic_viscosity` and :func:`air_thermal_diffusivity` at the same clamped
    mean temperature (the same arithmetic, the ratio T / 300 K formed once)."""
    t_s = np.asarray(skin_temperature_k, dtype=float)
    t_i = np.asarray(inner_temperature_k, dtype=float)
    d = np.asarray(air_gap_m, dtype=float)
    t_m = 0.5 * (t_s + t_i)
    dt = t_s - t_i
    ratio = np.maximum(t_m, _T_PROPERTY_MIN) / 300.0
    k = 0.0263 * ratio**0.87  # air_conductivity(t_m)
    if model == "hollands":
        t_mc = np.maximum(t_m, _T_PROPERTY_MIN)
        d3 = d**3 if gap_cubed is None else gap_cubed
        # nu alpha of air_kinematic_viscosity and air_thermal_diffusivity at t_mc
        ra = GRAVITY * np.maximum(dt, 0.0) * d3 / (t_mc * (15.89e-6 * ratio**1.79) * (22.5e-6 * ratio**1.87))
        nu = hollands_nusselt(ra)
    else:
        nu = 1.0
    d_safe = np.where(d > 0.0, d, 1.0)
    q_cd = np.where(d > 0.0, nu * k / d_safe * dt, 0.0)
    q_r = f_rad * STEFAN_BOLTZMANN * (_t4(t_s) - _t4(t_i))
    return q_cd, q_r


class GarmentBalance(NamedTuple):
    """Per-facet solution of the garment energy balance; all arrays broadcast to the facets."""

    outer_temperature_k: np.ndarray  # fabric outer surface [K]
    inner_temperature_k: np.ndarray  # fabric inner surface [K]
    residual: np.ndarray  # q_in + q_rad - q_conv - q_emit (- storage) [W m^-2]
    q_in: np.ndarray  # delivered from skin across the gap (or contact) [W m^-2], seed Eq. 6
    q_gap_conduction: np.ndarray  # conduction + convection part of q_in [W m^-2]
    q_gap_radiation: np.ndarray  # radiation part of q_in [W m^-2]
    q_fabric: np.ndarray  # conduction through the fabric [W m^-2]
    q_rad: np.ndarray  # absorbed environment radiation [W m^-2], seed Eq. 3-4
    q_conv: np.ndarray  # convection to the air [W m^-2], seed Eq. 9
    q_emit: np.ndarray  # emission eps sigma T^4 [W m^-2], seed Eq. 8
    q_storage: np.ndarray  # C (T - T_prev) / dt, 0 in steady state [W m^-2]
    iterations: int  # Newton/bisection iterations of the slowest facet
    q_evap: np.ndarray | float = 0.0  # latent loss of a wet fabric [W m^-2] (Lewis relation)


def _outer_coefficient(h_forced, delta_t, natural_floor):
    if natural_floor:
        return np.maximum(h_forced, 2.38 * np.abs(delta_t) ** 0.25)  # ISO 7730 floor
    return h_forced


def _balance(t_out, p):
    """Residual and flux terms at outer temperature t_out; p holds broadcast parameters."""
    dt_air = t_out - p["t_air"]
    h_out = _outer_coefficient(p["h"], dt_air, p["natural_floor"])
    q_conv = h_out * dt_air
    q_emit = p["eps_f"] * STEFAN_BOLTZMANN * _t4(t_out)
    q_evap = fabric_evaporation(t_out, p["t_air"], p["rh"], h_out, p["wet"])
    q_out = q_conv + q_emit + q_evap - p["q_rad"]
    u_f = p["u_f"]
    insulated = u_f <= 0.0
    contact = (p["gap"] <= 0.0) & ~insulated
    u_safe = np.where(insulated, 1.0, u_f)
    t_in = np.where(insulated | contact, p["t_skin"], t_out + q_out / u_safe)
    q_cd, q_r = air_gap_flux(p["t_skin"], t_in, p["gap"], p["eps_s"], p["eps_in"], p["gap_model"])
    q_fabric = np.where(insulated, 0.0, u_f * (t_in - t_out))
    # contact: the gap vanishes and q_in is the fabric conduction from skin temperature
    q_cd = np.where(contact, q_fabric, np.where(insulated, 0.0, q_cd))
    q_r = np.where(contact | insulated, 0.0, q_r)
    q_in = q_cd + q_r
    q_store = p["c_dt"] * (t_out - p["t_prev"])
    residual = q_in - q_out - q_store
    return residual, (t_in, q_in, q_cd, q_r, q_fabric, q_conv, q_emit, q_store, q_evap)


def _solve(p, lo, hi, tol, max_iter):
    """Safeguarded Newton on the strictly decreasing residual, bracket lo < root < hi."""
    t = 0.5 * (lo + hi)
    delta = 1e-4  # [K], central-difference step for the derivative
    iterations = 0
    active = np.ones(t.shape, dtype=bool)
    for iterations in range(1, max_iter + 1):
        f = _balance(t, p)[0]
        active = np.abs(f) > tol
        if not active.any():
            break
        # shrink the bracket with the current point (f decreasing: f > 0 means root above)
        lo = np.where(active & (f > 0.0), t, lo)
        hi = np.where(active & (f < 0.0), t, hi)
        dfdt = (_balance(t + delta, p)[0] - _balance(t - delta, p)[0]) / (2.0 * delta)
        ok = dfdt < 0.0
        t_newton = t - f / np.where(ok, dfdt, -1.0)
        inside = ok & (t_newton > lo) & (t_newton < hi) & (iterations <= 40)
        t_next = np.where(inside, t_newton, 0.5 * (lo + hi))
        # stop on a collapsed bracket (residual at the round-off floor)
        collapsed = (hi - lo) <= 4.0 * np.finfo(float).eps * np.abs(t)
        t = np.where(active & ~collapsed, t_next, t)
        if not (active & ~collapsed).any():
            break
    return t, iterations


def _parameters(
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gap_m,
    fabric_thickness_m,
    fabric_conductivity,
    fabric_emissivity,
    skin_emissivity,
    inner_emissivity,
    natural_floor,
    gap_model,
    c_dt,
    t_prev,
    check_previous=True,
    wetted_fraction=0.0,
    relative_humidity=0.5,
):
    if gap_model not in ("hollands", "conduction"):
        raise ValueError(f"invalid model selection {gap_model}")
    _check_inputs(
        skin_temperature_k,
        air_temperature_k,
        absorbed_radiation,
        h_forced,
        air_gap_m,
        fabric_thickness_m,
        fabric_conductivity,
        fabric_emissivity,
        skin_emissivity,
        inner_emissivity,
        t_prev if check_previous else None,
    )
    require("wetted_fraction", wetted_fraction, 0.0, 1.0)
    require("relative_humidity", relative_humidity, 0.0, 1.0)
    eps_f = np.asarray(fabric_emissivity, dtype=float)
    eps_in = eps_f if inner_emissivity is None else np.asarray(inner_emissivity, dtype=float)
    thick = np.asarray(fabric_thickness_m, dtype=float)
    k_f = np.asarray(fabric_conductivity, dtype=float)
    u_f = k_f / np.maximum(thick, 1e-9)  # fabric conductance k_f / l_f, 1 / R2 (seed Eq. 7)
    arrays = dict(
        t_skin=skin_temperature_k,
        t_air=air_temperature_k,
        q_rad=absorbed_radiation,
        h=h_forced,
        gap=air_gap_m,
        u_f=u_f,
        eps_f=eps_f,
        eps_in=eps_in,
        eps_s=skin_emissivity,
        c_dt=c_dt,
        t_prev=t_prev,
        wet=wetted_fraction,
        rh=relative_humidity,
    )
    b = np.broadcast_arrays(*[np.asarray(v, dtype=float) for v in arrays.values()])
    p = {k: np.array(v) for k, v in zip(arrays, b)}
    p["natural_floor"] = bool(natural_floor)
    p["gap_model"] = gap_model
    return p


def _check_inputs(t_skin, t_air, q_rad, h, gap, thickness, k_f, eps_f, eps_s, eps_in, t_prev) -> None:
    """ValueError for NaN, infinite or non-physical inputs of the garment balance."""
    require("skin_temperature_k", t_skin, 1.0, 1e4)
    require("air_temperature_k", t_air, 1.0, 1e4)
    require("absorbed_radiation", q_rad, -1e5, 1e5)
    require("h_forced", h, 0.0, 1e4)
    require("air_gap_m", gap, 0.0, 10.0)
    require("fabric_thickness_m", thickness, 0.0, 1.0)
    require("fabric_conductivity", k_f, 0.0, 1e3)
    for name, eps in (("fabric_emissivity", eps_f), ("skin_emissivity", eps_s), ("inner_emissivity", eps_in)):
        if eps is not None:
            require(name, eps, 0.0, 1.0)
    if t_prev is not None:
        require("previous_outer_temperature_k", t_prev, 1.0, 1e4)


def _bracket(p):
    """Bounds with residual >= 0 at lo and <= 0 at hi (see the module docstring)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        # outer surface in radiative (or convective) balance with the absorbed radiation alone
        es = p["eps_f"] * STEFAN_BOLTZMANN
        t_rad = np.where(es > 0.0, (np.maximum(p["q_rad"], 0.0) / es) ** 0.25, np.inf)
        t_cnv = np.where(p["h"] > 0.0, p["t_air"] + np.maximum(p["q_rad"], 0.0) / p["h"], np.inf)
    # below the air, a wet surface's evaporation is at most w LR h (1 - RH) p_sat(T_air): below
    # t_evap the convective gain outweighs it whatever h is
    t_evap = p["t_air"] - p["wet"] * LEWIS_RATIO_K_PA * (1.0 - p["rh"]) * saturation_vapour_pressure(
        p["t_air"]
    )
    lo = np.minimum(np.minimum(np.minimum(p["t_skin"], p["t_air"]), t_rad), t_evap)
    hi = np.maximum(np.maximum(p["t_skin"], p["t_air"]), np.minimum(t_rad, t_cnv))
    lo = np.minimum(lo, p["t_prev"])
    hi = np.maximum(hi, p["t_prev"])
    lo = np.maximum(lo - 1.0, 1.0)
    hi = np.where(np.isfinite(hi), hi, 1e4) + 1.0
    return lo, hi


def _result(t, p, iterations):
    residual, (t_in, q_in, q_cd, q_r, q_fab, q_conv, q_emit, q_store, q_evap) = _balance(t, p)
    return GarmentBalance(
        t,
        t_in,
        residual,
        q_in,
        q_cd,
        q_r,
        q_fab,
        p["q_rad"].copy(),
        q_conv,
        q_emit,
        q_store,
        iterations,
        q_evap,
    )


def steady_state(
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gap_m,
    fabric_thickness_m,
    fabric_conductivity=0.05,
    fabric_emissivity=0.9,
    skin_emissivity=0.98,
    inner_emissivity=None,
    natural_floor=True,
    gap_model="hollands",
    tol=1e-6,
    max_iter=100,
    wetted_fraction=0.0,
    relative_humidity=0.5,
):
    """Steady-state garment temperatures per facet (seed Eq. 5-9), bracketed Newton.

    Parameters
    ----------
    skin_temperature_k : numeric
        Skin temperature under the facet [K].
    air_temperature_k : numeric
        Ambient air temperature [K].
    absorbed_radiation : numeric
        Short + long wave radiation absorbed by the outer fabric surface [W m^-2] (q_rad).
    h_forced : numeric
        Outer convective coefficient [W m^-2 K^-1], e.g. from
        :py:func:`humv_usd.physics.convection.mitchell`.
    air_gap_m : numeric
        Skin-fabric air gap [m]; 0 is contact (no gap resistance).
    fabric_thickness_m : numeric
        Fabric thickness [m], > 0 (clamped to 1 nm).
    fabric_conductivity : numeric, default 0.05
        Fabric (fibre + entrapped air) conductivity [W m^-1 K^-1]; 0 makes an insulated plate.
    fabric_emissivity : numeric, default 0.9
        Outer-surface emissivity [0-1] (absorptance for long wave is in ``absorbed_radiation``).
    skin_emissivity : numeric, default 0.98
        Skin emissivity [0-1].
    inner_emissivity : numeric, optional
        Fabric inner-surface emissivity [0-1]; defaults to ``fabric_emissivity``.
    natural_floor : bool, default True
        Use max(h_forced, 2.38 |T_out - T_air|^0.25) outside (ISO 7730 natural convection).
    gap_model : str, default 'hollands'
        Air-gap model, see :py:func:`air_gap_flux`.
    tol : float, default 1e-6
        Residual tolerance [W m^-2].
    max_iter : int, default 100
        Iteration cap (the bracket halves at least every other iteration after 40).
    wetted_fraction : numeric, default 0
        Wetted fraction of the outer surface [0-1] (sweat wicked into the fabric); it
        evaporates by :func:`fabric_evaporation`.
    relative_humidity : numeric, default 0.5
        Air relative humidity [0-1] (used only by the evaporation of a wet fabric).

    Returns
    -------
    GarmentBalance
        Temperatures, per-facet residual and the flux terms.

    Notes
    -----
    Solves q_in(T_in) + q_rad = h (T_out - T_air) + eps sigma T_out^4 (+ q_evap of a wet
    fabric) (seed Eq. 5, 8, 9) with
    T_in = T_out + (l_f / k_f) q_out (seed Eq. 6, R2 = l_f / k_f) and q_in from
    :py:func:`air_gap_flux` (seed Eq. 7, R1). The residual is strictly decreasing in T_out, and
    the bracket [min(T_skin, T_air, (q_rad / eps sigma)^(1/4)) - 1,
    max(T_skin, T_air, min((q_rad / eps sigma)^(1/4), T_air + q_rad / h)) + 1] contains the
    root; Newton steps that leave the shrinking bracket are replaced by bisection.

    References
    ----------
    .. [1] Press, W. H. et al. (2007). Numerical Recipes, 3rd ed., section 9.4 (rtsafe).
    .. [2] The seed paper, section 2.2.3, Eq. 5-9.
    """
    p = _parameters(
        skin_temperature_k,
        air_temperature_k,
        absorbed_radiation,
        h_forced,
        air_gap_m,
        fabric_thickness_m,
        fabric_conductivity,
        fabric_emissivity,
        skin_emissivity,
        inner_emissivity,
        natural_floor,
        gap_model,
        0.0,
        air_temperature_k,
        wetted_fraction=wetted_fraction,
        relative_humidity=relative_humidity,
    )
    lo, hi = _bracket(p)
    t, it = _solve(p, lo, hi, tol, max_iter)
    return _result(t, p, it)


def areal_heat_capacity(density, specific_heat, thickness_m):
    """Areal heat capacity of a fabric, rho c l [J m^-2 K^-1].

    Parameters
    ----------
    density : numeric
        Bulk fabric density [kg m^-3] (about 200-500 for woven textiles).
    specific_heat : numeric
        Specific heat [J kg^-1 K^-1] (about 1300 for cotton, 1400 for polyester).
    thickness_m : numeric
        Fabric thickness [m].

    Returns
    -------
    numeric
        Heat capacity per unit area [J m^-2 K^-1].
    """
    return (
        np.asarray(density, dtype=float)
        * np.asarray(specific_heat, dtype=float)
        * np.asarray(thickness_m, dtype=float)
    )


def transient_step(
    previous_outer_temperature_k,
    time_step_s,
    heat_capacity,
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gap_m,
    fabric_thickness_m,
    fabric_conductivity=0.05,
    fabric_emissivity=0.9,
    skin_emissivity=0.98,
    inner_emissivity=None,
    natural_floor=True,
    gap_model="hollands",
    tol=1e-6,
    max_iter=100,
    wetted_fraction=0.0,
    relative_humidity=0.5,
):
    """One implicit (backward Euler) step of the garment balance with fabric heat capacity.

    Parameters
    ----------
    previous_outer_temperature_k : numeric
        Outer fabric temperature at the start of the step [K].
    time_step_s : numeric
        Time step [s]; any size (backward Euler is L-stable); ``np.inf`` gives the steady state.
    heat_capacity : numeric
        Areal heat capacity of the fabric [J m^-2 K^-1], see :py:func:`areal_heat_capacity`.
    skin_temperature_k, air_temperature_k, absorbed_radiation, h_forced, air_gap_m, \
fabric_thickness_m, fabric_conductivity, fabric_emissivity, skin_emissivity, \
inner_emissivity, natural_floor, gap_model, tol, max_iter, wetted_fraction, relative_humidity
        As in :py:func:`steady_state`, at the end of the step.

    Returns
    -------
    GarmentBalance
        State at the end of the step; ``q_storage`` is C (T - T_prev) / dt and the residual
        q_in + q_rad - q_conv - q_emit - q_storage.

    Notes
    -----
    C (T^{n+1} - T^n) / dt = q_in(T^{n+1}) + q_rad - q_conv(T^{n+1}) - q_emit(T^{n+1}), with the
    capacity lumped in one fabric node (the fabric's Biot number l h / k is below 1 for
    l < 1 mm; for thicker fabric this is a one-node approximation). Each step is solved with
    the same bracketed Newton as the steady state; the storage term keeps the residual strictly
    decreasing, so there is no step-size limit and no overshoot of the equilibrium.

    References
    ----------
    .. [1] Hairer, E., Wanner, G. (1996). Solving Ordinary Differential Equations II: Stiff and
       Differential-Algebraic Problems, 2nd ed., Springer (backward Euler, L-stability).
    """
    dt = require("time_step_s", time_step_s, 1e-9, np.inf, allow_inf=True)
    c_dt = require("heat_capacity", heat_capacity, 0.0, 1e7) / dt
    p = _parameters(
        skin_temperature_k,
        air_temperature_k,
        absorbed_radiation,
        h_forced,
        air_gap_m,
        fabric_thickness_m,
        fabric_conductivity,
        fabric_emissivity,
        skin_emissivity,
        inner_emissivity,
        natural_floor,
        gap_model,
        c_dt,
        previous_outer_temperature_k,
        wetted_fraction=wetted_fraction,
        relative_humidity=relative_humidity,
    )
    lo, hi = _bracket(p)
    t, it = _solve(p, lo, hi, tol, max_iter)
    return _result(t, p, it)


def net_flux(
    outer_temperature_k,
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gap_m,
    fabric_thickness_m,
    fabric_conductivity=0.05,
    fabric_emissivity=0.9,
    skin_emissivity=0.98,
    inner_emissivity=None,
    natural_floor=True,
    gap_model="hollands",
    wetted_fraction=0.0,
    relative_humidity=0.5,
):
    """Net heat flux into the outer fabric surface, q_in + q_rad - q_conv - q_emit [W m^-2].

    Parameters
    ----------
    outer_temperature_k : numeric
        Outer fabric temperature [K].
    skin_temperature_k, air_temperature_k, absorbed_radiation, h_forced, air_gap_m, \
fabric_thickness_m, fabric_conductivity, fabric_emissivity, skin_emissivity, \
inner_emissivity, natural_floor, gap_model
        As in :py:func:`steady_state`.

    Returns
    -------
    numeric
        Net flux [W m^-2]; zero at the steady state, C dT/dt in a transient.
    """
    p = _parameters(
        skin_temperature_k,
        air_temperature_k,
        absorbed_radiation,
        h_forced,
        air_gap_m,
        fabric_thickness_m,
        fabric_conductivity,
        fabric_emissivity,
        skin_emissivity,
        inner_emissivity,
        natural_floor,
        gap_model,
        0.0,
        outer_temperature_k,
        check_previous=False,  # a diagnostic: any outer temperature may be evaluated
        wetted_fraction=wetted_fraction,
        relative_humidity=relative_humidity,
    )
    return _balance(np.broadcast_to(np.asarray(outer_temperature_k, dtype=float), p["t_air"].shape), p)[0]


# ----------------------------------------------------------------------------- layered garments
def gap_temperature_for_flux(
    flux,
    cold_temperature_k,
    air_gap_m,
    hot_emissivity=0.9,
    cold_emissivity=0.9,
    model="hollands",
    tol=1e-9,
    max_iter=80,
):
    """Warm-side temperature of an air gap that carries a given flux to its cold side.

    Parameters
    ----------
    flux : numeric
        Heat flux across the gap from the warm (inner) to the cold (outer) side [W m^-2];
        negative when heat flows inward.
    cold_temperature_k : numeric
        Temperature of the gap's outer side [K].
    air_gap_m : numeric
        Gap thickness [m]; 0 is contact (the warm side equals the cold side).
    hot_emissivity, cold_emissivity : numeric
        Emissivities of the inner and outer surfaces [0-1].
    model : str, default 'hollands'
        As in :py:func:`air_gap_flux`.
    tol : float, default 1e-9
        Flux tolerance [W m^-2].
    max_iter : int, default 80
        Iteration cap.

    Returns
    -------
    numeric
        T_hot with q_cd + q_r of :py:func:`air_gap_flux` (T_hot, T_cold) = ``flux`` [K].

    Notes
    -----
    The gap flux is strictly increasing in T_hot (conduction with k_air(T_m) > 0, Hollands'
    Nusselt number non-decreasing in T_hot - T_cold, sign(T) T^4 radiation), so the root is
    unique. Bracket: for q >= 0, T_cold <= T_hot <= T_cold + q d / k_air(T_cold) (conduction
    alone, Nu >= 1, k_air(T_m) >= k_air(T_cold)); for q < 0 the layer is stable (Nu = 1),
    T_cold + q d / k_air(100 K) <= T_hot <= T_cold. Safeguarded Newton (Numerical Recipes
    rtsafe) inside the shrinking bracket.
    """
    if model not in ("hollands", "conduction"):
        raise ValueError(f"invalid model selection {model}")
    q, t_c, d, e_h, e_c = (
        np.array(v, dtype=float)
        for v in np.broadcast_arrays(flux, cold_temperature_k, air_gap_m, hot_emissivity, cold_emissivity)
    )
    shape = q.shape
    q, t_c, d, e_h, e_c = (v.ravel() for v in (q, t_c, d, e_h, e_c))
    t = t_c.copy()  # contact: no gap, no difference
    idx = np.flatnonzero(d > 0.0)  # facets still iterating
    q, t_c, d, e_h, e_c = q[idx], t_c[idx], d[idx], e_h[idx], e_c[idx]
    lo = np.where(q >= 0.0, t_c, t_c + q * d / air_conductivity(_T_PROPERTY_MIN)) - 1e-9 * np.abs(t_c)
    hi = np.where(q >= 0.0, t_c + q * d / air_conductivity(t_c), t_c) + 1e-9 * np.abs(t_c)
    f_rad = grey_plates_exchange_factor(e_h, e_c)
    # start from the gap linearised at the cold side (exact for small differences)
    h_lin = air_conductivity(t_c) / d + 4.0 * f_rad * STEFAN_BOLTZMANN * np.abs(t_c) ** 3
    x = np.clip(t_c + q / h_lin, lo, hi)
    step = 1e-5  # [K], finite-difference step of the slope (Nusselt and property terms included)
    # the flux at x and at x + step in one evaluation of 2 m gaps (the slope of a gap that
    # converges now goes unused): each gap's arithmetic as in two evaluations, in half the calls
    t_c2, d2, f_rad2 = (np.concatenate([v, v]) for v in (t_c, d, f_rad))
    d3 = d2**3
    for it in range(max_iter):
        if idx.size == 0:
            break
        m = idx.size
        q_cd, q_r = _air_gap_flux(np.concatenate([x, x + step]), t_c2, d2, f_rad2, model, d3)
        g = q_cd + q_r
        f = g[:m] - q
        done = (np.abs(f) <= tol + 1e-12 * np.abs(q)) | ((hi - lo) <= 4.0 * np.finfo(float).eps * np.abs(x))
        t[idx[done]] = x[done]
        keep = ~done
        g_step = g[m:][keep]
        idx, q, lo, hi, x, f = (v[keep] for v in (idx, q, lo, hi, x, f))
        if idx.size == 0:
            break
        keep2 = np.concatenate([keep, keep])
        t_c2, d2, f_rad2, d3 = t_c2[keep2], d2[keep2], f_rad2[keep2], d3[keep2]
        lo = np.where(f < 0.0, x, lo)
        hi = np.where(f > 0.0, x, hi)
        slope = (g_step - q - f) / step
        ok = slope > 0.0
        x_newton = x - f / np.where(ok, slope, 1.0)
        inside = ok & (x_newton > lo) & (x_newton < hi) & (it < 40)
        x = np.where(inside, x_newton, 0.5 * (lo + hi))
    t[idx] = x
    return t.reshape(shape)


class StackBalance(NamedTuple):
    """Per-facet solution of a layered garment stack; layer axis first (0 = on the skin)."""

    outer_temperature_k: np.ndarray  # (n, ...) outer surface of each layer [K]
    inner_temperature_k: np.ndarray  # (n, ...) inner surface of each layer [K]
    residual: np.ndarray  # (...) skin flux - what the stack needs [W m^-2]
    q_in: np.ndarray  # (...) delivered from the skin into the stack [W m^-2]
    q_gap: np.ndarray  # (n, ...) across the gap under each layer = its fabric conduction [W m^-2]
    q_rad: np.ndarray  # (...) absorbed by the outermost surface [W m^-2]
    q_conv: np.ndarray  # (...) convection from the outermost surface [W m^-2]
    q_emit: np.ndarray  # (...) emission of the outermost surface [W m^-2]
    q_evap: np.ndarray  # (...) evaporation from the outermost surface [W m^-2]
    q_storage: np.ndarray  # (n, ...) C_i (T_i - T_i,prev) / dt [W m^-2]
    iterations: int


def _stack_balance(t_out, p):
    """Residual of the stack at outermost temperature ``t_out``, carrying the flux inward."""
    n = p["n"]
    q_conv, q_emit, q_evap = _stack_outer(t_out, p)
    q = q_conv + q_emit + q_evap - p["q_rad"]  # leaves layer n-1 outward
    t_o = [None] * n
    t_i = [None] * n
    q_gap = [None] * n
    q_store = [None] * n
    t = t_out
    for i in range(n - 1, -1, -1):
        t_o[i] = t
        # the layer's capacity sits at its outer surface: its fabric conducts what leaves
        # outward plus what it stores, and the (massless) gap under it delivers the same
        q_store[i] = p["c_dt"][i] * (t - p["t_prev"][i])
        q = q + q_store[i]
        t_i[i] = t + q / p["u"][i]
        q_gap[i] = q
        if i > 0:
            t = gap_temperature_for_flux(q, t_i[i], p["gap"][i], p["eps"][i - 1], p["eps"][i], p["gap_model"])
    contact = p["gap"][0] <= 0.0
    q_cd, q_r = air_gap_flux(
        p["t_skin"], t_i[0], np.where(contact, 1.0, p["gap"][0]), p["eps_s"], p["eps"][0], p["gap_model"]
    )
    # contact: the skin is layer 0's inner surface, the fabric conducts from the skin
    q_in = np.where(contact, p["u"][0] * (p["t_skin"] - t_o[0]), q_cd + q_r)
    residual = q_in - q_gap[0]
    t_i[0] = np.where(contact, p["t_skin"], t_i[0])
    extra = (np.stack(t_o), np.stack(t_i), q_in, np.stack(q_gap), q_conv, q_emit, q_evap, np.stack(q_store))
    return residual, extra


def _stack_parameters(
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gaps_m,
    thicknesses_m,
    conductivities,
    emissivities,
    skin_emissivity,
    natural_floor,
    gap_model,
    wetted_fraction,
    relative_humidity,
    c_dt,
    t_prev,
    evaporation_limit=np.inf,
):
    if gap_model not in ("hollands", "conduction"):
        raise ValueError(f"invalid model selection {gap_model}")
    require("skin_temperature_k", skin_temperature_k, 1.0, 1e4)
    require("air_temperature_k", air_temperature_k, 1.0, 1e4)
    require("absorbed_radiation", absorbed_radiation, -1e5, 1e5)
    require("h_forced", h_forced, 0.0, 1e4)
    require("air_gaps_m", air_gaps_m, 0.0, 10.0)
    require("thicknesses_m", thicknesses_m, 1e-9, 1.0)
    require("conductivities", conductivities, 1e-6, 1e3)
    require("emissivities", emissivities, 0.0, 1.0)
    require("skin_emissivity", skin_emissivity, 0.0, 1.0)
    require("wetted_fraction", wetted_fraction, 0.0, 1.0)
    require("relative_humidity", relative_humidity, 0.0, 1.0)
    require("evaporation_limit", evaporation_limit, 0.0, np.inf, allow_inf=True)
    require("previous_temperatures_k", t_prev, 1.0, 1e4)
    gaps = np.asarray(air_gaps_m, dtype=float)
    if gaps.ndim < 1 or gaps.shape[0] < 1:
        raise ValueError("air_gaps_m: expected one gap per layer along the first axis")
    n = gaps.shape[0]
    per_layer = dict(
        gap=gaps, thick=thicknesses_m, k=conductivities, eps=emissivities, c_dt=c_dt, t_prev=t_prev
    )
    per_layer = {k: np.asarray(v, dtype=float) for k, v in per_layer.items()}
    for k, v in per_layer.items():
        if v.ndim == 0:
            per_layer[k] = np.broadcast_to(v, (n,))
        elif v.shape[0] != n:
            raise ValueError(f"{k}: expected {n} layers along the first axis, got shape {v.shape}")
    facet = dict(
        t_skin=skin_temperature_k,
        t_air=air_temperature_k,
        q_rad=absorbed_radiation,
        h=h_forced,
        eps_s=skin_emissivity,
        wet=wetted_fraction,
        rh=relative_humidity,
        evap_limit=evaporation_limit,
    )
    shape = np.broadcast_shapes(
        *[np.shape(v) for v in facet.values()], *[v.shape[1:] for v in per_layer.values()]
    )
    p = {k: np.array(np.broadcast_to(np.asarray(v, dtype=float), shape)) for k, v in facet.items()}
    for k, v in per_layer.items():
        v = v.reshape(v.shape[:1] + (1,) * (len(shape) + 1 - v.ndim) + v.shape[1:])
        p[k] = np.array(np.broadcast_to(v, (n,) + shape))
    p["u"] = p.pop("k") / p.pop("thick")  # fabric conductance k / l per layer
    p["n"] = n
    p["natural_floor"] = bool(natural_floor)
    p["gap_model"] = gap_model
    return p


def _stack_bracket(p):
    """Bounds of the outermost temperature (as :func:`_bracket`, with every layer's previous
    temperature): below the lower one all heat flows outward-in, above the upper one out."""
    q = {
        "t_skin": p["t_skin"],
        "t_air": p["t_air"],
        "q_rad": p["q_rad"],
        "h": p["h"],
        "eps_f": p["eps"][-1],
        "wet": p["wet"],
        "rh": p["rh"],
        "t_prev": p["t_prev"].min(axis=0),
    }
    lo, _ = _bracket(q)
    q["t_prev"] = p["t_prev"].max(axis=0)
    _, hi = _bracket(q)
    return lo, hi


#: Keys of the stack parameters that hold one value per facet / one row per layer and facet.
_FACET_KEYS = ("t_skin", "t_air", "q_rad", "h", "eps_s", "wet", "rh", "evap_limit")
_LAYER_KEYS = ("gap", "eps", "c_dt", "t_prev", "u")


def _stack_take(p, idx):
    """The stack parameters of the facets ``idx`` (flat facet axis)."""
    out = dict(p)
    for k in _FACET_KEYS:
        out[k] = p[k][idx]
    for k in _LAYER_KEYS:
        out[k] = p[k][:, idx]
    return out


def _stack_outer(t, p):
    """(q_conv, q_emit, q_evap) leaving the outermost surface at ``t`` [W m^-2]."""
    dt_air = t - p["t_air"]
    h_out = _outer_coefficient(p["h"], dt_air, p["natural_floor"])
    q_conv = h_out * dt_air
    q_emit = p["eps"][-1] * STEFAN_BOLTZMANN * _t4(t)
    if p["wet"].any():
        q_evap = fabric_evaporation(t, p["t_air"], p["rh"], h_out, p["wet"], p["evap_limit"])
    else:  # dry: what fabric_evaporation gives (0 W m^-2), without its two vapour pressures
        q_evap = np.zeros_like(t)
    return q_conv, q_emit, q_evap


#: Iterations of the stack's Newton on all layer temperatures before a facet is handed to the
#: shooting solver (:func:`_stack_shoot`); every Table 1 stack converges in <= 6.
_STACK_NEWTON_MAX_ITER = 40
#: [K] forward-difference step of the gap fluxes' and the outer loss's slopes in that Newton
_STACK_NEWTON_DELTA_K = 1e-6
#: [K] largest change of any layer temperature per Newton step (far starts, e.g. hot sun)
_STACK_NEWTON_MAX_STEP_K = 20.0


def _stack_newton(p, tol, max_iter=_STACK_NEWTON_MAX_ITER):
    """Newton on every layer's outer (T_i) and inner (S_i) surface temperature at once, per
    facet of a flat facet axis: (T (n, m), S (n, m), converged (m,), iterations).

    The 2n node balances (Incropera et al. 2007, sec. 3.1 and 5.8, a lumped node network):

    - inner surface of layer i: q_gap,i(W_i, S_i) = k_i / l_i (S_i - T_i), W_0 = T_skin and
      W_i = T_{i-1} (contact, gap 0: S_i = W_i);
    - outer surface of layer i (its capacity node): k_i / l_i (S_i - T_i) = C_i / dt (T_i -
      T_i,prev) + q_leaving,i, q_leaving,i = k_{i+1} / l_{i+1} (S_{i+1} - T_{i+1}) and,
      outermost, h (T - T_air) + eps sigma T^4 + q_evap - q_rad.

    The Jacobian is block tridiagonal (2n <= 8 unknowns per facet: one batched dense solve);
    the gap fluxes' and the outer loss's derivatives are forward / central differences. Unlike
    the shooting from the outermost temperature, whose residual grows by C / dt over the gap
    conductance per layer (3e11 W m^-2 K^-1 for three heavy layers: round-off of the outer
    temperature moved the innermost by 1e-5 K), these balances are as well conditioned as the
    stack itself: they converge quadratically, in 4-6 iterations from the previous step's
    temperatures (a steady state from a line skin -> air), to every node balance within
    (``tol`` + 1e-10 of the largest flux) / 2n (their sum is the stack's residual), or within the
    change 4 ulps of the temperatures make in it (round-off). A step moves no temperature by more than 20 K.
    """
    n = p["n"]
    t_skin, t_air, q_rad = p["t_skin"], p["t_air"], p["q_rad"]
    gap, u, c, prev = p["gap"], p["u"], p["c_dt"], p["t_prev"]
    contact = gap <= 0.0
    f_rad = grey_plates_exchange_factor(np.concatenate([p["eps_s"][None], p["eps"][:-1]]), p["eps"])
    d = np.where(contact, 1.0, gap)
    d3 = d**3
    line = t_skin + (np.arange(1, n + 1) / (n + 1))[:, None] * (t_air - t_skin)
    t = np.where(c > 0.0, prev, line)  # outer surfaces
    s = t.copy()  # inner surfaces
    t_done, s_done = t.copy(), s.copy()
    converged = np.zeros(t_skin.size, dtype=bool)
    idx = np.arange(t_skin.size)
    sub = {k: p[k] for k in ("t_air", "h", "wet", "rh", "evap_limit", "eps")}
    sub["natural_floor"] = p["natural_floor"]
    rows = 2 * n
    delta = _STACK_NEWTON_DELTA_K
    iterations = 0
    while iterations < max_iter:
        iterations += 1
        m = idx.size
        cn, un, cm = contact[:, idx], u[:, idx], c[:, idx]
        w = np.concatenate([t_skin[idx][None], t[:-1]])
        # each gap at (W, S), (W + delta, S), (W, S + delta) in one evaluation
        q_cd, q_r = _air_gap_flux(
            np.stack([w, w + delta, w]),
            np.stack([s, s, s + delta]),
            d[:, idx],
            f_rad[:, idx],
            p["gap_model"],
            d3[:, idx],
        )
        g3 = q_cd + q_r
        g_w, g_s = (g3[1] - g3[0]) / delta, (g3[2] - g3[0]) / delta
        q_fab = un * (s - t)
        # contact: the fabric's inner surface is the warm side (scaled by k / l as a flux)
        bal_in = np.where(cn, un * (w - s), g3[0] - q_fab)
        sub_m = {k: v[..., idx] if isinstance(v, np.ndarray) else v for k, v in sub.items()}
        sub3 = {
            k: np.concatenate([v, v, v], axis=-1) if isinstance(v, np.ndarray) else v
            for k, v in sub_m.items()
        }
        t_n = t[-1]
        q_out3 = sum(_stack_outer(np.concatenate([t_n, t_n + delta, t_n - delta]), sub3))
        q_out = q_out3[:m] - q_rad[idx]
        dq_out = (q_out3[m : 2 * m] - q_out3[2 * m :]) / (2.0 * delta)
        bal_out = q_fab - cm * (t - prev[:, idx]) - np.concatenate([q_fab[1:], q_out[None]])
        residual = np.empty((m, rows))
        residual[:, 0::2], residual[:, 1::2] = bal_in.T, bal_out.T
        jac = np.zeros((m, rows, rows))
        for i in range(n):
            a, b = 2 * i, 2 * i + 1
            jac[:, a, a] = np.where(cn[i], -un[i], g_s[i] - un[i])
            jac[:, a, b] = np.where(cn[i], 0.0, un[i])
            if i > 0:
                jac[:, a, b - 2] = np.where(cn[i], un[i], g_w[i])
            jac[:, b, a] = un[i]
            jac[:, b, b] = -un[i] - cm[i]
            if i < n - 1:
                jac[:, b, a + 2] = -un[i + 1]
                jac[:, b, b + 2] = un[i + 1]
            else:
                jac[:, b, b] -= dq_out
        x = np.empty((m, rows))
        x[:, 0::2], x[:, 1::2] = s.T, t.T
        scale = np.maximum(np.abs(q_fab).max(axis=0), np.abs(q_out))
        # the stack's residual (skin flux - what the stack needs) is the sum of the 2n balances
        floor = (tol + 1e-10 * scale[:, None]) / rows + 4.0 * _EPS * np.abs(jac).sum(axis=2) * np.abs(x)
        done = (np.abs(residual) <= floor).all(axis=1)
        converged[idx[done]] = True
        t_done[:, idx[done]], s_done[:, idx[done]] = t[:, done], s[:, done]
        keep = ~done
        if not keep.any():
            break
        with np.errstate(all="ignore"):
            try:
                step = np.linalg.solve(jac[keep], -residual[keep][..., None])[..., 0]
            except np.linalg.LinAlgError:  # a singular facet: all left to the shooting
                break
        step = np.clip(step, -_STACK_NEWTON_MAX_STEP_K, _STACK_NEWTON_MAX_STEP_K)
        finite = np.isfinite(step).all(axis=1)
        idx = idx[keep][finite]
        s = s[:, keep][:, finite] + step[finite][:, 0::2].T
        t = t[:, keep][:, finite] + step[finite][:, 1::2].T
        if idx.size == 0:
            break
    return t_done, s_done, converged, iterations


def _stack_state(t, s, p):
    """The stack's fluxes at the layer temperatures ``t`` (outer) and ``s`` (inner), (n, m):
    the terms of :func:`_stack_balance`, with each gap's flux carried inward from the outer
    surface (what leaves it plus each layer's storage) and the skin's gap at its own
    temperatures: (residual, extra) as :func:`_stack_balance`."""
    n = p["n"]
    contact = p["gap"] <= 0.0
    # contact surfaces exactly at the warm side's temperature
    s = np.where(contact, np.concatenate([p["t_skin"][None], t[:-1]]), s)
    q_conv, q_emit, q_evap = _stack_outer(t[-1], p)
    q_store = p["c_dt"] * (t - p["t_prev"])
    q_gap = np.empty_like(t)
    q = q_conv + q_emit + q_evap - p["q_rad"]
    for i in range(n - 1, -1, -1):
        q = q + q_store[i]
        q_gap[i] = q
    q_cd, q_r = air_gap_flux(
        p["t_skin"], s[0], np.where(contact[0], 1.0, p["gap"][0]), p["eps_s"], p["eps"][0], p["gap_model"]
    )
    q_in = np.where(contact[0], p["u"][0] * (p["t_skin"] - t[0]), q_cd + q_r)
    return q_in - q_gap[0], (t, s, q_in, q_gap, q_conv, q_emit, q_evap, q_store)


def _stack_shoot(flat, tol, max_iter):
    """Bracketed Newton on the outermost temperature (shooting inward through the layers),
    iterating only on the facets whose residual is still above the tolerance: (outermost
    temperature, iterations). The fallback of :func:`_stack_newton` (it cannot leave its
    bracket, but its residual's slope grows by C / dt over the gap conductance per layer)."""
    lo, hi = _stack_bracket(flat)
    # a time step starts from the layer's previous temperature (a few Newton steps away), a
    # steady state from the middle of the bracket
    t = np.where(flat["c_dt"][-1] > 0.0, np.clip(flat["t_prev"][-1], lo, hi), 0.5 * (lo + hi))
    idx = np.arange(t.size)
    # [K] central-difference step of the slope, per facet: 1e-4 K, then the last step's size
    # (at least 1e-9 K, 1e4 ulps): a stack of three heavy layers is so curved within 1e-4 K of
    # its root (f' changes 2x) that a 1e-4 K chord slope made Newton converge only linearly
    delta = np.full(t.size, 1e-4)
    iterations = 0
    for iterations in range(1, max_iter + 1):
        m = idx.size
        x = t[idx]
        dx = delta[idx]
        # the residual and its central-difference slope in one stack evaluation of 3 m facets
        # (x, x + dx, x - dx; the slope of a facet that converges now goes unused): each
        # facet's arithmetic is the same as in three evaluations, in a third of the calls
        f3, extra = _stack_balance(np.concatenate([x, x + dx, x - dx]), _stack_take(flat, np.tile(idx, 3)))
        f = f3[:m]
        dfdt = (f3[m : 2 * m] - f3[2 * m :]) / (2.0 * dx)
        # the nested gap solves carry round-off of the fluxes through them: a relative floor;
        # and a facet whose Newton step |f / f'| is below the collapsed bracket's width
        # (4 ulps of x, below) is solved to round-off: a stiff stack (a heavy outer layer's
        # storage carried through the gaps, f' ~ 1e7 W m^-2 K^-1) has a residual floor of
        # about 1e-6 W m^-2 at the root, which bisection only closed in on, ulp by ulp
        floor = np.maximum(tol + 1e-10 * np.abs(extra[3][:, :m]).max(axis=0), 4.0 * _EPS * np.abs(x * dfdt))
        active = np.abs(f) > floor
        if not active.any():
            break
        idx, x, f, dfdt = idx[active], x[active], f[active], dfdt[active]
        lo[idx] = np.where(f > 0.0, x, lo[idx])
        hi[idx] = np.where(f < 0.0, x, hi[idx])
        ok = dfdt < 0.0
        t_newton = x - f / np.where(ok, dfdt, -1.0)
        inside = ok & (t_newton > lo[idx]) & (t_newton < hi[idx]) & (iterations <= 40)
        t_next = np.where(inside, t_newton, 0.5 * (lo[idx] + hi[idx]))
        moving = (hi[idx] - lo[idx]) > 4.0 * _EPS * np.abs(x)
        t[idx] = np.where(moving, t_next, x)
        delta[idx] = np.clip(np.abs(t_next - x), 1e-9, 1e-4)
        idx = idx[moving]
        if idx.size == 0:
            break
    return t, iterations


def _stack_solve(p, tol, max_iter):
    """Every layer's temperatures of every facet: Newton on all of them at once
    (:func:`_stack_newton`), the shooting (:func:`_stack_shoot`) for any facet it leaves."""
    shape = p["t_skin"].shape
    n = p["n"]
    flat = dict(p)
    for k in _FACET_KEYS:
        flat[k] = p[k].reshape(-1)
    for k in _LAYER_KEYS:
        flat[k] = p[k].reshape(n, -1)
    t, s, converged, iterations = _stack_newton(flat, tol, min(max_iter, _STACK_NEWTON_MAX_ITER))
    residual, extra = _stack_state(t, s, flat)
    if not converged.all():
        left = np.flatnonzero(~converged)
        sub = _stack_take(flat, left)
        t_left, shot = _stack_shoot(sub, tol, max_iter)
        iterations = max(iterations, shot)
        res_left, extra_left = _stack_balance(t_left, sub)
        residual[left] = res_left
        for whole, part in zip(extra, extra_left):
            whole[..., left] = part
    t_o, t_i, q_in, q_gap, q_conv, q_emit, q_evap, q_store = extra
    layered = (n,) + shape
    return StackBalance(
        t_o.reshape(layered),
        t_i.reshape(layered),
        residual.reshape(shape),
        q_in.reshape(shape),
        q_gap.reshape(layered),
        p["q_rad"].copy(),
        q_conv.reshape(shape),
        q_emit.reshape(shape),
        q_evap.reshape(shape),
        q_store.reshape(layered),
        iterations,
    )


def stack_steady_state(
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gaps_m,
    thicknesses_m,
    conductivities,
    emissivities,
    skin_emissivity=0.98,
    natural_floor=True,
    gap_model="hollands",
    wetted_fraction=0.0,
    relative_humidity=0.5,
    tol=1e-6,
    max_iter=100,
    evaporation_limit=np.inf,
):
    """Steady state of layered garments in series over the skin, per facet.

    Parameters
    ----------
    skin_temperature_k, air_temperature_k : numeric
        Skin and air temperatures [K].
    absorbed_radiation : numeric
        Short + long wave absorbed by the outermost surface [W m^-2].
    h_forced : numeric
        Outer convective coefficient [W m^-2 K^-1].
    air_gaps_m : array_like, (n, ...)
        Air gap under each layer [m]: layer 0's to the skin, layer i's to the outer surface of
        layer i - 1 (not to the skin); 0 is contact.
    thicknesses_m, conductivities, emissivities : array_like, (n, ...) or (n,)
        Fabric thickness [m] (> 0), conductivity [W m^-1 K^-1] (> 0) and long-wave emissivity
        (both sides) [0-1] of each layer.
    skin_emissivity : numeric, default 0.98
    natural_floor, gap_model
        As in :py:func:`steady_state`.
    wetted_fraction, relative_humidity : numeric
        Wetted fraction of the outermost surface [0-1] and air humidity [0-1]
        (:func:`fabric_evaporation`).
    evaporation_limit : numeric, default inf
        Largest evaporation from the outermost surface [W m^-2] (the sweat supply).
    tol, max_iter
        As in :py:func:`steady_state`; the residual tolerance is tol + 1e-10 times the largest
        flux, split over the 2n node balances, or each balance's change over 4 ulps of the
        temperatures (the root to round-off); the shooting fallback's is tol + 1e-10 times the
        largest gap flux (its nested gap solves carry round-off of the fluxes through them),
        or, for a stiff stack, the residual's change over 4 ulps of the outermost temperature.

    Returns
    -------
    StackBalance
        Temperatures of every layer's surfaces, the skin flux, the residual and flux terms.

    Notes
    -----
    In steady state one flux q crosses every element in series (seed Eq. 5-9 extended to
    layers): q = q_gap,0(T_skin, T_in,0) = k_0/l_0 (T_in,0 - T_out,0) = q_gap,1(T_out,0, T_in,1)
    = ... = k_{n-1}/l_{n-1} (T_in,n-1 - T_out,n-1) = h (T_out,n-1 - T_air) + eps sigma
    T_out,n-1^4 + q_evap - q_rad. Each gap is :func:`air_gap_flux` at its own surfaces'
    temperatures and emissivities. With radiation linearised as h_r = F sigma (T1^2 + T2^2)
    (T1 + T2), q = (T_skin - T_env) / (sum of the series resistances 1 / (k/d + h_r) + l / k
    + 1 / (h + h_r,out)), the textbook series-resistance form (Incropera et al. 2007, ch. 3.1).
    Every layer's two surface temperatures are solved together (:func:`_stack_newton`); the
    residual reported is the skin flux minus what the stack passes (the sum of the node
    balances).

    References
    ----------
    .. [1] Incropera, F. P. et al. (2007). Fundamentals of Heat and Mass Transfer, 6th ed.,
       sec. 3.1 (composite walls) and 13.3 (radiation shields between parallel plates).
    .. [2] The seed paper, section 2.2.3, Eq. 5-9.
    """
    gaps = np.asarray(air_gaps_m, dtype=float)
    # the steady state is the implicit step of infinite length (no storage; the previous
    # temperatures, here the air's, then do not enter)
    return stack_transient_step(
        np.broadcast_to(
            np.asarray(air_temperature_k, dtype=float), gaps.shape[:1] + np.shape(air_temperature_k)
        ),
        np.inf,
        0.0,
        skin_temperature_k,
        air_temperature_k,
        absorbed_radiation,
        h_forced,
        gaps,
        thicknesses_m,
        conductivities,
        emissivities,
        skin_emissivity=skin_emissivity,
        natural_floor=natural_floor,
        gap_model=gap_model,
        wetted_fraction=wetted_fraction,
        relative_humidity=relative_humidity,
        tol=tol,
        max_iter=max_iter,
        evaporation_limit=evaporation_limit,
    )


def stack_transient_step(
    previous_temperatures_k,
    time_step_s,
    heat_capacities,
    skin_temperature_k,
    air_temperature_k,
    absorbed_radiation,
    h_forced,
    air_gaps_m,
    thicknesses_m,
    conductivities,
    emissivities,
    skin_emissivity=0.98,
    natural_floor=True,
    gap_model="hollands",
    wetted_fraction=0.0,
    relative_humidity=0.5,
    tol=1e-6,
    max_iter=100,
    evaporation_limit=np.inf,
):
    """One implicit (backward Euler) step of layered garments with each layer's heat capacity.

    Parameters
    ----------
    previous_temperatures_k : array_like, (n, ...)
        Outer-surface temperature of each layer at the start of the step [K].
    time_step_s : numeric
        Time step [s]; ``np.inf`` gives the steady state.
    heat_capacities : array_like, (n, ...) or (n,)
        Areal heat capacity of each layer [J m^-2 K^-1] (:func:`areal_heat_capacity`).
    skin_temperature_k, ..., max_iter
        As in :func:`stack_steady_state`, at the end of the step.

    Returns
    -------
    StackBalance
        State at the end of the step.

    Notes
    -----
    Each layer's capacity C_i is lumped at its outer surface (a node network: skin - gap -
    fabric conductance - capacity node - gap - ...):
    C_i (T_i - T_i,prev) / dt = k_i / l_i (T_in,i - T_i) - q_leaving,i, where q_leaving is the
    gap flux to the next layer or, outermost, h (T - T_air) + eps sigma T^4 + q_evap - q_rad.
    (:func:`transient_step` places the single layer's storage at the gap instead; the two agree
    in contact and differ by the fabric's Biot number otherwise.) The storage terms grow with
    the outermost temperature, so the residual stays strictly decreasing and each step is
    unconditionally stable (backward Euler, Hairer & Wanner 1996).
    """
    dt = require("time_step_s", time_step_s, 1e-9, np.inf, allow_inf=True)
    c_dt = require("heat_capacities", heat_capacities, 0.0, 1e7) / dt
    p = _stack_parameters(
        skin_temperature_k,
        air_temperature_k,
        absorbed_radiation,
        h_forced,
        air_gaps_m,
        thicknesses_m,
        conductivities,
        emissivities,
        skin_emissivity,
        natural_floor,
        gap_model,
        wetted_fraction,
        relative_humidity,
        c_dt,
        previous_temperatures_k,
        evaporation_limit,
    )
    return _stack_solve(p, tol, max_iter)


#: Insulation of the air boundary layer of a nude standing manikin [m^2 K W^-1] (0.7 clo,
#: ISO 9920:2007 sec. 5; 1 clo = 0.155 m^2 K W^-1).
NUDE_BOUNDARY_INSULATION = 0.7 * 0.155


def intrinsic_insulation(
    air_gap_m, thickness_m, conductivity, fabric_emissivity=0.9, skin_emissivity=0.98, temperature_k=306.0
):
    """Local intrinsic insulation of one garment layer over the skin [m^2 K W^-1].

    Parameters
    ----------
    air_gap_m : numeric
        Skin-fabric air gap [m] (still air; 0 is contact).
    thickness_m, conductivity : numeric
        Fabric thickness [m] and effective conductivity [W m^-1 K^-1].
    fabric_emissivity, skin_emissivity : numeric
        Emissivities of the facing surfaces [0-1].
    temperature_k : float, default 306
        Temperature at which the gap's radiation is linearised [K].

    Returns
    -------
    numeric
        R = 1 / (k_air / d + 4 F sigma T^3) + l / k (gap conduction and grey-plate radiation in
        parallel, in series with the fabric), the steady state of :func:`steady_state` for small
        temperature differences.
    """
    d = np.asarray(air_gap_m, dtype=float)
    h_r = (
        4.0
        * grey_plates_exchange_factor(skin_emissivity, fabric_emissivity)
        * STEFAN_BOLTZMANN
        * temperature_k**3
    )
    h_gap = np.where(d > 0.0, air_conductivity(temperature_k) / np.where(d > 0.0, d, 1.0) + h_r, np.inf)
    return 1.0 / h_gap + np.asarray(thickness_m, dtype=float) / np.asarray(conductivity, dtype=float)


def garment_insulation(
    covered_fraction, local_insulation, method="parallel", boundary=NUDE_BOUNDARY_INSULATION
):
    """Whole-body effective insulation of one garment, I_clu [m^2 K W^-1].

    Parameters
    ----------
    covered_fraction : numeric
        Fraction of the body surface the garment covers [0-1].
    local_insulation : numeric
        Its intrinsic insulation where it covers [m^2 K W^-1] (:func:`intrinsic_insulation`).
    method : str, default 'parallel'
        'parallel': heat flows through covered and bare skin side by side,
        I_T = 1 / (f / (R + I_a) + (1 - f) / I_a); 'serial': area-weighted resistance,
        I_T = I_a + f R.
    boundary : numeric
        Boundary-layer insulation I_a of the nude body [m^2 K W^-1].

    Returns
    -------
    numeric
        I_clu = I_T - I_a [m^2 K W^-1] (divide by 0.155 for clo).

    Notes
    -----
    Manikin standards compute total insulation by either method (ISO 15831:2004 allows both;
    ISO 9920 tables mix them); the serial value is the larger, by up to 2x for garments that
    cover part of the body, so a measured garment value is expected between the two
    (Kuklane, Gao, Holmér et al. 2007).

    References
    ----------
    .. [1] Kuklane, K., Gao, C., Holmér, I. et al. (2007). Calculation of clothing insulation by
       serial and parallel methods: effects on clothing choice by IREQ and thermal responses in
       the cold. Int. J. Occup. Saf. Ergon. 13(2), 103-116.
    .. [2] ISO 9920:2007 Ergonomics of the thermal environment - Estimation of thermal
       insulation and water vapour resistance of a clothing ensemble.

    Raises
    ------
    ValueError
        If ``method`` is not 'parallel' or 'serial'.
    """
    f = np.asarray(covered_fraction, dtype=float)
    r = np.asarray(local_insulation, dtype=float)
    if method == "parallel":
        return 1.0 / (f / (r + boundary) + (1.0 - f) / boundary) - boundary
    if method == "serial":
        return f * r
    raise ValueError(f"invalid model selection {method}")


def extreme_grid_counts(skin_temperature_k=306.15, fabric_emissivity=0.9, solar_absorptance=0.7):
    """Solve the garment balance over the DESIGN.md extreme grid and count what went wrong.

    Parameters
    ----------
    skin_temperature_k : float, default 306.15
        Skin temperature for every case [K].
    fabric_emissivity : float, default 0.9
        Outer fabric emissivity (also its long-wave absorptance) [0-1].
    solar_absorptance : float, default 0.7
        Fabric solar absorptance [0-1].

    Returns
    -------
    dict
        ``cases`` (steady facets + transient facet-steps), ``steady_cases``,
        ``transient_cases``, ``nonfinite`` (NaN/Inf in any temperature or flux),
        ``max_residual`` [W m^-2], ``monotonic_air_violations`` (warmer air gave a colder
        garment), ``monotonic_wind_violations`` (more wind moved the garment away from the
        air temperature), ``max_iterations``; monotonicity is checked to 1e-6 K.

    Notes
    -----
    Grid: air -40, -10, 10, 30, 55 degC; wind 0, 0.5, 2, 8, 30 m/s (Mitchell h with the ISO 7730
    floor); absorbed sun 0, 300, 1200 W m^-2 (times ``solar_absorptance``, plus eps sigma T_sky^4
    of a Berdahl-Martin clear sky at RH 50 %); air gap 0, 1, 5, 20, 50 mm; fabric 0.1, 1, 10 mm;
    transient steps 1 s, 60 s, 600 s from 20 K below and above the air temperature.
    """
    t_air = 273.15 + np.array([-40.0, -10.0, 10.0, 30.0, 55.0])
    wind = np.array([0.0, 0.5, 2.0, 8.0, 30.0])
    sun = np.array([0.0, 300.0, 1200.0])
    gap = np.array([0.0, 1e-3, 5e-3, 20e-3, 50e-3])
    fabric = np.array([0.1e-3, 1e-3, 10e-3])
    ta, v, g, d, l = np.meshgrid(t_air, wind, sun, gap, fabric, indexing="ij")
    t_sky, _ = effective_sky_temperature(ta, 0.5)
    q_rad = solar_absorptance * g + fabric_emissivity * STEFAN_BOLTZMANN * t_sky**4
    h = mitchell(v)
    common = dict(
        skin_temperature_k=skin_temperature_k,
        air_temperature_k=ta,
        absorbed_radiation=q_rad,
        h_forced=h,
        air_gap_m=d,
        fabric_thickness_m=l,
        fabric_emissivity=fabric_emissivity,
    )
    with np.errstate(all="ignore"):
        st = steady_state(**common)
        results = [st]
        n_transient = 0
        for dt_step in (1.0, 60.0, 600.0):
            for offset in (-20.0, 20.0):
                tr = transient_step(ta + offset, dt_step, areal_heat_capacity(300.0, 1300.0, l), **common)
                results.append(tr)
                n_transient += tr.outer_temperature_k.size
    nonfinite = 0
    max_res = 0.0
    max_it = 0
    for r in results:
        fields = [np.asarray(x) for name, x in zip(r._fields, r) if name != "iterations"]
        bad = np.zeros(r.outer_temperature_k.shape, dtype=bool)
        for x in fields:
            bad |= ~np.isfinite(x)
        nonfinite += int(bad.sum())
        max_res = max(max_res, float(np.nanmax(np.abs(r.residual))))
        max_it = max(max_it, int(r.iterations))
    t_out = st.outer_temperature_k
    # 1 uK slack: where the natural floor dominates, neighbouring cases are the same problem
    # and differ only by the solver tolerance (about 1e-8 K)
    air_viol = int((np.diff(t_out, axis=0) < -1e-6).sum())
    dist = np.abs(t_out - ta)
    wind_viol = int((np.diff(dist, axis=1) > 1e-6).sum())
    return dict(
        cases=int(t_out.size + n_transient),
        steady_cases=int(t_out.size),
        transient_cases=int(n_transient),
        nonfinite=nonfinite,
        max_residual=max_res,
        monotonic_air_violations=air_viol,
        monotonic_wind_violations=wind_viol,
        max_iterations=max_it,
    )
