"""Snow cover (issue 30.4): its solar spectrum from the ice's optical constants and the grain
size, its heat conduction, and a snow layer on a ground slab that melts at 0 degC.

Optics. Snow is a dense packing of ice grains: in the visible ice barely absorbs (imaginary
index k ~ 1e-9) and snow reflects 0.96-0.99; from 0.8 um ice absorbs more and more, with
bands at 1.03, 1.25, 1.5 and 2.0 um, so the near-infrared albedo falls with grain size (light
travels farther through ice in bigger grains) while the visible hardly changes (Wiscombe &
Warren 1980; Warren 1982). :func:`spherical_albedo` is the closed form of the asymptotic
radiative transfer theory (Kokhanovsky & Zege 2004) for a semi-infinite snowpack,
r = exp(-sqrt(alpha)), alpha = 16 B gamma d / (9 (1 - g)), gamma = 4 pi k / lambda, with the
ice's k from Warren & Brandt (2008) (:data:`ICE_ABSORPTION_INDEX`) and the optical diameter d
= 6 / (rho_ice SSA). It agrees with Mie + discrete-ordinate computations within a few percent
where gamma d << 1 (lambda < ~1.4 um for d < 1 mm); in the strong bands (1.5, 2.0, >= 2.7 um)
it goes to 0 and the snow reflects only at grain surfaces (:data:`SURFACE_REFLECTANCE`).

Heat. The effective conductivity of snow grows with its density (Sturm et al. 1997,
:func:`effective_conductivity`); its heat capacity is the ice's (the air's is < 0.1 %).
:func:`simulate_cover` puts a snow layer of a given depth on top of a ground slab
(:mod:`humv_usd.physics.slab`) and steps both with the slab's implicit scheme; the snow cannot
warm above 0 degC: the surplus of the surface balance (and the heat of any snow node that
would rise above 0 degC) melts snow, latent heat of fusion :data:`LATENT_HEAT_OF_FUSION`,
so a sunlit snow surface under air above 0 degC stays at 0 degC while its water equivalent
falls. Where it is all melted the face goes on as the bare ground slab, starting from the
temperatures the ground had under the snow.

Simplifications (stated where they matter): the layer keeps its initial thickness for heat
conduction until it melts out (its water equivalent is tracked, its depth is not re-meshed);
melt water drains (no refreezing, no wet snow); no sublimation, no compaction, no new snow;
the bare ground after melt-out is dry.

References
----------
.. [1] Warren, S. G. & Brandt, R. E. (2008). Optical constants of ice from the ultraviolet to
   the microwave: a revised compilation. J. Geophys. Res. 113:D14220.
.. [2] Kokhanovsky, A. A. & Zege, E. P. (2004). Scattering optics of snow. Appl. Opt.
   43:1589-1602.
.. [3] Libois, Q. et al. (2013). Influence of grain shape on light penetration in snow. The
   Cryosphere 7:1803-1818 (B = 1.6, g = 0.845 for natural snow; with Picard et al. 2009).
.. [4] Wiscombe, W. J. & Warren, S. G. (1980). A model for the spectral albedo of snow. I: Pure
   snow. J. Atmos. Sci. 37:2712-2733.
.. [5] Warren, S. G. (1982). Optical properties of snow. Rev. Geophys. 20:67-89.
.. [6] Sturm, M., Holmgren, J., Koenig, M. & Morris, K. (1997). The thermal conductivity of
   seasonal snow. J. Glaciol. 43:26-41 (eq. 4).
.. [7] Feistel, R. & Wagner, W. (2006). A new equation of state for H2O ice Ih. J. Phys. Chem.
   Ref. Data 35:1021-1047 (c_p = 2097 J kg^-1 K^-1 and rho = 916.7 kg m^-3 at 273.15 K).
.. [8] Anderson, E. A. (1976). A point energy and mass balance model of a snow cover. NOAA
   Technical Report NWS 19 (melt from the surplus of the surface energy balance at 0 degC).
.. [9] Warren, S. G., Brandt, R. E. & Grenfell, T. C. (2006). Visible and near-ultraviolet
   absorption spectrum of ice from transmission of solar radiation into snow. Appl. Opt.
   45:5320-5334.
.. [10] Rogers, R. R. & Yau, M. K. (1989). A Short Course in Cloud Physics, 3rd ed., Table 2.1
   (latent heat of fusion 3.34e5 J kg^-1 at 0 degC).
"""

from __future__ import annotations

import numpy as np

from humv_usd.physics import slab
from humv_usd.physics.checks import require

#: melting point of ice at 1 atm [K]
MELT_TEMPERATURE_K = 273.15
#: latent heat of fusion of ice at 0 degC [J kg^-1] (Rogers & Yau 1989, Table 2.1)
LATENT_HEAT_OF_FUSION = 3.34e5
#: density of ice at 0 degC [kg m^-3] (Feistel & Wagner 2006)
ICE_DENSITY = 916.7
#: specific heat of ice at 0 degC [J kg^-1 K^-1] (Feistel & Wagner 2006)
ICE_SPECIFIC_HEAT = 2097.0
#: absorption enhancement B and asymmetry g of natural snow grains (Libois et al. 2013)
GRAIN_B, GRAIN_G = 1.6, 0.845
#: reflectance of snow where ice is opaque (the strong 1.5, 2.0 and >= 2.7 um bands): the
#: grains' surface reflection only, a Fresnel reflectance of ice (n 1.2-1.4) [0-1]. An
#: estimate consistent with snow's 8-14 um emissivity of 0.98-0.99 (Dozier & Warren 1982).
SURFACE_REFLECTANCE = 0.01

#: Imaginary refractive index k of ice at -7 degC, Warren & Brandt (2008), their tabulated
#: values at these wavelengths [um] (0.40-2.50 um; the 1.03, 1.27, 1.5 and 2.0 um bands and the
#: 1.1, 1.8 and 2.25 um windows between them), interpolated in log k
ICE_ABSORPTION_INDEX = (
    (0.40, 2.365e-11),
    (0.45, 9.239e-11),
    (0.50, 5.889e-10),
    (0.55, 2.289e-9),
    (0.60, 5.730e-9),
    (0.65, 1.430e-8),
    (0.70, 2.900e-8),
    (0.75, 5.870e-8),
    (0.80, 1.340e-7),
    (0.85, 1.830e-7),
    (0.90, 4.200e-7),
    (0.95, 6.020e-7),
    (1.00, 1.620e-6),
    (1.03, 2.330e-6),
    (1.10, 1.700e-6),
    (1.15, 2.290e-6),
    (1.20, 6.710e-6),
    (1.27, 1.350e-5),
    (1.30, 1.320e-5),
    (1.40, 1.980e-5),
    (1.449, 2.030e-4),
    (1.493, 5.532e-4),
    (1.563, 3.858e-4),
    (1.65, 2.361e-4),
    (1.73, 1.650e-4),
    (1.83, 1.302e-4),
    (1.89, 2.566e-4),
    (1.942, 1.108e-3),
    (2.00, 1.640e-3),
    (2.105, 7.586e-4),
    (2.20, 2.550e-4),
    (2.245, 2.026e-4),
    (2.30, 2.838e-4),
    (2.41, 5.956e-4),
    (2.50, 7.530e-4),
)


def ice_absorption_index(wavelength_um):
    """Imaginary refractive index k of ice [-] (Warren & Brandt 2008, :data:`ICE_ABSORPTION_INDEX`).

    Parameters
    ----------
    wavelength_um : numeric
        Wavelength [um], 0.40-2.50 (held at the end values outside).

    Returns
    -------
    numeric
        k, interpolated linearly in log k between the tabulated wavelengths.
    """
    wl, k = np.asarray(ICE_ABSORPTION_INDEX).T
    return np.exp(np.interp(np.asarray(wavelength_um, dtype=float), wl, np.log(k)))


def optical_diameter_m(specific_surface_area_m2_kg):
    """Optical grain diameter d = 6 / (rho_ice SSA) [m] of snow with the specific surface area
    SSA [m^2 kg^-1] (the diameter of ice spheres with the same surface per mass;
    Kokhanovsky & Zege 2004). Fresh snow 40-150 m^2/kg (d 0.04-0.16 mm), aged snow 10-30."""
    return 6.0 / (ICE_DENSITY * np.asarray(specific_surface_area_m2_kg, dtype=float))


def spherical_albedo(wavelength_um, grain_diameter_m, b=GRAIN_B, g=GRAIN_G):
    """Spherical (white-sky, diffuse) albedo of a deep, clean snowpack [0-1].

    Parameters
    ----------
    wavelength_um : numeric
        Wavelength [um], 0.40-2.50.
    grain_diameter_m : numeric
        Optical grain diameter d [m] (:func:`optical_diameter_m`).
    b, g : float
        Absorption enhancement and asymmetry of the grains (:data:`GRAIN_B`, :data:`GRAIN_G`).

    Returns
    -------
    numeric
        r = max(exp(-sqrt(16 B gamma d / (9 (1 - g)))), :data:`SURFACE_REFLECTANCE`) with
        gamma = 4 pi k(lambda) / lambda the ice's absorption coefficient [m^-1].

    Notes
    -----
    Kokhanovsky & Zege (2004): r = exp(-4 sqrt(beta / (3 (1 - g)))) with the co-albedo of single
    scattering beta = B gamma d / 3 for large weakly absorbing grains. Valid for gamma d << 1
    and a snowpack optically semi-infinite (> ~10 cm in the visible, less in the infrared);
    the diffuse albedo is the albedo at a solar zenith angle of about 50 degrees.
    """
    wl = np.asarray(wavelength_um, dtype=float)
    gamma = 4.0 * np.pi * ice_absorption_index(wl) / (wl * 1e-6)
    alpha = 16.0 * b * gamma * np.asarray(grain_diameter_m, dtype=float) / (9.0 * (1.0 - g))
    return np.maximum(np.exp(-np.sqrt(alpha)), SURFACE_REFLECTANCE)


def extinction_coefficient(wavelength_um, grain_diameter_m, density_kg_m3, b=GRAIN_B, g=GRAIN_G):
    """Asymptotic flux extinction coefficient k_e of snow [m^-1] (Kokhanovsky & Zege 2004):
    light decays as exp(-k_e z) with depth, k_e = sigma_ext sqrt(3 beta (1 - g)), sigma_ext =
    3 rho / (rho_ice d) (grains much larger than the wavelength, extinction efficiency 2),
    beta = B gamma d / 3 the co-albedo of :func:`spherical_albedo`. In the visible 1 / k_e is
    10-30 cm (Warren et al. 2006 measured e-folding depths of 10-20 cm at 0.4-0.6 um in fine
    Antarctic snow); beyond 1 um a few mm."""
    wl = np.asarray(wavelength_um, dtype=float)
    d = np.asarray(grain_diameter_m, dtype=float)
    gamma = 4.0 * np.pi * ice_absorption_index(wl) / (wl * 1e-6)
    sigma = 3.0 * np.asarray(density_kg_m3, dtype=float) / (ICE_DENSITY * d)
    return sigma * np.sqrt(3.0 * (b * gamma * d / 3.0) * (1.0 - g))


def layer_albedo(reflectance_deep, extinction_per_m, depth_m, ground_reflectance):
    """Albedo of a snow layer ``depth_m`` deep over a Lambertian ground (two-flux theory).

    Parameters
    ----------
    reflectance_deep : numeric
        Albedo of the same snow infinitely deep, R_inf (:func:`spherical_albedo`).
    extinction_per_m : numeric
        Its asymptotic extinction coefficient k_e [m^-1] (:func:`extinction_coefficient`).
    depth_m : numeric
        Snow depth h [m].
    ground_reflectance : numeric
        Reflectance of the ground under it, R_g [0-1].

    Returns
    -------
    numeric
        R = (1 - R_g (a - b coth(k_e h))) / (a - R_g + b coth(k_e h)), a = (1 + R_inf^2) /
        (2 R_inf), b = (1 - R_inf^2) / (2 R_inf): R_g at h = 0, R_inf for h >> 1 / k_e.

    Notes
    -----
    Kubelka's (1948) solution of the two-flux equations for a layer over a background, written
    with the layer's own R_inf = a - b and its flux extinction k_e = b S (S, K the two-flux
    scattering and absorption coefficients, k_e = sqrt(K (K + 2 S))). With R_inf and k_e of the
    asymptotic theory it gives the visible darkening of shallow snow over dark ground
    (Wiscombe & Warren 1980, section 5: snow thinner than a few centimetres of water
    equivalent is not semi-infinite in the visible).

    References
    ----------
    .. [1] Kubelka, P. (1948). New contributions to the optics of intensely light-scattering
       materials. Part I. J. Opt. Soc. Am. 38:448-457.
    """
    r = np.clip(np.asarray(reflectance_deep, dtype=float), 1e-6, 1.0 - 1e-9)
    a, b = (1.0 + r**2) / (2.0 * r), (1.0 - r**2) / (2.0 * r)
    x = np.asarray(extinction_per_m, dtype=float) * np.asarray(depth_m, dtype=float)
    coth = 1.0 / np.tanh(np.maximum(x, 1e-12))
    rg = np.asarray(ground_reflectance, dtype=float)
    return (1.0 - rg * (a - b * coth)) / (a - rg + b * coth)


def effective_conductivity(density_kg_m3):
    """Effective thermal conductivity of seasonal snow [W m^-1 K^-1] (Sturm et al. 1997, eq. 4).

    Parameters
    ----------
    density_kg_m3 : numeric
        Snow density [kg m^-3], 100-600 (the regression's data: 0.1-0.6 g/cm^3).

    Returns
    -------
    numeric
        k = 0.138 - 1.01 rho + 3.233 rho^2 for 0.156 <= rho <= 0.6 g/cm^3, k = 0.023 + 0.234 rho
        below (rho in g/cm^3): 0.06 W/(m K) at 150 kg/m^3, 0.09 at 250, 0.18 at 350.
    """
    rho = np.asarray(density_kg_m3, dtype=float) / 1000.0
    return np.where(rho < 0.156, 0.023 + 0.234 * rho, 0.138 - 1.01 * rho + 3.233 * rho**2)


def layers(depth_m: float, max_layer_m: float = 0.02) -> np.ndarray:
    """Layer thicknesses [m] of a snow layer ``depth_m`` deep: at least 3, at most 25."""
    n = int(np.clip(np.ceil(depth_m / max_layer_m), 3, 25))
    return np.full(n, depth_m / n)


#: :func:`humv_usd.physics.slab.step_many`'s forcing arguments
FORCING = ("absorbed_solar", "sky_longwave", "air_temperature_k", "h_conv")


def simulate_cover(
    forcing_times_s,
    absorbed_solar_snow,
    absorbed_solar_bare,
    sky_longwave,
    air_temperature_k,
    h_conv,
    snow_depth_m,
    snow_density_kg_m3,
    ground_thickness_m,
    ground_conductivity,
    ground_volumetric_heat_capacity,
    emissivity_snow=0.985,
    emissivity_bare=0.95,
    bottom="fixed",
    deep_temperature_k=None,
):
    """Surface temperature and snow water equivalent of F ground slabs under melting snow.

    Parameters
    ----------
    forcing_times_s : array (M,)
        Increasing sample times [s]; the state starts at the first, in equilibrium with the
        time-mean forcing (the snow held at or below 0 degC), with the full snow cover.
    absorbed_solar_snow, absorbed_solar_bare : array (M, F) or broadcastable
        Absorbed short wave [W m^-2] with the snow's and with the bare ground's absorptivity.
    sky_longwave, air_temperature_k, h_conv : array (M, F) or broadcastable
        Incident long wave [W m^-2], air temperature [K], convective coefficient
        [W m^-2 K^-1] (as :func:`humv_usd.physics.slab.step_many`).
    snow_depth_m : float
        Snow depth at the first sample [m], 0.001-10 (ValueError outside).
    snow_density_kg_m3 : float
        Snow density [kg m^-3], 30-916.7 (ValueError outside): conductivity :func:`effective_conductivity`, heat capacity
        rho c_ice, water equivalent rho x depth.
    ground_thickness_m, ground_conductivity, ground_volumetric_heat_capacity : array (N,)
        The bare ground's slab layers (:func:`humv_usd.physics.slab.step_many`).
    emissivity_snow, emissivity_bare : float
        Long-wave emissivities.
    bottom, deep_temperature_k
        As in :func:`humv_usd.physics.slab.step_many` ('fixed': the bottom held).

    Returns
    -------
    tuple
        (surface temperature (M, F) [K], max |surface residual| of the steps not melting
        [W m^-2], snow water equivalent (M, F) [kg m^-2]; 0 where melted out).

    Notes
    -----
    Each step is the slab's backward-Euler step (:func:`humv_usd.physics.slab.step_many`) of
    the column snow over ground, the surface capped at :data:`MELT_TEMPERATURE_K`; the
    surplus Q_m of the capped surface node's balance and the heat C_i (T_i - T_m) of any
    snow node above T_m melt dW = -(Q_m + sum C_i (T_i - T_m) / dt) dt / L_f of the water
    equivalent W (Anderson 1976's melt term in an implicit column). A face whose W reaches 0
    continues as the bare ground slab from its ground nodes' temperatures.
    """
    require("snow_depth_m", snow_depth_m, 1e-3, 10.0)
    require("snow_density_kg_m3", snow_density_kg_m3, 30.0, ICE_DENSITY)
    times = np.asarray(forcing_times_s, dtype=float)
    m = times.size

    def as_2d(v):
        v = np.asarray(v, dtype=float)
        return v.reshape(-1, 1) if v.ndim == 1 else v

    forcing = [
        as_2d(v) for v in (absorbed_solar_snow, absorbed_solar_bare, sky_longwave, air_temperature_k, h_conv)
    ]
    shape = np.broadcast_shapes(*[f.shape for f in forcing], (m, 1))
    a_snow, a_bare, l_in, t_air, h = (np.broadcast_to(f, shape) for f in forcing)
    nf = shape[1]
    dz_s = layers(float(snow_depth_m))
    ns = dz_s.size
    dz_g = np.asarray(ground_thickness_m, dtype=float)
    k_g = np.broadcast_to(np.asarray(ground_conductivity, dtype=float), dz_g.shape)
    rc_g = np.broadcast_to(np.asarray(ground_volumetric_heat_capacity, dtype=float), dz_g.shape)
    dz = np.concatenate([dz_s, dz_g])
    k = np.concatenate([np.full(ns, float(effective_conductivity(snow_density_kg_m3))), k_g])
    rc = np.concatenate([np.full(ns, snow_density_kg_m3 * ICE_SPECIFIC_HEAT), rc_g])
    cap = slab._operators(dz, k, rc)[1]  # node heat capacities [J m^-2 K^-1]
    snow_kw = dict(
        layer_thickness_m=dz,
        conductivity=k,
        volumetric_heat_capacity=rc,
        emissivity=emissivity_snow,
        bottom=bottom,
        deep_temperature_k=deep_temperature_k,
        melt_temperature_k=MELT_TEMPERATURE_K,
    )
    bare_kw = dict(
        layer_thickness_m=dz_g,
        conductivity=k_g,
        volumetric_heat_capacity=rc_g,
        emissivity=emissivity_bare,
        bottom=bottom,
        deep_temperature_k=deep_temperature_k,
    )
    mean = [f.mean(axis=0) for f in (a_snow, l_in, t_air, h)]
    start = np.broadcast_to(mean[2][:, None], (nf, dz.size + 1))
    t_snow, _ = slab.step_many(start, np.inf, **dict(zip(FORCING, mean)), **snow_kw)
    t_snow[:, : ns + 1] = np.minimum(t_snow[:, : ns + 1], MELT_TEMPERATURE_K)
    t_bare = np.zeros((nf, dz_g.size + 1))
    swe = np.full(nf, float(snow_depth_m) * float(snow_density_kg_m3))
    covered = np.ones(nf, dtype=bool)
    out, swe_out = np.empty((m, nf)), np.empty((m, nf))
    out[0], swe_out[0] = t_snow[:, 0], swe
    max_res = 0.0
    for i in range(1, m):
        dt = times[i] - times[i - 1]
        c, b = np.flatnonzero(covered), np.flatnonzero(~covered)
        if b.size:
            now = (a_bare[i, b], l_in[i, b], t_air[i, b], h[i, b])
            t_b, res = slab.step_many(t_bare[b], dt, **dict(zip(FORCING, now)), **bare_kw)
            t_bare[b] = t_b
            out[i, b] = t_b[:, 0]
            max_res = max(max_res, float(np.max(np.abs(res))))
        if c.size:
            now = (a_snow[i, c], l_in[i, c], t_air[i, c], h[i, c])
            t_c, res, melt = slab.step_many(
                t_snow[c], dt, **dict(zip(FORCING, now)), **snow_kw, return_melt_flux=True
            )
            over = np.maximum(t_c[:, 1 : ns + 1] - MELT_TEMPERATURE_K, 0.0)
            melt = melt + over @ cap[1 : ns + 1] / dt
            t_c[:, 1 : ns + 1] -= over
            t_snow[c] = t_c
            out[i, c] = t_c[:, 0]
            max_res = max(max_res, float(np.max(np.abs(res))))
            swe[c] -= melt * dt / LATENT_HEAT_OF_FUSION
            gone = c[swe[c] <= 0.0]
            swe[gone] = 0.0
            covered[gone] = False
            t_bare[gone] = t_snow[gone, ns:]
        swe_out[i] = swe
    return out, max_res, swe_out
