"""The tree of a description in Skidy's schema: ``parent``, ``support`` and ``child`` (1-based, 0 = world).

``parent`` gives the tree; without it, ``support`` (the root-to-body paths) does; without either, the bodies
form a serial chain. ``support`` and ``child`` given beside ``parent`` are checked against it. (Skidy itself
builds a serial chain unless both ``parent`` and ``support`` are given: ``load(..., dialect="skidy")`` reads a
file that way, :mod:`._yaml_skidy`.)
"""

from __future__ import annotations

import warnings

from .._errors import DescriptionWarning
from ..model._validate import check_parents, describe_value


def is_int(value) -> bool:
    """Whether ``value`` is an integer (and not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool)


def read_tree(reader, n) -> list[int]:
    """0-based parent indices (-1 = world) from ``parent``, or from ``support``, checked for consistency;
    ``reader`` is the :class:`~._yaml_values.ValueReader` of the description (its ``data``, ``error`` and ``source``)."""
    d = reader.data
    support = d.get("support")
    if support is not None:
        if not isinstance(support, list) or len(support) != n:
            raise reader.error("support", f"expected {n} lists (one per joint), got {describe_value(support)}")
        for i, s in enumerate(support):
            if not isinstance(s, list) or not s or not all(is_int(b) and 1 <= b <= n for b in s):
                raise reader.error(f"support[{i}]", f"expected a non-empty list of body indices in 1..{n}, got {describe_value(s)}")
            if s[-1] != i + 1:
                raise reader.error(f"support[{i}]", f"expected the path from the root to body {i + 1}, ending with {i + 1}, got {s}")
    if "parent" in d:
        key, given = "parent", d["parent"]
        if not isinstance(given, list) or len(given) != n:
            raise reader.error("parent", f"expected {n} body indices (one per joint), got {describe_value(given)}")
    elif support is not None:
        key, given = "support", [s[-2] if len(s) > 1 else 0 for s in support]
    else:
        key, given = "parent", list(range(n))
    check_parents(given, first=1, where=lambda i: f"{key}[{i}]", where_all=key)
    _check_paths(reader, given, key, support)
    return [p - 1 for p in given]


def _check_paths(reader, given, key, support) -> None:
    """``support`` and ``child`` against the 1-based parents ``given`` (from ``key``)."""
    n = len(given)
    paths = []
    for i in range(n):
        path = [i + 1]
        while given[path[0] - 1] != 0:
            path.insert(0, given[path[0] - 1])
        paths.append(path)
    for i, s in enumerate(support or ()):
        if s != paths[i]:
            raise reader.error(f"support[{i}]", f"expected {paths[i]} (the bodies from the root to body {i + 1} "
                                              f"given by {key}), got {s}")
    _check_children(reader, given, key)


def _check_children(reader, given, key) -> None:
    """``child`` against the 1-based parents ``given``. Skidy reads only ``parent`` (its own example files
    carry ``child`` lists off by one), so a ``child`` that disagrees is ignored with one warning that
    names what the parents make of it."""
    child = reader.data.get("child")
    if child is None:
        return
    n = len(given)
    expected = [[k + 1 for k in range(n) if given[k] == i + 1] for i in range(n)]
    problem = None
    if not isinstance(child, list) or len(child) != n:
        problem = f"expected {n} lists (one per joint), got {describe_value(child)}"
    else:
        for i, c in enumerate(child):
            if not isinstance(c, list) or not all(is_int(b) for b in c) or sorted(c) != expected[i]:
                shown = c if isinstance(c, list) else describe_value(c)
                problem = f"child[{i}] is {shown}, but the bodies whose parent is body {i + 1} are {expected[i]}"
                break
    if problem is not None:
        warnings.warn(
            f"{reader.source}: child: ignored, as Skidy ignores it: {problem}. The tree follows {key}, "
            f"which gives child: {expected}", DescriptionWarning, stacklevel=4)
