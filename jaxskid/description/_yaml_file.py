"""Reading a YAML or JSON description file into a mapping: the file's syntax, nothing of its meaning.

Errors name the file (and the line and column of a syntax error): an unknown extension, unreadable or
binary bytes, text that is not UTF-8, an empty file, invalid YAML or JSON (a value an explicit tag such as
``!!int`` cannot be made of, nesting too deep to read), and a key given twice in one mapping (which PyYAML and
``json`` would otherwise resolve silently, keeping the last value).
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from .._errors import ModelError

SUFFIXES = (".yaml", ".yml", ".json")


def load_mapping(path: Path):
    """The data in ``path`` (``.yaml``, ``.yml`` or ``.json``), as PyYAML's safe loader or ``json`` gives it."""
    source = str(path)
    try:
        return _parse(_read_text(path), path.suffix.lower() == ".json")
    except ModelError as exc:
        raise exc.located(source=source) from None


def _read_text(path: Path) -> str:
    if path.suffix.lower() not in SUFFIXES:
        raise ModelError(f"expected a .yaml, .yml or .json file, got {path.suffix or 'no extension'!r}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"cannot read the file: {exc.strerror or exc}") from None
    if b"\x00" in raw:
        raise ModelError("expected a text file (YAML or JSON), found binary data")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ModelError(f"expected UTF-8 text, found an invalid byte at offset {exc.start}") from None
    if not text.strip():
        raise ModelError("the file is empty; expected a robot description")
    return text


def _parse(text: str, is_json: bool):
    try:
        data = json.loads(text, object_pairs_hook=_json_object) if is_json else yaml.load(text, Loader=_Loader)
    except json.JSONDecodeError as exc:
        raise ModelError(f"line {exc.lineno}, column {exc.colno}: invalid JSON: {exc.msg}") from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        raise ModelError(f"{where}invalid YAML: {exc.problem or exc.context}") from None
    except yaml.YAMLError as exc:
        raise ModelError(f"invalid YAML: {exc}") from None
    except ModelError:  # a duplicate JSON key (_json_object)
        raise
    except RecursionError:
        raise ModelError("expected a description, got lists or mappings nested too deeply to read") from None
    except (ValueError, TypeError, AttributeError, OverflowError) as exc:  # a value PyYAML's tag cannot construct
        raise ModelError(f"invalid YAML: a value its tag cannot be made of ({type(exc).__name__}: {exc})") from None
    if data is None:
        raise ModelError("the file is empty; expected a robot description")
    return data


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader, rejecting a key given twice in one mapping."""


def _yaml_mapping(loader, node, deep=False):
    loader.flatten_mapping(node)
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # unhashable: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                "while reading a mapping", node.start_mark, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _yaml_mapping)


def _json_object(pairs):
    out = {}
    for key, value in pairs:
        if key in out:
            raise ModelError(f"invalid JSON: duplicate key {key!r}")
        out[key] = value
    return out
