"""Radiance environment maps (seed section 2.2.2, Eq. 1-2): the lat-long map and its geometry.

The seed's DIRSIG spherical collector becomes a :class:`RadianceMap`: an equirectangular
(lat-long) image per band around a point (the avatar's centre), rows = zenith angle 0..pi from +Z,
columns = azimuth 0..2pi counter-clockwise from +X. A pixel holds the radiance arriving from its
direction [W m^-2 sr^-1]; its solid angle is seed Eq. 2. The sun is not in the map: it is a
directional term (unit vector + per-band normal irradiance), so no map resolution smears it.

:func:`irradiance_table` convolves a map with the clamped cosine on a grid of normals (the
unoccluded irradiance of the q_rad estimators, :mod:`humv_usd.thermal.qrad`). Maps are built
from the sky and the scene by :func:`humv_usd.thermal.scene_radiance.radiance_map`.

Units: SI; radiance [W m^-2 sr^-1], irradiance [W m^-2].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from humv_usd.thermal.sky import BANDS


# --------------------------------------------------------------------------- map geometry
def map_shape(resolution) -> tuple[int, int]:
    """(rows, columns) of a map from an int (square) or a pair."""
    if np.isscalar(resolution):
        return int(resolution), int(resolution)
    n_theta, n_phi = resolution
    return int(n_theta), int(n_phi)


def latlong_directions(resolution=360) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre directions and pixel solid angles of a lat-long map (seed Eq. 2).

    Parameters
    ----------
    resolution : int or (int, int)
        (rows, columns) = (zenith steps over [0, pi], azimuth steps over [0, 2 pi]); an int n
        means n x n as the seed's 360 x 360 collector.

    Returns
    -------
    directions : array (rows*cols, 3)
        Unit vectors, row-major (row = zenith index).
    solid_angles : array (rows*cols,)
        Omega = dphi (cos theta0 - cos theta1) [sr]; sums to 4 pi.
    """
    n_theta, n_phi = map_shape(resolution)
    edges = np.linspace(0.0, np.pi, n_theta + 1)
    theta = 0.5 * (edges[:-1] + edges[1:])
    phi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    d = np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi), ct), axis=-1)
    omega = (2.0 * np.pi / n_phi) * (np.cos(edges[:-1]) - np.cos(edges[1:]))
    return d.reshape(-1, 3), np.repeat(omega, n_phi)


def latlong_index(directions, resolution) -> np.ndarray:
    """Flat pixel index (nearest pixel) of each unit direction in a lat-long map."""
    n_theta, n_phi = map_shape(resolution)
    d = np.asarray(directions, dtype=float)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2.0 * np.pi)
    i = np.minimum((theta * (n_theta / np.pi)).astype(np.int64), n_theta - 1)
    j = np.minimum((phi * (n_phi / (2.0 * np.pi))).astype(np.int64), n_phi - 1)
    return i * n_phi + j


def cosine_weights(normals, directions, solid_angles, normalize):
    """max(n.w, 0) Omega per (normal, pixel); normalized rows sum to pi exactly."""
    w = normals @ directions.T
    np.maximum(w, 0.0, out=w)
    w *= solid_angles
    if normalize:
        s = w.sum(axis=1, keepdims=True)
        w *= np.divide(np.pi, s, out=np.zeros_like(s), where=s > 0)
    return w


@dataclass
class RadianceMap:
    """Lat-long radiance per band around a point, plus the sun as a directional term.

    Attributes
    ----------
    radiance : array (bands, rows, cols)
        Incoming radiance by direction [W m^-2 sr^-1], sun excluded.
    center : array (3,)
        Collector position [m].
    bands : tuple of str
    sun_direction : array (3,) or None
        Unit vector towards the sun (None: no sun, e.g. night or below the horizon).
    sun_irradiance : array (bands,)
        Normal beam irradiance per band [W m^-2].
    sky_radiance : array (bands, rows, cols) or None
        The far field alone (sky, and the sky model's ground below the horizon), without the
        scene faces that ``radiance`` shows from ``center``: what a ray that misses every face
        sees (:func:`humv_usd.thermal.qrad.absorbed_radiation`); None: as ``radiance``.
    """

    radiance: np.ndarray
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bands: tuple = BANDS
    sun_direction: np.ndarray | None = None
    sun_irradiance: np.ndarray | None = None
    #: (bands, rows, cols) the far field alone, without the scene faces that ``radiance``
    #: shows from ``center`` [W m^-2 sr^-1]: what a ray that misses every face sees (None: as
    #: ``radiance``)
    sky_radiance: np.ndarray | None = None

    def __post_init__(self):
        self.radiance = np.asarray(self.radiance, dtype=float)
        if self.sky_radiance is not None:
            self.sky_radiance = np.asarray(self.sky_radiance, dtype=float).reshape(self.radiance.shape)
        if self.sun_irradiance is None:
            self.sun_irradiance = np.zeros(self.radiance.shape[0])
        self._geometry = None

    @property
    def resolution(self) -> tuple[int, int]:
        return self.radiance.shape[1], self.radiance.shape[2]

    @property
    def n_bands(self) -> int:
        return self.radiance.shape[0]

    def geometry(self):
        """(directions (P, 3), solid angles (P,)), cached."""
        if self._geometry is None:
            self._geometry = latlong_directions(self.resolution)
        return self._geometry

    def flat(self) -> np.ndarray:
        """Radiance as (bands, pixels)."""
        return self.radiance.reshape(self.n_bands, -1)

    def lookup(self, directions) -> np.ndarray:
        """Per-band radiance of the pixel holding each direction (nearest) -> (bands, N)."""
        return self.flat()[:, latlong_index(directions, self.resolution)]

    def irradiance(self, normals, normalize=False, chunk=256) -> np.ndarray:
        """Unoccluded irradiance int L max(cos, 0) d omega on planes with these normals.

        Parameters
        ----------
        normals : array (N, 3)
            Unit plane normals.
        normalize : bool
            Rescale the cosine weights of each normal to sum to pi (removes the terminator's
            discretisation bias; a uniform map then gives pi L exactly).

        Returns
        -------
        array (bands, N) [W m^-2], sun excluded.
        """
        d, omega = self.geometry()
        lflat = self.flat().T.astype(np.float32)
        normals = np.asarray(normals, dtype=float)
        out = np.empty((self.n_bands, len(normals)))
        for a in range(0, len(normals), chunk):
            w = cosine_weights(
                normals[a : a + chunk].astype(np.float32),
                d.astype(np.float32),
                omega.astype(np.float32),
                normalize,
            )
            out[:, a : a + chunk] = (w @ lflat).T
        return out


def irradiance_table(env: RadianceMap, grid=64):
    """Cosine-convolved map on a lat-long grid of normals incl. the poles, for interpolation.

    Parameters
    ----------
    env : RadianceMap
    grid : int
        Rows of the table over the normal's zenith 0..pi (grid + 1 rows incl. both poles).

    Returns
    -------
    array (bands, grid + 1, cols + 1)
        Irradiance [W m^-2] (cosine weights of each normal rescaled to sum to pi, as
        ``RadianceMap.irradiance(normalize=True)``) at normal zenith theta_i = i pi / grid and
        azimuth phi_j = 2 pi j / cols, cols = the map's columns; the last column repeats the
        first.

    Notes
    -----
    For a fixed normal zenith, the clamped-cosine kernel max(0, cos t_n cos t + sin t_n sin t
    cos(phi - phi_n)) depends on azimuth only through phi - phi_n, so each map row's
    contribution is a circular cross-correlation in azimuth, done exactly by FFT
    (O(rows_n rows cols log cols) instead of a dense (normals x pixels) product).
    """
    n_theta, n_phi = env.resolution
    edges = np.linspace(0.0, np.pi, n_theta + 1)
    theta = 0.5 * (edges[:-1] + edges[1:])
    omega = (2.0 * np.pi / n_phi) * (np.cos(edges[:-1]) - np.cos(edges[1:]))  # (R,)
    theta_n = np.linspace(0.0, np.pi, int(grid) + 1)  # (T,)
    dphi = (np.arange(n_phi) + 0.5) * (2.0 * np.pi / n_phi)  # phi_c - phi_n
    kern = (
        np.cos(theta_n)[:, None, None] * np.cos(theta)[None, :, None]
        + np.sin(theta_n)[:, None, None] * np.sin(theta)[None, :, None] * np.cos(dphi)[None, None, :]
    )
    np.maximum(kern, 0.0, out=kern)
    kern *= omega[None, :, None]  # (T, R, C)
    weight_sum = kern.sum(axis=(1, 2))  # (T,)
    fk = np.conj(np.fft.rfft(kern, axis=2))  # (T, R, F)
    fl = np.fft.rfft(env.radiance, axis=2)  # (B, R, F)
    prod = np.matmul(fl.transpose(2, 0, 1), fk.transpose(2, 1, 0))  # (F, B, T)
    e = np.fft.irfft(prod.transpose(1, 2, 0), n=n_phi, axis=2)  # (B, T, C)
    e *= (np.pi / weight_sum)[None, :, None]
    return np.concatenate([e, e[:, :, :1]], axis=2)


def interp_table(table, normals):
    grid = table.shape[1] - 1
    cols = table.shape[2] - 1
    theta = np.arccos(np.clip(normals[:, 2], -1.0, 1.0)) * (grid / np.pi)
    phi = np.mod(np.arctan2(normals[:, 1], normals[:, 0]), 2.0 * np.pi) * (cols / (2.0 * np.pi))
    i = np.minimum(theta.astype(np.int64), grid - 1)
    j = np.minimum(phi.astype(np.int64), cols - 1)
    u, v = theta - i, phi - j
    return (
        (1 - u) * (1 - v) * table[:, i, j]
        + (1 - u) * v * table[:, i, j + 1]
        + u * (1 - v) * table[:, i + 1, j]
        + u * v * table[:, i + 1, j + 1]
    )
