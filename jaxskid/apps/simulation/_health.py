"""Whether a fixed step integrates a closed loop stably: the check behind :class:`RolloutWarning`.

A step of RK4 maps a mode ``exp(lambda t)`` of the closed loop linearised at a state to ``R(h lambda)``, with
``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24`` (Hairer & Wanner, "Solving Ordinary Differential Equations II",
sec. IV.2). Where ``|R(h lambda)| > 1`` for a mode the system itself damps (``Re lambda <= 0``), the
integrator injects energy there: stiff contact springs and joint dampers on light links do this to a
quadruped at 1 ms (solo12, ``examples/quadruped_drop.py``: ``KD = 0.5`` on its knees puts an eigenvalue near
-1.3e3 to -4.9e3 s^-1 into the loop). :func:`step_stability` linearises the rollout's own vector field
(controller and contacts included) at given states by reverse-mode differentiation, takes the eigenvalues
and finds the largest step that keeps every damped mode within RK4's stability region.
:func:`jaxskid.rollout` runs it by default on the final states of rollouts with :class:`GroundContact`, and
warns once per call, naming the rollouts and that step; ``health=True`` asks for it in any scene and
``health=False`` skips it.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ._field import as_controls, dynamics_field


MARGIN = 0.7
"""The step the warning names is this fraction of the largest stable one at the states checked: the robot at rest
where it settles is stiffer than where a too long step left it (solo12: -5.2e3 against -4.0e3 s^-1)."""


class RolloutWarning(UserWarning):
    """A rollout's step amplifies a damped mode of its closed loop (the integrator injects energy): the message
    names the rollouts and a step that keeps them stable (:mod:`jaxskid.apps.simulation._health`)."""


class StepStability(NamedTuple):
    """:func:`step_stability`'s result, one entry per state (batch axes of ``x``).

    ``amplification``: ``max |R(h lambda)|`` over the damped modes (``<= 1``: stable at ``dt``);
    ``fastest``: the eigenvalue of largest magnitude (complex, 1/s); ``stable_dt``: the largest step (s), at most
    ``dt``, that keeps every damped mode within RK4's stability region.
    """

    amplification: np.ndarray
    fastest: np.ndarray
    stable_dt: np.ndarray


def _rk4_gain(z):
    return np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)


def _largest_stable(eigenvalues: np.ndarray, dt: float) -> float:
    """The largest ``h <= dt`` with ``|R(h lambda)| <= 1`` for every eigenvalue (bisection on a log scale)."""
    if _rk4_gain(dt * eigenvalues).max() <= 1 + 1e-9:
        return dt
    lo, hi = 0.0, dt
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _rk4_gain(mid * eigenvalues).max() <= 1 + 1e-9 else (lo, mid)
    return lo


def step_stability(dyn, controls, x, dt: float, params=None) -> StepStability:
    """How RK4 at step ``dt`` treats the closed loop ``dx/dt = f(t, x)`` of ``rollout(dyn, x, controls, dt, ...)``
    linearised at the states ``x`` ``(..., nq + nv)`` (module docstring). ``params``: one parameter set
    (``None``: the defaults). Modes that grow by themselves (``Re lambda > 0``, an unstable plant) are not
    counted against the step. A floating base's quaternion adds a neutral direction (``lambda = 0``)."""
    controller, _ = as_controls(controls)
    x = jnp.asarray(x)
    p = dyn.param_vector(params, x.dtype)
    field = dynamics_field(dyn, controller, p, False, "reverse")
    nq = dyn.nq
    z0 = controller.init(x[(0,) * (x.ndim - 1)]) if controller is not None else ()

    def rate(x1):
        (dq, dv, _), _ = field(0.0, (x1[:nq], x1[nq:], z0), None if controller is not None else jnp.zeros(dyn.nv))
        return jnp.concatenate([dq, dv])

    flat = x.reshape((-1, x.shape[-1]))
    # reverse mode: the quantities' closed-form pullbacks (native kernels on CPU) rather than forward mode
    # through their JAX form, whose program for a dozen contact frames took a minute to compile
    jac = np.asarray(jax.jit(jax.vmap(jax.jacrev(rate)))(flat))
    amplification, fastest, stable = [], [], []
    for j in jac:
        ev = np.linalg.eigvals(j)
        damped = ev[ev.real <= 1e-9 * max(1.0, float(np.abs(ev).max()))]
        amplification.append(float(_rk4_gain(dt * damped).max()) if damped.size else 1.0)
        fastest.append(ev[np.argmax(np.abs(ev))])
        stable.append(_largest_stable(damped, dt) if damped.size else dt)
    shape = x.shape[:-1]
    return StepStability(np.reshape(amplification, shape), np.reshape(fastest, shape), np.reshape(stable, shape))


def warn_if_unstable(dyn, controls, x_final, dt, params=None, stacklevel: int = 3) -> StepStability:
    """:func:`step_stability` at the rollouts' final states and at their final configurations at rest, and one
    :class:`RolloutWarning` naming the rollouts the step does not integrate stably and the step that would.

    At rest is where a damped scene ends and where it is stiffest: feet that stick to the ground under
    regularised friction. A step too long for that state keeps the robot from ever reaching it (solo12 at
    1 ms chatters on its feet), so the final state alone, still moving, would not show it."""
    x_final = jnp.asarray(x_final)
    at_rest = x_final.at[..., dyn.nq:].set(0.0)
    both = step_stability(dyn, controls, jnp.stack([x_final, at_rest]), float(np.max(dt)), params)
    check = StepStability(*(np.take_along_axis(a, np.argmax(both.amplification, axis=0)[None], axis=0)[0]
                            for a in both))
    bad = np.argwhere(np.atleast_1d(check.amplification) > 1 + 1e-9)
    if bad.size:
        names = ", ".join(str(tuple(int(i) for i in b)) if len(b) > 1 else str(int(b[0])) for b in bad[:5])
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        rollouts = f"rollouts {names}{more} of {np.size(check.amplification)}" if np.ndim(check.amplification) \
            else "the rollout"
        fix = MARGIN * float(np.min(check.stable_dt))
        fastest = np.atleast_1d(check.fastest).ravel()[np.argmax(np.atleast_1d(check.amplification).ravel())]
        warnings.warn(
            f"rollout: dt = {float(np.max(dt)):.3g} s amplifies a damped mode of the closed loop at the final state "
            f"(moving or at rest) of {rollouts} (RK4 gain {float(np.max(check.amplification)):.6f} per step; fastest eigenvalue "
            f"{complex(fastest):.4g} 1/s): the integrator injects energy. dt <= {fix:.3g} s keeps every mode "
            f"stable (or lower the stiffness or damping that makes it)", RolloutWarning, stacklevel=stacklevel)
    return check


def warn_if_below_ground(contact, x_final, stacklevel: int = 3) -> np.ndarray:
    """One :class:`RolloutWarning` where a floating base ends below the ground of ``contact`` (a
    :class:`~jaxskid.GroundContact`) and none of its contact frames is on the base
    (:meth:`~jaxskid.GroundContact.on_base`): nothing holds the base up, so it falls through the floor. Returns
    whether each rollout's base ended below the ground ``(...)`` (all False for a fixed base or a base with
    contact frames)."""
    x_final = np.asarray(x_final)
    height = float(contact.height)
    below = x_final[..., 2] < height
    if not contact.dyn.floating_base or not below.any() or contact.on_base():
        return np.zeros(x_final.shape[:-1], bool)
    bad = np.argwhere(np.atleast_1d(below))
    if bad.size:
        names = ", ".join(str(tuple(int(i) for i in b)) if len(b) > 1 else str(int(b[0])) for b in bad[:5])
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        which = f"rollouts {names}{more} of {np.size(below)}" if np.ndim(below) else "the rollout"
        shown = ", ".join(contact.frames[:4]) + (", ..." if len(contact.frames) > 4 else "")
        warnings.warn(
            f"rollout: the floating base of {which} ends below the ground (base z = "
            f"{float(np.min(x_final[..., 2])):.3g} m < height {height:g} m), and none of GroundContact's frames "
            f"({shown}) is on the base: it passes through the floor. Give the base contact points: "
            f"jaxskid.collision_points(urdf, links=[<base link>]) as end-effectors, and their radii to "
            f"GroundContact", RolloutWarning, stacklevel=stacklevel)
    return below


@jax.jit
def _ended_finite(x):
    """Whether every rollout's last saved state is finite: one compiled reduction (three eager operations made a
    hundred-step rollout of the Panda half as slow again, ``benchmarks/rollouts.py``, batch 1)."""
    return jnp.all(jnp.isfinite(x[..., -1, :]))


def warn_if_not_finite(dyn, controls, traj, dt, params=None, analyse=lambda: True, stacklevel: int = 3) -> bool:
    """One :class:`RolloutWarning` where a rollout's last saved state is not finite (NaN and inf do not leave a
    rollout once they enter it): the rollouts, when it first went wrong and, where ``analyse()`` (RK4, one step and
    one parameter set; asked only then), whether the step integrates the closed loop at the first saved state
    stably, and the step that would. Returns whether every rollout ended finite (one reduction on the device when
    they did)."""
    if bool(_ended_finite(traj.x)):
        return True
    x = np.asarray(traj.x)
    bad = ~np.isfinite(x).all(-1)  # (..., n_saved)
    ended = np.argwhere(np.atleast_1d(bad[..., -1]))
    first = tuple(int(i) for i in ended[0]) if bad.ndim > 1 else ()
    k = int(np.argmax(bad[first]))
    times = np.asarray(traj.t)
    t = float(times[first][k] if times.ndim > 1 else times[k])
    names = ", ".join(str(tuple(int(i) for i in b)) if len(b) > 1 else str(int(b[0])) for b in ended[:5])
    more = f" and {len(ended) - 5} more" if len(ended) > 5 else ""
    which = f"rollouts {names}{more} of {np.size(bad[..., -1])}" if bad.ndim > 1 else "the rollout"
    since = f"from t = {t:.4g} s (saved state {k})" if k else "at every saved state"
    text = f"rollout: the state of {which} is not finite {since} on: it diverged."
    start = x[first][0]
    if k and np.isfinite(start).all() and analyse():
        check = step_stability(dyn, controls, jnp.asarray(start), float(np.max(dt)), params)
        if float(check.amplification) > 1 + 1e-9:
            text += (f" dt = {float(np.max(dt)):.3g} s amplifies a damped mode of the closed loop at the first saved "
                     f"state (RK4 gain {float(check.amplification):.4g} per step; fastest eigenvalue "
                     f"{complex(check.fastest):.4g} 1/s): dt <= {MARGIN * float(check.stable_dt):.3g} s keeps every "
                     f"mode stable there (or lower the stiffness or damping that makes it)")
        else:
            text += (" The step integrates the closed loop stably at the first saved state: look for torques, "
                     "forces or parameters that grow without bound, or a singular mass matrix")
    elif k:
        text += " A shorter step (or, for a stiff loop, an implicit diffrax solver such as Kvaerno5) may hold it"
    warnings.warn(text, RolloutWarning, stacklevel=stacklevel)
    return False
