"""Cross-validation of identified parameters: predicted against measured joint forces on other data.

:func:`validate` predicts ``tau = Y(q, qd, qdd) pi`` (or the model's inverse dynamics) on samples not used in
the fit and reports each joint's RMS error, absolute and relative to the measured RMS;
:func:`plot_validation` draws predicted and measured torques per joint (matplotlib, imported on use).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..._errors import RequestError, ShapeError
from ...runtime._dynamics import Dynamics


class Validation(NamedTuple):
    """Per joint: ``rms`` (n,) the RMS of ``predicted - measured``, ``relative`` (n,) that over the RMS of
    ``measured`` (``inf`` for a joint measured as all zero); ``predicted`` and ``measured`` (samples, n)."""

    rms: np.ndarray
    relative: np.ndarray
    predicted: np.ndarray
    measured: np.ndarray


def validate(model, params, *data, base=None, kinematics=None) -> Validation:
    """Joint-force prediction errors of identified parameters on (validation) samples.

    Called as ``validate(dyn, params, q, qd, qdd, tau)`` with a :class:`Dynamics`, or
    ``validate(y, params, tau)`` with a regressor already evaluated, ``y (samples, n, p)``.

    Args:
        model: a :class:`Dynamics` with the quantity ``regressor`` (or ``inverse_dynamics``, for a dict of
            parameters), or a regressor ``(samples, n, p)``.
        params: the identified parameters: standard parameters (one per regressor column), base parameters
            (with ``base``), an :class:`Estimate`, or, with a :class:`Dynamics` lowered with
            ``inverse_dynamics``, a dict of the robot's own parameters.
        data: ``q, qd, qdd, tau`` (samples, n) each for a :class:`Dynamics`; ``tau`` for a regressor.
        base: the :class:`BaseParameters` that ``params`` are base parameters of.
        kinematics: the parameters the regressor of a :class:`Dynamics` is evaluated at (default: the
            robot's defaults).
    """
    params = getattr(params, "params", params)  # an Estimate
    if isinstance(model, Dynamics):
        if len(data) != 4:
            raise RequestError(f"validate: expected validate(dyn, params, q, qd, qdd, tau), got {len(data)} arrays "
                               "after params")
        q, qd, qdd, tau = (np.asarray(x, dtype=float) for x in data)
        predicted = _predict(model, params, q, qd, qdd, base, kinematics)
    else:
        if len(data) != 1:
            raise RequestError(f"validate: expected validate(y, params, tau) with a regressor y, got {len(data)} "
                               "arrays after params")
        y, tau = np.asarray(model, dtype=float), np.asarray(data[0], dtype=float)
        if y.ndim != 3:
            raise ShapeError(f"validate: expected a regressor y (samples, n, p), got shape {y.shape}")
        predicted = _linear(y, params, base)
    if tau.shape != predicted.shape:
        raise ShapeError(f"validate: tau has shape {tau.shape}; expected {predicted.shape} (samples, n)")
    rms = np.sqrt(np.mean((predicted - tau) ** 2, axis=0))
    scale = np.sqrt(np.mean(tau**2, axis=0))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(scale > 0, rms / np.where(scale > 0, scale, 1.0), np.where(rms > 0, np.inf, 0.0))
    return Validation(rms, relative, predicted, tau)


def _linear(y, params, base) -> np.ndarray:
    if base is not None:
        y = np.asarray(base.reduce(y))
    params = np.asarray(params, dtype=float)
    if params.shape != (y.shape[-1],):
        kind = "base parameters" if base is not None else "standard parameters (one per regressor column)"
        raise ShapeError(f"validate: expected {y.shape[-1]} {kind}, got params of shape {params.shape}")
    return y @ params


def _predict(dyn: Dynamics, params, q, qd, qdd, base, kinematics) -> np.ndarray:
    if not (q.ndim == 2 and q.shape[1] == dyn.n_dof and q.shape == qd.shape == qdd.shape):
        raise ShapeError(f"validate: expected q, qd, qdd (samples, {dyn.n_dof}) each, got {q.shape}, {qd.shape}, "
                         f"{qdd.shape}")
    if isinstance(params, Mapping):
        if "inverse_dynamics" not in dyn.quantities:
            raise RequestError("validate: a dict of parameters needs the quantity inverse_dynamics; lowered: "
                               f"{', '.join(dyn.quantities)}")
        return np.asarray(dyn.inverse_dynamics(q, qd, qdd, params))
    if "regressor" not in dyn.quantities:
        raise RequestError(f"validate: standard or base parameters need the quantity regressor; lowered: "
                           f"{', '.join(dyn.quantities)}")
    return _linear(np.asarray(dyn.regressor(q, qd, qdd, kinematics)), params, base)


def plot_validation(result: Validation, path, *, t=None, names=None, title: str | None = None) -> Path:
    """Draw measured and predicted joint forces, one panel per joint (RMS errors in the panel titles), and
    save the figure to ``path`` (any format matplotlib writes, from the suffix). Returns the path.

    ``t`` (samples,): the time axis (default: the sample index); ``names``: the joints' names."""
    from matplotlib.figure import Figure  # optional dependency: imported only to plot

    n = result.measured.shape[1]
    names = list(names) if names is not None else [f"joint {j + 1}" for j in range(n)]
    if len(names) != n:
        raise ShapeError(f"plot_validation: {len(names)} names for {n} joints")
    x = np.arange(result.measured.shape[0]) if t is None else np.asarray(t, dtype=float)
    if x.shape != result.measured.shape[:1]:
        raise ShapeError(f"plot_validation: t has shape {x.shape}; expected ({result.measured.shape[0]},)")
    cols = min(n, 3)
    rows = -(-n // cols)
    fig = Figure(figsize=(4.5 * cols, 2.8 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for j in range(n):
        ax = axes[j]
        ax.plot(x, result.measured[:, j], color="0.6", lw=1.5, label="measured")
        ax.plot(x, result.predicted[:, j], color="C0", lw=1.0, ls="--", label="predicted")
        ax.set_title(f"{names[j]}: RMS {result.rms[j]:.3g} ({100 * result.relative[j]:.2g} %)", fontsize=9)
        ax.set_xlabel("t [s]" if t is not None else "sample")
    for ax in axes[n:]:
        ax.set_visible(False)
    axes[0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=100)
    return path
