"""Reading and writing the TOML files of scenarios and campaigns.

Python reads TOML (``tomllib``) but does not write it; the files lookout writes hold
only tables, strings, booleans, integers, floats and (nested) lists of them, so the
writer below covers exactly that. Floats are written with ``repr``, which TOML
reads back to the same double: a written file gives the same numbers.
"""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Any


class FileError(ValueError):
    """A scenario or campaign file that cannot be used; the message is one line that
    names the file, the key (and its line where it can be found) and the condition."""


def _key(key: str) -> str:
    """A key as TOML writes it: bare when it can be, quoted otherwise (a key path such
    as ``observer.wave_frequency`` inside a table is one key, not a nested one)."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _scalar(key)


def _scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_scalar(item) for item in value) + "]"
    if isinstance(value, dict):  # a table inside an array: an inline table
        return "{ " + ", ".join(f"{_key(key)} = {_scalar(item)}" for key, item in value.items() if item is not None) + " }"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def _comment(text: str | None) -> list[str]:
    return [f"# {line}".rstrip() for line in text.splitlines()] if text else []


def dumps(document: dict, comments: dict[str, str] | None = None, header: str | None = None) -> str:
    """``document`` as TOML text.

    ``comments`` maps a dotted key (``settings.duration``) to a comment written above
    it; ``header`` is written as comment lines at the top. ``None`` values are left
    out (TOML has no null: the reader's default applies).
    """
    comments = comments or {}
    lines = _comment(header)
    if lines:
        lines.append("")

    def table(prefix: str, values: dict) -> None:
        scalars = {k: v for k, v in values.items() if v is not None and not isinstance(v, dict)}
        tables = {k: v for k, v in values.items() if isinstance(v, dict)}
        for key, value in scalars.items():
            lines.extend(_comment(comments.get(f"{prefix}{key}")))
            lines.append(f"{_key(key)} = {_scalar(value)}")
        for key, value in tables.items():
            lines.append("")
            lines.extend(_comment(comments.get(f"{prefix}{key}")))
            lines.append(f"[{prefix}{_key(key)}]")
            table(f"{prefix}{_key(key)}.", value)

    table("", document)
    return "\n".join(lines) + "\n"


def write(path: str | Path, document: dict, comments: dict[str, str] | None = None, header: str | None = None) -> Path:
    """Write ``document`` to ``path`` as TOML (see :func:`dumps`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dumps(document, comments, header))
    return path


def read(path: str | Path) -> tuple[dict, str]:
    """The parsed document and the text of ``path``; a missing file or a TOML syntax
    error is a :class:`FileError` naming the file (and the parser's line)."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise FileError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise FileError(f"{path}: cannot be read ({error})") from None
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise FileError(f"{path}: not valid TOML: {error}") from None
    return _with_plugins_resolved(document, path.parent), text


def _with_plugins_resolved(document: dict, folder: Path) -> dict:
    """The document with its ``plugins`` file paths made absolute (they are relative to
    the file that names them); a module's dotted name stays as it is."""
    from lookout.scenario.registry import plugin_file

    plugins = document.get("plugins")
    if isinstance(plugins, list):
        document["plugins"] = [str(file) if isinstance(each, str) and (file := plugin_file(each, folder)) is not None else each for each in plugins]
    return document


def key_line(text: str, location: tuple) -> int | None:
    """The line (1-based) where the key at ``location`` (a path like
    ``("settings", "noise_std", 0)``) is set in ``text``, if it can be found.

    The table headers (``[settings.vessel]``) narrow the search to the right table,
    and an index followed by a key names an element of an array of tables
    (``("sensors", "dgnss2", "failures", 1, "start")``: under the second
    ``[[sensors.dgnss2.failures]]``); dotted keys and inline tables are not followed
    (then the nearest enclosing key or table that is, or None).
    """
    names = [part for index, part in enumerate(location) if isinstance(part, str) or any(isinstance(p, str) for p in location[index + 1 :])]
    while names:  # the key itself, else the nearest enclosing key that is set on a line
        line = _key_line(text, names)
        if line is not None:
            return line
        names = names[:-1]
    return None


def _key_line(text: str, names: list) -> int | None:
    *tables, key = names
    current: list = []
    elements: dict[tuple, int] = {}  # array of tables -> elements seen so far
    pattern = re.compile(rf"^\s*(\"?){re.escape(key)}\1\s*=") if isinstance(key, str) else None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        array = re.match(r"^\[\[\s*([^\[\]]+?)\s*\]\]$", stripped)
        header = array or re.match(r"^\[\s*([^\[\]]+?)\s*\]$", stripped)
        if header:
            parts = [part.strip().strip('"') for part in header.group(1).split(".")]
            if array:
                elements[tuple(parts)] = elements.get(tuple(parts), 0) + 1
            # the element of each array of tables the header is in (or is), by its index
            current = []
            for depth in range(len(parts)):
                current.append(parts[depth])
                seen = elements.get(tuple(parts[: depth + 1]))
                if seen is not None and (array or depth < len(parts) - 1):
                    current.append(seen - 1)
            if current == names:  # the key is a table: its header
                return number
            continue
        if pattern is not None and current == tables and pattern.match(line):
            return number
    return None
