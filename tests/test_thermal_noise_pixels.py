"""The thermal layer's noise as the render states it per pixel (pipeline.ir_pass.thermal_noise:
each face's q_rad noise carried through the smooth shading), against what two q_rad seeds do to
the image (issue 25.3: "measured by comparing independent seeds").

Extended (two composes and four renders of the demo, ~5 min on 2 cores): `make test-extended`."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest
from conftest import HUMVVEX_DEMO
from scipy import ndimage

from humv_usd.images import read_exr
from humv_usd.pipeline.compose import compose
from humv_usd.pipeline.render import render_stage
from humv_usd.scenario import validate
from humv_usd.thermal import qrad as Q

pytestmark = pytest.mark.extended

SENSORS = ("lwir640", "mwir_insb")


def _inner_person(a) -> np.ndarray:
    """Person pixels away from label and depth edges (3 x 3)."""
    label = a["body_region"] * 1000 + a["material_kind"] * 10 + a["instance_id"]
    edge = np.zeros(label.shape, dtype=bool)
    for x in (label, a["class_id"]):
        edge |= ndimage.maximum_filter(x, 3) != ndimage.minimum_filter(x, 3)
    d = a["depth"]
    edge |= (ndimage.maximum_filter(d, 3) - ndimage.minimum_filter(d, 3)) > 0.05
    return (a["class_id"] == 1) & ~edge


def test_stated_thermal_noise_per_pixel_matches_two_qrad_seeds(tmp_path, monkeypatch):
    raw = tomllib.loads(HUMVVEX_DEMO.read_text())  # the demo: JOS-3, q_rad rays
    stated, images = {}, []
    original = Q.absorbed_radiation
    for offset in (1000, 2000):  # the q_rad rays' seeds alone differ (same person, scene, render seed)

        def seeded(*args, _offset=offset, **kw):
            kw["seed"] = kw.get("seed", 0) + _offset
            return original(*args, **kw)

        monkeypatch.setattr(Q, "absorbed_radiation", seeded)
        out = tmp_path / f"q{offset}"
        compose(validate(copy.deepcopy(raw)), out)
        m = render_stage(out / "stage.usda", out / "render", spp=16, sensors=list(SENSORS), seed=7)
        for s in m["sensors"]:
            person = s["frames"][0]["quality"]["regions"]["person"]
            stated.setdefault(s["name"], []).append(person["thermal_noise_mean_k"])
        images.append({s: read_exr(out / "render" / s / "0000.exr") for s in SENSORS})
    monkeypatch.setattr(Q, "absorbed_radiation", original)
    for s in SENSORS:
        a, b = images[0][s], images[1][s]
        inner = _inner_person(a)
        assert inner.sum() > 1000
        d = (a["brightness_temperature"] - b["brightness_temperature"])[inner] / np.sqrt(2.0)
        # the mean of the pixels' sigmas, from the mean |d| of a Gaussian difference (sqrt(pi/2))
        measured = float(np.mean(np.abs(d))) * np.sqrt(np.pi / 2.0)
        ratio = np.mean(stated[s]) / measured
        # s8: 1.3-1.4 (each face's own noise stated a little high); 3.3 when every pixel took
        # its mesh's flat-face RMS
        assert 0.8 < ratio < 1.8, (s, stated[s], measured)
