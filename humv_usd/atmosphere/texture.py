"""The dome light's sky texture: a lat-long image of the atmosphere layer's visible sky, so that
viewers that read only UsdLux (Blender, usdview, Omniverse) show the sky's colour and its
brightness against zenith (issue 27).

The environment tool authors the sky as a UsdLux DomeLight whose intensity is the luminance of
the uniform sky with the frame's diffuse horizontal illuminance,
:math:`E_d / \\pi` [nit], :math:`E_d` = DHI x 120 lm/W (:data:`humv_usd.usd.environment.DIFFUSE_EFFICACY_LM_W`,
Littlefair 1985). A dome's radiance is intensity x texture (UsdLux), so the texture here is
*relative*: linear Rec. 709 / sRGB primaries (D65), normalised so that the cosine-weighted mean
of its luminance over the upper hemisphere is 1 (:func:`hemisphere_luminance`). The dome then
still gives the horizontal illuminance :math:`\\pi \\cdot E_d/\\pi \\cdot 1 = E_d`: the
photometric scale stays the environment layer's, the texture adds the colour and the angular
shape of the atmosphere layer's sky (frame 0's table; the intensity follows the frames).

Colour: CIE 1931 XYZ of the sky spectral radiance (the colour-matching functions of
:mod:`humv_usd.physics.cie`, trapezoid on their 5 nm grid within the table's wavelengths),
then IEC 61966-2-1's XYZ-to-linear-sRGB matrix; negative components (out of gamut) are
clipped to 0 before the normalisation. Below 2.5 um the atmosphere layer's sky is the
isotropic SPCTRL2 diffuse skylight (Bird & Riordan 1986), so a clear day's texture is uniform
in zenith; the thermal sky's angular law (Martin & Berdahl 1984, LOWTRAN7) adds nothing
visible.

Where the table has no visible spectrum (no EO sensor: the grid is the infrared bands', or the
sky is dark) the texture is uniform neutral (1, 1, 1): the model's visible sky is isotropic,
and the colour is unknown.
"""

from __future__ import annotations

import numpy as np

from humv_usd.compat import trapezoid
from humv_usd.physics.cie import CMF_WAVELENGTHS_NM, CMF_XYZ, XYZ_TO_SRGB

#: Texture height [px] (rows span zenith 0..180 deg, 2.8 deg each); the width is twice the height
#: (OpenEXR's lat-long layout, which UsdLux's DomeLight follows).
TEXTURE_HEIGHT = 64
#: Visible range [um] the sky table must span for a coloured texture (the CIE 1931 functions
#: carry 99.9 % of their Y weight here).
VISIBLE_UM = (0.40, 0.70)
#: Rec. 709 / sRGB luminance weights of linear R, G, B: the Y row of the inverse of XYZ_TO_SRGB
#: (IEC 61966-2-1).
LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


def row_zenith_deg(height: int = TEXTURE_HEIGHT) -> np.ndarray:
    """Zenith angle [deg] of each texture row's centre: row 0 at the top (latitude +90, the
    dome's pole), (i + 0.5) x 180 / height."""
    return (np.arange(height) + 0.5) * 180.0 / height


def sky_xyz(zenith_deg, wavelengths_um, radiance) -> np.ndarray | None:
    """CIE 1931 X, Y, Z (Z, 3) [W m-2 sr-1 x CMF] of a sky spectral radiance table (Z, W)
    [W m-2 sr-1 um-1] against zenith, or None when the table does not span :data:`VISIBLE_UM`.

    The radiance is interpolated linearly onto the colour-matching functions' 5 nm grid within
    the table's wavelengths (zero outside) and integrated with the trapezoid rule [um]."""
    wl = np.asarray(wavelengths_um, dtype=float)
    rad = np.asarray(radiance, dtype=float).reshape(np.size(zenith_deg), wl.size)
    if wl.size < 2 or wl[0] > VISIBLE_UM[0] or wl[-1] < VISIBLE_UM[1]:
        return None
    grid = CMF_WAVELENGTHS_NM * 1e-3
    inside = (grid >= wl[0]) & (grid <= wl[-1])
    g = grid[inside]
    per_row = np.stack([np.interp(g, wl, row) for row in rad])  # (Z, G)
    return trapezoid(per_row[:, :, None] * CMF_XYZ[inside][None, :, :], g, axis=1)


def hemisphere_luminance(rgb, height: int | None = None) -> float:
    r"""Cosine-weighted mean luminance of a lat-long texture's upper hemisphere: each row's
    Rec. 709 luminance (mean over the row) times the exact weight of its zenith band,
    :math:`\int 2\cos\theta\sin\theta\,d\theta = \sin^2\theta_1 - \sin^2\theta_0` (the rows
    above the horizon sum to 1). A uniform texture of luminance L gives L; a dome of
    intensity I and this texture gives the horizontal illuminance :math:`\pi I` times it."""
    rgb = np.asarray(rgb, dtype=float)
    h = rgb.shape[0] if height is None else height
    edges = np.radians(np.minimum(np.arange(h + 1) * 180.0 / h, 90.0))
    weight = np.sin(edges[1:]) ** 2 - np.sin(edges[:-1]) ** 2  # 0 below the horizon
    lum = (rgb.reshape(h, -1, 3) @ LUMINANCE_WEIGHTS).mean(axis=1)
    return float(weight @ lum)


def sky_texture(zenith_deg, wavelengths_um, radiance, height: int = TEXTURE_HEIGHT) -> tuple[np.ndarray, str]:
    """(height, 2 x height, 3) float32 lat-long texture of the sky (module doc) and how it was
    made.

    ``zenith_deg`` (Z,) ascending within 0-90 [deg], ``wavelengths_um`` (W,), ``radiance``
    (Z, W) [W m-2 sr-1 um-1] (the atmosphere layer's ``skySpectralRadiance``; None for none).
    Each row's colour is the table's linear sRGB at the row's zenith (linear in zenith between
    table rows, as the render's sky map); rows below the horizon hold the horizon's (the ground
    covers them; the render does the same). Normalised to :func:`hemisphere_luminance` = 1.
    """
    zen_rows = row_zenith_deg(height)
    xyz = None if radiance is None else sky_xyz(zenith_deg, wavelengths_um, radiance)
    how = ""
    if xyz is not None:
        rgb = np.maximum(xyz @ XYZ_TO_SRGB.T, 0.0)  # (Z, 3)
        z = np.asarray(zenith_deg, dtype=float)
        rows = np.stack([np.interp(np.minimum(zen_rows, 90.0), z, rgb[:, c]) for c in range(3)], axis=1)
        tex = np.broadcast_to(rows[:, None, :], (height, 2 * height, 3))
        mean = hemisphere_luminance(tex)
        if mean > 0.0:
            tex = tex / mean
            zenith_rgb, horizon_rgb = rgb[0] / mean, rgb[-1] / mean
            how = (
                "lat-long, linear sRGB of the sky table's visible spectrum (CIE 1931), cosine-weighted "
                f"mean luminance 1; zenith RGB {', '.join(f'{v:.3f}' for v in zenith_rgb)}, horizon RGB "
                f"{', '.join(f'{v:.3f}' for v in horizon_rgb)}"
            )
            return np.ascontiguousarray(tex, dtype=np.float32), how
        how = "uniform neutral: the sky table is dark in the visible"
    else:
        how = "uniform neutral: the sky table has no visible spectrum (no EO sensor)"
    return np.ones((height, 2 * height, 3), dtype=np.float32), how
