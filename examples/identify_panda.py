"""Identify the Panda's base inertial parameters from noisy simulated torques.

    python examples/identify_panda.py [OUT_DIR]        # or JAXSKID_EXAMPLE_OUT=...; default examples/out/

1. The regressor Y(q, qd, qdd) (tau = Y pi, 10 parameters per link) is derived and lowered.
2. The base parameters (identifiable combinations) come from QR with column pivoting on random states.
3. The "measurements": torques along exciting sum-of-sines trajectories from the URDF's own inertias,
   with joint noise of different sizes.
4. Ordinary and weighted least squares estimate the base parameters; the physically consistent fit
   (:class:`jaxskid.PhysicallyConsistent`: least squares made consistent, then Levenberg-Marquardt on the
   log-Cholesky parameters) gives all 70 standard parameters, as accurate as least squares.
5. The estimates are checked against the truth and on a validation trajectory; a figure is saved.
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

LOCK = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0}
NOISE = np.array([0.3, 0.3, 0.2, 0.2, 0.1, 0.05, 0.05])  # Nm, per joint
BATCH = 500  # one batch size: every new size compiles the 490-output regressor again


def excitation(rng, t, n=7, harmonics=5, base_freq=0.2):
    """Sum-of-sines joint trajectories (Swevers et al. 1997) and their exact derivatives, (len(t), n) each."""
    w = 2 * np.pi * base_freq * np.arange(1, harmonics + 1)
    a = rng.normal(scale=0.5, size=(n, harmonics)) / np.arange(1, harmonics + 1)
    b = rng.normal(scale=0.5, size=(n, harmonics)) / np.arange(1, harmonics + 1)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = s @ a.T + c @ b.T
    qd = (c * w) @ a.T - (s * w) @ b.T
    qdd = -(s * w**2) @ a.T - (c * w**2) @ b.T
    return q, qd, qdd


def plot(figure: Path, t, tau_v, pred, z_scores) -> Path:
    """Measured against identified torques on the validation trajectory, and the estimates' z-scores."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for j, color in zip((1, 3, 5), ("C0", "C1", "C2")):
        axes[0].plot(t, tau_v[:, j], color=color, lw=2, alpha=0.4, label=f"joint {j + 1} true")
        axes[0].plot(t, pred[:, j], color=color, ls="--", label=f"joint {j + 1} identified")
    axes[0].set(xlabel="t [s]", ylabel="tau [Nm]", title="validation trajectory")
    axes[0].legend(fontsize=7, ncol=2)
    axes[1].bar(np.arange(len(z_scores)), z_scores)
    axes[1].axhline(3, color="k", lw=0.5)
    axes[1].axhline(-3, color="k", lw=0.5)
    axes[1].set(xlabel="base parameter", ylabel="(estimate - truth) / std",
                title=f"{len(z_scores)} base parameters, weighted least squares")
    return save_figure(fig, figure)


def main(out_dir=None, seed=0):
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    robot = jaxskid.load(erd_urdf("panda_description/urdf/panda.urdf"), lock=LOCK)
    dyn = jaxskid.lower(robot, ["regressor", "inverse_dynamics"])
    names = jaxskid.standard_parameter_names(robot)
    base = jaxskid.base_parameters(dyn, samples=BATCH, names=names)
    pi_true = jaxskid.standard_params(robot)
    truth = base.project(pi_true)

    # measurements: two exciting trajectories of 10 s at 50 Hz, torques + noise
    t = np.arange(BATCH) * 0.02
    q, qd, qdd = (np.concatenate(parts) for parts in zip(excitation(rng, t), excitation(rng, t)))
    tau = np.asarray(dyn.inverse_dynamics(q, qd, qdd))
    measured = tau + NOISE * rng.normal(size=tau.shape)
    y = np.concatenate([np.asarray(dyn.regressor(q[k:k + BATCH], qd[k:k + BATCH], qdd[k:k + BATCH]))
                        for k in range(0, len(q), BATCH)])
    yb = np.asarray(base.reduce(y))

    ols = jaxskid.identify(yb, measured, jaxskid.LeastSquares())
    wls = jaxskid.identify(yb, measured, jaxskid.WeightedLeastSquares())
    z_scores = (wls.params - truth) / np.sqrt(np.diag(wls.covariance))
    mahalanobis = float((wls.params - truth) @ np.linalg.solve(wls.covariance, wls.params - truth))

    # physically consistent fit of all 70 parameters: least squares made consistent, then Levenberg-Marquardt
    # on the log-Cholesky parameters, weighted by the joints' estimated noise
    fit = jaxskid.identify(y, measured, jaxskid.PhysicallyConsistent(sigma="estimate"))
    consistent = bool(jaxskid.physically_consistent(fit.params).all())
    consistent_error = float(np.linalg.norm(base.project(fit.params) - truth))
    unconstrained = np.linalg.lstsq(y.reshape(-1, 70), measured.reshape(-1), rcond=None)[0]
    consistent_ols = bool(jaxskid.physically_consistent(unconstrained).all())

    # validation on a fresh trajectory
    qv, qdv, qddv = excitation(np.random.default_rng(seed + 1), t)
    yv = np.asarray(dyn.regressor(qv, qdv, qddv))
    tau_v = np.asarray(dyn.inverse_dynamics(qv, qdv, qddv))
    pred = np.asarray(base.reduce(yv)) @ wls.params
    rms_validation = np.sqrt(np.mean((pred - tau_v) ** 2, axis=0))
    rms_physical = np.sqrt(np.mean((yv @ fit.params - tau_v) ** 2, axis=0))
    elapsed = time.perf_counter() - start

    figure = plot(output_dir(out_dir) / "identify_panda.png", t, tau_v, pred, z_scores)

    result = {
        "n_base": base.n_base,
        "max_abs_z": float(np.abs(z_scores).max()),
        "mahalanobis": mahalanobis,
        "noise_estimate": wls.residual_std,
        "ols_error": float(np.linalg.norm(ols.params - truth)),
        "wls_error": float(np.linalg.norm(wls.params - truth)),
        "rms_validation": rms_validation,
        "rms_physical": rms_physical,
        "physically_consistent": consistent,
        "consistent_error": consistent_error,
        "ols_standard_consistent": consistent_ols,
        "seconds": elapsed,
        "figure": figure,
    }
    print(f"Panda: {robot.n_dof} joints, {len(pi_true)} standard -> {base.n_base} base parameters")
    print(f"samples: {len(q)} states x 7 joints, noise {NOISE.tolist()} Nm")
    print(f"estimated noise (WLS): {np.round(wls.residual_std, 3).tolist()}")
    print(f"|error| OLS {result['ols_error']:.4f}, WLS {result['wls_error']:.4f}; max |z| {result['max_abs_z']:.2f}; "
          f"Mahalanobis {mahalanobis:.1f} (chi2 with {base.n_base} dof)")
    print(f"validation RMS torque error [Nm]: {np.round(rms_validation, 4).tolist()}")
    print(f"physically consistent fit: consistent {consistent} (unconstrained standard LS: {consistent_ols}), "
          f"|base error| {consistent_error:.4f}, validation RMS {np.round(rms_physical, 4).tolist()}")
    print(f"done in {elapsed:.1f} s; figure {figure}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
