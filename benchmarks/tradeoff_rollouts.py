"""Rollouts: error against work for every integrator a rollout can use (the rollout part of tradeoff.py).

    python benchmarks/tradeoff_rollouts.py [--robots panda,quadruped] [--repeats 3] [--out benchmarks/out]
    python benchmarks/tradeoff_rollouts.py --markdown docs/performance/tradeoff_rollouts.md   # also the documentation's table

Passive rollouts (tau = 0 as a policy) from rest at 64 states q0 ~ U(-1, 1) over 0.5 s with closed-form
forward dynamics and the default parameters, the final state saved (``SaveAt(t1=True)``). Error: max
|q(T) - q_ref(T)| in rad against jaxskid's RK4 at a step 8x smaller than the smallest fixed step (its own
error estimated by Richardson extrapolation). Methods:

* jaxskid's fixed-step ``SemiImplicitEuler`` and ``RK4`` in ``jaxskid.rollout`` (float64 and float32);
* diffrax's adaptive ``Tsit5`` and ``Dopri8`` in ``jaxskid.rollout`` with ``PIDController(rtol=tol, atol=tol)``,
  initial step 0.05 s;
* diffrax's fixed-step ``Euler``, ``Heun``, ``Midpoint`` and the classical RK4 as a ``ButcherTableau`` (diffrax
  has no RK4 class), as one would write them with diffrax alone: ``diffeqsolve`` of ``jaxskid.vector_field``
  with ``ConstantStepSize``, ``jax.vmap``-ed and compiled with ``jaxskid.jit``; and the RK4 tableau as the
  integrator of ``jaxskid.rollout`` (diffrax's step in jaxskid's loop).

Work: vector-field evaluations per rollout (adaptive solvers: from diffrax's counts of accepted and rejected
steps of the same solve, mean over the 64 rollouts) and wall time per rollout (the batch's time / 64, median
of interleaved repeats). The table goes to ``<out>/tradeoff_rollouts.md``, the plots to
``<out>/tradeoff_rollouts.png``; ``tradeoff.py`` includes both in its own report.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import doc_tables  # benchmarks/doc_tables.py, beside this script

ROOT = Path(__file__).resolve().parents[1]
HORIZON = 0.5  # s
N_ROLLOUTS = 64
OURS = (  # (integrator, step size in s, dtype)
    ("semi-implicit Euler", 1e-3, "float64"),
    ("semi-implicit Euler", 4e-3, "float64"),
    ("semi-implicit Euler", 1.6e-2, "float64"),
    ("RK4", 1e-3, "float64"),
    ("RK4", 4e-3, "float64"),
    ("RK4", 1.6e-2, "float64"),
    ("RK4", 4e-3, "float32"),
    ("semi-implicit Euler", 4e-3, "float32"),
)
ADAPTIVE = tuple((name, tol) for name in ("Tsit5", "Dopri8") for tol in (1e-4, 1e-6, 1e-8, 1e-10))
ADAPTIVE_DT0 = 0.05  # s: the initial step (and the grid: 10 steps)
DIFFRAX_FIXED = (  # (solver, step size in s); "RK4 tableau in rollout": the tableau as jaxskid.rollout's integrator
    ("Euler", 1e-3), ("Heun", 1e-3), ("Midpoint", 1e-3), ("RK4 tableau", 1e-3), ("RK4 tableau", 4e-3),
    ("Heun", 4e-3), ("RK4 tableau in rollout", 1e-3), ("RK4 tableau in rollout", 4e-3),
)


def classical_rk4():
    """The classical RK4 as a diffrax explicit Runge-Kutta solver (Butcher tableau: Hairer, Norsett & Wanner,
    "Solving Ordinary Differential Equations I", Table 1.2)."""
    import diffrax

    class ClassicalRK4(diffrax.AbstractERK):
        tableau = diffrax.ButcherTableau(
            c=np.array([0.5, 0.5, 1.0]), b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]), b_error=np.zeros(4),
            a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
        )
        interpolation_cls = diffrax.ThirdOrderHermitePolynomialInterpolation.from_k

        def order(self, terms):
            return 4

    return ClassicalRK4()


def solver(name: str):
    import diffrax

    return classical_rk4() if name.startswith("RK4 tableau") else getattr(diffrax, name)()


def evaluations_per_step(s) -> tuple[int, int]:
    """(vector-field evaluations per step, once at the start) of a diffrax solver in ``diffeqsolve``."""
    tableau = getattr(s, "tableau", None)
    if tableau is None:  # Euler
        return 1, 0
    stages = len(tableau.c) + 1
    return (stages - 1, 1) if tableau.fsal else (stages, 0)


def round_robin(calls: dict, repeats: int) -> dict:
    """Median wall time of each call; the calls are interleaved so that a loaded machine slows them alike."""
    for fn in calls.values():
        fn()
    times = {k: [] for k in calls}
    for _ in range(repeats):
        for k, fn in calls.items():
            t = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t)
    return {k: float(np.median(v)) for k, v in times.items()}


def methods(dyn, x0: np.ndarray):
    """``{(method, step or tolerance, dtype): (call, evaluations per rollout)}``; ``call()`` gives the final q of
    every rollout."""
    import diffrax
    import jax
    import jax.numpy as jnp

    import jaxskid

    n = dyn.n_dof
    final = jaxskid.SaveAt(t1=True)

    def policy(t, x):
        return jnp.zeros(x.shape[0] // 2, x.dtype)

    def ours(integrator, dt, dtype):
        steps, x = round(HORIZON / dt), jnp.asarray(x0, dtype)
        if isinstance(integrator, diffrax.AbstractSolver):  # each step afresh (made_jump): every stage
            per_step = sum(evaluations_per_step(integrator)) if integrator.tableau.fsal else evaluations_per_step(
                integrator)[0]
        else:
            per_step = 4 if isinstance(integrator, jaxskid.RK4) else 1
        return (lambda: jaxskid.rollout(dyn, x, policy, dt, steps, integrator, saveat=final).x[:, -1, :n],
                steps * per_step)

    out = {}
    for name, dt, dtype in OURS:
        out[name, dt, dtype] = ours(jaxskid.RK4() if name == "RK4" else jaxskid.SemiImplicitEuler(), dt, dtype)
    x = jnp.asarray(x0)
    for name, tol in ADAPTIVE:
        out[name, tol, "float64"] = adaptive(dyn, x, policy, solver(name), tol)
    term = diffrax.ODETerm(jaxskid.vector_field(dyn, policy))
    for name, dt in DIFFRAX_FIXED:
        if name.endswith("in rollout"):
            out[name, dt, "float64"] = ours(solver(name), dt, "float64")
            continue
        s, steps = solver(name), round(HORIZON / dt)

        @jaxskid.jit
        def direct(x, s=s, dt=dt, steps=steps):
            def one(y):
                return diffrax.diffeqsolve(term, s, 0.0, HORIZON, dt, y, stepsize_controller=diffrax.ConstantStepSize(),
                                           saveat=diffrax.SaveAt(t1=True), max_steps=steps + 2).ys[-1, :n]

            return jax.vmap(one)(x)

        per_step, start = evaluations_per_step(s)
        out[name, dt, "float64"] = (lambda f=direct: f(x), start + steps * per_step)
    return out


def adaptive(dyn, x, policy, s, tol):
    """An adaptive solve in ``jaxskid.rollout``, and its evaluations per rollout from diffrax's step counts."""
    import diffrax
    import jax

    import jaxskid

    steps = round(HORIZON / ADAPTIVE_DT0)
    controller = diffrax.PIDController(rtol=tol, atol=tol)
    def call():
        return jaxskid.rollout(dyn, x, policy, ADAPTIVE_DT0, steps, s, stepsize_controller=controller,
                               saveat=jaxskid.SaveAt(t1=True)).x[:, -1, :dyn.n_dof]

    term = diffrax.ODETerm(jaxskid.vector_field(dyn, policy))
    count = jaxskid.jit(jax.vmap(lambda y: diffrax.diffeqsolve(
        term, s, 0.0, HORIZON, ADAPTIVE_DT0, y, stepsize_controller=controller, max_steps=16 * steps + 4096,
        saveat=diffrax.SaveAt(t1=True)).stats["num_steps"]))
    per_step, start = evaluations_per_step(s)
    return call, start + per_step * float(np.mean(np.asarray(count(x))))


def study(robot, q0: np.ndarray, repeats: int, cache: str) -> dict:
    """Error, evaluations and time per rollout of every method on ``robot`` from rest at ``q0 (64, n)``."""
    import jaxskid

    dyn = jaxskid.lower(robot, ["forward_dynamics", "mass_matrix", "inverse_dynamics"], cache_dir=cache)
    x0 = np.concatenate([q0, np.zeros_like(q0)], axis=1)
    dt_ref = min(dt for _, dt, _ in OURS) / 8
    runs = methods(dyn, x0)
    ref = {dt: np.asarray(reference(dyn, x0, dt), np.float64) for dt in (dt_ref, 2 * dt_ref)}
    out = {"dt_ref": dt_ref, "reference_error": float(np.max(np.abs(ref[2 * dt_ref] - ref[dt_ref]))) / 15,
           "rows": []}  # Richardson, RK4: 2^4 - 1
    calls = {}
    for key, (call, evaluations) in runs.items():
        t = time.perf_counter()
        final = np.asarray(call(), np.float64)
        print(f"    {key[0]:24s} {key[1]:<8g} {key[2]}: first call {time.perf_counter() - t:.1f} s", flush=True)
        calls[key] = lambda c=call: np.asarray(c())
        out["rows"].append({"method": key[0], "setting": key[1], "dtype": key[2], "evaluations": evaluations,
                            "err": float(np.max(np.abs(final - ref[dt_ref])))})
    times = round_robin(calls, repeats)
    for row in out["rows"]:
        row["time"] = times[row["method"], row["setting"], row["dtype"]] / len(q0)
    return out


def reference(dyn, x0, dt):
    import jax.numpy as jnp

    import jaxskid

    steps = round(HORIZON / dt)
    return jaxskid.rollout(dyn, jnp.asarray(x0), lambda t, x: jnp.zeros(x.shape[0] // 2, x.dtype), dt, steps,
                           saveat=jaxskid.SaveAt(t1=True)).x[:, -1, :dyn.n_dof]


def kind(method: str) -> str:
    if method in ("RK4", "semi-implicit Euler"):
        return "jaxskid"
    return "diffrax adaptive" if method in ("Tsit5", "Dopri8") else "diffrax fixed"


def table(results: dict) -> str:
    caption = (f"Rollouts, error against work (benchmarks/tradeoff_rollouts.py): tau = 0, from rest at {N_ROLLOUTS} "
               f"states q0 ~ U(-1, 1), horizon {HORIZON} s, closed-form forward dynamics, final state saved. Error "
               "= max |q(T) - q_ref(T)| in rad against RK4 at the reference step (its own error by Richardson "
               "extrapolation). Work: vector-field evaluations per rollout, wall time per rollout (batch of "
               f"{N_ROLLOUTS}, median of interleaved repeats) and per evaluation. Adaptive: step size chosen by "
               f"diffrax's PIDController(rtol=atol=tol) from {ADAPTIVE_DT0} s.")
    header = ("| robot | kind | method | step s / tol | dtype | evaluations | us per rollout | ns per evaluation | "
              "error (rad) | reference step s | reference error |")
    lines = [caption, "", header, "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, res in results.items():
        for r in res["rows"]:
            lines.append(
                f"| {key} | {kind(r['method'])} | {r['method']} | {r['setting']:g} | {r['dtype']} | "
                f"{r['evaluations']:.0f} | {r['time'] * 1e6:.1f} | {r['time'] / r['evaluations'] * 1e9:.0f} | "
                f"{r['err']:.1e} | {res['dt_ref']:g} | {res['reference_error']:.1e} |")
    return "\n".join(lines) + "\n"


def plot(ax_time, ax_work, key: str, res: dict) -> None:
    """Error against time per rollout (``ax_time``) and against evaluations per rollout (``ax_work``)."""
    import matplotlib
    import matplotlib.ticker

    floor = 1e-17
    styles = {"jaxskid": "-", "diffrax adaptive": "--", "diffrax fixed": ":"}
    groups = dict.fromkeys((r["method"], r["dtype"]) for r in res["rows"])
    for k, (method, dtype) in enumerate(groups):
        rows = [r for r in res["rows"] if (r["method"], r["dtype"]) == (method, dtype)]
        err = [max(r["err"], floor) for r in rows]
        style = {"marker": "^" if dtype == "float32" else "o", "ls": styles[kind(method)],
                 "color": matplotlib.colormaps["tab20"](k % 20),
                 "label": f"{method}, {dtype}" if dtype == "float32" else method}
        ax_time.plot([r["time"] * 1e6 for r in rows], err, **style)
        ax_work.plot([r["evaluations"] for r in rows], err, **style)
    for ax, xlabel in ((ax_time, "us per rollout (batch of 64)"), (ax_work, "vector-field evaluations per rollout")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"max |q(T) - q_ref(T)| (rad), T = {HORIZON} s")
        ax.set_title(f"{key}: rollouts (solid jaxskid, dashed diffrax adaptive, dotted diffrax fixed)", fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    ax_work.legend(fontsize=6)


def main(argv=None):
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxskid

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="panda,quadruped")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    doc_tables.add_option(ap)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    robots = {"panda": (Path(importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots")) / "panda_description/urdf/panda.urdf",
        {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
        "quadruped": (ROOT / "robots" / "quadruped_12dof.yaml", None)}
    results = {}
    with tempfile.TemporaryDirectory() as cache:
        for key in args.robots.split(","):
            path, lock = robots[key]
            robot = jaxskid.load(path, lock=lock)
            q0 = np.random.default_rng(1).uniform(-1, 1, size=(N_ROLLOUTS, robot.n_dof))
            print(f"{key}: {robot.n_dof} DOF", flush=True)
            results[key] = study(robot, q0, args.repeats, cache)
    text = (f"# jaxskid rollouts: error against work\n\njax {importlib.metadata.version('jax')}, diffrax "
            f"{importlib.metadata.version('diffrax')}, {platform.machine()}, {os.cpu_count()} CPUs\n\n" + table(results))
    print(text)
    (args.out / "tradeoff_rollouts.md").write_text(text)
    doc_tables.write(args.markdown, table(results).splitlines())
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(results), 2, figsize=(13, 4.8 * len(results)), squeeze=False)
    for row, (key, res) in enumerate(results.items()):
        plot(axes[row][0], axes[row][1], key, res)
    fig.tight_layout()
    fig.savefig(args.out / "tradeoff_rollouts.png", dpi=110)


if __name__ == "__main__":
    main()
