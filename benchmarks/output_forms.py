"""How the generated function assembles its result, and how it computes sine and cosine, against speed.

    python benchmarks/output_forms.py [--quantity mass_matrix] [--batch 65536] [--repeats 15] [--markdown PATH]

The same derived program (Panda, 7 DOF, fingers locked, 70 symbolic inertial parameters, float64) is
printed with each output form and each sine/cosine, compiled the way :class:`jaxskid.Dynamics` compiles
it, and timed interleaved (medians per state). Forms:

- ``stack``: ``jnp.stack([...])`` of the entries;
- ``flat-where``: one chain ``jnp.where(index == k, value_k, out)`` over the flattened entries;
- ``nested-where``: one chain per axis on ``lax.broadcasted_iota``;
- ``broadcast-nested``: the same, with the inputs broadcast to the output's shape first (what jaxskid
  generates).

Trig ``xla`` is ``jnp.sin``/``jnp.cos``; ``fused`` is the multiply-add version of
:mod:`jaxskid._fused` (what jaxskid's programs use on CPU; on other platforms they call XLA's), forced
here on every platform. Pinocchio's ``crba`` (or ``rnea``) per call from
Python is printed beside them (``computeCoriolisMatrix``, ``aba`` for the other quantities). For
``forward_dynamics`` the pivots' reciprocals are also timed as plain divisions (``/ division``).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402
from jaxskid.runtime._dynamics import compiler_options  # noqa: E402
from jaxskid._fused import SOURCE as HELPERS  # noqa: E402
from jaxskid.codegen import Layout  # noqa: E402
from jaxskid.codegen._jax import JaxPrinter, function_source, jax_names  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)

ROOT = Path(__file__).resolve().parents[1]
ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
URDF = ERD / "panda_description/urdf/panda.urdf"
LOCK = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}


def variants(eqs, name: str) -> dict[str, tuple[str, bool, bool]]:
    """Source of ``_name(*args, p, spread)`` in every (form, trig) combination, whether to spread, and
    whether reciprocals are divisions instead of Newton's iteration."""
    layout = Layout(eqs, (name,), jax_names)
    (kernel,) = layout.programs
    generated = function_source(layout, kernel, JaxPrinter())
    body = generated[: generated.index("\n\n\n@jax.custom_jvp")] + "\n"
    head = body[: body.index("    _z = jnp.zeros(")]
    qty = eqs.quantities[name]
    printer = JaxPrinter()
    outs = [printer.doprint(e) for e in kernel.outputs]
    dtype = f"jnp.result_type({qty.args[0]}, p)"
    size, shape = len(outs), tuple(qty.shape)
    flat = [f"    _out = jnp.zeros(({size},), {dtype})", f"    _i = jnp.arange({size})"]
    flat += [f"    _out = jnp.where(_i == {k}, {e}, _out)" for k, e in enumerate(outs) if e != "0.0"]
    flat.append(f"    return _out.reshape({shape!r})")
    stack = [f"    _z = jnp.zeros((), {dtype})",
             "    return jnp.stack([" + ", ".join(e if e != "0.0" else "_z" for e in outs) + f"]).reshape({shape!r})"]
    forms = {"stack": (head + "\n".join(stack) + "\n", False), "flat-where": (head + "\n".join(flat) + "\n", False),
             "nested-where": (body, False), "broadcast-nested": (body, True)}
    out = {}
    for form, (src, spread) in forms.items():
        out[f"{form} / fused"] = (src, spread, False)
        out[f"{form} / xla"] = (re.sub(r"\b_(sin|cos)\(", r"jnp.\1(", src), spread, False)
        if "_recip(" in src:  # the pivots of forward dynamics: Newton's iteration against a division
            out[f"{form} / fused / division"] = (src, spread, True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quantity", default="mass_matrix", choices=("mass_matrix", "inverse_dynamics", "coriolis_matrix", "forward_dynamics"))
    ap.add_argument("--batch", type=int, default=65536)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--robot", default="panda", choices=("panda", "quadruped"),
                    help="the Panda URDF (fingers locked) or robots/quadruped_12dof.yaml (a 12-DOF tree)")
    doc_tables.add_option(ap)
    args = ap.parse_args(argv)
    robot = jaxskid.load(URDF, lock=LOCK) if args.robot == "panda" else jaxskid.load(ROOT / "robots/quadruped_12dof.yaml")
    eqs = jaxskid.derive(robot, [args.quantity])
    nargs = len(eqs.quantities[args.quantity].args)
    rng = np.random.default_rng(0)
    states = [jnp.asarray(rng.uniform(-1, 1, (args.batch, robot.n_dof))) for _ in range(nargs)]
    p = jnp.asarray([robot.default_params()[k] for k in eqs.parameters])
    fns, ref = {}, None
    shape = tuple(eqs.quantities[args.quantity].shape)
    for label, (src, spread, division) in variants(eqs, args.quantity).items():
        ns = {"jax": jax, "jnp": jnp}
        exec(HELPERS, ns)  # noqa: S102
        if "/ fused" in label:  # the multiply-adds on every platform (the helpers use them on CPU only)
            ns["_sin"] = lambda x, ns=ns: ns["_sincos"](x)[0]
            ns["_cos"] = lambda x, ns=ns: ns["_sincos"](x)[1]
        if division:
            ns["_recip"] = lambda x: 1.0 / x
        exec(src, ns)  # noqa: S102
        body, how = ns["_" + args.quantity], ns["_spread"](shape) if spread else ns["_same"]
        fn = lambda *a, body=body, how=how: body(*a, how)  # noqa: E731
        f = jax.jit(jax.vmap(fn, in_axes=(*([0] * nargs), None)), compiler_options=compiler_options())
        t0 = time.perf_counter()
        out = np.asarray(f(*states, p))
        kernels = len(re.findall(r"= \S+ fusion\(", f.lower(*states, p).compile().as_text()))
        ref = out if ref is None else ref
        err = float(np.max(np.abs(out - ref) / (1 + np.abs(ref))))
        fns[label] = (f, time.perf_counter() - t0, kernels, err)
    times = {k: [] for k in fns}
    for _ in range(args.repeats):
        for label, (f, *_rest) in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(*states, p))
            times[label].append((time.perf_counter() - t0) / args.batch)
    if args.robot == "panda":
        model = pin.buildReducedModel(pin.buildModelFromUrdf(str(URDF)),
                                      [pin.buildModelFromUrdf(str(URDF)).getJointId(j) for j in LOCK],
                                      pin.neutral(pin.buildModelFromUrdf(str(URDF))))
    else:  # the same description, built in Pinocchio by the tests' converter
        sys.path.insert(0, str(ROOT / "tests"))
        from pinref import to_pinocchio

        model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    qs = [np.asarray(s[:2000]) for s in states]
    call, peer_name = {
        "mass_matrix": (lambda k: pin.crba(model, data, qs[0][k]), "crba"),
        "inverse_dynamics": (lambda k: pin.rnea(model, data, qs[0][k], qs[1][k], qs[2][k]), "rnea"),
        "coriolis_matrix": (lambda k: pin.computeCoriolisMatrix(model, data, qs[0][k], qs[1][k]), "computeCoriolisMatrix"),
        "forward_dynamics": (lambda k: pin.aba(model, data, qs[0][k], qs[1][k], qs[2][k]), "aba"),
    }[args.quantity]
    peer = []
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(len(qs[0])):
            call(k)
        peer.append((time.perf_counter() - t0) / len(qs[0]))
    peer_t = float(np.median(peer))
    print(f"{args.quantity}, {args.robot} {robot.n_dof} DOF, {len(eqs.parameters)} symbolic parameters, float64, batch {args.batch}, "
          f"jax {jax.__version__}; Pinocchio {peer_name} "
          f"{peer_t * 1e9:.0f} ns per call")
    print(f"{'form / trig':36s} {'ns/state':>9s} {'x Pinocchio':>12s} {'kernels':>8s} {'compile s':>10s} {'max rel diff':>13s}")
    rows = []
    for label, (_f, t_compile, kernels, err) in fns.items():
        t = float(np.median(times[label]))
        print(f"{label:36s} {t * 1e9:9.1f} {peer_t / t:12.1f} {kernels:8d} {t_compile:10.2f} {err:13.1e}")
        rows.append([label, doc_tables.duration(t), doc_tables.ratio(peer_t / t), kernels, f"{t_compile:.2f} s",
                     f"{err:.1e}"])
    lines = doc_tables.table(["form / trig", "per state", "against Pinocchio", "fused kernels", "compile",
                              "max relative difference"], rows)
    doc_tables.write(args.markdown, lines, f"`{args.quantity}` of the {args.robot} ({robot.n_dof} DOF, "
                     f"{len(eqs.parameters)} symbolic parameters), float64, batch {args.batch}, medians of "
                     f"{args.repeats} interleaved repeats; Pinocchio's `{peer_name}` {peer_t * 1e9:.0f} ns per call "
                     "from Python.")


if __name__ == "__main__":
    main()
