"""``[thermal] radiation_rays`` left out: the q_rad rays follow the thermal cameras' NETD
(issue 25.3), by the closed form of :func:`humv_usd.thermal.human.auto_radiation_rays`."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from humv_usd.scenario.spec import SECTIONS
from humv_usd.thermal import human as H


def _cams(monkeypatch, *cams):
    sensors = [
        SimpleNamespace(skip_reason=None, kind=kind, is_reflective=reflective, netd_k=netd)
        for kind, reflective, netd in cams
    ]
    monkeypatch.setattr(H, "stage_sensors", lambda stage: sensors)


def test_rays_follow_the_most_demanding_thermal_camera(monkeypatch):
    assert SECTIONS["thermal"].keys["radiation_rays"].default is None  # the rule is the default
    # LWIR cameras of NETD 50 mK need fewer than the base: the base
    _cams(monkeypatch, ("LWIR", False, 0.05), ("EO", False, 0.0))
    assert H.auto_radiation_rays(None) == (H.AUTO_RAYS_BASE, 0.05)
    # a cooled MWIR camera (20 mK) beside it sets the rays: the layer's noise within the share of
    # NETD/3 the render leaves, sqrt(1 - s^2) NETD / 3, at noise ~ 1/sqrt(rays)
    _cams(monkeypatch, ("LWIR", False, 0.05), ("MWIR", False, 0.02))
    rays, netd = H.auto_radiation_rays(None)
    allowed = np.sqrt(1.0 - H.AUTO_RENDER_SHARE**2) * 0.02 / 3.0
    assert netd == 0.02 and rays == int(np.ceil(H.AUTO_RAYS_BASE * (H.AUTO_PIXEL_NOISE_K / allowed) ** 2))
    assert 687 < rays <= 800  # 547 and 687 rays met the demo's mwir_insb target by 0.004 and 0.03 mK
    # the noise the layer then adds, with the render's share, meets the target
    noise = H.AUTO_PIXEL_NOISE_K * np.sqrt(H.AUTO_RAYS_BASE / rays)
    assert np.hypot(noise, H.AUTO_RENDER_SHARE * 0.02 / 3.0) <= 0.02 / 3.0
    # more demanding, more rays, up to the key's cap
    _cams(monkeypatch, ("MWIR", False, 0.01))
    assert H.auto_radiation_rays(None)[0] > rays
    _cams(monkeypatch, ("MWIR", False, 0.001))
    assert H.auto_radiation_rays(None)[0] == H.AUTO_RAYS_MAX == SECTIONS["thermal"].keys["radiation_rays"].hi


def test_reflective_and_eo_cameras_do_not_count(monkeypatch):
    _cams(monkeypatch, ("NIR", True, 0.001), ("EO", False, 0.0))
    assert H.auto_radiation_rays(None) == (H.AUTO_RAYS_BASE, None)
    _cams(monkeypatch)
    assert H.auto_radiation_rays(None) == (H.AUTO_RAYS_BASE, None)
