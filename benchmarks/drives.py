"""The regressor with drives against the regressor without, and against Pinocchio, in one run.

    python benchmarks/drives.py [--robots ur10,panda] [--batch 4096] [--repeats 9] [--markdown PATH]

For each robot (example-robot-data's UR10 and the Panda with its fingers locked) the regressor is lowered
twice, without drives (10 columns per body) and with them (``load(..., drives=True)``: 4 more per joint,
armature, viscous and Coulomb friction, offset). Both are timed per state on one batch of random states
(medians, the calls alternated so that the machine's load hits both alike), with whether each runs as a native
kernel; Pinocchio's ``computeJointTorqueRegressor`` per call on the same states is the peer. The drive columns
are ``(qdd, qd, sign(qd), 1)`` per joint: a regressor with drives should cost about what one without does.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import jaxskid  # noqa: E402
from core import add_robot_options, alternating_medians, median_time  # noqa: E402
import doc_tables  # noqa: E402  (benchmarks/doc_tables.py, beside this script)

ERD = Path(pin.__file__).parents[4] / "share" / "example-robot-data" / "robots"
ROBOTS = {
    "ur10": (ERD / "ur_description/urdf/ur10_robot.urdf", None),
    "panda": (ERD / "panda_description/urdf/panda.urdf", {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_robot_options(parser, robots="ur10,panda", batch=4096, repeats=9)
    args = parser.parse_args()
    out = doc_tables.Lines()
    out("| robot | batch | without drives | with drives | with / without | native (without, with) "
          "| Pinocchio per call | with drives against Pinocchio |")
    out("|---|---|---|---|---|---|---|---|")
    for name in args.robots.split(","):
        path, lock = ROBOTS[name]
        plain = jaxskid.lower(jaxskid.load(path, lock=lock), ["regressor"])
        driven = jaxskid.lower(jaxskid.load(path, lock=lock, drives=True), ["regressor"])
        n, rng = plain.n_dof, np.random.default_rng(0)
        q, qd, qdd = (jax.numpy.asarray(rng.uniform(-2, 2, (args.batch, n))) for _ in range(3))
        without, with_ = alternating_medians(
            [lambda: plain.regressor(q, qd, qdd).block_until_ready(),
             lambda: driven.regressor(q, qd, qdd).block_until_ready()], args.repeats)
        model = pin.buildModelFromUrdf(str(path))
        if lock:
            ids = [model.getJointId(j) for j in lock]
            model = pin.buildReducedModel(model, ids, pin.neutral(model))
        data = model.createData()
        states = [(np.asarray(a[k]) for a in (q, qd, qdd)) for k in range(256)]
        states = [tuple(s) for s in states]

        def pinocchio():
            for s in states:
                pin.computeJointTorqueRegressor(model, data, *s)

        peer = median_time(pinocchio, args.repeats) / len(states)
        per_without, per_with = without / args.batch, with_ / args.batch
        native = (plain.native_target("regressor") is not None, driven.native_target("regressor") is not None)
        out(f"| {name} ({n}) | {args.batch} | {per_without * 1e6:.3f} µs | {per_with * 1e6:.3f} µs "
              f"| {per_with / per_without:.2f}x | {native[0]}, {native[1]} | {peer * 1e6:.2f} µs "
            f"| {peer / per_with:.1f}x |")
    doc_tables.write(args.markdown, out, f"The regressor, float64, per state at batch {args.batch}, medians of "
                     f"{args.repeats} alternated runs; Pinocchio's `computeJointTorqueRegressor` per call from Python.")


if __name__ == "__main__":
    main()
