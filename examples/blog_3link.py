"""The seed blog's workflow on the 3-link arm: derive the equations of motion, simulate, plot the angles.

    python examples/blog_3link.py [OUT_DIR]            # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

1. Derive M(q), C(q, qd) qd and Q_grav(q) of robots/arm_3dof.yaml in closed form (SymPy), keeping the
   lengths, masses, radius and g symbolic, and print a few entries in textbook form.
2. Lower them to JAX and let the arm fall from a raised pose with no torque for 5 s (RK4, 1 ms).
3. Check the simulation against something independent: the total energy 1/2 qd^T M qd + V, with the
   potential V = -sum_i g . (m_i p_i + R_i m_i c_i) from the forward kinematics, must stay constant.
4. Plot the joint angles and the energy error.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "arm_3dof.yaml"


def output_dir(out_dir=None) -> Path:
    path = Path(out_dir or os.environ.get("JAXSKID_EXAMPLE_OUT") or Path(__file__).parent / "out")
    path.mkdir(parents=True, exist_ok=True)
    return path


def closed_form(eqs, expr):
    """An output of the derived straight-line program as one expression (intermediates substituted)."""
    for sym, value in reversed(eqs.assignments):
        if expr.has(sym):
            expr = expr.xreplace({sym: value})
    names = {sp.Symbol(f"_{k}{i}", real=True): sp.Symbol(f"{k}{i + 1}", real=True)
             for k in ("q", "qd", "qdd") for i in range(eqs.robot.n_dof)}
    return sp.simplify(sp.trigsimp(expr)).xreplace(names)


def main(out_dir=None, seconds=5.0, dt=1e-3):
    start = time.perf_counter()
    robot = jaxskid.load(ROBOT)
    quantities = ["mass_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics", "forward_kinematics"]
    eqs = jaxskid.derive(robot, quantities)
    derive_seconds = time.perf_counter() - start
    mass = eqs.quantities["mass_matrix"].outputs
    m33 = closed_form(eqs, mass[8])
    g3 = closed_form(eqs, eqs.quantities["gravity_torques"].outputs[2])
    ops = {name: eqs.operation_count([name]) for name in quantities[:4]}

    dyn = jaxskid.lower(robot, quantities)
    params = robot.default_params()
    pi = jaxskid.standard_params(robot).reshape(-1, 10)
    gravity = np.array([float(sp.sympify(g).xreplace({jaxskid.symbol(k): v for k, v in params.items()}))
                        for g in robot.gravity])

    def energy(x):
        q, qd = x[:3], x[3:]
        poses = dyn.forward_kinematics(q)
        potential = 0.0
        for i, link in enumerate(robot.link_names):
            r, p = poses[link][:3, :3], poses[link][:3, 3]
            potential = potential - gravity @ (pi[i, 0] * p + r @ pi[i, 1:4])
        return 0.5 * qd @ dyn.mass_matrix(q) @ qd + potential

    x0 = jnp.array([0.3, -1.0, 1.2, 0.0, 0.0, 0.0])
    steps = int(round(seconds / dt))
    traj = jaxskid.rollout(dyn, x0, np.zeros((steps, 3)), dt, steps, jaxskid.RK4())
    e = np.asarray(jax.vmap(energy)(traj.x))
    drift = float(np.abs(e - e[0]).max() / np.abs(e).max())
    elapsed = time.perf_counter() - start

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(traj.t)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for j, name in enumerate(robot.joint_names):
        axes[0].plot(t, np.asarray(traj.q[:, j]), label=name)
    axes[0].set(xlabel="t [s]", ylabel="q [rad]", title="3-link arm falling freely (RK4, 1 ms)")
    axes[0].legend()
    axes[1].plot(t, (e - e[0]) / np.abs(e).max())
    axes[1].set(xlabel="t [s]", ylabel="relative energy error", title="energy from forward kinematics")
    fig.tight_layout()
    figure = output_dir(out_dir) / "blog_3link.png"
    fig.savefig(figure, dpi=100)
    plt.close(fig)

    result = {
        "M33": m33,
        "Qgrav3": g3,
        "operations": ops,
        "derive_seconds": derive_seconds,
        "energy_drift": drift,
        "final_q": np.asarray(traj.q[-1]),
        "seconds": elapsed,
        "figure": figure,
    }
    print(f"derived {', '.join(quantities)} in {derive_seconds:.2f} s; operations {ops}")
    print(f"M[3,3] = {m33}")
    print(f"Q_grav[3] = {g3}")
    print(f"simulated {seconds} s; relative energy drift {drift:.1e}; final q {np.round(result['final_q'], 4).tolist()}")
    print(f"done in {elapsed:.1f} s; figure {figure}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
