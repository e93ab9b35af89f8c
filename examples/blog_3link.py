"""The seed blog's workflow on the 3-link arm: derive the equations of motion, simulate, plot the angles.

    python examples/blog_3link.py [OUT_DIR]            # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

1. Derive M(q), C(q, qd) qd and Q_grav(q) of robots/arm_3dof.yaml in closed form (SymPy), keeping the
   lengths, masses, radius and g symbolic, and print a few entries in textbook form.
2. Lower them to JAX and let the arm fall from a raised pose with no torque for 5 s (RK4, 1 ms).
3. Check the simulation against something independent: the total energy 1/2 qd^T M qd + V, with the
   potential V = -sum_i g . (m_i p_i + R_i m_i c_i) from the forward kinematics, must stay constant.
4. Plot the joint angles and the energy error.
5. The blog's own arm and route (:func:`blog_arm`): frames 1 and 2 at the base origin turn about z, then y;
   frame 3 sits ``frame2_l`` along frame 2's x axis and turns about y; every mass, centre of mass and inertia
   is a symbol (``frame1_m``, ``frame1_Jzz``, ...). Derive H, d and g by the Euler-Lagrange equations of the
   link energies (``Options(route="lagrange")``: H = d^2 K / dqd^2, d = (d^2 K / dqd dq) qd - dK/dq,
   g = dU/dq) and by the screw route; show that the difference of the closed forms is identically zero and
   that the lowered functions agree numerically; export H, d and g as C99, as the blog does.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402
from _common import output_dir, save_figure  # noqa: E402  (examples/_common.py, beside this script)

ROBOT = Path(__file__).resolve().parents[1] / "robots" / "arm_3dof.yaml"


def closed_form(eqs, expr):
    """An output of the derived straight-line program as one expression (intermediates substituted)."""
    for sym, value in reversed(eqs.assignments):
        if expr.has(sym):
            expr = expr.xreplace({sym: value})
    names = {sp.Symbol(f"_{k}{i}", real=True): sp.Symbol(f"{k}{i + 1}", real=True)
             for k in ("q", "qd", "qdd") for i in range(eqs.robot.n_dof)}
    return sp.simplify(sp.trigsimp(expr)).xreplace(names)


def blog_arm() -> jaxskid.Robot:
    """The blog's 3-link arm with symbolic inertial parameters, built in Python.

    Frame 1 turns about the base's z axis (q1), frame 2 at the same point about frame 1's y axis (q2), frame 3
    at ``frame2_l`` along frame 2's x axis about its y axis (q3). Body k has mass ``framek_m``, its centre of
    mass ``framek_c`` along its x axis (frame 1's on the z axis) and principal inertias ``framek_Jxx``,
    ``framek_Jyy``, ``framek_Jzz`` about the centre of mass; gravity is ``-g`` along z.
    """
    from jaxskid import Frame, Joint, Robot, pose, screw, spatial_inertia, symbol

    def body(k, com):
        j = [symbol(f"frame{k}_J{a}") for a in ("xx", "yy", "zz")]
        return spatial_inertia(symbol(f"frame{k}_m"), com, (j[0], 0, 0, j[1], 0, j[2]))

    c = [symbol(f"frame{k}_c") for k in (1, 2, 3)]
    joints = [
        Joint("q1", "revolute", -1, pose(), screw("revolute", (0, 0, 1)), body(1, (0, 0, c[0])), "frame1"),
        Joint("q2", "revolute", 0, pose(), screw("revolute", (0, 1, 0)), body(2, (c[1], 0, 0)), "frame2"),
        Joint("q3", "revolute", 1, pose(translation=(symbol("frame2_l"), 0, 0)), screw("revolute", (0, 1, 0)),
              body(3, (c[2], 0, 0)), "frame3"),
    ]
    tip = Frame("tip", 2, pose(translation=(symbol("frame3_l"), 0, 0)))
    defaults = {"g": 9.81, "frame2_l": 0.5, "frame3_l": 0.4, "frame1_c": 0.05, "frame2_c": 0.25, "frame3_c": 0.2}
    for k, (m, jxx, jyy, jzz) in enumerate([(2.0, 0.02, 0.02, 0.01), (1.5, 0.002, 0.03, 0.03),
                                            (1.0, 0.001, 0.015, 0.015)], start=1):
        defaults.update({f"frame{k}_m": m, f"frame{k}_Jxx": jxx, f"frame{k}_Jyy": jyy, f"frame{k}_Jzz": jzz})
    return Robot.create("blog_3link", joints, (0, 0, -symbol("g")), [tip], ["tip"], defaults)


def blog_route(out_dir: Path) -> dict:
    """Step 5: the blog's arm both ways, the symbolic and numeric comparison, and the C99 export."""
    from jaxskid.testing import closed_form, vanishes

    robot = blog_arm()
    names = ["mass_matrix", "coriolis_torques", "gravity_torques"]
    t = time.perf_counter()
    lagrange = jaxskid.derive(robot, names, options=jaxskid.Options(route="lagrange"))
    derive_seconds = time.perf_counter() - t
    screw = jaxskid.derive(robot, names)
    q = screw.arguments["q"].symbols
    identical = all(vanishes(a - b, q) for n in names
                    for a, b in zip(closed_form(lagrange, n), closed_form(screw, n), strict=True))
    rng = np.random.default_rng(0)
    qs, qds = rng.uniform(-np.pi, np.pi, size=(2, 256, 3))
    ours, theirs = jaxskid.lower(lagrange), jaxskid.lower(screw)
    numeric = max(float(np.max(np.abs(np.asarray(f(*a)) - np.asarray(getattr(theirs, n)(*a)))))
                  for n, a in (("mass_matrix", (qs,)), ("coriolis_torques", (qs, qds)), ("gravity_torques", (qs,)))
                  for f in (getattr(ours, n),))
    files = jaxskid.codegen.generate(lagrange, "c", out_dir / "blog_3link_c", force=True)
    ops = {n: (lagrange.operation_count([n]), screw.operation_count([n])) for n in names}
    print(f"blog arm: {len(robot.parameters)} symbolic parameters; Euler-Lagrange route derived in "
          f"{derive_seconds:.2f} s; operations (Lagrange, screw) {ops}")
    print(f"blog arm: Lagrange - screw closed forms identically zero: {identical}; lowered, 256 states: max "
          f"|difference| {numeric:.1e}")
    print(f"blog arm: H, d, g as C99 ({', '.join(n for n in names)}): {', '.join(str(f) for f in files)}")
    return {"routes_identical": identical, "routes_max_diff": numeric, "c_files": files, "lagrange_ops": ops}


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
    figure = save_figure(fig, output_dir(out_dir) / "blog_3link.png")

    blog = blog_route(output_dir(out_dir))
    result = {
        **blog,
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
    print(f"done in {time.perf_counter() - start:.1f} s; figure {figure}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
