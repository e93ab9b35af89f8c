"""The on-disk cache of generated JAX modules: where it lives, how an entry is keyed, sealed, written and
loaded. Nothing here knows SymPy: an entry is text, and its key is a hash of plain strings.

An entry is the generated module followed by two comment lines,

    # jaxskid-key: <the request's key>
    # jaxskid-checksum: <sha256 of everything above this line>

so that a truncated or corrupted file, or a file left by another request under the same short name, is
recognised before anything in it runs, and regenerated.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
from collections.abc import Sequence
from pathlib import Path

from .._files import write_atomic
from .._generated import GeneratedModule
from ._module import generated_module

log = logging.getLogger("jaxskid")

_KEY_PREFIX = "# jaxskid-key: "
_CHECK_PREFIX = "# jaxskid-checksum: "


def cache_dir() -> Path:
    """Where generated modules are cached: ``$JAXSKID_CACHE_DIR``, else ``~/.cache/jaxskid``."""
    env = os.environ.get("JAXSKID_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "jaxskid"


def request_key(parts: Sequence[str]) -> str:
    """The key of a request: the sha256 of ``parts``, every string that determines the generated module
    (the generator's version, the robot's fingerprint, the quantities, the options, the defaults)."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()


def entry_path(directory: str | os.PathLike | None, label: str, key: str) -> Path:
    """``<directory>/<label>-<key[:20]>.py`` (default directory: :func:`cache_dir`), ``label`` made a
    file name (the robot's name)."""
    stem = re.sub(r"[^A-Za-z0-9_]+", "_", label)[:40] or "robot"
    return Path(directory or cache_dir()) / f"{stem}-{key[:20]}.py"


def seal(text: str, key: str) -> str:
    """``text`` with the key and checksum lines of a cache entry appended (see the module docstring)."""
    body = f"{text}{_KEY_PREFIX}{key}\n"
    return f"{body}{_CHECK_PREFIX}{hashlib.sha256(body.encode()).hexdigest()}\n"


def unseal(entry: str, key: str | None = None) -> str:
    """The module text of a sealed entry. Raises ValueError if the checksum does not match, or if the
    entry belongs to another key than ``key`` (when given)."""
    body, sep, tail = entry.rpartition(_CHECK_PREFIX)
    if not sep or tail.strip() != hashlib.sha256(body.encode()).hexdigest():
        raise ValueError("checksum mismatch")
    text, sep, stored = body.rpartition(_KEY_PREFIX)
    if not sep or (key is not None and stored.strip() != key):
        raise ValueError("the entry belongs to another request")
    return text


def load_module(text: str, origin: str) -> dict:
    """Execute generated module source and return its namespace (``origin``: its file, for tracebacks)."""
    namespace: dict = {"__name__": f"jaxskid_generated_{Path(origin).stem.replace('-', '_')}"}
    exec(compile(text, origin, "exec"), namespace)  # noqa: S102 - our own generated, checksummed code
    return namespace


def read_entry(path: Path, key: str) -> GeneratedModule | None:
    """The module of the cache entry at ``path`` (its ``source``: the entry's text), or None if there is
    none; an entry that is unreadable, corrupted or another request's is logged and treated as missing."""
    if not path.exists():
        return None
    try:
        entry = path.read_text()
        module = generated_module(load_module(unseal(entry, key), str(path)), entry, path)
    except Exception as exc:  # corrupted entry: the caller regenerates it
        log.warning("jaxskid: cache entry %s is unreadable (%s); regenerating", path, exc)
        return None
    log.debug("jaxskid: loaded %s from the cache", path)
    return module


def store_entry(path: Path | None, module: str, key: str) -> GeneratedModule:
    """Seal ``module``, load it and, when ``path`` is given, write it there (a failed write is logged:
    the module still serves this process)."""
    entry = seal(module, key)
    namespace = load_module(module, str(path) if path else "<jaxskid>")
    if path is not None:
        try:
            write_atomic(path, entry)
        except OSError as exc:
            log.warning("jaxskid: could not write the cache entry %s (%s); it is used uncached", path, exc)
    return generated_module(namespace, entry, path)
