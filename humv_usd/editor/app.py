"""The editor's page (NiceGUI): one tab per scenario section of the spec, plus Sweep, Plan, 3D,
Preview and Run.

One server edits one scenario file; its state (the document, the jobs) lives in the server, so a
page that is closed and opened again finds its jobs still running and their logs. Files are
served only from the scenario's folder and the output folder (:func:`humv_usd.editor.safety.inside`).
"""

from __future__ import annotations

import logging
import math
import secrets
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomlkit
from fastapi import HTTPException
from fastapi.responses import FileResponse
from nicegui import app, run, ui

from humv_usd.catalog.garments import GARMENTS
from humv_usd.editor.document import SaveRefused, ScenarioDocument
from humv_usd.editor.fields import Field, ValueSource, all_fields, section_groups, value_source, value_text
from humv_usd.editor.guard import LOOPBACK_NAMES, RequestGuard
from humv_usd.editor.jobs import JobManager, humv_command, outputs
from humv_usd.editor.plan import plan_svg
from humv_usd.editor.preview import (
    PREVIEW_SCENARIO,
    PREVIEW_STAGE_DIR,
    PREVIEW_WIDTH_PX,
    QUALITIES,
    make_preview,
    preview_commands,
    preview_notes,
    preview_resolution,
    preview_scenario,
)
from humv_usd.editor.safety import UploadExists, inside, store_upload, sweep_base, upload_target
from humv_usd.editor.stage3d import framing, stage_view
from humv_usd.environment.sun import scenario_sun
from humv_usd.errors import InputError
from humv_usd.fileio import write_text_atomic
from humv_usd.pipeline.budget import MAX_SPP, require_fits, scenario_render_budget
from humv_usd.scenario.spec import SECTIONS
from humv_usd.sweep.spec import load_sweep

log = logging.getLogger(__name__)

LOCAL_HOSTS = LOOPBACK_NAMES
#: tab titles of the spec's sections (a section not listed is titled by its name)
TAB_TITLES = {
    "general": "General",
    "human": "Human / Clothing / Motion",
    "placement": "Placement",
    "scene": "Scene",
    "sensor": "Sensor",
    "thermal": "Thermal",
    "atmosphere": "Atmosphere",
    "annotations": "Annotations",
}

#: a value the sensor preset gives (blue, italic) or one computed from others (grey, italic),
#: shown in the empty field; the user's own values are plain black
SOURCE_CSS = """
.humv-from-preset input::placeholder, .humv-from-preset .q-field__native span { color: #1565c0; font-style: italic; opacity: 1; }
.humv-from-preset .q-field__bottom { color: #1565c0; }
.humv-computed input::placeholder { color: #616161; font-style: italic; opacity: 1; }
"""


@dataclass
class Editor:
    """The server's state: the document, the output folder, the jobs."""

    doc: ScenarioDocument
    out_dir: Path
    token: str | None = None
    jobs: JobManager = field(default_factory=JobManager)
    sweep_file: str = "sweep.toml"
    _sun: dict = field(default_factory=dict)
    last_valid = None

    def sun(self, scenario) -> tuple[float, float] | None:
        """Sun azimuth and zenith at frame 0 [deg] (cached per site, time and weather)."""
        key = repr((scenario["general"], scenario["atmosphere"]))
        if key not in self._sun:
            try:
                state = scenario_sun(scenario, [0.0])
                self._sun[key] = (float(state.azimuth_deg[0]), float(state.zenith_deg[0]))
            except (InputError, ValueError) as exc:
                log.warning("sun position: %s", exc)
                self._sun[key] = None
        return self._sun[key]


EDITOR: Editor | None = None


def _file_response(root: Path, rel: str) -> FileResponse:
    try:
        path = inside(root, rel, "file")
    except InputError as exc:
        raise HTTPException(status_code=403, detail=str(exc)) from None
    if not path.is_file():
        raise HTTPException(status_code=404, detail=f"{rel}: not found")
    return FileResponse(path, headers={"Cache-Control": "no-store"})


def _install_routes(editor: Editor) -> None:
    @app.get("/files/out/{rel:path}")
    def out_file(rel: str):
        return _file_response(editor.out_dir, rel)

    @app.get("/files/scenario/{rel:path}")
    def scenario_file(rel: str):
        return _file_response(editor.doc.folder, rel)


class Page:
    """The widgets of one open page and how they follow the document."""

    def __init__(self, editor: Editor):
        self.editor = editor
        self.doc = editor.doc
        self.widgets: dict[str, ui.element] = {}
        self.fields: dict[str, Field] = {}
        self.sources: dict[str, ValueSource] = {}  # what each sensor field now says of its value
        self.section_boxes: dict[str, ui.element] = {}
        self.preview_started: float | None = None
        self.shown_preview_job = None
        self.stage_job = None
        self.shown_stage_job = None
        # a page opened again finds the server's jobs: show the latest preview when it ends
        self.preview_job = editor.jobs.latest("preview")
        if self.preview_job is not None:
            self.preview_started = self.preview_job.started
        self.build()

    # -- layout ------------------------------------------------------------------------------
    def build(self) -> None:
        doc = self.doc
        ui.add_css(SOURCE_CSS)
        with ui.header().classes("items-center bg-blue-grey-9 q-py-xs"):
            ui.label("HumV editor").classes("text-h6")
            ui.label(str(doc.path)).classes("text-caption")
            ui.space()
            self.status = ui.label("").props("data-testid=status").classes("text-subtitle2")
            ui.button("Save", on_click=self.save, icon="save").props("data-testid=save color=positive")
            ui.button("Reload", on_click=self.reload, icon="refresh").props("flat color=white")
        self.banner = ui.column().classes("w-full")
        self.other_problems = ui.column().classes("w-full text-negative").props("data-testid=problems")
        names = list(SECTIONS) + ["sweep", "plan", "view3d", "preview", "run"]
        titles = {
            **TAB_TITLES,
            "sweep": "Sweep",
            "plan": "Plan",
            "view3d": "3D",
            "preview": "Preview",
            "run": "Run",
        }
        with ui.tabs(on_change=self.tab_opened).classes("w-full").props("dense align=left") as tabs:
            tab = {n: ui.tab(n, titles.get(n, n.capitalize())).props(f"data-testid=tab-{n}") for n in names}
        with ui.tab_panels(tabs, value=tab["general"]).classes("w-full"):
            for name in SECTIONS:
                with ui.tab_panel(tab[name]):
                    self.section_boxes[name] = ui.column().classes("w-full")
                    self.fill_section(name)
            with ui.tab_panel(tab["sweep"]):
                self.build_sweep()
            with ui.tab_panel(tab["plan"]):
                self.plan = ui.html("", sanitize=False).props("data-testid=plan")
            with ui.tab_panel(tab["view3d"]):
                self.build_3d()
            with ui.tab_panel(tab["preview"]):
                self.build_preview()
            with ui.tab_panel(tab["run"]):
                self.build_run()
        self.refresh()
        self.seen_version = self.doc.version
        ui.timer(0.5, self.poll)

    def fill_section(self, name: str) -> None:
        box = self.section_boxes[name]
        box.clear()
        for where in [w for w in self.widgets if w == name or w.startswith((name + ".", name + "["))]:
            del self.widgets[where]
            self.fields.pop(where, None)
            self.sources.pop(where, None)
        groups, slots = section_groups(self.doc.raw(), name)
        with box:
            ui.label(SECTIONS[name].doc).classes("text-caption text-grey-7")
            if name == "human":
                self.garment_help()
            for group in groups:
                with ui.card().classes("w-full q-pa-sm").props(f"data-group={group.where}"):
                    with ui.row().classes("items-center w-full"):
                        ui.label(group.title).classes("text-subtitle1 text-weight-medium")
                        if group.index is not None:
                            ui.space()
                            ui.button(
                                "Remove",
                                icon="delete",
                                on_click=lambda g=group: self.remove_table(name, g.path[:-1], g.index),
                            ).props("flat dense color=negative")
                    with ui.grid(columns=3).classes("w-full gap-x-4 gap-y-0"):
                        for f in group.fields:
                            self.field_widget(f)
            for slot in slots:
                label = slot.where.split(".")[-1]
                ui.button(
                    f"Add {label}", icon="add", on_click=lambda s=slot: self.add_table(name, s.path)
                ).props(f"outline data-testid=add-{slot.where}")

    def garment_help(self) -> None:
        rows = [f"{name} ({g.fabric})" for name, g in GARMENTS.items()]
        ui.label("Garments from the catalogue (fabric): " + ", ".join(rows)).classes("text-caption")

    def field_widget(self, f: Field) -> None:
        value = self.doc.get(f.path)
        label = f"{f.name} [{f.unit}]" if f.unit else f.name
        with ui.element("div").classes("w-full").props(f'data-field="{f.where}"'):
            if f.key.kind == "choice":
                w = ui.select(
                    list(f.key.choices),
                    value=value if value in f.key.choices else None,
                    label=label,
                    clearable=not f.key.required,
                    on_change=lambda e, f=f: self.changed(f, e.value or ""),
                )
            else:
                w = ui.input(
                    label=label,
                    value=value_text(f.key, value),
                    placeholder=f.default_text,
                    on_change=lambda e, f=f: self.changed(f, e.value or ""),
                )
            w.without_auto_validation()  # the page sets the errors (NiceGUI would clear them after on_change)
            w.props(f'hint="{_attr(f.allowed or f.default_text)}" bottom-slots')
            w.classes("w-full")
            w.tooltip(f.help)
        self.widgets[f.where] = w
        self.fields[f.where] = f

    def show_sources(self, scenario=None) -> None:
        """Mark every sensor field a preset fills as the preset's, computed or the user's."""
        raw = self.doc.raw()
        scenario = self.doc.scenario() if scenario is None else scenario
        for where, f in self.fields.items():  # a preset or band edit changes what the others show
            if where.startswith("sensor["):
                self.show_source(f, value_source(raw, scenario, f))

    def show_source(self, f: Field, src: ValueSource | None) -> None:
        """A sensor key a preset fills: whose value it is, under the field (and, left out, the
        preset's or the computed value as the empty field's placeholder, shown in grey)."""
        w = self.widgets[f.where]
        if src is None or self.sources.get(f.where) == src:
            return
        self.sources[f.where] = src
        w.props(f'hint="{_attr(src.note)}" data-source={src.kind}')
        w.classes(remove="humv-from-preset humv-computed")
        if src.kind != "user":
            w.classes("humv-from-preset" if src.kind == "preset" else "humv-computed")
        if isinstance(w, ui.input):
            w.props(f'placeholder="{_attr(src.text if src.kind != "user" else f.default_text)}" stack-label')
        w.update()

    # -- document changes --------------------------------------------------------------------
    def changed(self, f: Field, text: str) -> None:
        self.doc.set_text(f, text)
        self.seen_version = self.doc.version
        self.refresh()

    def add_table(self, section: str, path: tuple) -> None:
        self.doc.add_table(path)
        self.seen_version = self.doc.version
        self.fill_section(section)
        self.refresh()

    def remove_table(self, section: str, path: tuple, index: int) -> None:
        self.doc.remove_table(path, index)
        self.seen_version = self.doc.version
        self.fill_section(section)
        self.refresh()

    def refresh(self) -> None:
        """Validate and show each problem at its field, the rest above the tabs; redraw the plan."""
        problems = self.doc.problems()
        fields = all_fields(self.doc.raw())
        at, other = ScenarioDocument.problems_by_field(problems, fields)
        for where, w in self.widgets.items():
            message = "; ".join(at[where]) if where in at else None
            if message != w.error:
                w.error = message
                w.update()
        self.other_problems.clear()
        with self.other_problems:
            for line in other:
                ui.label(line).classes("text-body2")
        state = "valid" if not problems else f"{len(problems)} problem(s)"
        self.status.set_text(state + (" · unsaved" if self.doc.modified else ""))
        scenario = self.doc.scenario()
        self.show_sources(scenario)
        if scenario is not None:
            self.editor.last_valid = scenario
        shown = scenario or self.editor.last_valid
        if shown is not None:
            sun = self.editor.sun(shown)
            self.plan.set_content(plan_svg(shown, *(sun or (None, None))))
        if hasattr(self, "sensor_choice"):
            ids = [s["id"] for s in shown["sensor"]] if shown is not None else []
            self.sensor_choice.set_options(
                ids,
                value=self.sensor_choice.value
                if self.sensor_choice.value in ids
                else (ids[0] if ids else None),
            )

    def save(self, overwrite: bool = False) -> bool:
        try:
            left = self.doc.save(overwrite_disk_change=overwrite)
        except SaveRefused as exc:
            ui.notify(str(exc), type="negative", multi_line=True, timeout=8000)
            if "changed on disk" in str(exc):
                self.disk_banner()
            return False
        ui.notify(
            f"saved {self.doc.path.name}" + (f" ({len(left)} problem(s))" if left else ""), type="positive"
        )
        self.banner.clear()
        self.refresh()
        return True

    def reload(self) -> None:
        self.doc.reload()
        self.banner.clear()
        self.follow()
        ui.notify(f"reloaded {self.doc.path.name}")

    def follow(self) -> None:
        """Show the document as it is now (after a reload or an edit in another page)."""
        for name in SECTIONS:
            self.fill_section(name)
        self.seen_version = self.doc.version
        self.refresh()

    def disk_banner(self) -> None:
        self.banner.clear()
        with (
            self.banner,
            ui.row().classes("items-center bg-amber-2 w-full q-pa-sm").props("data-testid=disk-changed"),
        ):
            ui.label(f"{self.doc.path.name} changed on disk since it was opened.")
            ui.button("Reload (drop my edits)", on_click=self.reload).props("dense")
            ui.button("Overwrite with my version", on_click=lambda: self.save(overwrite=True)).props("dense")

    # -- sweep -------------------------------------------------------------------------------
    def build_sweep(self) -> None:
        ui.label(
            "A sweep file (TOML in the scenario's folder: [sweep] base and name, [set], [grid], [random], "
            "[render]; see README 'Datasets') varies scenario keys. Each top-level table is edited as TOML "
            "here; Check validates every variant as `humv-usd sweep` does."
        ).classes("text-caption")
        with ui.row().classes("items-center"):
            self.sweep_name = ui.input("sweep file", value=self.editor.sweep_file).props(
                "data-testid=sweep-file"
            )
            ui.button("Open", on_click=self.open_sweep).props("outline")
            ui.button("Save and check", on_click=self.save_sweep).props("outline data-testid=sweep-save")
            ui.button("Dry run", on_click=lambda: self.run_sweep(dry_run=True)).props("outline")
            ui.button("Run sweep", on_click=self.run_sweep).props("outline")
        self.sweep_check = ui.column().classes("w-full").props("data-testid=sweep-check")
        self.sweep_box = ui.column().classes("w-full")
        self.sweep_doc = None
        self.sweep_errors: dict[str, str] = {}
        self.open_sweep()

    def _sweep_path(self) -> Path | None:
        try:
            return inside(self.doc.folder, self.sweep_name.value or "", "sweep file")
        except InputError as exc:
            ui.notify(str(exc), type="negative")
            return None

    def open_sweep(self) -> None:
        path = self._sweep_path()
        self.sweep_box.clear()
        self.sweep_errors = {}
        if path is None:
            return
        self.editor.sweep_file = self.sweep_name.value
        if path.is_file():
            text = path.read_text(encoding="utf-8")
        else:
            text = f'[sweep]\nname = "{path.stem}"\nbase = "{self.doc.path.name}"\n\n[grid]\n"placement.0.heading_deg" = [0.0, 90.0]\n'
        try:
            self.sweep_doc = tomlkit.parse(text)
        except tomlkit.exceptions.TOMLKitError as exc:
            with self.sweep_box:
                ui.label(f"{path.name}: not valid TOML: {exc}").classes("text-negative")
            return
        with self.sweep_box:
            for key in list(self.sweep_doc):
                value = self.sweep_doc[key].unwrap()
                text = (
                    tomlkit.dumps({key: value})
                    if isinstance(value, dict)
                    else tomlkit.item(value).as_string()
                )
                ui.textarea(
                    key, value=text, on_change=lambda e, k=key: self.sweep_changed(k, e.sender, e.value)
                ).classes("w-full").props("autogrow").without_auto_validation()

    def sweep_changed(self, key: str, widget, text: str) -> None:
        import tomllib

        try:
            parsed = tomllib.loads(text)
            value = (
                parsed.get(key, parsed)
                if len(parsed) == 1 and key in parsed
                else tomllib.loads(f"v = {text}")["v"]
            )
        except tomllib.TOMLDecodeError as exc:
            self.sweep_errors[key] = f"[{key}]: not TOML ({exc})"
            widget.error = self.sweep_errors[key]
            widget.update()
            return
        self.sweep_errors.pop(key, None)
        widget.error = None
        widget.update()
        self.sweep_doc[key] = value

    async def save_sweep(self) -> None:
        path = self._sweep_path()
        if path is None or self.sweep_doc is None:
            return
        if self.sweep_errors:
            ui.notify("not saved: " + next(iter(self.sweep_errors.values())), type="negative")
            return
        self.sweep_check.clear()
        try:
            sweep_base(self.doc.folder, path, self.sweep_doc)
        except InputError as exc:
            ui.notify("not saved: " + str(exc), type="negative", multi_line=True)
            with self.sweep_check:
                ui.label(str(exc)).classes("text-negative text-body2")
            return
        write_text_atomic(path, tomlkit.dumps(self.sweep_doc))
        try:
            sweep = await run.io_bound(load_sweep, path)
        except InputError as exc:
            with self.sweep_check:
                for line in exc.problems:
                    ui.label(line).classes("text-negative text-body2")
            return
        with self.sweep_check:
            ui.label(f"{path.name}: {len(sweep.variants)} variant(s), every one valid").classes(
                "text-positive"
            )

    def run_sweep(self, dry_run: bool = False) -> None:
        path = self._sweep_path()
        if path is None or not path.is_file():
            ui.notify("save the sweep file first", type="warning")
            return
        try:
            sweep_base(self.doc.folder, path, tomlkit.parse(path.read_text(encoding="utf-8")))
        except (InputError, tomlkit.exceptions.TOMLKitError, UnicodeDecodeError) as exc:
            ui.notify(str(exc), type="negative", multi_line=True)
            return
        args = ["sweep", str(path), "-o", str(self.editor.out_dir / "sweep")] + (
            ["--dry-run"] if dry_run else ["--quiet"]
        )
        self.start_job("sweep", [humv_command(*args)])

    def tab_opened(self, e) -> None:
        """The Preview or 3D tab: start the warm worker now, so that its imports overlap the
        user's reading and the first preview does not wait for them."""
        if e.value in ("preview", "view3d"):
            self.editor.jobs.warm_up(self.doc.folder)

    # -- 3D ----------------------------------------------------------------------------------
    def build_3d(self) -> None:
        with ui.row().classes("items-center"):
            ui.button("Compose and show", icon="view_in_ar", on_click=self.compose_3d).props(
                "data-testid=show-3d"
            )
            self.view_info = ui.label(
                f"the fast preview's stage (OUT/{PREVIEW_STAGE_DIR}: meshes at frame 0, cameras)"
            ).classes("text-caption")
        self.scene = ui.scene(width=1000, height=620, grid=(200, 100)).props("data-testid=scene3d")

    def write_fast_copy(self) -> Path:
        """Write the fast preview's scenario copy (editor.preview.preview_scenario) into the
        output folder; returns its path."""
        path = self.editor.out_dir / PREVIEW_SCENARIO
        raw = preview_scenario(self.doc.raw(), self.doc.scenario(), self.doc.folder)
        write_text_atomic(path, tomlkit.dumps(raw))
        return path

    def compose_3d(self) -> None:
        """Compose the fast preview's copy (the geometry and every camera as the scenario has
        them; one layer cache with the fast preview) and show it."""
        if not self.ensure_saved():
            return
        source, stage_dir = self.write_fast_copy(), self.editor.out_dir / PREVIEW_STAGE_DIR
        self.stage_job = self.start_job(
            "compose", [humv_command("compose", str(source), "-o", str(stage_dir))], warm=True
        )

    async def show_stage(self) -> None:
        glb = self.editor.out_dir / ".editor" / "stage.glb"
        stage = self.editor.out_dir / PREVIEW_STAGE_DIR / "stage.usda"
        try:
            view = await run.io_bound(stage_view, stage, glb)
        except InputError as exc:
            ui.notify(str(exc), type="negative")
            return
        self.scene.clear()
        with self.scene:
            self.scene.gltf(f"/files/out/.editor/stage.glb?t={time.time():.0f}")
            for cam in view.cameras:
                self.camera_lines(cam)
        self.scene.move_camera(*_eye(view), duration=0)
        self.view_info.set_text(
            f"{view.meshes} meshes, {view.triangles} triangles, {len(view.cameras)} cameras"
        )

    def camera_lines(self, cam) -> None:
        o, fwd, up = cam.origin, cam.forward, cam.up
        right = np.cross(fwd, up)
        t = math.tan(math.radians(cam.fov_x_deg) / 2) * 2.0
        corners = [
            o + 2.0 * fwd + t * sx * right + 0.75 * t * sy * up
            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))
        ]
        for k, c in enumerate(corners):
            self.scene.line(list(o), list(c)).material("#d62728")
            self.scene.line(list(c), list(corners[(k + 1) % 4])).material("#d62728")
        self.scene.text(cam.name).move(*o)

    # -- preview -----------------------------------------------------------------------------
    def build_preview(self) -> None:
        with ui.row().classes("items-center"):
            self.sensor_choice = (
                ui.select([], label="sensor").props("data-testid=preview-sensor").classes("w-64")
            )
            self.preview_quality = (
                ui.select(list(QUALITIES), value=QUALITIES[0], label="quality")
                .props("data-testid=preview-quality")
                .classes("w-32")
            )
            ui.button("Preview", icon="photo_camera", on_click=self.preview).props("data-testid=preview")
            self.preview_info = ui.label(
                f"frame 0, at most {PREVIEW_WIDTH_PX} px wide, 2 samples per pixel, one sub-band"
            ).classes("text-caption")
        # the fast preview is not the scenario's signature: say so, and what it lowered
        self.preview_mark = (
            ui.label("").classes("text-caption text-orange-9").props("data-testid=preview-mark")
        )
        with ui.row().classes("items-start"):
            self.preview_image = ui.image().classes("w-[800px]").props("data-testid=preview-image")
            self.colour_bar = ui.column().classes("items-center")

    def preview(self) -> None:
        sensor = self.sensor_choice.value
        if not sensor or not self.ensure_saved():
            return
        scenario, out = self.doc.scenario(), self.editor.out_dir
        quality = self.preview_quality.value or QUALITIES[0]
        source = self.doc.path
        if quality == "fast":  # its own scenario copy and folder: never the real layers
            source = self.write_fast_copy()
        size = preview_resolution(scenario, sensor)
        steps = [humv_command(*args) for args in preview_commands(source, out, sensor, size, quality)]
        self.preview_started = time.time()
        job = self.start_job("preview", steps, warm=True)
        if job is not None:
            job.sensor = sensor
            job.quality = quality
            job.notes = preview_notes(scenario) if quality == "fast" else []
            self.preview_job = job

    def show_preview(self, job) -> None:
        try:
            p = make_preview(self.editor.out_dir / "preview", job.sensor)
        except (FileNotFoundError, KeyError, OSError) as exc:
            ui.notify(str(exc), type="negative")
            return
        rel = p.png.relative_to(self.editor.out_dir)
        self.preview_image.set_source(f"/files/out/{rel}?t={time.time():.3f}")
        took = time.time() - (self.preview_started or time.time())
        self.preview_info.set_text(f"{p.sensor}: frame 0: {took:.1f} s from the click to the image")
        self.preview_mark.set_text(
            f"FAST PREVIEW, not the scenario's quality (its own stage in OUT/{PREVIEW_STAGE_DIR}): "
            + "; ".join(job.notes)
            if job.quality == "fast"
            else "full quality: the scenario's own layers (OUT/stage.usda)"
        )
        self.colour_bar.clear()
        if p.levels_k:
            lo, hi = p.levels_k
            gradient = ", ".join(reversed(p.colour_stops))
            with self.colour_bar:
                ui.label(f"{hi:.1f} K").props("data-testid=bar-high")
                ui.element("div").style(f"width:24px;height:380px;background:linear-gradient({gradient})")
                ui.label(f"{lo:.1f} K").props("data-testid=bar-low")
                ui.label("brightness\ntemperature").classes("text-caption")

    # -- run ---------------------------------------------------------------------------------
    def build_run(self) -> None:
        with ui.row().classes("items-center"):
            ui.button("Compose", on_click=self.compose).props("data-testid=run-compose")
            # empty: the render's automatic quality (infrared until the error is NETD/3)
            self.spp = (
                ui.number("spp", value=None, min=1, max=MAX_SPP, precision=0, placeholder="auto")
                .props("clearable")
                .classes("w-24")
            )
            ui.button("Compose + render", on_click=self.render).props("data-testid=run-render")
            ui.button("Cancel", on_click=self.cancel, icon="stop").props("color=negative data-testid=cancel")
            ui.label(f"output folder: {self.editor.out_dir}").classes("text-caption")
        self.job_label = ui.label("no job yet").props("data-testid=job-state")
        self.progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
        self.log = ui.log(max_lines=2000).classes("w-full h-80").props("data-testid=log")
        self.shown_lines = (None, 0)
        ui.label("Outputs").classes("text-subtitle1")
        self.links = ui.column().props("data-testid=outputs")
        ui.label("Upload a file into the scenario folder (BVH, weather CSV, USD asset)").classes(
            "text-caption"
        )
        ui.upload(on_upload=self.upload, auto_upload=True, max_file_size=64 * 1024 * 1024).props(
            "accept=.bvh,.csv,.usd,.usda,.usdc,.usdz,.toml"
        )

    def compose(self) -> None:
        if self.ensure_saved():
            self.start_job(
                "compose", [humv_command("compose", str(self.doc.path), "-o", str(self.editor.out_dir))]
            )

    def render(self) -> None:
        if not self.ensure_saved():
            return
        spp = ["--spp", str(int(self.spp.value))] if self.spp.value else []
        out = self.editor.out_dir
        scenario = self.doc.scenario()
        if self.spp.value:  # the render's own memory check, before anything runs
            try:
                require_fits(scenario_render_budget(scenario, int(self.spp.value)), out)
            except InputError as exc:
                ui.notify(str(exc), type="negative", multi_line=True, timeout=10000)
                return
        images = scenario.frame_count * len(scenario["sensor"])  # one EXR per sensor and frame
        self.start_job(
            "render",
            [
                humv_command("compose", str(self.doc.path), "-o", str(out)),
                humv_command("render", str(out / "stage.usda"), "-o", str(out / "render"), *spp),
            ],
            watch=(1, out / "render", "*/[0-9][0-9][0-9][0-9].exr", images),
        )

    def cancel(self) -> None:
        job = self.editor.jobs.latest()
        if job and not job.finished:
            job.cancel()
            ui.notify(f"job {job.id} cancelled")

    def start_job(self, kind: str, steps: list[list[str]], watch=None, warm: bool = False):
        """``warm``: in the warm worker (cli.warm: imports and JOS-3's compile paid once; the
        preview and the 3D view, short commands run again and again)."""
        running = [j for j in self.editor.jobs.jobs.values() if not j.finished]
        if running:
            ui.notify(f"job {running[0].id} ({running[0].kind}) is still running", type="warning")
            return None
        return self.editor.jobs.start(
            kind, steps, self.editor.out_dir, cwd=self.doc.folder, watch=watch, warm=warm
        )

    def ensure_saved(self) -> bool:
        """Jobs run on the file: save edits first (refused while the scenario has problems)."""
        problems = self.doc.problems()
        if problems:
            ui.notify("fix the scenario first: " + problems[0], type="negative", multi_line=True)
            return False
        if self.doc.modified or not self.doc.exists:
            return self.save()
        return True

    async def upload(self, e) -> None:
        name = e.file.name
        try:
            upload_target(self.doc.folder, name, e.file.size())
            data = await e.file.read()
            self.store(name, data, replace=False)
        except UploadExists as exc:
            self.ask_replace(name, data, str(exc))
        except InputError as exc:
            ui.notify(str(exc), type="negative", multi_line=True)

    def store(self, name: str, data: bytes, replace: bool) -> None:
        """Write an upload atomically; the scenario being edited only by valid scenario bytes."""
        target = store_upload(self.doc.folder, name, data, replace=replace, check=self.doc.check_replacement)
        ui.notify(f"uploaded {target.name}" + (" (replaced)" if replace else ""))
        if target == self.doc.path and not self.doc.modified:
            self.reload()

    def ask_replace(self, name: str, data: bytes, why: str) -> None:
        """An upload named like an existing file replaces it only when the user says so."""
        with ui.dialog() as dialog, ui.card():
            ui.label(why)
            with ui.row():

                def replace() -> None:
                    dialog.close()
                    try:
                        self.store(name, data, replace=True)
                    except InputError as exc:
                        ui.notify(str(exc), type="negative", multi_line=True)

                ui.button(f"Replace {name}", on_click=replace).props("data-testid=upload-replace")
                ui.button("Keep the file", on_click=dialog.close).props("outline")
        dialog.open()

    # -- polling -----------------------------------------------------------------------------
    async def poll(self) -> None:
        if self.doc.version != self.seen_version:
            self.follow()
        if self.doc.disk_changed():
            if not self.doc.modified:
                self.reload()
            elif not self.banner.default_slot.children:
                self.disk_banner()
        job = self.editor.jobs.latest()
        if job is None:
            return
        shown_id, count = self.shown_lines
        if shown_id != job.id:
            self.log.clear()
            count = 0
        for line in job.lines[count:]:
            self.log.push(line)
        self.shown_lines = (job.id, len(job.lines))
        files = job.files_done()
        images = f", images {files[0]}/{files[1]}" if files else ""
        self.job_label.set_text(
            f"job {job.id} {job.kind}: {job.state}, step {min(job.step + 1, len(job.steps))}/{len(job.steps)}"
            f"{images}, {job.seconds:.1f} s"
        )
        self.progress.set_value(job.progress if job.finished or job.progress > 0 else 0.05)
        if job.finished and getattr(self, "_links_for", None) != job.id:
            self._links_for = job.id
            self.links.clear()
            with self.links:
                for rel in outputs(self.editor.out_dir)[:60]:
                    ui.link(str(rel), f"/files/out/{rel}", new_tab=True)
        pj = self.preview_job
        if pj is not None and pj.finished and self.shown_preview_job is not pj:
            self.shown_preview_job = pj
            if pj.state == "done":
                self.show_preview(pj)
            else:
                ui.notify(f"preview {pj.state}; see the Run tab's log", type="negative")
        sj = self.stage_job
        if sj is not None and sj.finished and self.shown_stage_job is not sj:
            self.shown_stage_job = sj
            if sj.state == "done":
                await self.show_stage()


def _eye(view) -> list[float]:
    """Where the 3D view starts: framed on the people and the sensors (:func:`framing`)."""
    eye, target = framing(view)
    return [*eye.tolist(), *target.tolist()]


def _attr(text: str) -> str:
    return text.replace('"', "'")


def new_token(host: str) -> str | None:
    """A secret for a server on another interface than the loopback (None on 127.0.0.1)."""
    return None if host in LOCAL_HOSTS else secrets.token_urlsafe(24)


def address(host: str, port: int, token: str | None) -> str:
    """The address to open in a browser."""
    shown = "localhost" if host in ("127.0.0.1", "::1") else host
    return f"http://{shown}:{port}/" + (f"?token={token}" if token else "")


def serve(
    scenario: Path,
    out_dir: Path,
    host: str = "127.0.0.1",
    port: int = 8765,
    token: str | None = None,
    show: bool = False,
    libraries=(),
) -> None:
    """Start the editor's server (blocks until stopped). ``token``: required on every request
    (``?token=`` once, then a cookie); must be given for a host other than the loopback."""
    global EDITOR
    if host not in LOCAL_HOSTS and not token:
        raise InputError(f"--host {host}: a server on another interface than 127.0.0.1 needs a token")
    EDITOR = Editor(ScenarioDocument(scenario, libraries), Path(out_dir).resolve(), token)
    _install_routes(EDITOR)
    # Host, Origin and token on every request and websocket handshake (DNS rebinding, other sites)
    app.add_middleware(RequestGuard, host=host, port=port, token=token)

    @ui.page("/")
    def index():
        Page(EDITOR)

    app.on_shutdown(EDITOR.jobs.shutdown)
    ui.run(
        host=host,
        port=port,
        title=f"HumV editor: {EDITOR.doc.path.name}",
        reload=False,
        show=show,
        show_welcome_message=False,
        reconnect_timeout=30.0,
        favicon="🌡",
    )
