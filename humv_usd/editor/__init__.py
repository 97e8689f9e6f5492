"""The HumV editor (``humv-usd edit``): a local web app over a scenario file.

The pure parts (no web framework) are importable and tested on their own:
:mod:`~humv_usd.editor.fields` (form fields from :mod:`humv_usd.scenario.spec`),
:mod:`~humv_usd.editor.document` (the TOML file: edit, validate, save), :mod:`~humv_usd.editor.safety`
(paths under the scenario and output folders), :mod:`~humv_usd.editor.plan` (top-down SVG),
:mod:`~humv_usd.editor.jobs` (compose/render/sweep processes), :mod:`~humv_usd.editor.preview`
(temperature-coloured preview), :mod:`~humv_usd.editor.stage3d` (the composed stage as glTF).
:mod:`~humv_usd.editor.app` is the NiceGUI page.
"""
