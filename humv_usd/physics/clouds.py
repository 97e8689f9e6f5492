"""Broken cloud: a moving field of cloud shadows on the ground (issue 30.4).

A cloud cover fraction N (``[atmosphere] cloud_cover``) says how much of the sky is cloud, not
where. With ``[atmosphere] cloud_size_m`` > 0 the clouds are a random field over the ground that
the wind carries along:

* a Gaussian random field f(x, y) of unit variance synthesized from :data:`MODES` cosine waves
  (random directions and phases from the scenario's seed, wavelengths log-spaced from
  ``cloud_size_m`` / 4 to 8 ``cloud_size_m``), whose amplitudes follow the power-law spectrum
  of cloud fields, E(k) ~ k^(-5/3) (Cahalan & Snider 1989: Landsat cloud radiance fields,
  -5/3 over 0.1-20 km; Lovejoy 1982 for the fractal area-perimeter of clouds). A sum of many
  waves of random phase is Gaussian by the central limit theorem (Shinozuka & Deodatis 1991,
  spectral representation of random fields);
* cloud where f > q with q = Phi^-1(1 - N), so the expected share of the ground in cloud shadow
  is N (Phi the standard normal distribution);
* frozen turbulence (Taylor's hypothesis): the field moves with the wind at cloud level,
  f(x - X(t), y - Y(t)), the displacement the integral of the cloud velocity from frame 0;
  cloud-level wind from the near-ground wind by the power law u(z) = u(10 m) (z / 10 m)^(1/7)
  at a cloud base of :data:`CLOUD_BASE_M` (Peterson & Hennessey 1978: the 1/7 law of neutral
  flow), i.e. 1.93 times the 10 m wind, from the wind's direction.

Under a cloud the direct beam is taken as blocked (an optically thick cumulus, beam
transmittance exp(-tau) < 1e-4 for tau > 10); between clouds the beam is the clear-sky beam.
The diffuse sky keeps the layer's value (Kasten & Czeplak's cloud mix, uniform).

References
----------
.. [1] Cahalan, R. F. & Snider, J. B. (1989). Marine stratocumulus structure. Remote Sens.
   Environ. 28:95-107.
.. [2] Lovejoy, S. (1982). Area-perimeter relation for rain and cloud areas. Science 216:185-187.
.. [3] Shinozuka, M. & Deodatis, G. (1991). Simulation of stochastic processes by spectral
   representation. Appl. Mech. Rev. 44:191-204.
.. [4] Peterson, E. W. & Hennessey, J. P. (1978). On the use of power laws for estimates of wind
   power potential. J. Appl. Meteorol. 17:390-394.
.. [5] Taylor, G. I. (1938). The spectrum of turbulence. Proc. R. Soc. Lond. A 164:476-490.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

#: cosine waves of the field
MODES = 96
#: height of the cloud base the cloud-level wind is taken at [m]
CLOUD_BASE_M = 1000.0
#: power-law exponent of the wind profile (neutral flow, Peterson & Hennessey 1978)
WIND_PROFILE_EXPONENT = 1.0 / 7.0
#: longest and shortest wavelength of the field over the cloud size
LONGEST, SHORTEST = 8.0, 0.25


def cloud_level_wind(wind_speed_m_s, height_m: float = CLOUD_BASE_M):
    """Wind speed at ``height_m`` [m/s] from the 10 m wind: u (z / 10)^(1/7)."""
    return np.asarray(wind_speed_m_s, dtype=float) * (height_m / 10.0) ** WIND_PROFILE_EXPONENT


@dataclass(frozen=True)
class CloudField:
    """The random field's waves: wave vectors (K, 2) [rad/m], amplitudes (K,), phases (K,)."""

    wavevectors: np.ndarray
    amplitudes: np.ndarray
    phases: np.ndarray

    def value(self, x, y) -> np.ndarray:
        """f at points (x, y) [m] (broadcast), unit variance over the plane."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        arg = x[..., None] * self.wavevectors[:, 0] + y[..., None] * self.wavevectors[:, 1] + self.phases
        return np.cos(arg) @ self.amplitudes


def moving_values(field: CloudField, x, y, displacement) -> np.ndarray:
    """(M, P) f at points (x, y) (P,) [m] under the field displaced by (M, 2) [m]: f(p - d_m),
    through cos(a - b) = cos a cos b + sin a sin b (two matrix products, not M x P x K cosines)."""
    x, y = np.asarray(x, dtype=float).ravel(), np.asarray(y, dtype=float).ravel()
    k = field.wavevectors
    a = np.outer(x, k[:, 0]) + np.outer(y, k[:, 1]) + field.phases  # (P, K)
    b = np.asarray(displacement, dtype=float).reshape(-1, 2) @ k.T  # (M, K)
    return (np.cos(b) * field.amplitudes) @ np.cos(a).T + (np.sin(b) * field.amplitudes) @ np.sin(a).T


def cloud_field(seed: int, cloud_size_m: float, modes: int = MODES) -> CloudField:
    """The seed's field of clouds of about ``cloud_size_m`` [m] (see the module doc)."""
    if not cloud_size_m > 0:
        raise ValueError(f"cloud_size_m must be > 0, got {cloud_size_m}")
    rng = np.random.default_rng([int(seed), 30_4])
    k = 2.0 * np.pi / (float(cloud_size_m) * np.geomspace(LONGEST, SHORTEST, modes))
    angle = rng.uniform(0.0, 2.0 * np.pi, modes)
    # log-spaced k: E(k) dk ~ k^(-5/3) k dlnk, so a^2 ~ k^(-2/3); sum a^2 / 2 = 1 (unit variance)
    a2 = k ** (-2.0 / 3.0)
    amp = np.sqrt(2.0 * a2 / a2.sum())
    return CloudField(
        np.stack([k * np.cos(angle), k * np.sin(angle)], axis=1), amp, rng.uniform(0.0, 2.0 * np.pi, modes)
    )


def cloud_threshold(cloud_cover) -> np.ndarray:
    """q = Phi^-1(1 - N): the field value above which there is cloud (+inf for N = 0)."""
    n = np.clip(np.asarray(cloud_cover, dtype=float), 0.0, 1.0)
    return ndtri(1.0 - n)


def cloud_displacement(times_s, cloud_speed_m_s, toward_deg: float) -> np.ndarray:
    """(M, 2) [m] east/north displacement of the cloud field at ``times_s`` [s after frame 0]:
    the trapezoidal integral of the cloud speed (M,) from t = 0, along the compass direction
    ``toward_deg`` the clouds move to."""
    t = np.asarray(times_s, dtype=float)
    v = np.broadcast_to(np.asarray(cloud_speed_m_s, dtype=float), t.shape)
    dist = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    if t[0] > 0.0:  # t = 0 before the samples: the first speed held from 0
        dist = dist + v[0] * t[0]
    elif t[-1] < 0.0:  # ... after them: the last speed held to 0
        dist = dist - dist[-1] + v[-1] * t[-1]
    else:
        dist = dist - np.interp(0.0, t, dist)
    a = np.radians(toward_deg)
    return np.stack([dist * np.sin(a), dist * np.cos(a)], axis=1)


def cloud_shadow(field: CloudField, x, y, displacement, cloud_cover) -> np.ndarray:
    """(M, P) 1 where points (x, y) (P,) [m] are in the sun and 0 under cloud at each of M
    times, given the field's displacement (M, 2) [m] and the cover (M,) or a scalar [0-1]."""
    d = np.asarray(displacement, dtype=float).reshape(-1, 2)
    q = np.broadcast_to(cloud_threshold(cloud_cover), (len(d),))
    return (moving_values(field, x, y, d) <= q[:, None]).astype(float)
