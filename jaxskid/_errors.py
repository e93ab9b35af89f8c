"""Exceptions raised by jaxskid.

Every error a user can cause by what they feed in is a :class:`JaxskidError`. Its message names where the
problem is (file and key path, when known) and what was expected, so that it reads well as one line.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence


def unknown_names(unknown: Iterable[str], known: Sequence[str], shown: int = 8) -> str:
    """``"'x' (did you mean 'y'?); the <known> are a, b, ... (n in all)"``'s two parts for an error message:
    each unknown name with the closest known ones, then the first ``shown`` known names."""
    parts = []
    for k in unknown:
        close = difflib.get_close_matches(str(k), list(known), n=3, cutoff=0.6)
        parts.append(f"{k!r}" + (f" (did you mean {', '.join(map(repr, close))}?)" if close else ""))
    listed = ", ".join(known[:shown]) + (f", ... ({len(known)} in all)" if len(known) > shown else "")
    return ", ".join(parts), listed or "(none)"


class JaxskidError(Exception):
    """Base class of all errors jaxskid raises on purpose."""


class DescriptionWarning(UserWarning):
    """A description holds something jaxskid reads differently from what it says, as Skidy does (a ``child``
    list that disagrees with ``parent``): the message names the file, the key and what is used instead."""


class PhysicalConsistencyWarning(UserWarning):
    """A body's default mass and inertia are not those of any rigid body (zero mass with a rotational inertia,
    principal moments that break the triangle inequality): the message names the file and the body. Every
    algorithm still runs on them; make it an error with
    ``warnings.simplefilter("error", jaxskid.PhysicalConsistencyWarning)``."""


class ModelError(JaxskidError, ValueError):
    """A robot description is malformed or violates an invariant.

    ``message`` says what was expected and what was found; ``where`` is the key path inside the description (``"mass_inertia[2].inertia"``); ``source`` is the
    file it came from, if any. ``str(err)`` reads ``"robot.yaml: mass_inertia[2].inertia: expected ..."``.
    """

    def __init__(self, message: str, *, where: str | None = None, source: str | None = None):
        self.message = message
        self.where = where
        self.source = source
        super().__init__(self._format())

    def _format(self) -> str:
        parts = [p for p in (self.source, self.where) if p]
        return ": ".join([*parts, self.message])

    def located(self, *, source: str | None = None, prefix: str | None = None) -> "ModelError":
        """The same error, with a file name and/or an outer key path added."""
        where = self.where
        if prefix:
            where = f"{prefix}.{where}" if where and not where.startswith("[") else f"{prefix}{where or ''}"
        return ModelError(self.message, where=where, source=source or self.source)

    def __reduce__(self):  # keep pickling (multiprocessing, pytest-xdist) working with keyword fields
        return (_rebuild_model_error, (self.message, self.where, self.source))


def _rebuild_model_error(message, where, source):
    return ModelError(message, where=where, source=source)


class RequestError(JaxskidError, ValueError):
    """A request names a quantity, parameter or argument that the lowered model does not have."""


class InputError(JaxskidError, ValueError):
    """An argument of a call holds values it cannot use: NaN or inf in a state or a parameter (the message
    names the argument and the first bad index), a parameter value that is not a number, or one no rigid
    body has (a negative mass). Raised by top-level calls, before anything runs."""


class ShapeError(JaxskidError, ValueError):
    """An argument passed to a generated function has the wrong shape or size."""


class IdentificationError(JaxskidError, ValueError):
    """Identification data that cannot determine the parameters asked for: a regressor whose columns are
    linearly dependent (the message names them and the combination), or too few equations."""


class IdentificationWarning(UserWarning):
    """Identification data that determine the parameters only poorly: a regressor with a large condition
    number (the message names the columns of the worst-determined direction)."""
