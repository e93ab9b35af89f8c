"""How the generated function assembles its result, and how it computes sine and cosine, against speed.

    python benchmarks/output_forms.py [--robot panda] [--quantity mass_matrix] [--forms stack,...] [--trig xla,fused]
                                      [--batch 65536] [--repeats 15] [--markdown PATH]

The same derived program (by default the Panda, 7 DOF, fingers locked, 70 symbolic inertial parameters, float64)
is printed with each output form and each sine/cosine, compiled the way :class:`jaxskid.Dynamics` compiles
it, and timed interleaved (medians per state). Each is also timed writing into its last result (the
column "into the last result": the result donated, as ``out=`` does), which takes the cost of fresh memory
out. Forms:

- ``stack``: ``jnp.stack([...])`` of the entries, each distinct entry computed once (a symmetric matrix's
  entries above and below the diagonal are one value);
- ``flat-where``: one chain ``jnp.where(index == k, value_k, out)`` over the flattened entries;
- ``nested-where``: one chain per axis on ``lax.broadcasted_iota``;
- ``broadcast-nested``: the same, with the inputs broadcast to the output's shape first (what jaxskid
  generates);
- ``gathered``: every distinct entry an output of variadic ``lax.reduce``s (by ``max``, exact) over two lanes
  of inputs broadcast to shape ``(2,)``, which XLA compiles into one multi-output kernel each, then stacked and
  placed by one gather (what jaxskid runs for a batch of a matrix in the JAX form on CPU,
  :mod:`jaxskid.runtime._gathered`, its batch padded as there).

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
from jaxskid.runtime._gathered import gathered, padded_batch  # noqa: E402
from jaxskid._generated import GeneratedQuantity  # noqa: E402
from jaxskid._fused import SOURCE as HELPERS  # noqa: E402
from jaxskid.codegen import Layout  # noqa: E402
from jaxskid.codegen._jax import JaxPrinter, function_source, jax_names  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)

ROOT = Path(__file__).resolve().parents[1]
ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
URDF = ERD / "panda_description/urdf/panda.urdf"
LOCK = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
URDFS = {"ur5": ERD / "ur_description/urdf/ur5_robot.urdf", "solo12": ERD / "solo_description/robots/solo12.urdf",
         "g1": ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf",
         "g1_hands": ERD / "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf"}
FORMS = ("stack", "flat-where", "nested-where", "broadcast-nested", "gathered")


def variants(eqs, name: str, which=FORMS, trig=("fused", "xla")) -> dict[str, tuple[str, object, bool]]:
    """Source of ``_name(*args, p, spread)`` in every (form, trig) combination, whether to spread (``True``: to
    the output's shape; a shape: to that one), and whether reciprocals are divisions instead of Newton's
    iteration."""
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
    stack, names = [f"    _z = jnp.zeros((), {dtype})"], {"0.0": "_z"}
    for e in outs:  # each distinct entry once: XLA compiled a repeated expression again
        if e not in names:
            names[e] = e if e.isidentifier() else f"_o{len(names)}"
            if names[e] != e:
                stack.append(f"    {names[e]} = {e}")
    distinct = [v for v in names.values() if v != "_z"]
    stack.append("    return jnp.stack([" + ", ".join(names[e] for e in outs) + f"]).reshape({shape!r})")
    forms = {"stack": (head + "\n".join(stack) + "\n", False), "flat-where": (head + "\n".join(flat) + "\n", False),
             "nested-where": (body, False), "broadcast-nested": (body, True), "gathered": (body, "gathered")}
    out = {}
    for form, (src, spread) in forms.items():
        if form not in which:
            continue
        if "fused" in trig:
            out[f"{form} / fused"] = (src, spread, False)
        if "xla" in trig:
            out[f"{form} / xla"] = (re.sub(r"\b_(sin|cos)\(", r"jnp.\1(", src), spread, False)
        if "_recip(" in src and "fused" in trig:  # the pivots of forward dynamics: Newton's iteration, a division
            out[f"{form} / fused / division"] = (src, spread, True)
    return out


def _robot(name: str):
    if name == "panda":
        return jaxskid.load(URDF, lock=LOCK)
    if name == "quadruped":
        return jaxskid.load(ROOT / "robots/quadruped_12dof.yaml")
    return jaxskid.load(URDFS[name])


def _compile(src: str, spread: bool, division: bool, label: str, quantity: str, shape, nargs: int):
    """The form's source executed and jitted as :class:`jaxskid.Dynamics` does, and the same writing into a
    donated earlier result."""
    ns = {"jax": jax, "jnp": jnp}
    exec(HELPERS, ns)  # noqa: S102
    if "/ fused" in label:  # the multiply-adds on every platform (the helpers use them on CPU only)
        ns["_sin"] = lambda x, ns=ns: ns["_sincos"](x)[0]
        ns["_cos"] = lambda x, ns=ns: ns["_sincos"](x)[1]
    if division:
        ns["_recip"] = lambda x: 1.0 / x
    exec(src, ns)  # noqa: S102
    if spread == "gathered":
        generated = GeneratedQuantity(quantity, (), tuple(shape), "", "", None, ns["_" + quantity])
        fn = _gathered_batch(gathered(generated), nargs)
    else:
        spread = shape if spread is True else spread  # True: the output's shape; a shape: that one
        body, how = ns["_" + quantity], ns["_spread"](spread) if spread else ns["_same"]
        fn = jax.vmap(lambda *a, body=body, how=how: body(*a, how), in_axes=(*([0] * nargs), None))
    into = jax.jit(lambda *a: fn(*a[:-1]), donate_argnums=(nargs + 1,), compiler_options=compiler_options())
    return jax.jit(fn, compiler_options=compiler_options()), into


def _gathered_batch(one, nargs: int):
    """``one`` mapped over a batch padded as :class:`jaxskid.Dynamics` pads it (:func:`padded_batch`)."""
    mapped = jax.vmap(one, in_axes=(*([0] * nargs), None))

    def fn(*args):
        size = args[0].shape[0]
        extra = padded_batch(size, args[0].dtype) - size
        states = [jnp.pad(x, ((0, extra), (0, 0)), mode="edge") for x in args[:-1]]
        return mapped(*states, args[-1])[:size]

    return fn


def _timed(fns: dict, states, p, repeats: int, batch: int) -> dict:
    """Median seconds per state of each form, fresh and into its last result, interleaved."""
    times = {k: ([], []) for k in fns}
    last = {k: jnp.array(f(*states, p)) for k, (f, *_rest) in fns.items()}
    for _ in range(repeats):
        for label, (f, into, *_rest) in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(*states, p))
            t1 = time.perf_counter()
            last[label] = jax.block_until_ready(into(*states, p, last[label]))
            times[label][0].append((t1 - t0) / batch)
            times[label][1].append((time.perf_counter() - t1) / batch)
    return {k: (float(np.median(a)), float(np.median(b))) for k, (a, b) in times.items()}


def _peer(args, robot, states):
    """Pinocchio's function for the quantity, seconds per call from Python (median of 5 sweeps), and its name."""
    if args.robot == "panda":
        full = pin.buildModelFromUrdf(str(URDF))
        model = pin.buildReducedModel(full, [full.getJointId(j) for j in LOCK], pin.neutral(full))
    elif args.robot == "quadruped":  # the same description, built in Pinocchio by the tests' converter
        sys.path.insert(0, str(ROOT / "tests"))
        from pinref import to_pinocchio

        model, _ = to_pinocchio(robot, robot.default_params())
    else:
        model = pin.buildModelFromUrdf(str(URDFS[args.robot]))
    data = model.createData()
    qs = [np.asarray(s[:2000]) for s in states]
    call, name = {
        "mass_matrix": (lambda k: pin.crba(model, data, qs[0][k]), "crba"),
        "inverse_dynamics": (lambda k: pin.rnea(model, data, qs[0][k], qs[1][k], qs[2][k]), "rnea"),
        "coriolis_matrix": (lambda k: pin.computeCoriolisMatrix(model, data, qs[0][k], qs[1][k]), "computeCoriolisMatrix"),
        "mass_matrix_dot": (lambda k: pin.computeCoriolisMatrix(model, data, qs[0][k], qs[1][k]), "computeCoriolisMatrix"),
        "regressor": (lambda k: pin.computeJointTorqueRegressor(model, data, qs[0][k], qs[1][k], qs[2][k]),
                      "computeJointTorqueRegressor"),
        "forward_dynamics": (lambda k: pin.aba(model, data, qs[0][k], qs[1][k], qs[2][k]), "aba"),
    }[args.quantity]
    sweeps = []
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(len(qs[0])):
            call(k)
        sweeps.append((time.perf_counter() - t0) / len(qs[0]))
    return float(np.median(sweeps)), name


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quantity", default="mass_matrix", choices=("mass_matrix", "inverse_dynamics", "coriolis_matrix",
                                                                  "forward_dynamics", "regressor", "mass_matrix_dot"))
    ap.add_argument("--batch", type=int, default=65536)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--robot", default="panda", choices=("panda", "quadruped", *URDFS),
                    help="the Panda URDF (fingers locked), robots/quadruped_12dof.yaml (a 12-DOF tree), or "
                         "example-robot-data's UR5, solo12, G1 (29 DOF) or G1 with hands (43), fixed base")
    ap.add_argument("--forms", default=",".join(FORMS), help=f"some of {', '.join(FORMS)}")
    ap.add_argument("--trig", default="fused,xla", help="fused, xla or both")
    doc_tables.add_option(ap)
    args = ap.parse_args(argv)
    robot = _robot(args.robot)
    eqs = jaxskid.derive(robot, [args.quantity])
    nargs = len(eqs.quantities[args.quantity].args)
    rng = np.random.default_rng(0)
    states = [jnp.asarray(rng.uniform(-1, 1, (args.batch, robot.n_dof))) for _ in range(nargs)]
    p = jnp.asarray([robot.default_params()[k] for k in eqs.parameters])
    fns, ref = {}, None
    shape = tuple(eqs.quantities[args.quantity].shape)
    forms = variants(eqs, args.quantity, args.forms.split(","), args.trig.split(","))
    for label, (src, spread, division) in forms.items():
        t0 = time.perf_counter()
        f, into = _compile(src, spread, division, label, args.quantity, shape, nargs)
        out = np.asarray(f(*states, p))
        kernels = len(re.findall(r"= \S+ fusion\(", f.lower(*states, p).compile().as_text()))
        ref = out if ref is None else ref
        err = float(np.max(np.abs(out - ref) / (1 + np.abs(ref))))
        fns[label] = (f, into, time.perf_counter() - t0, kernels, err)
    times = _timed(fns, states, p, args.repeats, args.batch)
    peer_t, peer_name = _peer(args, robot, states)
    print(f"{args.quantity}, {args.robot} {robot.n_dof} DOF, {len(eqs.parameters)} symbolic parameters, float64, "
          f"batch {args.batch}, jax {jax.__version__}; Pinocchio {peer_name} {peer_t * 1e9:.0f} ns per call")
    rows = []
    for label, (_f, _into, t_compile, kernels, err) in fns.items():
        t, t_into = times[label]
        print(f"{label:36s} {t * 1e9:9.1f} ns, into the last result {t_into * 1e9:9.1f} ns, x Pinocchio "
              f"{peer_t / t:.1f}, {kernels} kernels, compile {t_compile:.2f} s, max rel diff {err:.1e}")
        rows.append([label, doc_tables.duration(t), doc_tables.duration(t_into), doc_tables.ratio(peer_t / t_into),
                     kernels, f"{t_compile:.2f} s", f"{err:.1e}"])
    lines = doc_tables.table(["form / trig", "per state", "into the last result", "against Pinocchio (into)",
                              "fused kernels", "compile", "max relative difference"], rows)
    doc_tables.write(args.markdown, lines, f"`{args.quantity}` of the {args.robot} ({robot.n_dof} DOF, "
                     f"{len(eqs.parameters)} symbolic parameters), float64, batch {args.batch}, medians of "
                     f"{args.repeats} interleaved repeats; Pinocchio's `{peer_name}` {peer_t * 1e9:.0f} ns per call "
                     "from Python.")


if __name__ == "__main__":
    main()
