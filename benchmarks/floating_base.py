"""Floating-base quantities against Pinocchio in the same run: tau, M and forward dynamics of solo12 and the G1
with a free-flyer root, and the constrained forward dynamics of solo12 standing on four point contacts.

    python benchmarks/floating_base.py [--robots solo12,g1] [--batch 4096] [--repeats 7] [--markdown PATH]

jaxskid: the median time per state of the public function on a batch (float64; ``q`` of shape (batch, nq)).
Forward dynamics is solved from M and tau (no closed form lowered). Pinocchio: the median time per call from
Python of ``rnea``, ``crba``, ``aba`` and ``constraintDynamics`` (four
``RigidConstraintModel`` 3-D contacts in LOCAL_WORLD_ALIGNED, ``initConstraintDynamics`` done once beforehand),
on models built with ``JointModelFreeFlyer``. The ratio is Pinocchio's time over jaxskid's (> 1: jaxskid is
faster per state).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)
from core import add_robot_options, median_time  # noqa: E402  (benchmarks/core.py, beside this script)

ERD = Path(importlib.metadata.distribution("example-robot-data").locate_file(
    "cmeel.prefix/share/example-robot-data/robots"))
ROBOTS = {"solo12": ERD / "solo_description/robots/solo12.urdf", "g1": ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf"}
FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
STAND = np.array([0, 0.8, -1.6, 0, 0.8, -1.6, 0, -0.8, 1.6, 0, -0.8, 1.6])


def states(model, batch: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    q = np.stack([pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq)) for _ in range(batch)])
    return q, rng.normal(size=(batch, model.nv)), rng.normal(size=(batch, model.nv))


def per_call(fn, args, repeats: int) -> float:
    """Median over ``repeats`` of the mean time per call over the rows of ``args``."""
    rows = list(zip(*args))[:200]

    def run():
        for row in rows:
            fn(*row)

    return median_time(run, repeats) / len(rows)


ROWS: list[list[str]] = []  # the table's rows so far, for --markdown


def row(name: str, ours: float, theirs: float, peer: str) -> None:
    print(f"{name:<38} {ours * 1e6:>10.3f} {theirs * 1e6:>12.3f} {theirs / ours:>8.1f}x")
    ROWS.append([name, f"{ours * 1e6:.2f} µs", f"{theirs * 1e6:.2f} µs (`{peer}`)", f"{theirs / ours:.1f}x"])


def free_flyer(name: str, batch: int, repeats: int, rng) -> None:
    path = ROBOTS[name]
    robot = jaxskid.load(path, floating_base=True)
    start = time.perf_counter()
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    data = model.createData()
    q, v, a = states(model, batch, rng)
    dyn.inverse_dynamics(q, v, a).block_until_ready()
    dyn.mass_matrix(q).block_until_ready()
    print(f"{name} floating base (nv {robot.nv}): derive + lower + compile {time.perf_counter() - start:.1f} s")
    row(f"{name} tau", median_time(lambda: dyn.inverse_dynamics(q, v, a).block_until_ready(), repeats) / batch,
        per_call(lambda *x: pin.rnea(model, data, *x), (q, v, a), repeats), "rnea")
    row(f"{name} M", median_time(lambda: dyn.mass_matrix(q).block_until_ready(), repeats) / batch,
        per_call(lambda x: pin.crba(model, data, x), (q,), repeats), "crba")
    dyn.forward_dynamics(q, v, a).block_until_ready()  # M and tau solved on M's sparsity (runtime/_sparse.py)
    row(f"{name} forward dynamics", median_time(lambda: dyn.forward_dynamics(q, v, a).block_until_ready(),
                                                repeats) / batch,
        per_call(lambda *x: pin.aba(model, data, *x), (q, v, a), repeats), "aba")


def contacts(batch: int, repeats: int, rng) -> None:
    base = jaxskid.load(ROBOTS["solo12"], floating_base=True)
    at = dict(zip(base.joint_names, STAND))
    robot = base.with_constraints([jaxskid.PointContact(f, at=at) for f in FEET])
    start = time.perf_counter()
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "constraint_jacobian", "constraint_drift",
                                "constraint_residual"])
    model = pin.buildModelFromUrdf(str(ROBOTS["solo12"]), pin.JointModelFreeFlyer())
    data = model.createData()
    q = np.stack([np.concatenate([rng.normal(0, 0.05, 3), pin.Quaternion(pin.exp3(rng.normal(0, 0.2, 3))).coeffs(),
                                  STAND + rng.normal(0, 0.1, 12)]) for _ in range(batch)])
    v, tau = rng.normal(size=(batch, model.nv)), rng.normal(size=(batch, model.nv))
    tau[:, :6] = 0
    dyn.constrained_forward_dynamics(q, v, tau)[0].block_until_ready()
    print(f"solo12 on 4 point contacts: derive + lower + compile {time.perf_counter() - start:.1f} s")
    models, datas = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    for f in FEET:
        frame = model.frames[model.getFrameId(f)]
        models.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, model, frame.parentJoint, frame.placement,
                                               pin.LOCAL_WORLD_ALIGNED))
        datas.append(models[-1].createData())
    pin.initConstraintDynamics(model, data, models, datas)
    row("solo12 constrained forward dynamics",
        median_time(lambda: dyn.constrained_forward_dynamics(q, v, tau)[0].block_until_ready(), repeats) / batch,
        per_call(lambda *x: pin.constraintDynamics(model, data, *x, models, datas), (q, v, tau), repeats),
        "constraintDynamics")


def main(batch: int = 4096, repeats: int = 7, robots=tuple(ROBOTS), markdown=None) -> None:
    rng = np.random.default_rng(0)
    print(f"{'quantity':<38} {'jaxskid us':>10} {'pinocchio us':>12} {'ratio':>9}   (batch {batch}, float64)")
    for name in robots:
        free_flyer(name, batch, repeats, rng)
    if "solo12" in robots:
        contacts(batch, repeats, rng)
    lines = doc_tables.table(["quantity", "jaxskid per state", "Pinocchio per call", "ratio"], ROWS)
    doc_tables.write(markdown, lines, f"Floating bases (Pinocchio's `JointModelFreeFlyer` models), float64, batch "
                     f"{batch}, medians of {repeats}, the generated modules cached; forward dynamics from M and tau "
                     "(the sparse solve); Pinocchio per call from Python in the same run.")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_robot_options(parser, robots=",".join(ROBOTS), batch=4096, repeats=7)
    args = parser.parse_args()
    main(args.batch, args.repeats, args.robots.split(","), args.markdown)
