"""Speed against accuracy for every option a user can choose: the 3-link arm (3 DOF), Panda (7 DOF) and the
12-DOF quadruped.

    python benchmarks/tradeoff.py [--batch 16384] [--repeats 7] [--limit 45] [--out benchmarks/out] [--markdown PATH]
    python benchmarks/tradeoff.py --settings "tape (default),route=lagrange" --no-rollouts --name routes
    python benchmarks/tradeoff.py --robots "" --no-rollouts --precision g1 --name precision_g1

For each setting (CSE strategy, simplification, trig handling, the derivation route: screw or Euler-Lagrange,
closed form or the numeric recursive evaluation in JAX of ``jaxskid.testing._recursive``; float64 and float32)
it measures:

* derive + print time (``jaxskid.lower`` on an empty cache) and the operation count, in a fresh process
  with a time limit (``--limit`` s): a setting that does not finish is reported as such;
* XLA compile time, and the batched time per state (``jax.vmap``, batch ``--batch``) of M, Q_grav and tau:
  medians of ``--repeats`` calls, every compiled function of a robot interleaved with the others so that a
  loaded machine slows them alike;
* the error of M, Q_grav and tau: max over 32 states of the normwise relative error against a 50-digit
  mpmath evaluation of the same symbolic expressions (``jaxskid.testing._reference``; each option's own
  expressions are checked to give the same 50-digit values), and against Pinocchio.

Rollouts (``benchmarks/tradeoff_rollouts.py``): ``jaxskid.rollout`` (forward dynamics
``qdd = M^-1 (tau - C qd - Q_grav)`` by the closed-form quantity ``forward_dynamics``) with tau = 0, from rest
under gravity: jaxskid's semi-implicit Euler and RK4 at several step sizes, diffrax's adaptive Tsit5 and Dopri8
at several tolerances, and diffrax's fixed-step Euler, Heun, Midpoint and classical RK4 tableau; error of q at
the horizon against RK4 at a step 8x smaller than the smallest (its own error estimated by Richardson
extrapolation) against work: vector-field evaluations and wall time per rollout.

``--precision g1`` adds the 29-DOF Unitree G1 (fixed base, 290 symbolic parameters): the error of M and of
forward dynamics in float64 and float32 (the default closed form, through the public functions) against the
50-digit value, with cond(M) at the states.

The table is printed and written to ``<out>/<name>.md`` (``--name``, default ``tradeoff``), the Pareto plot
(time against error) to ``<out>/<name>.png``; ``--settings`` picks settings by label, ``--no-rollouts`` skips
the rollout study; ``python benchmarks/tradeoff_rollouts.py`` runs the rollout study alone.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import multiprocessing as mp
import os
import platform
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import doc_tables  # benchmarks/doc_tables.py, beside this script
import numpy as np
import tradeoff_rollouts

ROOT = Path(__file__).resolve().parents[1]
ERD = Path(importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"))
ROBOTS = {
    "arm3": (ROOT / "robots" / "arm_3dof.yaml", None),
    "panda": (ERD / "panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "quadruped": (ROOT / "robots" / "quadruped_12dof.yaml", None),
}
PRECISION_ROBOTS = {"g1": ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf"}
QUANTITIES = ("mass_matrix", "gravity_torques", "inverse_dynamics")
SHORT = {"mass_matrix": "M", "gravity_torques": "Q_grav", "inverse_dynamics": "tau"}
ARGS = {"mass_matrix": ("q",), "gravity_torques": ("q",), "inverse_dynamics": ("q", "qd", "qdd")}
DTYPES = ("float64", "float32")
N_ACCURACY = 32  # states for the error columns (the first states of the timing batch)
MAX_OPS = 100_000  # a setting with more operations is derived but not compiled (XLA would take minutes)


@dataclass(frozen=True)
class Setting:
    label: str
    kind: str  # "closed" or "recursive"
    options: dict


SETTINGS = (
    Setting("tape (default)", "closed", {}),
    Setting("cse=sympy", "closed", {"cse": "sympy"}),
    Setting("cse=none", "closed", {"cse": "none"}),
    Setting("simplify=expand", "closed", {"simplify": "expand"}),
    Setting("simplify=trigsimp", "closed", {"simplify": "trigsimp"}),
    Setting("trig=inline", "closed", {"trig": "inline"}),
    Setting("route=lagrange", "closed", {"route": "lagrange"}),
    Setting("recursive JAX", "recursive", {}),
)


# ---------------------------------------------------------------------------------------------- helpers
def _setup_jax():
    import jax

    jax.config.update("jax_enable_x64", True)
    return jax


def load_robot(key: str):
    import jaxskid

    path, lock = ROBOTS[key]
    return jaxskid.load(path, lock=lock)


def rel_err_max(got, ref_hi, ref_lo=None) -> float:
    """Max over states of ||got - ref|| / ||ref|| (entries of one state flattened)."""
    got = np.asarray(got, dtype=np.float64).reshape(len(ref_hi), -1)
    hi = np.asarray(ref_hi).reshape(len(ref_hi), -1)
    diff = got - hi if ref_lo is None else (got - hi) - np.asarray(ref_lo).reshape(len(ref_hi), -1)
    return float(np.max(np.linalg.norm(diff, axis=1) / np.maximum(np.linalg.norm(hi, axis=1), 1e-300)))


# ---------------------------------------------------------------------------------------------- child side
def derive_setting(job: dict) -> dict:
    """In a fresh process, under the time limit: derive + print one closed-form setting into the cache."""
    _setup_jax()
    import jaxskid
    from jaxskid.testing import _reference

    robot = load_robot(job["robot"])
    options = jaxskid.Options(**job["setting"].options)
    t = time.perf_counter()
    jaxskid.lower(robot, QUANTITIES, options=options, cache_dir=job["cache"])
    out = {"derive": time.perf_counter() - t}
    eqs = jaxskid.derive(robot, QUANTITIES, options=options)
    out["ops"] = {q: eqs.operation_count([q]) for q in QUANTITIES}
    if sum(out["ops"].values()) <= MAX_OPS:
        # the option's own expressions at 50 digits equal the reference (of the default program)
        own = _reference.mp_reference(eqs, QUANTITIES, job["states"], job["params"])
        out["same_expressions"] = max(rel_err_max(own[q].hi, job["ref"][q][0][:2]) for q in QUANTITIES)
    return out


def _child(conn, fn_name, job):
    try:
        result = globals()[fn_name](job)
        conn.send(("ok", result))
    except Exception:  # noqa: BLE001 - reported in the table
        conn.send(("error", traceback.format_exc(limit=3)))
    finally:
        conn.close()


def run_limited(fn_name: str, job: dict, limit: float) -> tuple[str, object, float]:
    """Run ``fn_name(job)`` in a fresh process; ("ok", result) or ("timeout" | "error", message)."""
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, fn_name, job), daemon=True)
    t = time.perf_counter()
    proc.start()
    child.close()
    status, result = "timeout", None
    if parent.poll(limit):
        try:
            status, result = parent.recv()
        except EOFError:
            status, result = "error", "the worker exited without a result"
    if proc.is_alive():
        proc.kill()
    proc.join()
    return status, result, time.perf_counter() - t


# ---------------------------------------------------------------------------------------------- parent side
def references(key: str, states: dict):
    """(robot, params, 50-digit reference of the default program, Pinocchio values) at the accuracy states."""
    import pinocchio as pin

    import jaxskid
    from jaxskid.testing import _reference

    robot = load_robot(key)
    params = np.array([robot.default_params()[k] for k in robot.parameters])
    eqs = jaxskid.derive(robot, QUANTITIES)
    assert eqs.parameters == robot.parameters
    acc = {k: v[:N_ACCURACY] for k, v in states.items()}
    ref = _reference.mp_reference(eqs, QUANTITIES, acc, params)
    if key == "panda":
        path, lock = ROBOTS[key]
        full = pin.buildModelFromUrdf(str(path))
        model = pin.buildReducedModel(full, [full.getJointId(j) for j in lock], pin.neutral(full))
    else:
        sys.path.insert(0, str(ROOT / "tests"))
        from pinref import to_pinocchio

        model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    pins = {q: [] for q in QUANTITIES}
    for k in range(N_ACCURACY):
        q, qd, qdd = (acc[a][k] for a in ("q", "qd", "qdd"))
        m = pin.crba(model, data, q)
        pins["mass_matrix"].append(np.triu(m) + np.triu(m, 1).T)
        pins["gravity_torques"].append(pin.computeGeneralizedGravity(model, data, q).copy())
        pins["inverse_dynamics"].append(pin.rnea(model, data, q, qd, qdd).copy())
    return robot, params, {q: (ref[q].hi, ref[q].lo) for q in QUANTITIES}, {q: np.array(v) for q, v in pins.items()}


def measure(key: str, robot, states, params, ref, pins, derived: dict, cache: str, repeats: int,
            settings=SETTINGS) -> list[dict]:
    """Compile every setting that was derived (and the recursive evaluation) in both dtypes; errors at the
    accuracy states; batched times, interleaved."""
    jax = _setup_jax()
    import jax.numpy as jnp

    import jaxskid
    from jaxskid.testing._recursive import recursive_dynamics

    rows, sources = [], {}
    for setting in settings:
        row = {"robot": key, "setting": setting.label, "status": "ok", "compile": {}, "err_mp": {}, "err_pin": {}}
        if setting.kind == "recursive":
            t = time.perf_counter()
            sources[setting.label] = recursive_dynamics(robot)
            row.update(derive=time.perf_counter() - t, ops=None)
        else:
            status, result, wall = derived[setting.label]
            row["status"] = status
            if status == "ok":
                row.update(derive=result["derive"], ops=result["ops"])
                if sum(result["ops"].values()) > MAX_OPS:
                    row["status"] = "too large"
                else:
                    options = jaxskid.Options(**setting.options)
                    sources[setting.label] = jaxskid.lower(robot, QUANTITIES, options=options, cache_dir=cache)
            else:
                row["message"] = result
        rows.append(row)
    calls = {}
    for row in rows:
        if row["setting"] not in sources:
            continue
        source = sources[row["setting"]]
        for dtype in DTYPES:
            p = jnp.asarray(params, dtype=dtype)
            for q in QUANTITIES:
                args = [jnp.asarray(states[a], dtype=dtype) for a in ARGS[q]]
                f = jax.jit(jax.vmap(source.raw(q), in_axes=(*([0] * len(args)), None)),
                            compiler_options=jaxskid.compiler_options())  # as jaxskid compiles its own
                t = time.perf_counter()
                compiled = f.lower(*args, p).compile()
                row["compile"][dtype, q] = time.perf_counter() - t
                value = np.asarray(compiled(*args, p))[:N_ACCURACY]
                row["err_mp"][dtype, q] = rel_err_max(value, *ref[q])
                row["err_pin"][dtype, q] = rel_err_max(value, pins[q])
                calls[row["setting"], dtype, q] = (lambda c=compiled, a=args, p=p: c(*a, p).block_until_ready())
        print(f"  compiled {row['setting']:20s} ({sum(row['compile'].values()):.1f} s)", flush=True)
    times = tradeoff_rollouts.round_robin(calls, repeats)  # the same interleaving as the rollout study
    batch = len(states["q"])
    for row in rows:
        row["time"] = {(d, q): times[s, d, q] / batch for (s, d, q) in times if s == row["setting"]}
    return rows


def precision_study(key: str) -> list[dict]:
    """float64 and float32 error of M and forward dynamics on a large robot against 50 digits."""
    _setup_jax()
    import jax.numpy as jnp

    import jaxskid
    from jaxskid.testing import _reference

    robot = jaxskid.load(PRECISION_ROBOTS[key])
    names = ("mass_matrix", "forward_dynamics")
    t = time.perf_counter()
    eqs = jaxskid.derive(robot, names)
    dyn = jaxskid.lower(eqs)
    setup = time.perf_counter() - t
    params = np.array([robot.default_params()[k] for k in robot.parameters])
    rng = np.random.default_rng(0)
    n = robot.n_dof
    # float32-representable inputs, so that both precisions see the same problem
    states = {a: rng.uniform(-1.5, 1.5, size=(N_ACCURACY, n)).astype(np.float32).astype(np.float64)
              for a in ("q", "qd")}
    states["tau"] = rng.uniform(-20, 20, size=(N_ACCURACY, n)).astype(np.float32).astype(np.float64)
    t = time.perf_counter()
    ref = _reference.mp_reference(eqs, names, states, params)
    mp_seconds = time.perf_counter() - t
    cond = float(np.median([np.linalg.cond(m) for m in ref["mass_matrix"].hi]))
    rows = []
    for dtype in DTYPES:
        p = jnp.asarray(params, dtype=dtype)
        x = {a: jnp.asarray(v, dtype=dtype) for a, v in states.items()}
        m = dyn.mass_matrix(x["q"], p)
        qdd = dyn.forward_dynamics(x["q"], x["qd"], x["tau"], p)
        assert m.dtype == qdd.dtype == dtype, (m.dtype, qdd.dtype)
        rows.append({"robot": key, "dof": n, "dtype": dtype, "cond": cond,
                     "M": rel_err_max(m, ref["mass_matrix"].hi, ref["mass_matrix"].lo),
                     "forward_dynamics": rel_err_max(qdd, ref["forward_dynamics"].hi, ref["forward_dynamics"].lo)})
    print(f"{key}: {n} DOF; derive + lower {setup:.1f} s, 50-digit reference {mp_seconds:.1f} s", flush=True)
    return rows


def precision_table(rows: list[dict]) -> str:
    lines = [f"Large robots: M and forward dynamics (closed form, default options, through the public functions) at "
             f"{N_ACCURACY} states (q, qd ~ U(-1.5, 1.5), tau ~ U(-20, 20) N m), max normwise relative error against "
             "the 50-digit value; cond(M) is the median 2-norm condition number at those states.", "",
             "| robot | DOF | dtype | M err mp | forward dynamics err mp | median cond(M) |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['robot']} | {r['dof']} | {r['dtype']} | {fmt_err(r['M'])} | "
                     f"{fmt_err(r['forward_dynamics'])} | {r['cond']:.1e} |")
    return "\n".join(lines)


def fmt_time(s: float) -> str:
    ns = s * 1e9
    return f"{ns:.0f}" if ns >= 100 else f"{ns:.1f}"


def fmt_err(e: float) -> str:
    return f"{e:.1e}"


def table(results: list[dict], rollout_results: dict, args) -> str:
    q_cols = " | ".join(f"{SHORT[q]} ns/state | {SHORT[q]} err mp | {SHORT[q]} err pin" for q in QUANTITIES)
    lines = [
        "# jaxskid speed-accuracy trade-off",
        "",
        f"jax {importlib.metadata.version('jax')}, pinocchio {importlib.metadata.version('pin')}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs; batch {args.batch}, median of {args.repeats} interleaved "
        f"repeats. Errors: max over {N_ACCURACY} states of the normwise relative error against the 50-digit mpmath "
        "value of the same expressions (mp) and against Pinocchio (pin). Derive = derive + print (`jaxskid.lower` "
        "on an empty cache; for the recursive evaluation, building it); compile = XLA, all three quantities, "
        "this dtype.",
        "",
        f"| robot | setting | dtype | derive s | ops M/Q_grav/tau | compile s | {q_cols} |",
        "|" + "---|" * (6 + 3 * len(QUANTITIES)),
    ]
    blank = " |" * (3 * len(QUANTITIES))
    for r in results:
        ops = "/".join(str(r["ops"][q]) for q in QUANTITIES) if r.get("ops") else "-"
        if r["status"] != "ok":
            if r["status"] == "timeout":
                why = f"did not finish in {args.limit:g} s"
            elif r["status"] == "too large":
                why = f"derived in {r['derive']:.1f} s, not compiled: over {MAX_OPS} operations"
            else:
                why = "failed: " + str(r.get("message", "")).strip().splitlines()[-1]
            lines.append(f"| {r['robot']} | {r['setting']} | - | {why} | {ops} | - |{blank}")
            continue
        for dtype in DTYPES:
            cells = []
            for q in QUANTITIES:
                cells += [fmt_time(r["time"][dtype, q]), fmt_err(r["err_mp"][dtype, q]),
                          fmt_err(r["err_pin"][dtype, q])]
            compile_s = sum(r["compile"][dtype, q] for q in QUANTITIES)
            lines.append(f"| {r['robot']} | {r['setting']} | {dtype} | {r['derive']:.2f} | {ops} | {compile_s:.1f} | "
                         + " | ".join(cells) + " |")
    if rollout_results:
        lines += ["", tradeoff_rollouts.table(rollout_results)]
    return "\n".join(lines) + "\n"


def pareto(points):
    """Indices of the points not dominated in (time, error), by increasing time."""
    order = sorted(range(len(points)), key=lambda k: (points[k][0], points[k][1]))
    front, best = [], np.inf
    for k in order:
        if points[k][1] < best:
            front.append(k)
            best = points[k][1]
    return front


def plot(results: list[dict], rollout_results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    robots = list(dict.fromkeys(r["robot"] for r in results))
    extra = 2 if rollout_results else 0
    fig, axes = plt.subplots(len(robots), len(QUANTITIES) + extra, figsize=(6 * (len(QUANTITIES) + extra),
                             4.4 * len(robots) + 0.8), squeeze=False)
    colors = {s.label: plt.cm.tab10(k) for k, s in enumerate(SETTINGS)}
    markers = {"float64": "o", "float32": "^"}
    floor = 1e-17  # errors of exactly zero are drawn here
    for row, key in enumerate(robots):
        for col, q in enumerate(QUANTITIES):
            ax = axes[row][col]
            pts = []
            for r in results:
                if r["robot"] != key or r["status"] != "ok":
                    continue
                for dtype in DTYPES:
                    t, e = r["time"][dtype, q] * 1e9, max(r["err_mp"][dtype, q], floor)
                    ax.scatter(t, e, color=colors[r["setting"]], marker=markers[dtype], s=45, zorder=3,
                               label=f"{r['setting']}, {dtype}")
                    pts.append((t, e))
            front = pareto(pts)
            if front:
                ax.step([pts[k][0] for k in front], [pts[k][1] for k in front], where="post", color="0.5", lw=1,
                        zorder=2)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel("ns per state (vmap, batched)")
            ax.set_ylabel("max rel. error vs 50-digit mpmath")
            ax.set_title(f"{key}: {SHORT[q]}")
            ax.grid(True, which="both", alpha=0.3)
        if key in rollout_results:
            tradeoff_rollouts.plot(axes[row][-2], axes[row][-1], key, rollout_results[key])
    handles, labels = axes[0][0].get_legend_handles_labels()
    seen = dict(zip(labels, handles))
    fig.legend(seen.values(), seen.keys(), loc="lower center", ncol=5, fontsize=8)
    fig.suptitle("jaxskid: batched time per state against error "
                 "(grey: Pareto front; circles float64, triangles float32)")
    fig.tight_layout(rect=(0, 0.08, 1, 0.97))
    fig.savefig(path, dpi=110)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=16384)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--limit", type=float, default=45.0,
                    help="seconds to derive one setting before it counts as not finished")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    ap.add_argument("--robots", default=",".join(ROBOTS))
    ap.add_argument("--settings", default=None, help="comma-separated setting labels (default: all)")
    ap.add_argument("--rollouts", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--name", default="tradeoff", help="stem of the table and plot written to --out")
    ap.add_argument("--precision", default="", help=f"comma-separated large robots ({', '.join(PRECISION_ROBOTS)}) "
                    "for the float32/float64 error of M and forward dynamics")
    doc_tables.add_option(ap)
    args = ap.parse_args(argv)
    labels = [s.label for s in SETTINGS]
    chosen = labels if args.settings is None else args.settings.split(",")
    unknown = sorted(set(chosen) - set(labels))
    if unknown:
        ap.error(f"unknown setting(s) {unknown}; settings: {labels}")
    settings = [s for s in SETTINGS if s.label in chosen]
    bad = sorted(set(filter(None, args.precision.split(","))) - set(PRECISION_ROBOTS))
    if bad:
        ap.error(f"unknown --precision robot(s) {bad}; available: {sorted(PRECISION_ROBOTS)}")
    args.out.mkdir(parents=True, exist_ok=True)
    _setup_jax()
    start = time.perf_counter()
    results, rollout_results = [], {}
    with tempfile.TemporaryDirectory() as cache:
        for key in filter(None, args.robots.split(",")):
            robot = load_robot(key)
            n = robot.n_dof
            rng = np.random.default_rng(0)
            # float32-representable states, so that both dtypes see the same inputs
            states = {a: rng.uniform(-1.5, 1.5, size=(args.batch, n)).astype(np.float32).astype(np.float64)
                      for a in ("q", "qd", "qdd")}
            t = time.perf_counter()
            robot, params, ref, pins = references(key, states)
            print(f"{key}: {n} DOF, {len(params)} parameters; 50-digit reference and Pinocchio at {N_ACCURACY} states "
                  f"in {time.perf_counter() - t:.1f} s", flush=True)
            derived = {}
            two = {k: v[:2] for k, v in states.items()}
            for setting in settings:
                if setting.kind != "closed":
                    continue
                job = {"robot": key, "setting": setting, "states": two, "params": params, "ref": ref, "cache": cache}
                status, result, wall = run_limited("derive_setting", job, args.limit)
                derived[setting.label] = (status, result, wall)
                note = status if status != "error" else result.strip().splitlines()[-1]
                print(f"  derived {setting.label:20s} {note} ({wall:.1f} s)", flush=True)
                # An option reshapes the same expressions (equal to 50 digits). The Euler-Lagrange route is another
                # formula, equal where every rotation of the description is exactly orthonormal: a URDF's decimal
                # angles and axes are so only to double precision.
                same = 1e-13 if "route" in setting.options else 1e-30
                if status == "ok" and result.get("same_expressions", 0.0) > same:
                    raise AssertionError(f"{key} {setting.label}: the option changed the function "
                                         f"({result['same_expressions']:.3g} at 50 digits)")
            results += measure(key, robot, states, params, ref, pins, derived, cache, args.repeats, settings)
            if not args.rollouts:
                continue
            t = time.perf_counter()
            q0 = np.random.default_rng(1).uniform(-1, 1, size=(tradeoff_rollouts.N_ROLLOUTS, n))
            rollout_results[key] = tradeoff_rollouts.study(robot, q0, max(3, args.repeats // 2), cache)
            print(f"  rollouts ({time.perf_counter() - t:.1f} s)", flush=True)
    precision = [row for key in filter(None, args.precision.split(",")) for row in precision_study(key)]
    text = table(results, rollout_results, args) if results else "# jaxskid speed-accuracy trade-off\n"
    if precision:
        text += "\n" + precision_table(precision) + "\n"
    print()
    print(text)
    (args.out / f"{args.name}.md").write_text(text)
    written = [args.out / f"{args.name}.md"]
    doc_tables.write(args.markdown, [line for line in text.splitlines() if not line.startswith("# ")])
    if results:
        written.append(args.out / f"{args.name}.png")
        plot(results, rollout_results, written[-1])
    print(f"wrote {', '.join(map(str, written))} in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
