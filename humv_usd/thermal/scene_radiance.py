"""Radiance of the scene around a person: scene surfaces' leaving radiance and the lat-long
radiance map at a point (the seed's DIRSIG spherical collector, section 2.2.2).

Scene faces are opaque Lambertian surfaces lit by the sky and the sun (one bounce); a map pixel
whose ray hits a scene face shows that face's leaving radiance, else the sky's.

Units: SI; radiance [W m^-2 sr^-1], irradiance [W m^-2], temperature [K].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.geometry.raycast import first_faces, ray_caster, unblocked
from humv_usd.thermal.radiance_map import RadianceMap, latlong_directions, map_shape


def mesh_caster(mesh, backend="embree"):
    """The ray caster (:mod:`humv_usd.geometry.raycast`) on a trimesh's triangles."""
    return ray_caster(mesh.vertices, mesh.faces, backend)


def ray_offset(mesh) -> float:
    """Distance [m] by which rays leave a face along its normal (clears float32 self-hits)."""
    return 1e-5 * float(np.linalg.norm(mesh.extents)) + 1e-7


@dataclass
class SceneSurfaces:
    """Scene geometry for ray casting with the per-band radiance leaving each face.

    Attributes
    ----------
    mesh : trimesh.Trimesh
    radiance : array (bands, faces)
        Lambertian leaving radiance per face [W m^-2 sr^-1].
    """

    mesh: trimesh.Trimesh
    radiance: np.ndarray


def scene_surface_radiance(
    mesh, temperature_k, emissivity, sky, solar_reflectance=0.2, shadows=True
) -> np.ndarray:
    """Per-face leaving radiance of opaque Lambertian scene surfaces, per band.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Scene faces (normals point out of the solid, into the air).
    temperature_k : numeric, (faces,)
        Surface temperature [K].
    emissivity : numeric, (faces,)
        Longwave emissivity [0-1]; longwave reflectance is 1 - emissivity.
    sky : ClearSky or UniformSky
        Environment that lights the surfaces.
    solar_reflectance : numeric, (faces,)
        Broadband shortwave reflectance [0-1].
    shadows : bool
        Test each face centroid for sun visibility against the scene.

    Returns
    -------
    array (2, faces) [W m^-2 sr^-1]: shortwave, longwave.

    Notes
    -----
    L_lw = [eps sigma T^4 + (1 - eps) E_lw] / pi, L_sw = rho E_sw / pi, with the incident E from
    an isotropic-sky view-factor split: E = E_down (1 + n_z)/2 + pi L_ground (1 - n_z)/2, plus
    the beam E_sun max(n.s, 0) if lit. One bounce, no inter-reflection between scene faces.
    """
    n = np.asarray(mesh.face_normals, dtype=float)
    nz = n[:, 2]
    e_down = sky.downwelling_irradiance()
    ground = sky.radiance(np.array([[0.0, 0.0, -1.0]]))[:, 0]
    up, down = 0.5 * (1.0 + nz), 0.5 * (1.0 - nz)
    e_lw = e_down[1] * up + np.pi * ground[1] * down
    sun = sky.sun
    e_sw_diffuse = e_down[0] - (0.0 if sun is None else sun[1][0] * sun[0][2])
    e_sw = e_sw_diffuse * up + np.pi * ground[0] * down
    if sun is not None:
        s, e_sun = sun
        cos = np.maximum(n @ s, 0.0)
        lit = np.ones(len(n), dtype=bool)
        if shadows:
            lit = unblocked(
                mesh_caster(mesh), mesh.triangles_center + n * ray_offset(mesh), np.broadcast_to(s, n.shape)
            )
        e_sw = e_sw + e_sun[0] * cos * lit
    t = np.broadcast_to(np.asarray(temperature_k, dtype=float), nz.shape)
    eps = np.broadcast_to(np.asarray(emissivity, dtype=float), nz.shape)
    rho = np.broadcast_to(np.asarray(solar_reflectance, dtype=float), nz.shape)
    lw = (eps * STEFAN_BOLTZMANN * t**4 + (1.0 - eps) * e_lw) / np.pi
    return np.stack([rho * e_sw / np.pi, lw])


def radiance_map(center, sky, scene: SceneSurfaces | None = None, resolution=360) -> RadianceMap:
    """Build the lat-long radiance map around a point (the DIRSIG spherical collector).

    Parameters
    ----------
    center : array-like (3,)
        Collector position [m] (the avatar's centre; the avatar itself is not in ``scene``).
    sky : ClearSky or UniformSky
        Far-field radiance by direction (sky above, ground below the horizon) and the sun.
    scene : SceneSurfaces, optional
        Scene faces; a pixel whose ray hits one shows that face's leaving radiance.
    resolution : int or (int, int)
        Map rows x columns (seed: 360 x 360).

    Returns
    -------
    RadianceMap
    """
    n_theta, n_phi = map_shape(resolution)
    d, _ = latlong_directions((n_theta, n_phi))
    rad = np.asarray(sky.radiance(d), dtype=float)
    sky_only = rad.copy()
    if scene is not None and len(scene.mesh.faces):
        origins = np.broadcast_to(np.asarray(center, dtype=float), d.shape)
        hit = first_faces(mesh_caster(scene.mesh), np.ascontiguousarray(origins), d)
        rad[:, hit >= 0] = np.asarray(scene.radiance)[:, hit[hit >= 0]]
    sun = sky.sun
    return RadianceMap(
        rad.reshape(-1, n_theta, n_phi),
        np.asarray(center, dtype=float),
        tuple(sky.bands),
        None if sun is None else sun[0],
        np.zeros(rad.shape[0]) if sun is None else sun[1],
        sky_only.reshape(-1, n_theta, n_phi),
    )
