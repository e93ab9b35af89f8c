"""Skidy's reading of a description: ``load(path, dialect="skidy")``.

A file in Skidy's schema can load in both tools and mean different things, because Skidy's parser
(``src/skidy/parser.py``, ``kinematics_generator.py``) reads some keys its own way. jaxskid's strict reader
(:mod:`._yaml_schema`) keeps its own meaning and refuses what it cannot read; with the Skidy dialect, the
description is first rewritten the way Skidy reads it, then read by the same strict reader:

* **Serial chain.** Skidy builds a tree only when both ``parent`` and ``support`` are given (and not
  empty); otherwise body i hangs from body i - 1 whatever ``parent`` says. The dialect does the same:
  ``parent`` becomes ``[0, 1, ..., n - 1]`` and ``support`` is dropped, with a :class:`DescriptionWarning`
  when the file's ``parent`` or ``support`` said otherwise.
* **``frame: com`` carries over.** Skidy remembers the ``frame`` of the last ``mass_inertia`` entry that
  gave one and applies it to the entries after it that give none; the dialect writes it into them.
* **Assignments of assignments.** ``assignments`` may be expressions of other assignments (``L2: 2*L1``);
  they are evaluated in dependency order. A cycle is a :class:`ModelError` at ``assignments`` naming its keys.
* **Unknown keys** at the top level and in the entries of ``joint_screw_coord``, ``body_ref_config``, ``ee``
  and ``mass_inertia`` are dropped with a warning (Skidy ignores them; jaxskid refuses them).
* **A prismatic joint's ``vec``** (a point on the axis, which a translation does not have) is dropped with a
  warning, as Skidy ignores it.

Nothing else changes: every value is still checked by the strict reader, and its errors name the file's keys.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

from .._errors import DescriptionWarning, ModelError, RequestError
from ..model._validate import describe_value, symbol, to_expr

DIALECTS = ("jaxskid", "skidy")
"""The ways a YAML/JSON description can be read: jaxskid's own (strict) and Skidy's."""

_POSE_KEYS = ("rotation", "translation", "xyzrpy")
_ENTRY_KEYS = {
    "joint_screw_coord": ("type", "axis", "vec"),
    "body_ref_config": _POSE_KEYS,
    "mass_inertia": ("mass", "inertia", "com", "frame", "rotation"),
}


def skidy_reading(data, source: str, known: Sequence[str]):
    """``data`` rewritten as Skidy reads it (module docstring), a new mapping for the strict reader; ``known``
    are the top-level keys the strict reader knows. ``data`` itself is left as it is."""
    if not isinstance(data, Mapping):
        return data  # the strict reader says what was expected
    d = dict(data)
    for key in [k for k in d if k not in known]:
        _ignored(source, str(key), f"unknown key, ignored as Skidy ignores it (known keys: {', '.join(known)})")
        del d[key]
    for key, allowed in _ENTRY_KEYS.items():
        if isinstance(d.get(key), list):
            d[key] = [_known_keys(e, f"{key}[{i}]", allowed, source) for i, e in enumerate(d[key])]
    ee = d.get("ee")
    if isinstance(ee, Mapping):
        d["ee"] = _known_keys(ee, "ee", _POSE_KEYS, source)
    elif isinstance(ee, list):
        d["ee"] = [_known_keys(e, f"ee[{i}]", _POSE_KEYS, source) for i, e in enumerate(ee)]
    _serial_chain(d, source)
    _carry_frames(d)
    _prismatic_vec(d, source)
    if isinstance(d.get("assignments"), Mapping):
        d["assignments"] = resolve_assignments(d["assignments"])
    return d


def _ignored(source: str, where: str, what: str) -> None:
    warnings.warn(f"{source}: {where}: {what}", DescriptionWarning, stacklevel=4)


def _known_keys(entry, where: str, allowed: Sequence[str], source: str):
    """A mapping entry without the keys Skidy does not read (each dropped with a warning)."""
    if not isinstance(entry, Mapping):
        return entry
    for key in [k for k in entry if k not in allowed]:
        _ignored(source, f"{where}.{key}", f"unknown key, ignored as Skidy ignores it (expected {', '.join(allowed)})")
    return {k: v for k, v in entry.items() if k in allowed}


def _serial_chain(d: dict, source: str) -> None:
    """Skidy's tree: ``parent`` and ``support`` both given, else a serial chain (module docstring)."""
    screws = d.get("joint_screw_coord")
    if (d.get("parent") and d.get("support")) or not isinstance(screws, list):
        return
    n = len(screws)
    serial = list(range(n))
    paths = [list(range(1, i + 2)) for i in range(n)]
    for key, given, chain in (("parent", d.get("parent"), serial), ("support", d.get("support"), paths)):
        if given and given != chain:
            other = "support" if key == "parent" else "parent"
            _ignored(source, key, f"ignored as Skidy ignores it without {other}: the bodies form a serial chain "
                                  f"(parent: {serial}); give both parent and support for a tree")
    d["parent"] = serial
    d.pop("support", None)


def _carry_frames(d: dict) -> None:
    """The ``frame`` of a ``mass_inertia`` entry carried over to the entries after it that give none."""
    entries = d.get("mass_inertia")
    if not isinstance(entries, list):
        return
    frame, out = "body", []
    for e in entries:
        if isinstance(e, Mapping) and "frame" in e:
            frame = e["frame"]
        elif isinstance(e, Mapping) and frame != "body":
            e = {**e, "frame": frame}
        out.append(e)
    d["mass_inertia"] = out


def _prismatic_vec(d: dict, source: str) -> None:
    """A prismatic ``{type, axis, vec}`` entry without its ``vec``."""
    screws = d.get("joint_screw_coord")
    if not isinstance(screws, list):
        return
    for i, s in enumerate(screws):
        if isinstance(s, Mapping) and s.get("type") == "prismatic" and "vec" in s:
            _ignored(source, f"joint_screw_coord[{i}].vec", "ignored as Skidy ignores it: a prismatic joint "
                                                             "translates along its axis and has no point on it")
            screws[i] = {k: v for k, v in s.items() if k != "vec"}


def resolve_assignments(values: Mapping) -> dict:
    """``values`` (name -> number or expression of numbers and other names) evaluated in dependency order.

    An entry that depends on a name that is no assignment is left as it is (the strict reader reports it);
    a cycle is a :class:`ModelError` at ``assignments`` that names the keys on it.
    """
    exprs, deps = {}, {}
    for key, v in values.items():
        if not isinstance(key, str) or not isinstance(v, str):
            exprs[key] = v
            continue
        e = to_expr(v, where=f"assignments.{key}")
        exprs[key] = e
        deps[key] = sorted(s.name for s in e.free_symbols if s.name in values and s.name != key)
        if symbol(key) in e.free_symbols:
            raise ModelError(f"{key!r} is defined by itself ({v}); expected a number or an expression of other "
                             "assignments", where=f"assignments.{key}")
    out, done = {}, {}
    for key in values:
        _evaluate(key, exprs, deps, done, [])
    for key, v in values.items():
        out[key] = done[key] if done.get(key) is not None else v
    return out


def _evaluate(key, exprs: dict, deps: dict, done: dict, path: list) -> None:
    """``done[key]``: the number of assignment ``key`` (None when it depends on names that are not assignments)."""
    if key in done:
        return
    if key in path:
        cycle = " -> ".join([*path[path.index(key):], key])
        raise ModelError(f"the assignments {', '.join(sorted(set(path[path.index(key):])))} refer to each other in a "
                         f"cycle ({cycle}); expected each to be a number or an expression of assignments defined "
                         "without it", where="assignments")
    for dep in deps.get(key, ()):
        _evaluate(dep, exprs, deps, done, [*path, key])
    e = exprs[key]
    if key not in deps:  # a number, or what the strict reader refuses
        done[key] = float(e) if isinstance(e, (int, float)) and not isinstance(e, bool) else None
        return
    known = {symbol(k): done[k] for k in deps[key] if done.get(k) is not None}
    value = e.xreplace(known) if known else e
    done[key] = float(value) if not value.free_symbols and value.is_real else None


def check_dialect(dialect, where: str = "dialect") -> str:
    """``dialect`` if it is one of :data:`DIALECTS`, else a :class:`RequestError` that names them."""
    if dialect not in DIALECTS:
        raise RequestError(f"{where}: expected one of {', '.join(DIALECTS)}, got {describe_value(dialect)}")
    return dialect
