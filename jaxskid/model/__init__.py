"""The robot model: an immutable tree of joints and bodies with symbolic inertial parameters.

:class:`Robot` (``_robot``) is built from :class:`Joint` s and :class:`Frame` s (``_joint``), whose drives are
:class:`Drive` s (``_drive``) and whose couplings are :class:`Mimic` s (``_mimic``), and validated in
one place (``_validate``); fixed joints are locked and welded by ``_fixed``; ``_lie`` holds the SymPy
spatial matrices and ``_parameters`` the rule that maps a user's parameters onto a model's. Its constraints
(contacts, loop closures) are ``_constraint``'s, whose satisfiability ``_closure`` checks numerically.

The names below are imported on first use: ``_parameters`` is sympy-free and serves the runtime, which
must not import SymPy by importing this package.
"""

import warnings
from importlib import import_module

_EXPORTS = {
    "Drive": "_drive",
    "Frame": "_joint",
    "FrameContact": "_constraint",
    "LoopClosure": "_constraint",
    "PointContact": "_constraint",
    "Joint": "_joint",
    "JointLimits": "_joint",
    "JOINT_TYPES": "_robot",
    "Mimic": "_mimic",
    "ParameterLayout": "_parameters",
    "Robot": "_robot",
    "lock_joint": "_fixed",
    "merge_fixed": "_fixed",
    "spatial_to_body": "_robot",
    "symbol": "_validate",
    "to_expr": "_validate",
    "check_model": "_validate",
}
_DEPRECATED = {"validate": ("check_model", "jaxskid.validate is the validation of an identified model against data")}
"""Old names, kept for a while with a DeprecationWarning: name -> (its new name, why it changed)."""
__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _DEPRECATED:
        new, why = _DEPRECATED[name]
        warnings.warn(f"jaxskid.model.{name} is deprecated: use jaxskid.model.{new} ({why})", DeprecationWarning,
                      stacklevel=2)
        name = new
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f"{__name__}.{_EXPORTS[name]}"), name)
