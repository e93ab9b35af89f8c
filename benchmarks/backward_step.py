"""The backward step of forward dynamics, the kernel of every rollout gradient, against Pinocchio.

    python benchmarks/backward_step.py [--robots panda,solo12,g1] [--batch 4096] [--repeats 11] [--markdown PATH]

For each robot (fixed base, from example-robot-data, every inertial parameter symbolic) it times, per state
on a batch (float64):

- ``forward``: ``qdd = FD(q, qd, tau, p)`` as the rollouts call it (the closed form, with the derivative rule
  of ``rollout``'s default ``autodiff="reverse"``: :func:`jaxskid.runtime._forward.accelerations`);
- ``forward + backward``: the same and its vector-Jacobian product with respect to q, qd, tau and all the
  parameters (``jax.vjp``; the backward step is lambda = M^-1 g and the VJP of inverse dynamics at lambda,
  run as one native kernel on CPU, :mod:`jaxskid.runtime._implicit`);

beside Pinocchio's ``computeABADerivatives`` per call from Python (the derivatives of qdd with respect to q,
qd and tau, without the parameters). The ratio is Pinocchio's time over jaxskid's backward step alone.
"""

from __future__ import annotations

import argparse

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402
from jaxskid.runtime._forward import accelerations  # noqa: E402
from core import add_robot_options, median_time  # noqa: E402  (benchmarks/core.py, beside this script)
from scaling import ERD, ROBOTS, _pinocchio_model  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py)


def measure(name: str, batch: int, repeats: int) -> str:
    path, lock = ROBOTS[name]
    robot = jaxskid.load(ERD / path, lock=lock)
    dyn = jaxskid.lower(robot, ["forward_dynamics"])
    fd = accelerations(dyn, batched=True, autodiff="reverse")
    n, p = robot.n_dof, jnp.asarray(dyn.param_vector())
    rng = np.random.default_rng(0)
    q, qd, tau, g = (jnp.asarray(rng.uniform(-1, 1, (batch, n))) for _ in range(4))
    mapped = jax.vmap(fd, in_axes=(0, 0, 0, None))

    @jax.jit
    def both(q, qd, tau, g, p):
        qdd, pullback = jax.vjp(mapped, q, qd, tau, p)
        return qdd, pullback(g)

    forward = jax.jit(mapped)
    jax.block_until_ready(forward(q, qd, tau, p))
    jax.block_until_ready(both(q, qd, tau, g, p))
    t_fwd = median_time(lambda: jax.block_until_ready(forward(q, qd, tau, p)), repeats) / batch
    t_both = median_time(lambda: jax.block_until_ready(both(q, qd, tau, g, p)), repeats) / batch
    model = _pinocchio_model(ERD / path, lock)
    data = model.createData()
    rows = list(zip(*(np.asarray(x) for x in (q, qd, tau))))[:200]

    def peer():
        for row in rows:
            pin.computeABADerivatives(model, data, *row)

    t_pin = median_time(peer, repeats) / len(rows)
    backward = t_both - t_fwd
    return (f"| {name} | {n} | {t_fwd * 1e6:.3f} µs | {t_both * 1e6:.3f} µs | {backward * 1e6:.3f} µs | "
            f"{t_pin * 1e6:.2f} µs | {t_pin / backward:.1f}x |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_robot_options(parser, robots="panda,solo12,g1", batch=4096, repeats=11)
    args = parser.parse_args()
    print(f"jax {jax.__version__}, Pinocchio {pin.__version__}, float64, batch {args.batch}")
    out = doc_tables.Lines()
    out("| robot | DOF | forward | forward + backward | backward | Pinocchio computeABADerivatives | ratio |")
    out("|---|---|---|---|---|---|---|")
    for name in args.robots.split(","):
        out(measure(name, args.batch, args.repeats))
    doc_tables.write(args.markdown, out, f"Per state at batch {args.batch}, float64, medians of {args.repeats}; "
                     "Pinocchio per call from Python. The ratio is Pinocchio's time over the backward step alone.")


if __name__ == "__main__":
    main()
