"""Shared geometry: triangle meshes (closest point, signed distance, ray casting) and the
pinhole camera model. Pure numpy + scipy + embreex; no USD, no Mitsuba.
"""
