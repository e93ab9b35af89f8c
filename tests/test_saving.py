"""What a rollout saves (jaxskid.SaveAt), per-rollout steps, and checkpointed gradients.

References: the full trajectory (every state) for its subsets, bit for bit; rollouts one by one for a batch
with one step per rollout; the gradient without checkpointing for the checkpointed one, and the compiler's
memory analysis for the memory it saves; central differences for the derivative with respect to the step.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import FD, Integral, load

import jaxskid


@pytest.fixture(scope="module")
def arm():
    return jaxskid.lower(load("arm_2r"), FD)


X0 = jnp.array([0.4, -0.3, 0.1, 0.2])
STEPS, DT = 60, 0.01
CONTROLS = np.random.default_rng(0).normal(size=(STEPS, 2))
CASES = [  # (SaveAt, the rows of the full trajectory it keeps)
    (jaxskid.SaveAt(every=4), np.arange(0, STEPS + 1, 4)),
    (jaxskid.SaveAt(ts=[0.0, 0.05, 0.13, 0.6]), np.array([0, 5, 13, 60])),
    (jaxskid.SaveAt(ts=[0.07, 0.3]), np.array([7, 30])),
    (jaxskid.SaveAt(t1=True), np.array([STEPS])),
    (jaxskid.SaveAt(t0=True, t1=True), np.array([0, STEPS])),
]


@pytest.mark.parametrize("checkpoint", [None, jaxskid.Checkpoint(block=7)], ids=["plain", "checkpoint7"])
@pytest.mark.parametrize("controls", ["array", "controller"])
def test_saved_states_are_rows_of_the_full_trajectory(arm, controls, checkpoint):
    """Bit for bit, also with a controller state and with checkpointed segments (7 steps: the last padded)."""
    u = CONTROLS if controls == "array" else Integral()
    full = jaxskid.rollout(arm, X0, u, DT, STEPS)
    assert full.x.shape == (STEPS + 1, 4) and full.tau.shape == (STEPS, 2)
    for saveat, rows in CASES:
        part = jaxskid.rollout(arm, X0, u, DT, STEPS, saveat=saveat, checkpoint=checkpoint)
        np.testing.assert_array_equal(np.asarray(part.x), np.asarray(full.x)[rows], err_msg=str(saveat))
        np.testing.assert_array_equal(np.asarray(part.tau), np.asarray(full.tau)[rows[:-1]], err_msg=str(saveat))
        np.testing.assert_allclose(np.asarray(part.t), rows * DT, rtol=1e-15, atol=0)
        if controls == "controller":
            np.testing.assert_array_equal(np.asarray(part.z), np.asarray(full.z)[rows])


def test_per_rollout_step_equals_separate_rollouts(arm):
    """dt (batch,): one step per rollout; the times are per rollout, and shared ones are not copied."""
    x0 = jnp.stack([X0, 0.5 * X0, -X0])
    dts = np.array([0.01, 0.005, 0.02])
    batch = jaxskid.rollout(arm, x0, CONTROLS, dts, STEPS)
    assert batch.t.shape == (3, STEPS + 1) and batch.x.shape == (3, STEPS + 1, 4)
    saved = jaxskid.rollout(arm, x0, CONTROLS, dts, STEPS, saveat=jaxskid.SaveAt(ts=[0.0, 0.3]))
    sweep = jaxskid.rollout(arm, X0, CONTROLS, dts, STEPS)  # one state, a sweep over the step
    for i in range(3):
        one = jaxskid.rollout(arm, x0[i], CONTROLS, float(dts[i]), STEPS)
        np.testing.assert_allclose(np.asarray(batch.x[i]), np.asarray(one.x), rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.asarray(batch.t[i]), np.asarray(one.t), rtol=1e-15)
        rows = np.array([0, round(0.3 / dts[i])])
        np.testing.assert_allclose(np.asarray(saved.x[i]), np.asarray(one.x)[rows], rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(sweep.x[0]), np.asarray(batch.x[0]), rtol=0, atol=1e-13)
    shared = jaxskid.rollout(arm, x0, CONTROLS, DT, STEPS, saveat=jaxskid.SaveAt(every=10))
    assert shared.t.shape == (7,) and shared.x.shape == (3, 7, 4) and shared.tau.shape == (3, 6, 2)


def test_traced_step_rounds_saved_times(arm):
    """Under jit the step is traced: times are taken to the nearest step, as the host check would accept."""
    saveat = jaxskid.SaveAt(ts=[0.0, 0.1, 0.25])
    traced = jax.jit(lambda dt: jaxskid.rollout(arm, X0, CONTROLS, dt, STEPS, saveat=saveat))(DT)
    concrete = jaxskid.rollout(arm, X0, CONTROLS, DT, STEPS, saveat=saveat)
    np.testing.assert_allclose(np.asarray(traced.x), np.asarray(concrete.x), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(traced.t), [0.0, 0.1, 0.25], rtol=1e-14)


def test_derivative_with_respect_to_the_step(arm):
    def final(dt):
        return jaxskid.rollout(arm, X0, CONTROLS, dt, STEPS, saveat=jaxskid.SaveAt(t1=True)).x[-1, 0]

    h = 1e-6
    fd = (final(DT + h) - final(DT - h)) / (2 * h)
    np.testing.assert_allclose(float(jax.grad(final)(DT)), float(fd), rtol=1e-6)


def test_checkpointed_gradient_equals_plain_and_uses_less_memory(arm):
    """A policy (no torque input to scan): 400 steps in 20 segments of 20."""
    steps = 400

    def policy(t, x):
        return -x[2:]

    def compiled(checkpoint):
        def f(x0):
            x = jaxskid.rollout(arm, x0, policy, 1e-3, steps, saveat=jaxskid.SaveAt(t1=True), checkpoint=checkpoint).x
            return jnp.sum(x * x)

        return jax.jit(jax.grad(f), compiler_options=jaxskid.compiler_options()).lower(X0).compile()

    plain, remat = compiled(None), compiled(jaxskid.Checkpoint())
    np.testing.assert_allclose(np.asarray(remat(X0)), np.asarray(plain(X0)), rtol=1e-12, atol=0)
    temp = [f.memory_analysis().temp_size_in_bytes for f in (plain, remat)]
    assert temp[1] < temp[0] / 3, temp


def test_bad_saveat_step_and_choices(arm):
    def run(**kwargs):
        dt = kwargs.pop("dt", DT)
        return jaxskid.rollout(arm, X0, CONTROLS, dt, kwargs.pop("steps", STEPS), **kwargs)

    bad = [
        (lambda: jaxskid.SaveAt(every=0), jaxskid.RequestError, r"every: expected a whole number >= 1, got 0"),
        (lambda: jaxskid.SaveAt(every=2.5), jaxskid.RequestError, r"every: expected a whole number"),
        (lambda: jaxskid.SaveAt(every=2, t1=True), jaxskid.RequestError, r"one of every=, ts= or t1=True"),
        (lambda: jaxskid.SaveAt(t0=True), jaxskid.RequestError, r"t0=True goes with t1=True"),
        (lambda: jaxskid.SaveAt(ts=[0.2, 0.1]), jaxskid.RequestError, r"strictly increasing.*ts\[0\] = 0.2"),
        (lambda: jaxskid.SaveAt(ts=[]), jaxskid.RequestError, r"non-empty"),
        (lambda: jaxskid.SaveAt(ts=[-0.1]), jaxskid.RequestError, r"times >= 0"),
        (lambda: jaxskid.Checkpoint(block=0), jaxskid.RequestError, r"block: expected a whole number"),
        (lambda: run(saveat=jaxskid.SaveAt(ts=[0.0, 0.015])), jaxskid.RequestError,
         r"ts\[1\] = 0.015 is not on the step grid.*dt = 0.01.*nearest step 2"),
        (lambda: run(saveat=jaxskid.SaveAt(ts=[0.7])), jaxskid.RequestError, r"ts\[0\] = 0.7 is after the final time"),
        (lambda: jaxskid.rollout(arm, jnp.stack([X0, X0]), CONTROLS, np.array([0.01, 0.004]), STEPS,
                                 saveat=jaxskid.SaveAt(ts=[0.05])),
         jaxskid.RequestError, r"not on the step grid.*\(rollout \(1,\)\).*dt = 0.004"),
        (lambda: run(saveat=jaxskid.SaveAt(every=7)), jaxskid.RequestError, r"multiple of 7, got steps=60"),
        (lambda: run(dt=0.0), jaxskid.RequestError, r"dt: expected finite steps > 0, got 0.0"),
        (lambda: run(dt=np.array([0.01, np.nan])), jaxskid.RequestError, r"dt: expected finite steps > 0, got nan"),
        (lambda: jaxskid.rollout(arm, jnp.stack([X0] * 3), CONTROLS, np.full(2, DT), STEPS), jaxskid.ShapeError,
         r"rollout: dt: batch \(2,\) does not broadcast with the state batch \(3,\)"),
        (lambda: run(steps=60.0), jaxskid.RequestError, r"steps: expected a whole number >= 1"),
        (lambda: run(saveat="final"), jaxskid.RequestError, r"saveat: expected a jaxskid.SaveAt \(diffrax solvers too\), got builtins.str"),
        (lambda: run(checkpoint=True), jaxskid.RequestError, r"checkpoint: expected None or jaxskid.Checkpoint"),
    ]
    for call, error, message in bad:
        with pytest.raises(error, match=message):
            call()
