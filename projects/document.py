"""Reading, writing and overriding project files (TOML, schema version 2).

- :func:`load_project` / :func:`loads_project` parse and validate (every problem at once,
  TOML syntax errors with line and column).
- :func:`save_project` / :func:`dumps_project` write a project back. Saving is atomic (a
  temporary file in the same folder, flushed and synced, then renamed over the target; a
  symbolic link is followed and the file's mode kept: :func:`projects.atomic.write_atomic`), and
  ``load(save(p)) == p`` exactly: floats are written with ``repr``, which round-trips.
  Comments of the original file are not kept.
- :func:`apply_overrides` applies ``KEY=VALUE`` overrides (the command line's ``--set``):
  dotted key paths, list indices as integers, the value read as a TOML value or else taken
  as a string, then the whole project validated again.
"""

from __future__ import annotations

import contextvars
import copy
import logging
import os
import re
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import tomlkit
import tomlkit.exceptions
import tomlkit.items

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomlkit reads too
    tomllib = None  # type: ignore[assignment]

from projects.atomic import write_atomic
from projects.schema import (
    Boundary,
    Contact,
    Problem,
    Project,
    ProjectError,
    schema_kind,
    validate_project,
)

logger = logging.getLogger(__name__)

# Polygons with more points than this are written one point per line.
_INLINE_POINTS = 8
_HEADER = "Runout project file, schema version 2: SI units, angles in degrees (docs/project-format.md)."
_TOMLKIT_AT = re.compile(r"\s+at line \d+ col \d+\s*$")
_TOMLLIB_AT = re.compile(r"\s*\(at line (\d+), column (\d+)\)")
# Long point arrays of the project being written (placeholder string -> TOML text): see _points.
_LONG_ARRAYS: contextvars.ContextVar[dict[str, str]] = contextvars.ContextVar("runout_long_arrays")
_PLACEHOLDER = "runout-points-" + uuid.uuid4().hex + "-"


# --------------------------------------------------------------------------------------------
# Reading


def parse_toml(text: str, source: str | None = None) -> dict[str, Any]:
    """Parse TOML text into plain data (dicts, lists, str, int, float, bool, dates).

    Uses the standard library's ``tomllib`` where present (Python >= 3.11), else tomlkit.

    Parameters
    ----------
    text : str
    source : str, optional
        Name used in error messages (a file name).

    Returns
    -------
    dict

    Raises
    ------
    ProjectError
        On a syntax error (duplicate keys included), with its line and column.
    """
    try:
        return _parse(text)
    except _TomlSyntaxError as exc:
        raise ProjectError([Problem("", None, str(exc))], source) from None


class _TomlSyntaxError(Exception):
    pass


def _parse(text: str) -> dict[str, Any]:
    try:
        return _parse_toml(text)
    except RecursionError:
        raise _TomlSyntaxError("TOML syntax error: arrays or tables nested too deeply") from None


def _parse_toml(text: str) -> dict[str, Any]:
    if tomllib is not None:
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            found = _TOMLLIB_AT.search(str(exc))
            reason = _TOMLLIB_AT.sub("", str(exc)).strip()
            if found is None:
                raise _TomlSyntaxError(f"TOML syntax error: {reason}") from None
            line, col = found.groups()
            raise _TomlSyntaxError(f"TOML syntax error at line {line}, column {col}: {reason}") from None
    try:
        return tomlkit.parse(text).unwrap()
    except tomlkit.exceptions.ParseError as exc:
        reason = _TOMLKIT_AT.sub("", str(exc)).rstrip(". ")
        raise _TomlSyntaxError(f"TOML syntax error at line {exc.line}, column {exc.col}: {reason}") from None
    except tomlkit.exceptions.TOMLKitError as exc:
        raise _TomlSyntaxError(f"TOML syntax error: {exc}") from None


def loads_project(text: str, overrides: Sequence[str] = (), source: str | None = None) -> Project:
    """Validate a project from TOML text.

    Parameters
    ----------
    text : str
        The file's contents.
    overrides : sequence of str
        ``KEY=VALUE`` overrides applied before validation (see :func:`apply_overrides`).
    source : str, optional
        Name used in error messages.

    Returns
    -------
    Project

    Raises
    ------
    ProjectError
        Listing every problem found.

    Notes
    -----
    A UTF-8 byte-order mark at the start (some Windows editors write one) is ignored.
    """
    if text.startswith("\ufeff"):
        text = text[1:]
    data = parse_toml(text, source)
    try:
        if overrides:
            return apply_overrides(data, overrides)
        return validate_project(data)
    except ProjectError as exc:
        raise ProjectError(exc.problems, source) from None
    except RecursionError:
        problem = Problem("", None, "values nested too deeply to be a project")
        raise ProjectError([problem], source) from None


def load_project(path: str | os.PathLike[str], overrides: Sequence[str] = ()) -> Project:
    """Read and validate a project file.

    Parameters
    ----------
    path : path-like
        A ``.toml`` project file.
    overrides : sequence of str
        ``KEY=VALUE`` overrides applied before validation, so that an override may repair
        a value of the file (see :func:`apply_overrides`).

    Returns
    -------
    Project

    Raises
    ------
    ProjectError
        When the file cannot be read (not a regular file, larger than
        :data:`projects.inputs.MAX_PROJECT_FILE_BYTES`, not UTF-8) or is not a valid project; the
        message starts with the file name.
    """
    from projects.inputs import MAX_PROJECT_FILE_BYTES, read_text

    path = Path(path)
    # a regular file of at most MAX_PROJECT_FILE_BYTES: /dev/zero, a FIFO or a huge file would hang
    text = read_text(path, what="the file", max_bytes=MAX_PROJECT_FILE_BYTES)
    return loads_project(text, overrides, source=str(path))


# --------------------------------------------------------------------------------------------
# Writing


def dumps_project(project: Project) -> str:
    """Write a project as TOML text, in the layout of the shipped examples.

    Parameters
    ----------
    project : Project

    Returns
    -------
    str
        TOML that :func:`loads_project` reads back to an equal project.
    """
    token = _LONG_ARRAYS.set({})
    try:
        return _dumps(project)
    finally:
        _LONG_ARRAYS.reset(token)


def _dumps(project: Project) -> str:
    data = project.to_dict()
    doc = tomlkit.document()
    doc.add(tomlkit.comment(_HEADER))
    doc.add(tomlkit.nl())
    doc["runout"] = _table(data["runout"])

    domain = _table({k: v for k, v in data["domain"].items() if k != "boundaries"})
    boundaries = tomlkit.table()
    for side, boundary in data["domain"]["boundaries"].items():
        boundaries[side] = _inline(boundary) if isinstance(boundary, Mapping) else boundary
    domain["boundaries"] = boundaries
    doc["domain"] = domain

    materials = tomlkit.table(is_super_table=True)
    for name, material in data["materials"].items():
        materials[name] = _table(material)
    doc["materials"] = materials

    bodies = tomlkit.aot()
    for body in data["bodies"]:
        table = tomlkit.table()
        for key, value in body.items():
            table[key] = _points(value) if key == "polygon_m" else _value(value)
        bodies.append(table)
    doc["bodies"] = bodies

    if data.get("structures"):
        structures = tomlkit.aot()
        for structure in data["structures"]:
            table = tomlkit.table()
            for key, value in structure.items():
                if key == "polygon_m":
                    table[key] = _points(value)
                else:
                    table[key] = _inline(value) if isinstance(value, Mapping) else _value(value)
            structures.append(table)
        doc["structures"] = structures

    if data.get("water"):
        doc["water"] = _water_table(data["water"])

    doc["particles"] = _table(data["particles"])
    numerics = _table({k: v for k, v in data["numerics"].items() if k != "advanced"})
    if "advanced" in data["numerics"]:
        numerics["advanced"] = _table(data["numerics"]["advanced"])
    doc["numerics"] = numerics

    stages = tomlkit.aot()
    for stage in data["stages"]:
        table = tomlkit.table()
        for key, value in stage.items():
            if key in ("damping", "failure", "seismic"):
                table[key] = _inline(value)
            elif key == "surcharges" and value:
                loads = tomlkit.aot()
                for load in value:
                    loads.append(_table(load))
                table[key] = loads
            elif key == "material_changes":
                changes = tomlkit.table(is_super_table=True)
                for name, change in value.items():
                    changes[name] = _table(change)
                table[key] = changes
            elif key == "water":
                table[key] = _water_table(value)
            else:
                table[key] = _value(value)
        stages.append(table)
    doc["stages"] = stages

    doc["output"] = _table(data["output"])
    if data.get("hazard"):
        doc["hazard"] = _table(data["hazard"])
    if data.get("targets"):
        targets = tomlkit.aot()
        for target in data["targets"]:
            targets.append(_table(target))
        doc["targets"] = targets
    text = tomlkit.dumps(doc)
    for token, array in _LONG_ARRAYS.get().items():
        text = text.replace(token, array, 1)
    return text


def _water_table(values: Mapping[str, Any]) -> tomlkit.items.Table:
    table = tomlkit.table()
    for key, value in values.items():
        table[key] = _points(value) if key.endswith("_line_m") else _value(value)
    return table


def _value(value: Any) -> Any:
    if isinstance(value, list):
        array = tomlkit.array()
        array.extend(_value(v) for v in value)
        return array
    return tomlkit.item(value)


def _table(values: Mapping[str, Any]) -> tomlkit.items.Table:
    table = tomlkit.table()
    for key, value in values.items():
        table[key] = _inline(value) if isinstance(value, Mapping) else _value(value)
    return table


def _inline(values: Mapping[str, Any]) -> tomlkit.items.InlineTable:
    table = tomlkit.inline_table()
    for key, value in values.items():
        table[key] = _value(value)
    return table


def _points(points: list[list[float]]) -> Any:
    if len(points) <= _INLINE_POINTS:
        array = tomlkit.array()
        for point in points:
            array.append(_value(point))
        return array
    # One point per line, written as text: tomlkit's arrays re-index on every append, which made
    # a 20,000-vertex outline take 80 s to write (and a 100,000-vertex one an hour). The text is
    # what tomlkit writes (floats with repr, four spaces, a comma after each point), put in place
    # of a placeholder string by dumps_project.
    long_arrays = _LONG_ARRAYS.get()
    token = f"{_PLACEHOLDER}{len(long_arrays)}"
    long_arrays[f'"{token}"'] = "[\n" + "".join(f"    [{_float_text(x)}, {_float_text(y)}],\n" for x, y in points) + "]"
    return token


def _float_text(value: Any) -> str:
    return repr(float(value)) if isinstance(value, float) else tomlkit.item(value).as_string()


def save_project(project: Project, path: str | os.PathLike[str]) -> None:
    """Write a project file atomically and durably (:func:`projects.atomic.write_atomic`).

    Parameters
    ----------
    project : Project
    path : path-like
        Target file; its folder must exist. A symbolic link is followed: the file it points
        to is replaced, the link stays.

    Raises
    ------
    OSError
        When the folder is not writable or the disk is full (the target is unchanged).
    """
    write_atomic(path, dumps_project(project), durable=True, follow_links=True)
    logger.debug("saved project %s", path)


# --------------------------------------------------------------------------------------------
# Overrides


def parse_override(text: str) -> tuple[list[str], Any]:
    """Split ``KEY=VALUE`` into the key path and the value.

    The value is read as a TOML value (``0.3``, ``true``, ``"x"``, ``[[0, 0], [1, 0]]``,
    ``{type = "friction", friction_angle_deg = 25}``); text that is not valid TOML is taken
    as a string (``apic``, ``My run``). Whitespace around the key and the value is ignored.

    Parameters
    ----------
    text : str

    Returns
    -------
    (list of str, value)

    Raises
    ------
    ProjectError
        When there is no ``=`` or the key is malformed.
    """
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep:
        raise ProjectError([Problem(key, None, "expected KEY=VALUE")])
    parts = key.split(".")
    if not key or any(not part.strip() for part in parts):
        problem = Problem(key or "(empty)", None, "malformed key path; expected names and indices joined by dots")
        raise ProjectError([problem])
    return [part.strip() for part in parts], _parse_value(raw.strip())


def _parse_value(raw: str) -> Any:
    try:
        values = _parse(f"value = {raw}\n")
    except _TomlSyntaxError:
        return raw
    if list(values) != ["value"]:  # e.g. "1\nother = 2": not one value
        return raw
    return values["value"]


def apply_overrides(project_or_dict: Project | Mapping[str, Any], overrides: Sequence[str]) -> Project:
    """Apply ``KEY=VALUE`` overrides and validate the result like a file.

    Key paths are dotted, with list indices as integers: ``numerics.scheme=apic``,
    ``materials.bars.friction_angle_deg=25``, ``bodies.0.polygon_m=[[0,0],[1,0],[1,1]]``,
    ``stages.1.material_changes.soil.cohesion_pa=0``. A key may be any key the schema allows
    at that place, present in the file or not, but materials, bodies and stages must exist.
    Setting ``numerics.time_step_s`` removes ``numerics.cfl`` and the other way round; setting
    ``numerics.preset`` removes ``numerics.time_step_s``.

    Parameters
    ----------
    project_or_dict : Project or mapping
        A validated project or the parsed (possibly invalid) file data; not modified.
    overrides : sequence of str

    Returns
    -------
    Project

    Raises
    ------
    ProjectError
        For unknown key paths (naming the key and what exists there) and for every problem
        of the resulting project.
    """
    if isinstance(project_or_dict, Project):
        data: dict[str, Any] = project_or_dict.to_dict()
    else:
        data = copy.deepcopy(dict(project_or_dict))
    problems: list[Problem] = []
    for text in overrides:
        try:
            parts, value = parse_override(text)
        except ProjectError as exc:
            problems.extend(exc.problems)
            continue
        problem = _set_path(data, parts, value)
        if problem is not None:
            problems.append(problem)
        else:
            logger.debug("override %s", text)
    if problems:
        raise ProjectError(problems)
    return validate_project(data)


def _set_path(data: dict[str, Any], parts: list[str], value: Any) -> Problem | None:
    """Set ``value`` at the key path, creating tables the schema allows; a Problem if the path is wrong."""
    node: Any = data
    schema: Any = Project
    done: list[str] = []
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        path = ".".join([*done, part])
        where = ".".join(done) if done else "the project"
        kind, inner = schema_kind(schema)
        if kind == "model":
            fields = inner.model_fields
            if part not in fields:
                return Problem(path, None, "unknown key; allowed: " + ", ".join(fields))
            child_schema = fields[part].annotation
            key: Any = part
        elif kind == "dict":
            is_change = done and done[-1] == "material_changes"
            if part not in node and not is_change:
                names = ", ".join(node) if node else "none"
                return Problem(path, None, f"no such material; defined: {names}")
            child_schema, key = inner, part
        elif kind == "list":
            count = len(node)
            if not re.fullmatch(r"\d+", part) or int(part) >= count:
                items = f"indices 0 to {count - 1}" if count else "no items"
                return Problem(path, None, f"no such item; {where} has {items}")
            child_schema, key = inner, int(part)
        else:  # only reached through a pair such as origin_m
            return Problem(".".join(parts), None, f"{where} is a value, not a table")
        if last:
            node[key] = value
            if done == ["numerics"] and part in ("time_step_s", "cfl"):
                node.pop("cfl" if part == "time_step_s" else "time_step_s", None)
            if done == ["numerics"] and part == "preset":  # the preset brings its own cfl
                node.pop("time_step_s", None)
            return None
        child = node.get(key) if isinstance(node, dict) else node[key]
        child_kind = schema_kind(child_schema)[0]
        if child is None and child_kind in ("model", "dict"):
            child = node[key] = {}
        elif isinstance(child, str) and schema_kind(child_schema)[1] in (Boundary, Contact):
            child = node[key] = {"type": child}  # "slip" -> {type = "slip"}: a key inside can be set
        if child_kind == "list" and not isinstance(child, list):
            # an optional list the file does not have ([[structures]], [[targets]]): no items, and
            # nothing is added to the data (the next part names the missing item)
            child = [] if child is None else list(child) if isinstance(child, tuple) else child
            if child:
                node[key] = child
        if not isinstance(child, (dict, list)):
            return Problem(".".join(parts), None, f"{path} is a value, not a table")
        node, schema = child, child_schema
        done.append(part)
    return None
