"""Mapping the model's error paths back to a description's own keys.

:meth:`Robot.create <jaxskid.Robot.create>` reports a problem at a path into its arguments
(``joints[1].inertia``, ``frames[0].offset[3]``); a reader records where each of those parts came from in
its file (``mass_inertia[1]``, ``ee[0]``) and relocates the error, so that the message names the file's key.
"""

from __future__ import annotations

from .._errors import ModelError


class KeyMap:
    """Where each part of the model came from: model path prefix (``joints[1].inertia``) -> key path."""

    def __init__(self, keys: dict[str, str] | None = None):
        self.keys: dict[str, str] = dict(keys or {})

    def add(self, model_path: str, key_path: str) -> None:
        self.keys[model_path] = key_path

    def relocate(self, err: ModelError) -> ModelError:
        """``err`` with the longest known prefix of its path replaced by the description's key path."""
        where = err.where or ""
        for k in range(len(where), 0, -1):
            if (k == len(where) or where[k] in ".[") and where[:k] in self.keys:
                return ModelError(err.message, where=self.keys[where[:k]] + where[k:], source=err.source)
        return err
