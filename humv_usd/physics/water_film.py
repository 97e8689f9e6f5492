"""Wet surfaces: the optics of liquid water and of a water film over a diffuse substrate.

A rained-on surface is part dry, part under a film (issue 30.4). Its reflectance is mixed by
the wet share ``delta`` of :func:`humv_usd.physics.evaporation.wet_fraction`:

    R = (1 - delta) R_dry + delta R_film(R_dry, d),

and, being opaque, its emissivity is 1 - R (Kirchhoff), so a wet surface's emissivity moves
from the dry value towards that of water.

Film over a diffuse substrate (:func:`film_reflectance`), as the directional-hemispherical
reflectance at normal incidence (the convention of the library's spectra, e.g. ECOSTRESS):
the interface reflects R_n (Fresnel at normal incidence), the rest enters the film and crosses
it straight down (transmittance t_0 = exp(-alpha d), alpha = 4 pi k / lambda), is reflected
diffusely by the substrate (albedo A, taken as the dry reflectance) and crosses the film as
diffuse light (t = 2 E_3(alpha d)) to meet the interface from inside, where r_i = 1 - (1 - r_e)
/ n^2 of it (r_e the interface's reflectance for diffuse light from outside) is reflected back
down: total internal reflection of the diffuse light beyond the critical angle. Summing the
bounces,

    R_film = R_n + (1 - R_n) t_0 A t (1 - r_i) / (1 - r_i A t^2).

With t_0 = t = 1 this is Lekner & Dorf's (1988) "why some things are darker when wet" (after
Angstrom 1925): a wet concrete of albedo 0.28 falls to about 0.19 in the visible. The film's own
absorption makes a film of a tenth of a millimetre optically thick beyond 2.7 um: in the
thermal infrared a wet surface emits and reflects like water (emissivity 1 - R_n, 0.98-0.99 at
8-12 um, Masuda et al. 1988 at nadir); in the visible it darkens (Twomey, Bohren & Mergenthaler
1986 measured the same darkening).

Film thickness: with the Deardorff wet share delta = (W / W_max)^(2/3), the water W [kg m^-2 =
mm] lies on the wet share as a film of d = W / delta = W_max delta^(1/2) [mm]
(:func:`film_thickness_mm`).

Liquid water's complex refractive index n + ik: Hale & Querry (1973), Table 1, read at the nodes
of :data:`WATER_OPTICAL_CONSTANTS` (interpolated: n linearly, k log-linearly). Fresnel
reflectance of an absorbing medium for unpolarized light: Born & Wolf, Principles of Optics,
7th ed., sec. 14.2 (the complex-angle form of :func:`fresnel_reflectance`).

References
----------
.. [1] Hale, G. M. & Querry, M. R. (1973). Optical constants of water in the 200-nm to 200-um
   wavelength region. Appl. Opt. 12:555-563.
.. [2] Lekner, J. & Dorf, M. C. (1988). Why some things are darker when wet. Appl. Opt.
   27:1278-1280.
.. [3] Angstrom, A. (1925). The albedo of various surfaces of ground. Geogr. Ann. 7:323-342.
.. [4] Twomey, S. A., Bohren, C. F. & Mergenthaler, J. L. (1986). Reflectance and albedo
   differences between wet and dry surfaces. Appl. Opt. 25:431-437.
.. [6] Masuda, K., Takashima, T. & Takayama, Y. (1988). Emissivity of pure and sea waters for
   the model sea surface in the infrared window regions. Remote Sens. Environ. 24:313-329.
.. [5] Siegel, R. & Howell, J. R. (2002). Thermal Radiation Heat Transfer, 4th ed., sec. 13.5
   (diffuse transmittance of an absorbing layer, 2 E_3(kappa d)).
"""

from __future__ import annotations

import numpy as np
from scipy.special import expn

#: Liquid water at 25 degC: wavelength [um], real index n, extinction coefficient k (Hale &
#: Querry 1973, Table 1; rounded readings at these nodes).
WATER_OPTICAL_CONSTANTS = np.array(
    [
        (0.40, 1.339, 1.86e-9),
        (0.45, 1.337, 1.02e-9),
        (0.50, 1.335, 1.00e-9),
        (0.55, 1.333, 1.96e-9),
        (0.60, 1.332, 1.09e-8),
        (0.65, 1.331, 1.64e-8),
        (0.70, 1.331, 3.35e-8),
        (0.80, 1.329, 1.25e-7),
        (0.90, 1.328, 4.86e-7),
        (1.00, 1.327, 2.89e-6),
        (1.20, 1.324, 9.89e-6),
        (1.45, 1.321, 2.90e-4),
        (1.65, 1.317, 6.00e-5),
        (1.94, 1.312, 1.76e-3),
        (2.20, 1.296, 2.89e-4),
        (2.50, 1.261, 1.74e-3),
        (2.80, 1.142, 0.115),
        (3.00, 1.371, 0.272),
        (3.50, 1.400, 0.0094),
        (4.00, 1.351, 0.0046),
        (4.50, 1.332, 0.0134),
        (5.00, 1.325, 0.0124),
        (6.00, 1.265, 0.107),
        (6.50, 1.320, 0.0392),
        (7.00, 1.317, 0.0320),
        (8.00, 1.291, 0.0343),
        (9.00, 1.262, 0.0399),
        (10.00, 1.218, 0.0508),
        (11.00, 1.153, 0.0968),
        (12.00, 1.111, 0.199),
        (13.00, 1.146, 0.305),
        (14.00, 1.210, 0.370),
    ]
)


def water_refractive_index(wavelength_um):
    """Complex refractive index n + ik of liquid water at wavelengths [um] (0.4-14; Hale &
    Querry 1973; n linear, k log-linear between the nodes of :data:`WATER_OPTICAL_CONSTANTS`)."""
    w = np.asarray(wavelength_um, dtype=float)
    t = WATER_OPTICAL_CONSTANTS
    n = np.interp(w, t[:, 0], t[:, 1])
    k = np.exp(np.interp(w, t[:, 0], np.log(t[:, 2])))
    return n + 1j * k


def water_absorption_coefficient(wavelength_um):
    """Absorption coefficient alpha = 4 pi k / lambda of liquid water [m^-1]."""
    w = np.asarray(wavelength_um, dtype=float)
    return 4.0 * np.pi * np.imag(water_refractive_index(w)) / (w * 1e-6)


def fresnel_reflectance(cos_incidence, refractive_index):
    """Unpolarized Fresnel reflectance [0-1] of a flat interface from a medium of index 1 into
    one of complex index ``refractive_index`` (n + ik) at incidence cosines ``cos_incidence``
    (Born & Wolf 1999, sec. 14.2: Snell's law with a complex angle). Broadcasts."""
    c = np.clip(np.asarray(cos_incidence, dtype=float), 0.0, 1.0)
    m = np.asarray(refractive_index, dtype=complex)
    sin2 = 1.0 - c * c
    ct = np.sqrt(m * m - sin2 + 0j)  # m cos(theta_t)
    rs = (c - ct) / (c + ct)
    rp = (m * m * c - ct) / (m * m * c + ct)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


#: Gauss-Legendre nodes of the hemispherical integrals over mu = cos(theta) in (0, 1)
_MU, _MU_W = np.polynomial.legendre.leggauss(64)
_MU, _MU_W = 0.5 * (_MU + 1.0), 0.5 * _MU_W


def diffuse_interface_reflectance(refractive_index):
    """Reflectance [0-1] of a flat interface for diffuse (Lambertian) light from the outside,
    r_e = 2 int_0^1 R(mu) mu dmu (64-point Gauss-Legendre in mu)."""
    m = np.asarray(refractive_index, dtype=complex)
    r = fresnel_reflectance(_MU, m[..., None])
    return 2.0 * np.sum(r * _MU * _MU_W, axis=-1)


def film_thickness_mm(wet_fraction, capacity_mm):
    """Film thickness [mm] on the wet share of a surface: W / delta with the Deardorff share
    delta = (W / W_max)^(2/3), i.e. W_max delta^(1/2)."""
    return np.asarray(capacity_mm, dtype=float) * np.sqrt(np.clip(np.asarray(wet_fraction, float), 0.0, 1.0))


def film_reflectance(wavelength_um, substrate_reflectance, thickness_mm):
    """Directional-hemispherical reflectance [0-1] at normal incidence of a water film
    ``thickness_mm`` thick over a Lambertian substrate of reflectance ``substrate_reflectance``
    (see the module doc: Lekner & Dorf 1988 with the film's absorption)."""
    w = np.asarray(wavelength_um, dtype=float)
    a = np.clip(np.asarray(substrate_reflectance, dtype=float), 0.0, 1.0)
    m = water_refractive_index(w)
    r_n = fresnel_reflectance(1.0, m)
    r_i = 1.0 - (1.0 - diffuse_interface_reflectance(m)) / np.real(m) ** 2
    tau = water_absorption_coefficient(w) * 1e-3 * np.asarray(thickness_mm, dtype=float)
    t0, t = np.exp(-tau), 2.0 * expn(3, tau)
    return r_n + (1.0 - r_n) * t0 * a * t * (1.0 - r_i) / (1.0 - r_i * a * t * t)


def wet_reflectance(wavelength_um, dry_reflectance, wet_fraction, capacity_mm):
    """Reflectance [0-1] of a surface whose share ``wet_fraction`` (Deardorff) is under a film
    of the water its capacity ``capacity_mm`` [mm] implies: (1 - delta) R_dry + delta R_film."""
    delta = np.clip(np.asarray(wet_fraction, dtype=float), 0.0, 1.0)
    dry = np.asarray(dry_reflectance, dtype=float)
    film = film_reflectance(wavelength_um, dry, film_thickness_mm(delta, capacity_mm))
    return (1.0 - delta) * dry + delta * film
