"""The thermal tool's q_rad pass for a wardrobe of hair alone (issue 29.2: hair on by default).

The hair faces get their own q_rad call with the body as a scene occluder
(``humv_usd.thermal.human._hair_radiation``) instead of a second pass over the whole clothed
person. With the deterministic 'brute' method both see the same occluders, so the hair faces'
absorbed radiation must be the clothed pass's, face by face.
"""

from __future__ import annotations

import numpy as np
import trimesh
from numpy.testing import assert_allclose

from humv_usd.bench import thermal as BT
from humv_usd.clothing.fit import fit_garment, prepare
from humv_usd.human.body import build_body
from humv_usd.scenario.load import default_hair
from humv_usd.thermal import human as H
from humv_usd.thermal import qrad as Q
from humv_usd.thermal import scene_radiance as SR
from humv_usd.usd.materials import StageMaterial


def _part(mesh: trimesh.Trimesh, garment, alpha, eps) -> H._Part:
    n = len(mesh.faces)
    material = StageMaterial(
        "/m", np.array([0.3, 100.0]), np.array([eps, eps]), solar_absorptivity=alpha, thickness=0.005
    )
    return H._Part(
        "/p" if garment is None else f"/p/{garment}",
        np.full(n, 3),
        np.asarray(mesh.faces).ravel(),
        np.asarray(mesh.faces),
        np.arange(n),
        np.zeros(n, dtype=int),
        np.zeros(n, dtype=int),
        material,
        garment,
    )


def test_hair_pass_sees_what_the_clothed_pass_sees():
    body_mesh, scene, sky, _, _ = BT.bench_scene(600)
    # a hair cap over the crude avatar's head (the torso capsule's top), beside the raised arm
    cap = trimesh.creation.icosphere(2, radius=0.19)
    cap.apply_translation([0.0, 0.0, 1.475])
    keep = cap.face_normals[:, 2] > 0.2
    cap = trimesh.Trimesh(cap.vertices, cap.faces[keep], process=False)
    cap.remove_unreferenced_vertices()
    body = _part(body_mesh, None, 0.62, 0.98)
    hair = _part(cap, "hair_short", 0.9, 0.95)
    parts = [body, hair]
    pts = [np.asarray(body_mesh.vertices), np.asarray(cap.vertices)]
    env = SR.radiance_map([0.0, 0.0, 1.0], sky, scene, 36)
    skin_k, air_k = 306.0, 290.0
    bare = H._trimesh(pts[:1], parts[:1])
    self_bare = H._self_radiance([body], skin_k, air_k)

    clothed = H._trimesh(pts, parts)
    absorb = np.concatenate(
        [np.repeat(p.absorptivity()[:, None], len(p.triangles), axis=1) for p in parts], axis=1
    )
    full = Q.absorbed_radiation(
        clothed,
        env,
        absorb,
        scene=scene,
        mesh_radiance=H._self_radiance(parts, skin_k, air_k),
        method="brute",
    ).sum(axis=0)[len(body.triangles) :]

    run = H._hair_radiation(pts, parts, env, scene, bare, self_bare, skin_k, air_k)
    alone = run(method="brute")
    assert alone.shape == (len(cap.faces),)
    assert_allclose(run.area, cap.area_faces)
    assert_allclose(alone, full, rtol=1e-6, atol=1e-6)

    # the body is really in the way: without it as an occluder the hair would see more sky
    no_body = Q.absorbed_radiation(
        cap,
        env,
        absorb[:, len(body.triangles) :],
        scene=scene,
        mesh_radiance=H._self_radiance([hair], skin_k, air_k),
        method="brute",
    ).sum(axis=0)
    assert np.abs(no_body - full).max() > 5.0


def test_tied_hair_on_a_child_whose_hair_proxy_reaches_no_neck_keeps_the_scalp_layer():
    """A drawn 5-yr-old (s8 contact sheet, seed 103): the tied tail's proxy faces lie on the head
    and the back, none on the neck; the compose failed ("part 1 (hair) selects no faces")."""
    # the legs as MakeHuman's age macro had them then (0.557; the Dutch median 0.545 reaches 2 neck faces)
    rig = prepare(build_body("male", 5.23, 1.1121, 22.11, "muscular", 0.331, sitting_height_ratio=0.557))
    tied, short = fit_garment(rig, "hair_tied"), fit_garment(rig, "hair_short")
    assert set(np.unique(tied.part_of)) == {0}
    assert len(tied.face_counts) == len(short.face_counts) > 100


def test_the_default_hair_takes_the_hair_only_pass_and_long_hair_does_not():
    """Long hair hangs off the back and face and shades them: it keeps the full clothed pass; the
    default styles of a person without a clothing key stay on the head and take the cheap one."""
    assert "hair_long" not in H.CLOSE_HAIR
    for sex in ("male", "female"):
        assert set(default_hair({"sex": sex})) <= set(H.CLOSE_HAIR)
