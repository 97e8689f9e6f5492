"""The scenario file being edited: a tomlkit document (comments and key order kept), validated
with the command line's own validator so the page shows the CLI's messages, saved atomically.
"""

from __future__ import annotations

import hashlib
import logging
import tomllib
from pathlib import Path
from typing import Any

import tomlkit
from tomlkit.exceptions import TOMLKitError

from humv_usd.editor.fields import Field, all_fields, parse_text
from humv_usd.editor.safety import inside
from humv_usd.errors import InputError
from humv_usd.fileio import write_text_atomic
from humv_usd.scenario.load import load_scenario, read_input_bytes, validate

log = logging.getLogger(__name__)

#: a new scenario: the required keys of [general] with example values
NEW_SCENARIO = """\
# Scenario written by the HumV editor (humv-usd edit).
[general]
name = "{name}"
start = 2018-10-24T14:05:00    # local time
utc_offset_h = -4.0
latitude_deg = 39.80
longitude_deg = -84.03
"""


class SaveRefused(InputError):
    """Saving would lose something (a valid file, someone else's change on disk)."""


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class ScenarioDocument:
    """A scenario TOML file open in the editor.

    Parameters
    ----------
    path : Path
        The scenario file; created from :data:`NEW_SCENARIO` on the first save when missing.
    """

    def __init__(self, path: Path, libraries=()):
        self.path = Path(path).resolve()
        self.folder = self.path.parent
        #: asset library folders (``humv-usd edit --library``): file keys may name files there too
        #: (read-only: uploads and saves stay in the scenario's folder)
        self.libraries = tuple(Path(p).resolve() for p in libraries)
        self.parse_errors: dict[str, str] = {}
        self.modified = False
        self.version = 0  # counts changes, so every open page can follow edits made in another
        self.reload()

    # -- reading -----------------------------------------------------------------------------
    def reload(self) -> None:
        """Read the file again (dropping unsaved edits)."""
        unreadable = None
        try:
            data = read_input_bytes(self.path, "scenario file")
            text = data.decode("utf-8")
            self.exists = True
        except FileNotFoundError:
            data, self.exists = b"", False
            text = NEW_SCENARIO.format(name=self.path.stem)
        except (InputError, UnicodeDecodeError) as exc:  # a folder, a FIFO, too large, not UTF-8
            data, self.exists, text = b"", True, ""
            unreadable = str(exc) if isinstance(exc, InputError) else f"{self.path}: not UTF-8 text ({exc})"
        try:
            self.doc = tomlkit.parse(text)
            self.load_error = unreadable
        except (TOMLKitError, RecursionError) as exc:
            self.doc = tomlkit.document()
            why = "nested too deeply" if isinstance(exc, RecursionError) else exc
            self.load_error = f"{self.path}: not valid TOML: {why}"
        self.disk_digest = self._disk_digest() if self.exists else None
        self.parse_errors = {}
        self.modified = False
        self.version = getattr(self, "version", 0) + 1

    @property
    def text(self) -> str:
        return tomlkit.dumps(self.doc)

    def raw(self) -> dict:
        """The document as plain Python values (what the validator reads)."""
        return self.doc.unwrap()

    def get(self, path: tuple) -> Any:
        node: Any = self.raw()
        for part in path:
            try:
                node = node[part]
            except (KeyError, IndexError, TypeError):
                return None
        return node

    def disk_changed(self) -> bool:
        """True when the file on disk is no longer what this document was read from or saved as."""
        return self._disk_digest() != self.disk_digest

    def _disk_digest(self) -> str | None:
        """The file's digest; None when it is missing; a marker (never a digest) when it cannot be
        read as a scenario (a folder, a FIFO: the page says so once instead of failing each poll)."""
        try:
            return _digest(read_input_bytes(self.path, "scenario file"))
        except FileNotFoundError:
            return None
        except InputError as exc:
            return f"unreadable: {exc}"

    # -- editing -----------------------------------------------------------------------------
    def _container(self, path: tuple, create: bool):
        node = self.doc
        for part in path:
            if isinstance(part, int):
                node = node[part]
                continue
            if part not in node:
                if not create:
                    return None
                node[part] = tomlkit.table(is_super_table=False)
            node = node[part]
        return node

    def set_text(self, field: Field, text: str) -> str | None:
        """Set a field from the text typed into it; returns the problem when the text is not a
        value of the field's type (the document keeps its previous value then)."""
        value, problem = parse_text(field.where, field.key, text)
        if problem:
            self.parse_errors[field.where] = problem
            return problem
        self.parse_errors.pop(field.where, None)
        self.set_value(field.path, value)
        return None

    def set_value(self, path: tuple, value: Any) -> None:
        """Set (or with None remove) the key at ``path``; comments and order stay where they were."""
        parent = self._container(path[:-1], create=value is not None)
        if parent is None:
            return
        key = path[-1]
        if value is None:
            if key in parent:
                del parent[key]
                self.modified = True
                self.version += 1
            return
        if key in parent and parent[key].unwrap() == value:
            return
        if isinstance(value, dict):  # a map key stays on its line: { "*glass*" = "glass" }
            inline = tomlkit.inline_table()
            inline.update(value)
            value = inline
        parent[key] = value
        self.modified = True
        self.version += 1

    def add_table(self, path: tuple) -> int:
        """Append an empty table to the array of tables at ``path``; returns its index."""
        parent = self._container(path[:-1], create=True)
        name = path[-1]
        if name not in parent:
            parent[name] = tomlkit.aot()
        parent[name].append(tomlkit.table())
        self.modified = True
        self.version += 1
        return len(parent[name]) - 1

    def remove_table(self, path: tuple, index: int) -> None:
        """Remove element ``index`` of the array of tables at ``path``."""
        parent = self._container(path[:-1], create=False)
        if parent is None or path[-1] not in parent:
            return
        del parent[path[-1]][index]
        if len(parent[path[-1]]) == 0:
            del parent[path[-1]]
        where_prefix = ".".join(str(p) for p in path)
        self.parse_errors = {k: v for k, v in self.parse_errors.items() if not k.startswith(where_prefix)}
        self.modified = True
        self.version += 1

    # -- checking ----------------------------------------------------------------------------
    def problems(self) -> list[str]:
        """Every problem, as ``humv-usd compose`` would print it (without the file-name prefix),
        plus texts that are not values and file keys outside the scenario folder."""
        if self.load_error:
            return [self.load_error]
        out = list(self.parse_errors.values())
        raw = self.raw()
        try:
            validate(raw, self.path)
        except InputError as exc:
            prefix = f"{self.path}: "
            out += [p.removeprefix(prefix) for p in exc.problems]
        out += self._path_keys_outside(raw)
        return out

    def _path_keys_outside(self, raw: dict) -> list[str]:
        """File keys (``path``, ``pathlist``) naming a file outside the scenario's folder."""
        out = []
        for f in all_fields(raw):
            value = self.get(f.path)
            if f.key.kind == "path" and isinstance(value, str):
                items = [(f.where, value)]
            elif f.key.kind == "pathlist" and isinstance(value, list):
                items = [(f"{f.where}[{i}]", v) for i, v in enumerate(value) if isinstance(v, str)]
            else:
                continue
            for where, text in items:
                try:
                    inside(self.folder, text, where)
                except InputError as exc:
                    if not self._in_a_library(text):
                        out.append(str(exc) + self._library_hint())
        return out

    def _in_a_library(self, text: str) -> bool:
        """Whether the file key ``text`` (absolute, or relative to the scenario's folder as compose
        reads it) resolves under one of the library folders."""
        if "\x00" in text or not self.libraries:
            return False
        path = (self.folder / text).resolve()
        return any(path == lib or lib in path.parents for lib in self.libraries)

    def _library_hint(self) -> str:
        if self.libraries:
            return " or the library folders " + ", ".join(str(p) for p in self.libraries)
        return " (a shared asset library: humv-usd edit --library DIR)"

    @staticmethod
    def problems_by_field(problems: list[str], fields: list[Field]) -> tuple[dict[str, list[str]], list[str]]:
        """Problems grouped by the field they name (``sensor[0].netd_k = ...``,
        ``sensor[0].resolution: missing ...``, ``sensor[0].position_m[2] = ...``); the rest apart."""
        wheres = sorted((f.where for f in fields), key=len, reverse=True)
        at: dict[str, list[str]] = {}
        other: list[str] = []
        for line in problems:
            for where in wheres:
                if line.startswith(where) and line[len(where) : len(where) + 1] in (" ", ":", "["):
                    at.setdefault(where, []).append(line)
                    break
            else:
                other.append(line)
        return at, other

    # -- saving ------------------------------------------------------------------------------
    def save(self, overwrite_disk_change: bool = False) -> list[str]:
        """Write the document atomically; returns the problems it still has (saved only when a
        valid file would not be replaced by an invalid one).

        Raises
        ------
        SaveRefused
            When the text of a field is not a value, when the scenario does not validate and the
            file on disk does, or when the file changed on disk since it was read (unless
            ``overwrite_disk_change``).
        """
        if self.load_error:  # the editor shows nothing of a file it cannot parse: never replace it
            raise SaveRefused(f"not saved: {self.load_error}; fix it in a text editor and reload")
        if self.parse_errors:
            raise SaveRefused("not saved: " + next(iter(self.parse_errors.values())))
        if self.disk_changed() and not overwrite_disk_change:
            raise SaveRefused(
                f"not saved: {self.path} changed on disk since it was opened; reload or overwrite"
            )
        problems = self.problems()
        if problems and self._disk_is_valid():
            raise SaveRefused(
                f"not saved: the scenario has {len(problems)} problem(s) and would replace a valid "
                f"{self.path.name}; first: {problems[0]}"
            )
        text = self.text
        write_text_atomic(self.path, text)
        self.disk_digest = _digest(text.encode("utf-8"))
        self.exists = True
        self.modified = False
        log.info("saved %s", self.path)
        return problems

    def check_replacement(self, target: Path, data: bytes) -> None:
        """Refuse ``data`` as the new content of this scenario file unless it is a valid scenario
        (an upload named like the file being edited); other targets pass.

        Raises
        ------
        SaveRefused
            When ``target`` is this scenario and ``data`` is not UTF-8 TOML that validates.
        """
        if Path(target).resolve() != self.path:
            return
        try:
            validate(tomllib.loads(data.decode("utf-8")), self.path)
            return
        except UnicodeDecodeError:
            problem = "not UTF-8 text"
        except tomllib.TOMLDecodeError as exc:
            problem = f"not valid TOML ({exc})"
        except InputError as exc:
            problem = exc.problems[0] if exc.problems else str(exc)
        raise SaveRefused(f"upload {self.path.name}: not a valid scenario, the file is kept: {problem}")

    def _disk_is_valid(self) -> bool:
        if not self.path.exists():
            return False
        try:
            load_scenario(self.path)
        except InputError:
            return False
        return True

    def scenario(self):
        """The validated scenario (defaults filled) or None when it has problems."""
        if self.load_error or self.parse_errors:
            return None
        try:
            return validate(self.raw(), self.path)
        except InputError:
            return None
