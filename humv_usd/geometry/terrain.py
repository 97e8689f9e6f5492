"""Terrain: a height field over the ground, its normals and material zones (issue 30.1).

The ground is z = plane(x, y) + taper(x, y) relief(x, y):

* plane: a tilted plane through the origin, ``slope_deg`` [along x, along y] (reaches the
  horizon: the ground beyond the modelled rectangle follows it);
* relief, inside the ground rectangle only: procedural hills (a sum of cosine waves of random
  directions, wavelengths and phases from ``seed``, scaled to an rms height ``hills_m``),
  ditches and embankments along polylines (raised-cosine cross-sections), and a digital
  elevation model from an image file (PNG 8/16 bit scaled to ``dem_height_m``, or a float TIFF /
  GeoTIFF in metres, read with OpenImageIO; the georeference is not read: the image spans
  ``dem_size_m`` centred at the origin, north up);
* taper: 1 inside, falling smoothly to 0 over :data:`TAPER_SHARE` of the rectangle's smaller
  side at its edge, so that the relief meets the plane of the ground beyond without a step.

Material zones (road, verge, field): strips of a width along a polyline, or a mask image
(> 0.5: inside); the later zone wins where zones overlap. Everything here is pure numpy and
takes plain dicts (the ``[scene.terrain]`` section); :func:`terrain_from_section` builds the
:class:`Terrain` that the scene tool meshes and that people and objects are placed on
(:meth:`Terrain.height`, :meth:`Terrain.normal`, :meth:`Terrain.zone_at`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from humv_usd.errors import InputError, bad_value

#: share of the ground rectangle's smaller side over which the relief fades into the plane
TAPER_SHARE = 0.1
#: number of cosine waves of the procedural hills
HILL_WAVES = 24
#: finite-difference step of :meth:`Terrain.normal` [m]
NORMAL_STEP_M = 0.05


@dataclass(frozen=True)
class Cut:
    """A ditch (``depth_m`` > 0 down) or an embankment (up) along a polyline."""

    kind: str  # "ditch" | "embankment"
    path_m: np.ndarray  # (K, 2)
    width_m: float
    depth_m: float


@dataclass(frozen=True)
class Zone:
    """A material zone: a strip along a polyline or the inside of a mask image."""

    material: str
    path_m: np.ndarray | None = None  # (K, 2)
    width_m: float = 0.0
    mask: np.ndarray | None = None  # (H, W) bool, row 0 = north
    mask_size_m: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Terrain:
    """A height field over the ground rectangle ``size_m`` centred at the origin."""

    size_m: tuple[float, float] = (100.0, 100.0)
    slope_deg: tuple[float, float] = (0.0, 0.0)
    hills_m: float = 0.0
    hill_size_m: float = 30.0
    seed: int = 0
    cuts: tuple[Cut, ...] = ()
    dem: np.ndarray | None = None  # (H, W) heights [m], row 0 = north
    dem_size_m: tuple[float, float] = (0.0, 0.0)
    zones: tuple[Zone, ...] = ()
    _waves: tuple = field(default=(), repr=False)

    @property
    def has_relief(self) -> bool:
        """Whether anything but the plane shapes the ground."""
        return self.hills_m > 0.0 or bool(self.cuts) or self.dem is not None

    def plane(self, x, y):
        """Height of the tilted plane [m] (the ground beyond the rectangle)."""
        gx, gy = (np.tan(np.radians(s)) for s in self.slope_deg)
        return gx * np.asarray(x, dtype=float) + gy * np.asarray(y, dtype=float)

    def taper(self, x, y):
        """1 inside, smoothly 0 at the rectangle's edge and beyond (C1 smoothstep)."""
        width = TAPER_SHARE * min(self.size_m)
        dx = self.size_m[0] / 2 - np.abs(np.asarray(x, dtype=float))
        dy = self.size_m[1] / 2 - np.abs(np.asarray(y, dtype=float))
        s = np.clip(np.minimum(dx, dy) / max(width, 1e-9), 0.0, 1.0)
        return s * s * (3.0 - 2.0 * s)

    def relief(self, x, y):
        """Height above the plane before the taper [m]."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        z = np.zeros(x.shape)
        if self.hills_m > 0.0:
            kx, ky, amp, phase = self._waves
            z += np.cos(np.multiply.outer(x, kx) + np.multiply.outer(y, ky) + phase) @ amp
        for c in self.cuts:
            d = polyline_distance(x, y, c.path_m)
            half = c.width_m / 2
            profile = 0.5 * (1.0 + np.cos(np.pi * np.clip(d / half, 0.0, 1.0)))
            z += (-1.0 if c.kind == "ditch" else 1.0) * c.depth_m * profile
        if self.dem is not None:
            z += _bilinear(self.dem, self.dem_size_m, x, y)
        return z

    def height(self, x, y):
        """Ground height z [m] at (x, y) [m] (numpy broadcasting; outside the rectangle: the
        plane)."""
        z = self.plane(x, y)
        if self.has_relief:
            z = z + self.taper(x, y) * self.relief(x, y)
        return z

    def normal(self, x, y):
        """(..., 3) unit upward normal of the ground at (x, y) (central differences of
        :meth:`height` over :data:`NORMAL_STEP_M`)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        h = NORMAL_STEP_M
        dzdx = (self.height(x + h, y) - self.height(x - h, y)) / (2 * h)
        dzdy = (self.height(x, y + h) - self.height(x, y - h)) / (2 * h)
        n = np.stack([-dzdx, -dzdy, np.ones(x.shape)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def zone_at(self, x, y):
        """Index of the material zone at (x, y) (-1: the ground's own material); the last
        zone that holds a point wins."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        out = np.full(x.shape, -1, dtype=np.int64)
        for i, z in enumerate(self.zones):
            if z.mask is not None:
                inside = _nearest(z.mask.astype(float), z.mask_size_m, x, y, outside=0.0) > 0.5
            else:
                inside = polyline_distance(x, y, z.path_m) <= z.width_m / 2
            out[inside] = i
        return out

    def material_at(self, x, y, ground_material: str):
        """Material name at each (x, y): its zone's, else ``ground_material``."""
        names = np.array([ground_material] + [z.material for z in self.zones], dtype=object)
        return names[self.zone_at(x, y) + 1]


def polyline_distance(x, y, path_m):
    """Distance [m] from points (x, y) to a polyline (K, 2) (a single point: to it)."""
    p = np.asarray(path_m, dtype=float).reshape(-1, 2)
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    best = np.full(np.broadcast(x, y).shape, np.inf)
    segs = [(p[i], p[i + 1]) for i in range(len(p) - 1)] or [(p[0], p[0])]
    for a, b in segs:
        ab = b - a
        t = ((x - a[0]) * ab[0] + (y - a[1]) * ab[1]) / max(float(ab @ ab), 1e-12)
        t = np.clip(t, 0.0, 1.0)
        best = np.minimum(best, np.hypot(x - a[0] - t * ab[0], y - a[1] - t * ab[1]))
    return best


def _grid_coords(shape, size_m, x, y):
    """Fractional (column, row) of (x, y) in an image of ``shape`` spanning ``size_m``, north up."""
    h, w = shape
    col = (np.asarray(x) / size_m[0] + 0.5) * (w - 1)
    row = (0.5 - np.asarray(y) / size_m[1]) * (h - 1)
    return col, row


def _bilinear(img, size_m, x, y):
    h, w = img.shape
    col, row = _grid_coords(img.shape, size_m, x, y)
    col, row = np.clip(col, 0, w - 1), np.clip(row, 0, h - 1)
    c0, r0 = np.minimum(np.floor(col).astype(int), w - 2), np.minimum(np.floor(row).astype(int), h - 2)
    fc, fr = col - c0, row - r0
    return (
        img[r0, c0] * (1 - fc) * (1 - fr)
        + img[r0, c0 + 1] * fc * (1 - fr)
        + img[r0 + 1, c0] * (1 - fc) * fr
        + img[r0 + 1, c0 + 1] * fc * fr
    )


def _nearest(img, size_m, x, y, outside=0.0):
    h, w = img.shape
    col, row = _grid_coords(img.shape, size_m, x, y)
    c, r = np.rint(col).astype(int), np.rint(row).astype(int)
    ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
    out = np.full(np.shape(c), outside, dtype=float)
    out[ok] = img[r[ok], c[ok]]
    return out


def _hill_waves(seed: int, hills_m: float, size_m: float):
    """(kx, ky, amplitude, phase) of :data:`HILL_WAVES` waves: wavelengths log-uniform over
    [size / 2, 2 size], amplitude proportional to the wavelength, rms of the sum = hills_m."""
    rng = np.random.default_rng(seed)
    lam = size_m * np.exp(rng.uniform(np.log(0.5), np.log(2.0), HILL_WAVES))
    theta = rng.uniform(0.0, 2 * np.pi, HILL_WAVES)
    phase = rng.uniform(0.0, 2 * np.pi, HILL_WAVES)
    amp = lam / np.sqrt(np.sum(lam**2) / 2.0) * hills_m  # rms of sum a_k cos = sqrt(sum a_k^2 / 2)
    k = 2 * np.pi / lam
    return k * np.cos(theta), k * np.sin(theta), amp, phase


def read_height_image(path, height_range_m=(0.0, 10.0), what="scene.terrain.dem_file"):
    """(H, W) heights [m] of a DEM image (row 0 = north): 8/16-bit integer images scaled from
    [0, 1] to ``height_range_m``, float images (TIFF, GeoTIFF) taken as metres. One channel (the
    first of several). InputError naming ``what`` when it cannot be read."""
    p = Path(path)
    inp = oiio.ImageInput.open(str(p))
    if inp is None:
        raise InputError(bad_value(what, str(p), f"cannot be read as an image ({oiio.geterror()[:120]})"))
    try:
        spec = inp.spec()
        data = inp.read_image(0, 0, 0, 1, "float")
        integer = spec.format.basetype in (
            oiio.UINT8,
            oiio.UINT16,
            oiio.INT8,
            oiio.INT16,
            oiio.UINT32,
            oiio.INT32,
        )
    finally:
        inp.close()
    img = np.asarray(data, dtype=float).reshape(spec.height, spec.width)
    if img.shape[0] < 2 or img.shape[1] < 2 or not np.all(np.isfinite(img)):
        raise InputError(bad_value(what, str(p), "expected at least 2 x 2 finite height samples"))
    if integer:
        lo, hi = height_range_m
        img = lo + img * (hi - lo)
    return img


def terrain_from_section(section: dict | None, ground_size_m=(100.0, 100.0), base_dir=".") -> Terrain:
    """The :class:`Terrain` of a ``[scene.terrain]`` section (None: flat ground).

    ``ground_size_m`` is ``[scene.ground] size_m`` (the rectangle the relief lives in);
    relative image paths resolve against ``base_dir`` (the loader normally makes them
    absolute)."""
    size = (float(ground_size_m[0]), float(ground_size_m[1]))
    if not section:
        return Terrain(size_m=size)
    cuts = tuple(
        Cut(c["kind"], np.asarray(c["path_m"], dtype=float), float(c["width_m"]), float(c["depth_m"]))
        for c in section.get("cut") or ()
    )
    zones = []
    for i, z in enumerate(section.get("zone") or ()):
        if z.get("mask_file"):
            mask_path = Path(base_dir) / z["mask_file"]
            mask = read_height_image(mask_path, (0.0, 1.0), f"scene.terrain.zone[{i}].mask_file") > 0.5
            zones.append(Zone(z["material"], mask=mask, mask_size_m=tuple(z.get("size_m") or size)))
        elif z.get("path_m"):
            zones.append(Zone(z["material"], np.asarray(z["path_m"], dtype=float), float(z["width_m"])))
        else:
            raise InputError(
                bad_value(
                    f"scene.terrain.zone[{i}]", z.get("material"), "needs path_m (a strip) or mask_file"
                )
            )
    dem = None
    if section.get("dem_file"):
        dem = read_height_image(
            Path(base_dir) / section["dem_file"], tuple(section.get("dem_height_m") or (0, 10))
        )
    hills = float(section.get("hills_m") or 0.0)
    hill_size = float(section.get("hill_size_m") or 30.0)
    seed = int(section.get("seed") or 0)
    return Terrain(
        size_m=size,
        slope_deg=tuple(float(v) for v in (section.get("slope_deg") or (0.0, 0.0))),
        hills_m=hills,
        hill_size_m=hill_size,
        seed=seed,
        cuts=cuts,
        dem=dem,
        dem_size_m=tuple(float(v) for v in (section.get("dem_size_m") or size)),
        zones=tuple(zones),
        _waves=_hill_waves(seed, hills, hill_size) if hills > 0 else (),
    )
