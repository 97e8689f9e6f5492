"""The render's scene elements and renderer interface (issue 24): each element names the
parameters it updates per frame, and those are parameters of the loaded Mitsuba scene; the
infrared and visible scenes are built from the same elements; one rule picks the estimator."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd import mode
from humv_usd.geometry.camera import CameraPose
from humv_usd.render.eo import EOScene
from humv_usd.render.ir import IRScene, SensorSetup
from humv_usd.render.renderer import ESTIMATORS, band_renderer, choose_estimator
from humv_usd.render.scene_export import Part
from humv_usd.usd.materials import StageMaterial


def _plate():
    material = StageMaterial(
        "/M", np.array([0.3, 20.0]), np.array([0.9, 0.9]), reflectance=np.array([0.1, 0.1])
    )
    part = Part(
        key="plate",
        mesh_path="/World/plate",
        material=material,
        instance_id=3,
        vertex_ids=np.arange(4),
        triangles=np.array([[0, 1, 2], [0, 2, 3]]),
        triangle_face=np.array([0, 0]),
    )
    vertices = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    pose = CameraPose(np.array([0.0, 0.0, 5.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]), 30.0)
    return [(part, vertices, False)], [SensorSetup("cam", 8, 6, pose)]


@pytest.mark.parametrize("sky_map", [False, True])
def test_ir_scene_elements_update_only_scene_parameters(tmp_path, sky_map):
    parts, sensors = _plate()
    scene = IRScene(parts, sensors, spp=1, max_depth=2, workdir=tmp_path, sky_map=sky_map, sun=True)
    keys = {e.key for e in scene.elements}
    assert {"sky", "sun", "cam", "plate"} <= keys
    names = set(scene.params.keys())
    for e in scene.elements:
        assert e.updates, e.key  # every element of this scene changes per frame
        assert set(e.updates) <= names, (e.key, set(e.updates) - names)
    # what the per-frame setters write are the elements' keys (a moved camera is a new pose)
    pose = CameraPose(np.array([0.0, 1.0, 5.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]), 40.0)
    scene.set_camera("cam", pose)
    scene.update()
    assert float(np.asarray(scene.params["cam.x_fov"]).ravel()[0]) == pytest.approx(40.0)


def test_eo_scene_is_built_from_the_same_elements(tmp_path):
    parts, sensors = _plate()
    ir = IRScene(parts, sensors, spp=1, max_depth=2, workdir=tmp_path, sun=True)
    eo = EOScene(parts, sensors, spp=1, max_depth=2, workdir=tmp_path, sky=True, sun=True)
    ir_by, eo_by = {e.key: e for e in ir.elements}, {e.key: e for e in eo.elements}
    assert ir_by.keys() == eo_by.keys()
    # the same camera but for the film's pixel format; the same mesh but for what its faces carry
    cam_ir, cam_eo = dict(ir_by["cam"].mitsuba), dict(eo_by["cam"].mitsuba)
    assert cam_ir.pop("film")["pixel_format"] == "luminance" and cam_eo.pop("film")["pixel_format"] == "xyz"
    assert cam_ir.keys() == cam_eo.keys() and cam_ir["fov"] == cam_eo["fov"]
    assert ir_by["cam"].updates == eo_by["cam"].updates
    assert "emitter" in ir_by["plate"].mitsuba and "emitter" not in eo_by["plate"].mitsuba
    assert set(eo_by["sun"].updates) <= set(eo.params.keys())
    mode.mitsuba()  # back to the mono variant for the tests that follow


def test_one_rule_picks_the_estimator():
    assert set(ESTIMATORS) == {"fast", "path"}
    assert choose_estimator("path", -1) == ("path", None)
    est, why = choose_estimator("fast", 5)
    assert est == "path" and "max_depth 5" in why
    if mode.is_vectorized():
        assert choose_estimator("fast", -1) == ("fast", None)
    assert band_renderer("fast").shares_samples and not band_renderer("path").shares_samples
    with pytest.raises(TypeError):
        band_renderer("path").render(None, "cam", None, None, None, None, 1, 0, info={})


def test_mitsuba_faces_the_estimators_corners_and_normals_share_one_winding(tmp_path):
    """A mirrored part (USD leftHanded) is drawn with its winding reversed: the faces Mitsuba
    loaded are the corners the fast estimator's smooth shading weights (``si.uv`` order) and
    its geometric normals point the way the reversed winding gives (down for this plate)."""
    from humv_usd.render import estimator as E

    [(part, vertices, _)], sensors = _plate()
    scene = IRScene([(part, vertices, True)], sensors, spp=1, max_depth=2, workdir=tmp_path)
    faces = np.asarray(scene.params["plate.faces"]).reshape(-1, 3)
    assert faces.tolist() == [[0, 2, 1], [0, 3, 2]]
    assert np.array_equal(scene.face_corners(part), faces)
    normals, areas = E.face_normals(scene)
    np.testing.assert_allclose(normals, [[0, 0, -1], [0, 0, -1]], atol=1e-7)
    np.testing.assert_allclose(areas, [2.0, 2.0])
    # the scene's cached blend is the estimator's blend of the same parts
    assert (scene.corner_blend() != E.corner_blend(scene)).nnz == 0
