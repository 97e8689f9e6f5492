"""Smooth shading of the shadowed term (the faces' emission) keeps a curved surface's mean
radiance (issue 25): a closed form on a faceted sphere, against the flat faces it shades."""

from __future__ import annotations

import numpy as np
from test_render import add_camera, add_material, add_mesh, new_stage
from test_render_eo_fast import _uv_sphere
from test_render_radiometry import MWIR
from test_render_smooth import ball_frame

from humv_usd.bench import surface_steps as SS
from humv_usd.physics import planck
from humv_usd.render import estimator as E


def test_smooth_shading_keeps_a_curved_surfaces_emitted_mean(tmp_path):
    """A black faceted sphere (eps 1, 48 x 24 segments, 7.5 deg between neighbouring normals, the
    garments' median) whose faces are hotter the more they face the camera, T_f = 300 K +
    20 K n_f.v (the sunlit person's faces turned to a camera near the sun's direction), in a
    300 K blackbody surround, seen from 12 m in MWIR: the flat faces leave B(T_f) per face
    (Kirchhoff: a black surface reflects nothing), so over the pixels away from the outline the
    mean radiance is the mean of B(T_f) at the faces hit by the pixel centres. The plain blend
    of the faces' temperatures to the corners shrinks the field's peak as it did the sun's
    cosine (about cos^2 of half the angle between neighbours) and reads the sphere low, as it
    read the humvvex person about 100 mK under flat faces; the one-ring gain of the shadowed
    term (:data:`humv_usd.render.estimator.DARK_GAIN_STEPS`) keeps it within 10 % of that shrink
    + 4 sigma."""
    t0, dt = 300.0, 20.0
    stage = new_stage(tmp_path / "s.usda", sky_k=t0)
    black = add_material(stage, "black", 1.0)
    pts, tris = _uv_sphere(48, 24)
    pts = np.asarray(pts, float)
    view = np.array([0.25, -0.15, 1.0]) / np.linalg.norm([0.25, -0.15, 1.0])  # towards the camera
    a, b, c = (pts[tris[:, k]] for k in range(3))
    nrm = np.cross(b - a, c - a)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    temps = t0 + dt * (nrm @ view)
    add_mesh(stage, "/World/Scene/ball", pts, [3] * len(tris), tris.ravel(), black, temps, instance_id=1)
    g = [(-200.0, -200.0, -5.0), (200.0, -200.0, -5.0), (200.0, 200.0, -5.0), (-200.0, 200.0, -5.0)]
    add_mesh(stage, "/World/Scene/ground", g, [4], [0, 1, 2, 3], black, t0, instance_id=2)
    add_camera(
        stage, "cam", tuple(12.0 * view), (0, 0, 0), fov_x_deg=11, resolution=(64, 64), band=MWIR,
        band_token="MWIR", up=(0, 1, 0),
    )  # fmt: skip
    stage.Save()
    fr, sid, (sub, rad, emissivity, trans), hits, inner = ball_frame(tmp_path / "s.usda")
    want = planck.band_radiance(t0 + dt * (hits.normal[inner] @ view), MWIR).mean()
    errors = {}
    for gains in (None, 0):
        radiance, stderr = E.render_band_fast(
            fr.scene, sid, fr.state, sub, emissivity, rad, 4, 5, trans, dark_gain_steps=gains
        )
        sigma = np.sqrt(np.sum(stderr[inner] ** 2)) / inner.sum()
        errors[gains] = (radiance[inner].mean() - want, sigma)
    old, sigma_old = errors[0]  # the plain blend: the test can fail
    got, sigma = errors[None]
    assert old < -8 * sigma_old, (old / want, sigma_old / want)
    assert abs(got) < 4 * sigma + 0.1 * abs(old), (got / want, old / want, sigma / want)


def test_the_smooth_fields_apparent_temperature_closes_kirchhoff_and_adds_the_sun():
    """The smooth-surface acceptance's reference field (issue 25): a black surface shows its
    temperature; a grey one in a blackbody surround at its own temperature too (Kirchhoff:
    eps B(T) + (1 - eps) B(T) = B(T)); a weak sun adds (1 - eps) E cos / (pi dB/dT) kelvin; the
    environment is read at the smooth normal's z (a linear table gives the linear value)."""
    band = (3.0, 5.0)
    t = np.array([290.0, 300.0, 310.0])
    zero = np.zeros(3)
    assert np.allclose(
        SS.smooth_apparent_temperature(t, np.ones(3), zero, zero, 0.0, [0.0, 0.0], band), t, atol=1e-6
    )
    for k, tk in enumerate(t):
        env = np.full(5, planck.band_radiance(tk, band))
        got = SS.smooth_apparent_temperature(t[[k]], [0.7], [0.3], [0.0], 0.0, env, band)
        assert abs(got[0] - tk) < 1e-6
    e, cos, eps = 0.5, 0.8, 0.7  # W m-2 in band: a weak sun, about 0.6 K
    env = np.full(3, planck.band_radiance(300.0, band))
    got = SS.smooth_apparent_temperature([300.0], [eps], [0.0], [cos], e, env, band)[0] - 300.0
    want = (1 - eps) * e * cos / np.pi / planck.band_radiance_derivative(300.0, band)
    assert abs(got / want - 1.0) < 0.02, (got, want)
    lo, hi = planck.band_radiance(280.0, band), planck.band_radiance(320.0, band)
    got = SS.smooth_apparent_temperature([300.0], [0.0], [0.5], [0.0], 0.0, [lo, 0.5 * (lo + hi), hi], band)
    assert abs(got[0] - planck.brightness_temperature(lo + 0.75 * (hi - lo), band)) < 1e-6
    assert np.isnan(SS.smooth_apparent_temperature([np.nan], [0.9], [0.0], [0.0], 0.0, env, band)[0])
