"""Identify a UR5 with joint friction and rotor inertia from encoder positions and noisy torques.

    python examples/identify_real_arm.py [OUT_DIR]     # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

The robot is example-robot-data's UR5 with a drive on every joint (``jaxskid.load(path, drives=True)``):
rotor inertia reflected at the joint (armature), viscous and Coulomb friction and a torque offset, with
values that differ from the URDF's (which has none). The script goes through what a real identification does:

1. **Excitation.** A periodic Fourier-series trajectory (5 harmonics, 10 s) within the URDF's position and
   velocity limits and an acceleration bound, optimised with ``jax.grad`` from 8 random starts at once for the
   condition number of the base regressor stacked at 10 times (60 equations for 58 base parameters)
   (:func:`jaxskid.design_excitation`), against the random starts' (random Fourier trajectories of the same
   harmonics within the same limits).
2. **Measurements.** Three periods of the trajectory at 200 Hz: encoder positions quantised to 1e-4 rad, and
   joint torques (inverse dynamics with the drives) with 1 % noise (of each joint's RMS torque).
3. **Filtering.** Velocities and accelerations from the quantised positions: forward-backward Butterworth
   filtering and central differences (:func:`jaxskid.estimate_derivatives`).
4. **Identification** of the base parameters (inertial and drive parameters together) by ordinary and weighted
   least squares, of all standard parameters by the physically consistent fit (every body's pseudo-inertia
   positive definite, armature and friction non-negative), and, without accelerations, from the balances
   over windows of 0.1 s. The momentum balance (:func:`jaxskid.momentum_balance`: the equations of motion
   integrated over each window, six equations per window, from positions and filtered velocities only)
   validates as well as the torque model. The energy balance (:func:`jaxskid.energy_balance`) gives one
   equation per window, and its stacked regressor here is conditioned about 1e6 against the torque model's
   1e2: the torque noise integrated into the work, amplified by it, leaves its validation error 1e2-1e3 times
   the noise.
5. **Validation** on another trajectory (another optimised excitation): predicted against measured torque,
   RMS error per joint against the noise's RMS; figures in the output directory.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxskid  # noqa: E402
from _common import erd_urdf, output_dir, save_figure  # noqa: E402  (examples/_common.py, beside this script)

DRIVES = {  # per joint: armature [kg m^2], viscous [N m s], Coulomb [N m], offset [N m]
    "Ia": [0.40, 0.40, 0.25, 0.05, 0.05, 0.04],
    "fv": [3.0, 3.0, 2.0, 0.6, 0.6, 0.5],
    "fc": [4.0, 4.0, 3.0, 1.0, 1.0, 0.8],
    "fo": [0.3, -0.2, 0.2, 0.05, -0.05, 0.02],
}
QUANTITIES = ["regressor", "kinetic_energy_regressor", "potential_energy_regressor", "friction_power_regressor",
              "momentum_regressor"]
PERIOD, HARMONICS, SAMPLES = 10.0, 5, 10  # excitation: period [s], harmonics, samples in the design's W
RATE, PERIODS = 200.0, 3  # measurement: Hz, periods recorded
ENCODER, NOISE = 1e-4, 0.01  # rad per count; torque noise, fraction of each joint's RMS torque
CUTOFF = 4.0  # Hz, Butterworth cutoff: 8 times the highest harmonic (0.5 Hz)
ACCELERATION = 4.0  # rad/s^2, the excitation's acceleration bound


def true_params(robot: jaxskid.Robot) -> dict:
    """The robot's parameters: the URDF's inertias and the drives of ``DRIVES`` (the URDF has none)."""
    params = dict(robot.default_params())
    for k, joint in enumerate(robot.joint_names):
        for key, values in DRIVES.items():
            params[f"{joint}_{key}"] = values[k]
    return params


def measure(dyn, traj, pi, rng, periods: int = PERIODS):
    """What the sensors give along ``traj``: time, quantised positions, noisy torques; and the true torques."""
    t = np.arange(int(round(periods * PERIOD * RATE))) / RATE
    q, qd, qdd = (np.asarray(x) for x in traj.evaluate(t))
    tau = np.einsum("snp,p->sn", np.asarray(dyn.regressor(q, qd, qdd)), pi)
    sigma = NOISE * np.sqrt(np.mean(tau**2, axis=0))
    measured = tau + sigma * rng.normal(size=tau.shape)
    return t, jaxskid.quantize(q, ENCODER), measured, tau, sigma


def filtered_regressor(dyn, t, q_measured):
    """The regressor at the filtered states, and those states (first and last half second cut: filter start-up)."""
    q, qd, qdd = jaxskid.estimate_derivatives(t, q_measured, method="butterworth", cutoff=CUTOFF)
    keep = slice(int(0.5 * RATE), -int(0.5 * RATE))
    return np.asarray(dyn.regressor(q[keep], qd[keep], qdd[keep])), keep, (q, qd)


def identify_all(dyn, robot, t, q_measured, tau_measured, base):
    """The estimates of every method, as standard-parameter predictors ``y -> tau``."""
    y, keep, (q, qd) = filtered_regressor(dyn, t, q_measured)
    tau = tau_measured[keep]
    yb = base.reduce(y)
    names = jaxskid.standard_parameter_names(robot)
    ols = jaxskid.identify(yb, tau, jaxskid.LeastSquares(), names=names)
    wls = jaxskid.identify(yb, tau, jaxskid.WeightedLeastSquares(), names=names)
    consistent = jaxskid.identify(y, tau, jaxskid.PhysicallyConsistent(drives=robot.n_dof, sigma="estimate"))
    window = int(0.1 * RATE)
    balance = jaxskid.energy_balance(dyn, t[keep], q[keep], qd[keep], tau, window=window)
    energy = jaxskid.identify(base.reduce(balance.y), balance.work, jaxskid.LeastSquares())
    impulses = jaxskid.momentum_balance(dyn, t[keep], q[keep], qd[keep], tau, window=window)
    momentum = jaxskid.identify(base.reduce(impulses.y), impulses.work, jaxskid.LeastSquares())
    return {
        "least squares": lambda yv: base.reduce(yv) @ ols.params,
        "weighted least squares": lambda yv: base.reduce(yv) @ wls.params,
        "physically consistent": lambda yv: yv @ consistent.params,
        "energy balance": lambda yv: base.reduce(yv) @ energy.params,
        "momentum balance": lambda yv: base.reduce(yv) @ momentum.params,
    }, consistent.params, len(tau), len(balance.work)


def plot(path: Path, result, design, t, tau, predicted, names) -> Path:
    """Left: the excitation's condition number per optimiser step (every start); right: measured against
    predicted torque on the validation trajectory, per joint."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13, 6.5))
    grid = fig.add_gridspec(3, 3)
    ax = fig.add_subplot(grid[:, 0])
    ax.semilogy(design.history.T, lw=0.8, alpha=0.7)
    ax.set(xlabel="optimiser step", ylabel="cond(W) of the base regressor",
           title=f"excitation: {design.initial_median:.0f} (random, median) -> {design.value:.0f}")
    for j in range(tau.shape[1]):
        a = fig.add_subplot(grid[j % 3, 1 + j // 3])
        a.plot(t, tau[:, j], color="0.6", lw=1.5, label="measured")
        a.plot(t, predicted[:, j], color="C3", lw=0.8, label="identified (WLS)")
        a.set_title(f"{names[j].removesuffix('_joint')} [N m]", fontsize=8)
        a.tick_params(labelsize=7)
        if j % 3 == 2:
            a.set_xlabel("t [s]")
        if j == 0:
            a.legend(fontsize=7)
    fig.suptitle(f"UR5 with drives: validation RMS / noise RMS per joint {np.round(result, 2).tolist()}")
    return save_figure(fig, path)


def main(out_dir=None, seed=0, steps=150) -> dict:
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    robot = jaxskid.load(erd_urdf("ur_description/urdf/ur5_robot.urdf"), drives=True)
    dyn = jaxskid.lower(robot, QUANTITIES)
    params = true_params(robot)
    pi = np.asarray(jaxskid.standard_params(robot, params))
    base = jaxskid.base_parameters(dyn, names=jaxskid.standard_parameter_names(robot))
    limits = {"acceleration": ACCELERATION}
    design = jaxskid.design_excitation(dyn, HARMONICS, PERIOD, SAMPLES, robot=robot, limits=limits, starts=8,
                                       steps=steps, seed=seed, base=base)
    # the validation trajectory: another seed, the same shapes, so XLA's cache holds the compiled optimiser
    check = jaxskid.design_excitation(dyn, HARMONICS, PERIOD, SAMPLES, robot=robot, limits=limits, starts=8,
                                      steps=steps, seed=seed + 1, base=base)

    t, q_m, tau_m, _, _ = measure(dyn, design.trajectory, pi, rng)
    predictors, consistent, rows, windows = identify_all(dyn, robot, t, q_m, tau_m, base)

    tv, qv_m, tauv_m, _, sigma_v = measure(dyn, check.trajectory, pi, rng, periods=1)
    yv, keep, _ = filtered_regressor(dyn, tv, qv_m)
    ratio = {name: np.sqrt(np.mean((f(yv) - tauv_m[keep]) ** 2, axis=0)) / sigma_v for name, f in predictors.items()}
    pseudo_pd = bool(jaxskid.physically_consistent(consistent, drives=robot.n_dof).all())
    drives_ok = bool((consistent[-4 * robot.n_dof:].reshape(-1, 4)[:, :3] >= 0).all())
    elapsed = time.perf_counter() - start
    figure = plot(output_dir(out_dir) / "identify_real_arm.png", ratio["weighted least squares"], design,
                  tv[keep], tauv_m[keep], predictors["weighted least squares"](yv), robot.joint_names)

    print(f"UR5 with drives: {robot.n_dof} joints, {len(pi)} standard -> {base.n_base} base parameters")
    print(f"excitation: cond(W) {design.initial_median:.0f} (random Fourier, median of 8), "
          f"{design.initial_best:.0f} (best random) -> {design.value:.1f} (optimised), "
          f"{design.initial_median / design.value:.0f}x smaller")
    print(f"measurements: {len(t)} samples at {RATE:.0f} Hz, encoder {ENCODER} rad, torque noise "
          f"{NOISE:.0%} of RMS; {rows} filtered samples, {windows} balance windows")
    for name, r in ratio.items():
        print(f"validation RMS error / noise RMS, {name:>22}: {np.round(r, 2).tolist()}")
    print(f"physically consistent fit: pseudo-inertias positive definite {pseudo_pd}, "
          f"armature and friction >= 0 {drives_ok}")
    print(f"done in {elapsed:.1f} s; figure {figure}")
    return {
        "cond_random": design.initial_median, "cond_optimised": design.value, "validation": ratio,
        "pseudo_inertia_pd": pseudo_pd, "drives_nonnegative": drives_ok, "seconds": elapsed, "figure": figure,
    }


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
