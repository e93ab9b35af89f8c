"""Time derivatives of the equations of motion: closed-form recursions against a chain-rule baseline.

    python benchmarks/derivatives.py [--robot panda] [--batch 4096] [--repeats 5] [--emitters classic]

Both routes give dM/dt, dC/dt, dQ_grav/dt, dtau/dt, dQ_ext/dt and their second derivatives:

* ``closed``: jaxskid's recursive closed forms (``jaxskid.symbolic``, Müller & Kumar 2021): the
  body-fixed recursions are differentiated, every intermediate named on one tape;
* ``chain``: the chain rule applied to the straight-line program of M, C, Q_grav, tau and Q_ext, i.e. the
  total time derivative ``d/dt = sum_x (dx/dt) d/dx`` of every assignment in forward mode (``q -> qd ->
  qdd ...``, ``wrench -> wrench_d -> ...``, parameters constant), and again for the second derivatives.
  This is Skidy's route (it differentiates its expressions with ``sympy.diff``) made to scale: on the full
  expanded trees it swells beyond 3-4 joints (see ``--skidy``, which times it on the hopping leg).

For each route and order the run prints the cold derive, lower (print + exec) and XLA compile times (batched
``vmap``, batch ``--batch``), the operation count of each quantity, its batched time per state (median of
``--repeats``), and the largest relative difference between the two routes. ``--emitters classic`` compiles
with ``xla_cpu_use_fusion_emitters=False``: XLA's default (new) CPU fusion emitters compile these long
straight-line programs into code 100-1000x slower (and compile some for many minutes).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
import sympy as sp  # noqa: E402

import jaxskid  # noqa: E402
from jaxskid.equations import Equations, Options, Quantity  # noqa: E402
from jaxskid.codegen import Layout  # noqa: E402
from jaxskid.codegen._jax import jax_names, module_source  # noqa: E402
from jaxskid.lowering._cache import load_module  # noqa: E402
from jaxskid.symbolic import Tape  # noqa: E402

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
ROBOTS = {
    "panda": lambda: jaxskid.load(ERD / "panda_description/urdf/panda.urdf",
                                  lock={"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
    "ur5": lambda: jaxskid.load(ERD / "ur_description/urdf/ur5_robot.urdf"),
    "hopping_leg": lambda: jaxskid.load(Path(__file__).parents[1] / "robots" / "hopping_leg.yaml"),
}
BASES = ("mass_matrix", "coriolis_matrix", "gravity_torques", "inverse_dynamics", "external_torques")
SUFFIX = {1: "_dot", 2: "_ddot"}
NEXT = {"q": "qd", "qd": "qdd", "qdd": "q3d", "q3d": "q4d", "wrench": "wrench_d", "wrench_d": "wrench_dd"}


# ------------------------------------------------------------------------------------------ chain rule
def chain_rule(eqs: Equations, names: dict[str, str], prefix: str) -> Equations:
    """Forward-mode total time derivative of the program: quantity ``src`` -> new quantity ``names[src]``.

    Every assignment ``s = e`` gets ``ds = sum_x de/dx dx`` (sympy.diff of the small expression ``e``),
    named on a fresh tape; leaves map q_i^(k) -> q_i^(k+1) and wrench^(k) -> wrench^(k+1).
    """
    d: dict = {}
    for a, b in NEXT.items():
        for s, t in zip(eqs.arguments[a].symbols, eqs.arguments[b].symbols):
            d[s] = t
    tape = Tape(prefix)

    def derivative(e):
        terms = [sp.diff(e, x) * d[x] for x in e.free_symbols if d.get(x, 0) != 0]
        return tape(sp.Add(*terms)) if terms else sp.Integer(0)

    for s, e in eqs.program(list(names)):
        d[s] = derivative(e)
    quantities = dict(eqs.quantities)
    for src, dst in names.items():
        q = eqs.quantities[src]
        spec = jaxskid.QUANTITIES[dst]
        outs = tuple(derivative(sp.sympify(e)) for e in q.outputs)
        quantities[dst] = Quantity(dst, spec.args, q.shape, outs, spec.equation, "chain rule")
    return dataclasses.replace(eqs, quantities=quantities, assignments=(*eqs.assignments, *tape.defs.items()),
                               _index={})


def derive_chain(robot) -> tuple[dict[int, Equations], dict[int, float]]:
    """The second derivatives differentiate the first-derivative program, so their time includes it."""
    eqs, times = {}, {}
    t = time.perf_counter()
    eqs[1] = chain_rule(jaxskid.derive(robot, list(BASES)), {b: b + "_dot" for b in BASES}, "_y")
    times[1] = time.perf_counter() - t
    eqs[2] = chain_rule(eqs[1], {b + "_dot": b + "_ddot" for b in BASES}, "_z")
    times[2] = time.perf_counter() - t
    return eqs, times


def derive_closed(robot) -> tuple[dict[int, Equations], dict[int, float]]:
    """Each order's set on its own (a fresh request), as a user would ask for it."""
    eqs, times = {}, {}
    for order, suffix in SUFFIX.items():
        t = time.perf_counter()
        eqs[order] = jaxskid.derive(robot, [b + suffix for b in BASES])
        times[order] = time.perf_counter() - t
    return eqs, times


def skidy_style(robot, timeout: float) -> list[tuple[str, float, int]]:
    """Skidy's own route on a small robot: full expression trees (``Options(cse="none")``), then sympy.diff."""
    out = []
    for base in BASES:
        t = time.perf_counter()
        eqs = jaxskid.derive(robot, [base], options=Options(cse="none"))
        first = chain_rule(eqs, {base: base + "_dot"}, "_y")
        second = chain_rule(first, {base + "_dot": base + "_ddot"}, "_z")
        # substitute back so that the result is one tree per entry, as Skidy's
        values = {}
        for s, e in second.assignments:
            values[s] = e.xreplace(values)
        trees = [sp.sympify(e).xreplace(values) for e in second.quantities[base + "_ddot"].outputs]
        elapsed = time.perf_counter() - t
        out.append((base + "_ddot", elapsed, sum(sp.count_ops(e) for e in trees)))
        if elapsed > timeout:
            break
    return out


# ------------------------------------------------------------------------------------------ measuring
def compile_set(robot, eqs: Equations, names: list[str], batch: int, options: dict | None):
    """Lower (print + exec) and compile the named quantities, batched; returns the timings and callables."""
    t = time.perf_counter()
    ns = load_module(module_source(Layout(eqs, tuple(names), jax_names)), "<benchmark>")
    lower_s = time.perf_counter() - t
    n, n_ee = robot.n_dof, len(robot.end_effectors)
    rng = np.random.default_rng(0)
    state = {a: rng.normal(size=(batch, n_ee, 6) if a.startswith("wrench") else (batch, n)) for a in eqs.arguments}
    p = jax.numpy.asarray(np.array([robot.default_params()[k] for k in eqs.parameters]))
    calls, compile_s = {}, {}
    for name in names:
        args = eqs.quantities[name].args
        fn = jax.jit(jax.vmap(ns[name], in_axes=(*([0] * len(args)), None)), compiler_options=options)
        xs = [state[a] for a in args]
        t = time.perf_counter()
        compiled = fn.lower(*xs, p).compile()
        compile_s[name] = time.perf_counter() - t
        calls[name] = lambda c=compiled, xs=xs: c(*xs, p).block_until_ready()  # returns the output
    return lower_s, compile_s, calls


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="panda", choices=sorted(ROBOTS))
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--emitters", default="classic", choices=("classic", "default"))
    ap.add_argument("--skidy", type=float, default=0.0, metavar="SECONDS",
                    help="also time Skidy's full-tree chain rule on the hopping leg (stop after SECONDS)")
    args = ap.parse_args()
    options = {"xla_cpu_use_fusion_emitters": False} if args.emitters == "classic" else None
    robot = ROBOTS[args.robot]()
    print(f"{robot.name}: {robot.n_dof} DOF, {len(robot.parameters)} symbolic parameters, batch {args.batch}, "
          f"jax {jax.__version__}, {args.emitters} XLA CPU emitters\n")
    sets = {}
    for route, derive in (("closed", derive_closed), ("chain", derive_chain)):
        eqs, derive_s = derive(robot)
        for order in (1, 2):
            names = [b + SUFFIX[order] for b in BASES]
            lower_s, compile_s, calls = compile_set(robot, eqs[order], names, args.batch, options)
            sets[route, order] = (eqs[order], names, derive_s[order], lower_s, compile_s, calls)
    # throughput: every function once per round, rounds interleaved, so that load changes hit all alike
    times = {(key, name): [] for key, s in sets.items() for name in s[1]}
    for _ in range(args.repeats + 1):
        for (key, name), ts in times.items():
            t = time.perf_counter()
            sets[key][5][name]()
            ts.append(time.perf_counter() - t)
    for (route, order), (eqs, names, d, lo, comp, calls) in sets.items():
        total = d + lo + sum(comp.values())
        print(f"[{route}, order {order}] derive {d:.1f} s, lower {lo:.1f} s, compile {sum(comp.values()):.1f} s; "
              f"derive + lower + compile {total:.1f} s")
        for name in names:
            ns = float(np.median(times[(route, order), name][1:])) / args.batch * 1e9
            ops = eqs.operation_count([name])
            print(f"    {name:24s} {ops:7d} ops  compile {comp[name]:6.1f} s  {ns:9.0f} ns/state")
        print()
    print("set (5 quantities)       derive    lower  compile    total  ops (shared)")
    for (route, order), (eqs, names, d, lo, comp, _) in sets.items():
        c = sum(comp.values())
        print(f"{route + ', order ' + str(order):22s} {d:7.1f}s {lo:7.1f}s {c:7.1f}s {d + lo + c:7.1f}s "
              f"{eqs.operation_count(names):8d}")
    print()
    for order in (1, 2):
        for name in sets["closed", order][1]:
            a, b = (np.asarray(sets[route, order][5][name]()) for route in ("closed", "chain"))
            err = np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)
            print(f"closed vs chain {name:24s} max relative difference {err:.1e}")
    if args.skidy:
        print("\nSkidy's route (full trees + sympy.diff) on the hopping leg, second derivatives:")
        for name, s, ops in skidy_style(ROBOTS["hopping_leg"](), args.skidy):
            print(f"    {name:24s} {s:7.1f} s  {ops:8d} ops")


if __name__ == "__main__":
    main()
