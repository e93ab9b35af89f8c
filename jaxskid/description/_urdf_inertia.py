"""A URDF link's inertia: the 6x6 mass-inertia in the link frame, and its 10 standard parameters.

``<inertial>`` gives the mass, the centre of mass and the inertia about it in the axes of the ``<origin>``
frame; jaxskid's body inertia is about the link frame's origin in its axes (:mod:`jaxskid.model._lie`). With
``symbolic_inertia`` each body's inertia is written with its parameters ``{link}_m, {link}_mcx, ...``
(:data:`jaxskid.model._lie.STANDARD_PARAMETER_NAMES`), the URDF's values being their defaults; a floating
base keeps its root link's inertia the same way.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import sympy as sp

from .._errors import DescriptionWarning, ModelError
from ..model import _lie as lie
from ..model._inertia_check import breaks_triangle
from ..model._robot import Joint, symbol
from ..model._validate import EIGEN_TOL


def exact(x) -> sp.Expr:
    x = float(x)
    return sp.Integer(int(x)) if x.is_integer() else sp.Float(x)


def rotation_translation(pose) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (round-off next to -1, 0, 1 snapped, so that right angles stay exact) and translation."""
    c = np.eye(4) if pose is None else np.asarray(pose, dtype=float)
    r = c[:3, :3]
    snapped = np.round(r)
    r = np.where(np.abs(r - snapped) < 1e-14, snapped, r)
    return r, c[:3, 3]


def link_inertia(inertial) -> np.ndarray:
    """The link's 6x6 mass-inertia in its own frame: the inertia about the centre of mass is rotated from
    the <inertial> frame into the link frame, then moved to the link origin (parallel-axis theorem)."""
    if inertial is None:  # URDF allows a link without <inertial>: massless, as in Pinocchio
        return np.zeros((6, 6))
    r, c = rotation_translation(inertial.origin)
    ic = r @ np.asarray(inertial.inertia, dtype=float) @ r.T
    m6 = np.array(lie.spatial_inertia(float(inertial.mass or 0.0), c.tolist(), sp.Matrix(ic)), dtype=float)
    return 0.5 * (m6 + m6.T)  # float round-off in the products breaks exact symmetry


def inertial_parameters(joints: list[Joint], symbolic: bool) -> tuple[list[Joint], dict[str, float]]:
    """With ``symbolic``, every body's inertia written with its 10 standard parameters, whose values
    become the defaults; else the joints as they are."""
    if not symbolic:
        return joints, {}
    out, defaults, owner = [], {}, {}
    for j in joints:
        names = _parameter_names(j.link, owner)
        defaults.update({n: float(v) for n, v in zip(names, lie.standard_parameters(j.inertia))})
        out.append(replace(j, inertia=lie.inertia_from_parameters(*(symbol(n) for n in names))))
    return out, defaults


def root_inertia(floating_base, root) -> sp.ImmutableMatrix | None:
    """The root link's numeric 6x6 inertia for a floating base (``None`` for a fixed one, which drops it)."""
    if floating_base is not True:  # Robot.create names what is wrong with a value that is not a bool
        return None
    return sp.ImmutableMatrix(6, 6, [exact(x) for x in link_inertia(root.inertial).flat])


def base_parameters(root_link: str, inertia, symbolic: bool, joints: list[Joint]) -> tuple:
    """The floating base's inertia written with its 10 standard parameters (as :func:`inertial_parameters`)."""
    if inertia is None or not symbolic:
        return inertia, {}
    owner = {}
    for j in joints:
        _parameter_names(j.link, owner)
    names = _parameter_names(root_link, owner)
    defaults = {n: float(v) for n, v in zip(names, lie.standard_parameters(inertia))}
    return lie.inertia_from_parameters(*(symbol(n) for n in names)), defaults


def _parameter_names(link: str, owner: dict[str, str]) -> list[str]:
    """``{link}_m, ..., {link}_Izz`` with ``link`` made a valid (ASCII) identifier; ``owner`` maps the
    prefixes already used to their links."""
    prefix = re.sub(r"[^0-9A-Za-z_]", "_", link)
    prefix = f"_{prefix}" if prefix[:1].isdigit() else prefix
    if prefix in owner:
        raise ModelError(
            f"expected link names that stay distinct as identifiers, got {owner[prefix]!r} and {link!r} "
            f"(both give parameters {prefix}_m, {prefix}_mcx, ...)",
            where=f"link[name={link}].name",
        )
    owner[prefix] = link
    return [f"{prefix}_{k}" for k in lie.STANDARD_PARAMETER_NAMES]


def balanced(ic: np.ndarray) -> np.ndarray | None:
    """A rotational inertia about the centre of mass that no rigid body has, made isotropic with the same trace
    (MuJoCo's ``balanceinertia``), for ``load(..., balance_inertia=True)``; None when ``ic`` is physical by the
    loader's own rules (positive semi-definite as :func:`~jaxskid.model._validate.check_positive_semidefinite`
    tests it, the triangle inequality as :func:`~jaxskid.model._inertia_check.breaks_triangle` does), or when
    its trace is negative (no balance makes that a body)."""
    moments = np.linalg.eigvalsh(0.5 * (ic + ic.T))
    indefinite = moments[0] < -EIGEN_TOL * max(1.0, float(np.abs(ic).max()))
    if not indefinite and not breaks_triangle(moments):
        return None
    trace = float(moments.sum())
    return None if trace < 0 else np.eye(3) * (trace / 3)


def put_balanced(source: str, links: Mapping, fixes: dict | None) -> None:
    """Put the balanced inertias of ``fixes`` (``{link: inertia}``, from :func:`_check_document`) into
    yourdfpy's links, with one warning."""
    if not fixes:
        return
    for name, ic in fixes.items():
        links[name].inertial.inertia = ic
    listed = ", ".join(f"{name} ({ic[0, 0]:.6g})" for name, ic in fixes.items())
    warnings.warn(f"{source}: link[name={next(iter(fixes))}].inertial.inertia: {len(fixes)} inertia(s) that no rigid "
                  f"body has made isotropic with the same trace (balance_inertia=True): {listed}",
                  DescriptionWarning, stacklevel=5)
