"""Rollouts with diffrax solvers, and the equations of motion as a diffrax vector field.

References: jaxskid's RK4 at a step 100x smaller (its measured order is 4, tests/test_simulate.py; its error
here is below 1e-9) for adaptive explicit (Tsit5) and implicit (Kvaerno5) solves; its gradient for the
gradient through diffrax's adjoint; the measured convergence order of a fixed-step diffrax solver; a direct
``diffrax.diffeqsolve`` of ``jaxskid.vector_field`` for the rollout that wraps it; single rollouts for a batch.
"""

from __future__ import annotations

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import optimistix
import pytest
from helpers import FD, Integral, load

import jaxskid

X0 = jnp.array([0.4, -0.3, 0.1, 0.2])
STEPS, DT, FINE = 10, 0.05, 100
CONTROLS = 0.5 * np.random.default_rng(1).normal(size=(STEPS, 2))


def policy(t, x):
    return jnp.array([0.6, -0.4]) * jnp.sin(6.0 * t) - 0.2 * x[2:]


def tight(tol=1e-12):
    return diffrax.PIDController(rtol=tol, atol=tol)


@pytest.fixture(scope="module")
def arm():
    return jaxskid.lower(load("arm_2r"), FD)


def reference(arm, controls, saveat=None):
    """RK4 at DT / FINE, the states every DT (or as ``saveat`` says, in fine steps)."""
    u = np.repeat(controls, FINE, axis=0) if isinstance(controls, np.ndarray) else controls
    return jaxskid.rollout(arm, X0, u, DT / FINE, STEPS * FINE, saveat=saveat or jaxskid.SaveAt(every=FINE))


@pytest.mark.parametrize("solver, controls", [
    (diffrax.Tsit5(), "array"), (diffrax.Tsit5(), "policy"), (diffrax.Kvaerno5(), "array"),
], ids=["Tsit5-array", "Tsit5-policy", "Kvaerno5-array"])
def test_adaptive_solvers_agree_with_fine_rk4(arm, solver, controls):
    """Array torques jump at every DT (the solver stops at each jump); a policy is smooth."""
    u = CONTROLS if controls == "array" else policy
    ours = jaxskid.rollout(arm, X0, u, DT, STEPS, solver, stepsize_controller=tight(1e-11))
    ref = reference(arm, u)
    assert ours.x.shape == (STEPS + 1, 4)
    np.testing.assert_allclose(np.asarray(ours.x), np.asarray(ref.x), rtol=0, atol=1e-8)
    np.testing.assert_allclose(np.asarray(ours.tau), np.asarray(ref.tau), rtol=0, atol=1e-8)
    if controls == "array":
        np.testing.assert_array_equal(np.asarray(ours.tau), CONTROLS)  # held over the grid


def test_gradient_through_adaptive_solve(arm):
    """diffrax's RecursiveCheckpointAdjoint, against the gradient of the fine RK4 rollout."""
    final = jaxskid.SaveAt(t1=True)

    def adaptive(x0):
        x = jaxskid.rollout(arm, x0, CONTROLS, DT, STEPS, diffrax.Tsit5(), stepsize_controller=tight(1e-11),
                            saveat=final, checkpoint=jaxskid.Checkpoint()).x
        return jnp.sum(x * x)

    def fine(x0):
        x = jaxskid.rollout(arm, x0, np.repeat(CONTROLS, FINE, axis=0), DT / FINE, STEPS * FINE, saveat=final).x
        return jnp.sum(x * x)

    grads = [jaxskid.jit(jax.grad(f))(X0) for f in (adaptive, fine)]  # jaxskid.jit: its compiler options
    np.testing.assert_allclose(np.asarray(grads[0]), np.asarray(grads[1]), rtol=1e-7)


def test_vector_field_in_diffeqsolve(arm):
    """The public vector field, solved by diffrax directly, equals the rollout; with a controller state too."""
    grid = DT * jnp.arange(STEPS + 1)
    clip = diffrax.ClipStepSizeController(tight(), jump_ts=grid[1:-1])
    end = diffrax.SaveAt(t1=True)
    direct = diffrax.diffeqsolve(diffrax.ODETerm(jaxskid.vector_field(arm, CONTROLS, dt=DT)), diffrax.Tsit5(),
                                 0.0, STEPS * DT, DT, X0, saveat=end, stepsize_controller=clip, max_steps=4096)
    ours = jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, diffrax.Tsit5(), stepsize_controller=tight(),
                           saveat=jaxskid.SaveAt(t1=True))
    np.testing.assert_allclose(np.asarray(direct.ys[-1]), np.asarray(ours.x[-1]), rtol=0, atol=1e-12)
    ctrl = Integral()
    y0 = (X0, ctrl.init(X0))
    direct = diffrax.diffeqsolve(diffrax.ODETerm(jaxskid.vector_field(arm, ctrl)), diffrax.Tsit5(), 0.0, STEPS * DT,
                                 DT, y0, saveat=end, stepsize_controller=tight(), max_steps=4096)
    ref = reference(arm, ctrl, jaxskid.SaveAt(t1=True))
    np.testing.assert_allclose(np.asarray(direct.ys[0][-1]), np.asarray(ref.x[-1]), rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(direct.ys[1][-1]), np.asarray(ref.z[-1]), rtol=0, atol=1e-9)

    class Damping(jaxskid.Controller):  # no state: y is x alone, as for a policy
        def __call__(self, t, x, z):
            return -x[2:], ()

    np.testing.assert_array_equal(np.asarray(jaxskid.vector_field(arm, Damping())(0.1, X0, None)),
                                  np.asarray(jaxskid.vector_field(arm, lambda t, x: -x[2:])(0.1, X0, None)))


SOLVE = {"integrator": diffrax.Tsit5(), "stepsize_controller": tight(1e-10)}


def test_adaptive_saved_subsets(arm):
    """Saved subsets are the rows of the full adaptive solution (diffrax.SaveAt(ts=...) at the grid times)."""
    full = jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, **SOLVE)
    for saveat, rows in ((jaxskid.SaveAt(every=5), [0, 5, 10]), (jaxskid.SaveAt(ts=[0.1, 0.35]), [2, 7])):
        part = jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, saveat=saveat, **SOLVE)
        np.testing.assert_allclose(np.asarray(part.x), np.asarray(full.x)[rows], rtol=0, atol=1e-13)
        np.testing.assert_array_equal(np.asarray(part.tau), np.asarray(full.tau)[rows[:-1]])


def test_adaptive_per_rollout_steps(arm):
    """One step per rollout (one diffeqsolve per rollout, vmapped) equals single solves."""
    dts = np.array([DT, DT / 2])
    batch = jaxskid.rollout(arm, jnp.stack([X0, -X0]), CONTROLS, dts, STEPS, **SOLVE)
    assert batch.t.shape == (2, STEPS + 1)
    for i, x0 in enumerate((X0, -X0)):
        one = jaxskid.rollout(arm, x0, CONTROLS, float(dts[i]), STEPS, **SOLVE)
        np.testing.assert_allclose(np.asarray(batch.x[i]), np.asarray(one.x), rtol=0, atol=1e-12)


def test_fixed_step_diffrax_solver_order_and_saving(arm):
    """A diffrax solver without a controller takes steps of dt in jaxskid's loops: Heun's measured order is 2,
    and saved subsets are rows of the full trajectory, bit for bit."""
    ref = reference(arm, policy, jaxskid.SaveAt(t1=True)).x[-1]
    steps = [40, 80, 160]
    errors = [float(jnp.abs(jaxskid.rollout(arm, X0, policy, STEPS * DT / s, s, diffrax.Heun()).x[-1] - ref).max())
              for s in steps]
    order = np.polyfit(np.log(1.0 / np.array(steps)), np.log(errors), 1)[0]
    assert abs(order - 2) < 0.2, (errors, order)
    full = jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, diffrax.Tsit5())
    part = jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, diffrax.Tsit5(), saveat=jaxskid.SaveAt(every=2))
    np.testing.assert_array_equal(np.asarray(part.x), np.asarray(full.x)[::2])
    # diffrax's chord iteration reports divergence near round-off with tighter tolerances (1e-8 here)
    implicit = diffrax.Kvaerno5(root_finder=diffrax.VeryChord(rtol=1e-6, atol=1e-6, norm=optimistix.max_norm))
    fine = jaxskid.rollout(arm, X0, policy, DT / 10, STEPS * 10, implicit, saveat=jaxskid.SaveAt(t1=True))
    np.testing.assert_allclose(np.asarray(fine.x[-1]), np.asarray(ref), rtol=0, atol=1e-8)


def test_bad_solver_choices(arm):
    def run(integrator, controller=None):
        return jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, integrator, stepsize_controller=controller)

    bad = [
        (lambda: run(jaxskid.RK4(), tight()), r"RK4 takes fixed steps of dt; for adaptive steps pass a diffrax"),
        (lambda: run(diffrax.Kvaerno5()), r"Kvaerno5 with fixed steps needs its root finder's tolerances"),
        (lambda: run(diffrax.Tsit5(), diffrax.StepTo(ts=[0.0, 0.5])), r"stepsize_controller: expected None"),
        (lambda: run(diffrax.SemiImplicitEuler()), r"SemiImplicitEuler takes the terms"),
        (lambda: run("rk4"), r"integrator: expected RK4\(\), SemiImplicitEuler\(\) or a diffrax solver"),
        (lambda: jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, saveat=diffrax.SaveAt(t1=True)),
         r"expected a jaxskid.SaveAt \(diffrax solvers too\), got diffrax.SaveAt"),
        (lambda: jaxskid.vector_field(arm, CONTROLS), r"vector_field: dt: array controls are held over a grid"),
    ]
    for call, message in bad:
        with pytest.raises(jaxskid.RequestError, match=message):
            call()
    with pytest.raises(jaxskid.ShapeError, match=r"vector_field: controls: expected shape \(steps, 2\)"):
        jaxskid.vector_field(arm, np.zeros(2), dt=DT)
