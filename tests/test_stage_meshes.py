"""One stage-mesh reader (issue 24): the render draws and the thermal tool solves the meshes
:func:`humv_usd.usd.mesh.scene_mesh_prims` finds — through instance proxies, purpose default or
render only, active prims only."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.render.scene_export import SceneMeshes
from humv_usd.usd.mesh import define_mesh, scene_mesh_prims

QUAD = (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), [4], [0, 1, 2, 3])


def _stage():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/World")
    define_mesh(stage, "/World/a", *QUAD)
    guide = define_mesh(stage, "/World/guide", *QUAD)
    guide.CreatePurposeAttr(UsdGeom.Tokens.guide)
    define_mesh(stage, "/World/off", *QUAD).GetPrim().SetActive(False)
    UsdGeom.Xform.Define(stage, "/World/proxies").CreatePurposeAttr(UsdGeom.Tokens.proxy)
    define_mesh(stage, "/World/proxies/b", *QUAD)  # purpose inherited: proxy
    stage.CreateClassPrim("/Proto")  # abstract: the prototype source is not drawn itself
    define_mesh(stage, "/Proto/c", *QUAD)
    inst = UsdGeom.Xform.Define(stage, "/World/inst").GetPrim()
    inst.GetReferences().AddInternalReference("/Proto")
    inst.SetInstanceable(True)
    return stage


def test_drawn_meshes_rule():
    stage = _stage()
    paths = [str(p.GetPath()) for p in scene_mesh_prims(stage)]
    assert paths == ["/World/a", "/World/inst/c"]  # guide, proxy-purpose and inactive left out
    assert stage.GetPrimAtPath("/World/inst/c").IsInstanceProxy()
    sub = [str(p.GetPath()) for p in scene_mesh_prims(stage, stage.GetPrimAtPath("/World/inst"))]
    assert sub == ["/World/inst/c"]  # a subtree by the same rule (the people's meshes)


def test_render_reads_by_the_same_rule():
    stage = _stage()
    assert [str(p.GetPath()) for p in SceneMeshes(stage).prims] == [
        str(p.GetPath()) for p in scene_mesh_prims(stage)
    ]
