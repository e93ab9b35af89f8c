"""diffrax solvers and step-size controllers in :func:`jaxskid.rollout`.

``rollout(..., integrator=solver, stepsize_controller=controller)`` with a ``diffrax.AbstractSolver``:

* no controller (or ``diffrax.ConstantStepSize()``): fixed steps of ``dt``. The solver's step
  (``solver.step``) runs inside jaxskid's own loops (:mod:`jaxskid.apps.simulation._loop`), exactly like :class:`RK4`, so
  saving, checkpointing, batching and per-rollout steps behave the same. Each step starts afresh
  (``made_jump=True``: an FSAL solver re-evaluates its first stage, since the torque may jump there). An
  implicit solver then needs its root finder's tolerances, e.g.
  ``diffrax.Kvaerno5(root_finder=diffrax.VeryChord(rtol=1e-6, atol=1e-6, norm=optimistix.max_norm))``
  (tighter ones can make the chord iteration report divergence near round-off: 1e-8 did on a 2-R arm at
  5 ms steps, where 1e-6 gave states within 1e-10); a step whose root finder fails gives nan. diffrax's step
  costs more than :class:`RK4`'s in these loops (``benchmarks/tradeoff_rollouts.py``).
* an adaptive controller (``diffrax.PIDController(rtol, atol)``): one ``diffrax.diffeqsolve`` from 0 to
  ``steps * dt`` with initial step ``dt``. Array controls are held over the grid ``t_k = k dt``, whose
  points are passed as ``jump_ts`` (``diffrax.ClipStepSizeController``): steps stop just before each jump
  and restart just after it. Saved states between steps come from the solver's dense output. At most
  ``16 * steps + 4096`` solver steps, rejected ones included (diffrax's ``max_steps``: more is an error);
  gradients use diffrax's ``RecursiveCheckpointAdjoint``. Implicit solvers take the controller's tolerances.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import diffrax
import jax
import jax.numpy as jnp

from ..._errors import RequestError
from ._field import held
from ._integrators import fixed_step
from ._saving import Checkpoint, SaveAt


@dataclass(frozen=True)
class DiffraxStep:
    """A diffrax solver as a fixed-step integrator: ``step(f, t, y, dt) -> (y1, aux)`` (see
    :mod:`jaxskid.apps.simulation._integrators`), ``aux`` from ``f`` at ``(t, y)``."""

    solver: diffrax.AbstractSolver

    def step(self, f: Callable, t, y, dt):
        pack, unpack = _packing(y[2])
        term = diffrax.ODETerm(lambda s, v, args: pack(f(s, unpack(v))[0]))
        state = self.solver.init(term, t, t + dt, pack(y), None)
        y1, _, _, _, result = self.solver.step(term, t, t + dt, pack(y), None, state, made_jump=True)
        ok = result == diffrax.RESULTS.successful
        return unpack(jax.tree.map(lambda a: jnp.where(ok, a, jnp.nan), y1)), f(t, y)[1]  # f's dynamics unused


def _packing(z0) -> tuple[Callable, Callable]:
    """(ours -> diffrax's, diffrax's -> ours) for ``y = (q, qd, z)``: diffrax's loops take no empty leaves, so
    without a controller state diffrax sees ``(q, qd)``."""
    if jax.tree.leaves(z0):
        return (lambda y: y), (lambda y: y)
    return (lambda y: y[:2]), (lambda y: (*y, z0))


@dataclass(frozen=True)
class Adaptive:
    """A diffrax solver with an adaptive step-size controller: one ``diffeqsolve`` per rollout."""

    solver: diffrax.AbstractSolver
    controller: diffrax.AbstractAdaptiveStepSizeController
    adaptive = True

    def run(self, *args):
        """:func:`adaptive_rollout` with this solver and controller."""
        return adaptive_rollout(self, *args)


def stepping(integrator, stepsize_controller):
    """The rollout's integrator from ``integrator`` and ``stepsize_controller``, checked."""
    if stepsize_controller is not None and not isinstance(
        stepsize_controller, (diffrax.ConstantStepSize, diffrax.AbstractAdaptiveStepSizeController)
    ):
        raise RequestError(
            f"rollout: stepsize_controller: expected None, diffrax.ConstantStepSize or an adaptive diffrax "
            f"controller (diffrax.PIDController(rtol, atol)), got {type(stepsize_controller).__name__}"
        )
    adaptive = isinstance(stepsize_controller, diffrax.AbstractAdaptiveStepSizeController)
    if not isinstance(integrator, diffrax.AbstractSolver):
        fixed_step(integrator)
        if adaptive:
            raise RequestError(f"rollout: {type(integrator).__name__} takes fixed steps of dt; for adaptive steps "
                               "pass a diffrax solver, e.g. integrator=diffrax.Tsit5()")
        return integrator
    structure = integrator.term_structure
    if not (isinstance(structure, type) and issubclass(structure, diffrax.AbstractTerm)):
        raise RequestError(f"rollout: integrator: {type(integrator).__name__} takes the terms {structure}; rollouts "
                           "give one ODETerm (first-order form: explicit or implicit Runge-Kutta solvers)")
    if adaptive:
        return Adaptive(integrator, stepsize_controller)
    if isinstance(integrator, diffrax.AbstractImplicitSolver) and not isinstance(
        getattr(integrator.root_finder, "rtol", None), (int, float)
    ):
        raise RequestError(
            f"rollout: {type(integrator).__name__} with fixed steps needs its root finder's tolerances: "
            "pass stepsize_controller=diffrax.PIDController(rtol=..., atol=...) for adaptive steps, or "
            "root_finder=diffrax.VeryChord(rtol=..., atol=..., norm=optimistix.max_norm)"
        )
    return DiffraxStep(integrator)


def adaptive_rollout(
    stepper: Adaptive, f: Callable, observe: Callable, y0, u, dt, steps: int, saveat: SaveAt, index,
    checkpoint: Checkpoint | None, tau0,
):
    """One adaptive diffrax solve of ``f(t, y, u_k) -> (dy/dt, tau)`` (:func:`~jaxskid.apps.simulation._field.dynamics_field`):
    the saved ``observe(y)`` ``(n_saved, ...)`` and torques ``(n_saved - 1, n)``, as for the fixed-step loops.

    ``u``: torques ``(steps, n)`` or None; ``index``: the step numbers of ``saveat.ts`` (else None).
    """
    grid = dt * jnp.arange(steps + 1, dtype=dt.dtype)
    controller = stepper.controller
    if u is not None and steps > 1:
        controller = diffrax.ClipStepSizeController(controller, jump_ts=grid[1:-1])
    pack, unpack = _packing(y0[2])

    def u_at(t):
        return None if u is None else held(u, grid, t)

    def save(t, y, args):  # the torque at a saved state: f's dynamics are unused there and removed
        x, z = observe(unpack(y))
        return x, f(t, unpack(y), u_at(t))[1].astype(tau0.dtype), *([z] if jax.tree.leaves(z) else [])

    k = saveat.block(steps)
    if k is None:
        where = diffrax.SaveAt(ts=grid[index], fn=save)
    elif saveat.t1:
        where = diffrax.SaveAt(t0=saveat.t0, t1=True, fn=save)
    else:
        where = diffrax.SaveAt(ts=grid[::k], fn=save)
    checkpoints = None if checkpoint is None else math.ceil(steps / checkpoint.size(steps))
    solution = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, args: pack(f(t, unpack(y), u_at(t))[0])), stepper.solver, grid[0], grid[-1],
        dt, pack(y0), saveat=where, stepsize_controller=controller, max_steps=16 * steps + 4096,
        adjoint=diffrax.RecursiveCheckpointAdjoint(checkpoints=checkpoints),
    )
    x, tau, *z = solution.ys
    return (x, z[0] if z else y0[2]), tau[:-1]
