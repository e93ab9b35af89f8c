"""Recover a 7-DOF arm's inertial parameters by gradient descent through the simulator.

    python examples/fit_through_simulation.py [OUT_DIR]    # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

The Franka Panda (example-robot-data, fingers locked) tracks eight reference motions under a PD +
gravity-compensation controller built on its *nominal* model. The "measured" trajectories come from the
true arm, each of whose links is 30 % lighter to 30 % heavier than nominal (mass, first moments and
inertia scaled together), with 1 mrad of encoder noise. Starting from the nominal model, Adam (optax)
fits the seven factors, and with them all 70 inertial parameters, by minimising the squared error between
simulated and measured joint positions over the whole batch of rollouts (one batched ``jaxskid.rollout``),
with ``jax.grad`` through 8 x 200 RK4 steps. The factors are fitted as logarithms, so they stay positive.
Link 1 turns about the vertical axis, so only its inertia about that axis shows in the motion: its factor
is the least well determined. The script saves a plot of the loss and of the largest relative error of
the factors (= of the masses) against iterations.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optax

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402
from _common import erd_urdf, output_dir, save_figure  # noqa: E402  (examples/_common.py, beside this script)

LOCK = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}


class Swing(jaxskid.Controller):
    """PD + gravity compensation (nominal model) about ``q_d(t) = q0 + 0.6 sin(3 t)``; its state is ``q0``."""

    def __init__(self, model, params, gains):
        self.model, self.params, (self.kp, self.kd) = model, params, gains

    def init(self, x0):
        return x0[: x0.shape[-1] // 2]

    def __call__(self, t, x, q0):
        n = x.shape[-1] // 2
        q, qd = x[:n], x[n:]
        error = q0 + 0.6 * jnp.sin(3.0 * t) - q
        derror = 1.8 * jnp.cos(3.0 * t) - qd
        kp, kd = jnp.asarray(self.kp), jnp.asarray(self.kd)
        tau = kp * error + kd * derror + self.model.gravity_torques(q, self.params)
        return tau, jnp.zeros_like(q0)

    def __eq__(self, other):
        return isinstance(other, Swing) and (other.model, other.kp, other.kd) == (self.model, self.kp, self.kd)

    def __hash__(self):
        return hash((Swing, id(self.model), self.kp, self.kd))


def main(out_dir=None, iterations=150, batch=8, steps=200, dt=4e-3, seed=0):
    rng = np.random.default_rng(seed)
    robot = jaxskid.load(erd_urdf("panda_description/urdf/panda.urdf"), lock=LOCK)
    nominal = robot.default_params()
    # each link's true inertial parameters (mass, first moments, inertia) are its nominal ones times a
    # factor, as for a link of another density; the factors are what is fitted
    links = list(dict.fromkeys(k.rsplit("_", 1)[0] for k in robot.parameters))
    plant = jaxskid.lower(robot, ["forward_dynamics"])
    model = jaxskid.lower(robot, ["gravity_torques"])  # the controller's nominal model
    p_nominal = plant.param_vector()
    link_of = jnp.asarray([links.index(k.rsplit("_", 1)[0]) for k in plant.parameters])
    true = rng.uniform(0.7, 1.3, len(links))
    masses = np.array([nominal[f"{link}_m"] for link in links])

    n = plant.n_dof
    # per-joint gains: the distal joints carry little inertia, and stiff gains there would make the
    # closed loop too fast for RK4 at 4 ms
    gains = ((60.0, 60.0, 60.0, 60.0, 10.0, 10.0, 4.0), (8.0, 8.0, 8.0, 8.0, 1.0, 1.0, 0.3))
    x0 = jnp.concatenate([jnp.asarray(rng.uniform(-0.5, 0.5, (batch, n))), jnp.zeros((batch, n))], axis=1)

    def simulate(log_m):
        params = p_nominal * jnp.exp(log_m)[link_of]
        return jaxskid.rollout(plant, x0, Swing(model, nominal, gains), dt, steps, params=params).q

    measured = simulate(jnp.log(true)) + 1e-3 * rng.normal(size=(batch, steps + 1, n))

    def loss(log_m):
        return jnp.mean((simulate(log_m) - measured) ** 2)

    optimizer = optax.adam(0.03)

    @jaxskid.jit
    def step(log_m, state):
        value, grad = jax.value_and_grad(loss)(log_m)
        updates, state = optimizer.update(grad, state, log_m)
        return optax.apply_updates(log_m, updates), state, value

    log_m = jnp.zeros(len(links))
    state = optimizer.init(log_m)
    losses, errors = [], []
    start = time.perf_counter()
    for _ in range(iterations):
        errors.append(float(np.max(np.abs(np.exp(log_m) - true) / true)))
        log_m, state, value = step(log_m, state)
        losses.append(float(value))
    elapsed = time.perf_counter() - start
    fitted = np.exp(np.asarray(log_m))
    errors.append(float(np.max(np.abs(fitted - true) / true)))

    out = output_dir(out_dir)
    figure = out / "fit_through_simulation.png"
    plot(figure, losses, errors)
    print(f"{iterations} Adam steps through {batch} x {steps} RK4 steps in {elapsed:.1f} s (compilation included)")
    for link, m, t, f in zip(links, masses, true, fitted):
        print(f"  {link:12s} mass: true {m * t:7.4f} kg   fitted {m * f:7.4f} kg   error {100 * abs(f - t) / t:5.2f} %")
    print(f"loss {losses[0]:.3e} -> {losses[-1]:.3e}; largest mass error {100 * errors[0]:.1f} % -> "
          f"{100 * errors[-1]:.2f} %")
    return {"losses": losses, "errors": errors, "true": true, "fitted": fitted, "seconds": elapsed, "figure": figure}


def plot(path: Path, losses, errors) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.5))
    a.semilogy(losses)
    a.set(xlabel="iteration", ylabel="mean squared position error (rad$^2$)", title="loss")
    b.semilogy(100 * np.asarray(errors))
    b.set(xlabel="iteration", ylabel="largest relative mass error (%)", title="parameter error")
    save_figure(fig, path, dpi=120)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
