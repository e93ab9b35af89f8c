"""Every example runs, and its key numbers are checked against what it claims.

Each example's ``main(out_dir)`` returns its key numbers; the references are the truth it was simulated
from, statistics (chi-square), statics, a Lyapunov function and a textbook closed form.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
import scipy.stats
import sympy as sp

from helpers import load_example as load


@pytest.mark.slow
def test_identify_panda(tmp_path):
    example = load("identify_panda")
    out = example.main(tmp_path)
    assert out["n_base"] == 43
    assert out["mahalanobis"] < scipy.stats.chi2.ppf(0.999, 43)
    np.testing.assert_allclose(out["noise_estimate"], example.NOISE, rtol=0.15)
    assert out["wls_error"] < 0.1 and out["max_abs_z"] < 4.5
    assert np.max(out["rms_validation"]) < 0.05  # Nm, a fraction of the measurement noise
    assert out["physically_consistent"]
    assert out["consistent_error"] < 1.5 * out["wls_error"]  # as accurate as least squares
    assert np.max(out["rms_physical"]) < 0.1
    assert out["figure"].exists() and out["figure"].stat().st_size > 10_000


@pytest.mark.slow
def test_identify_real_arm(tmp_path):
    """UR5 with drives, 1 % torque noise, 1e-4 rad encoder: the thresholds the example is meant to meet."""
    out = load("identify_real_arm").main(tmp_path)
    assert out["cond_random"] >= 10 * out["cond_optimised"]
    for method in ("least squares", "weighted least squares", "physically consistent"):
        assert np.all(out["validation"][method] <= 1.5), (method, out["validation"][method])
        assert np.all(out["validation"][method] >= 0.9)  # the noise itself: nothing fits below it
    # without accelerations: the momentum balance within 2x of the torque model's validation error
    assert np.all(out["validation"]["momentum balance"] <= 2 * out["validation"]["least squares"])
    assert out["pseudo_inertia_pd"] and out["drives_nonnegative"]
    assert out["figure"].exists() and out["figure"].stat().st_size > 10_000


@pytest.mark.slow
def test_quadruped_drop(tmp_path):
    """64 pushed drops of the floating-base solo12 on compliant ground: every rollout comes to rest standing, its
    normal forces carrying the weight (sum of the URDF's masses times g) within 1e-4, quaternions unit-norm; the
    mechanical energy never rises after touchdown, and the rollout's step check stays silent."""
    import warnings

    import jaxskid

    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxskid.RolloutWarning)
        out = load("quadruped_drop").main(tmp_path, batch=64)
    assert out["settled"] == out["batch"] == 64 and out["load_error"] < 1e-4
    assert out["energy_rise"] <= 1e-8
    assert out["quaternion_error"] < 1e-12 and out["height_spread"] < 1e-3
    assert out["figure"].exists()


@pytest.mark.slow
def test_batched_rollouts(tmp_path):
    out = load("batched_rollouts").main(tmp_path, batch=1024)
    assert out["max_final_speed"] < 1e-3
    assert out["equilibrium_residual"] < 1e-3  # Nm: the arms came to rest where statics says
    assert out["max_abs_error"][0] < 1e-6  # the waist carries no gravity load
    assert np.all(out["mean_abs_error"][1:] > 5e-3)  # the others show the mass mismatch
    assert out["figure"].exists()


@pytest.mark.slow
def test_fit_through_simulation(tmp_path):
    out = load("fit_through_simulation").main(tmp_path)
    assert out["losses"][-1] < 0.05 * out["losses"][0]
    assert out["errors"][0] > 0.2 and out["errors"][-1] < 0.12  # the largest relative error of the factors
    assert out["figure"].exists()


def test_adaptive_2r(tmp_path):
    out = load("adaptive_2r").main(tmp_path)
    per_5s = out["error_per_5s"]
    assert per_5s[-1] < 1e-3 * per_5s[0]
    assert np.max(out["parameter_error"]) < 5e-3
    assert out["lyapunov_max_increase"] < 1e-9 * out["lyapunov_start"]
    assert out["figure"].exists()


def test_blog_3link(tmp_path):
    out = load("blog_3link").main(tmp_path)
    m3, l3, r, g, q2, q3 = sp.symbols("m3 l3 r g q2 q3", real=True)
    assert sp.simplify(out["M33"] - m3 * (4 * l3**2 + 3 * r**2) / 12) == 0  # solid cylinder about its end
    assert sp.simplify(out["Qgrav3"] + g * l3 * m3 * sp.cos(q2 + q3) / 2) == 0
    assert out["energy_drift"] < 1e-6
    assert out["figure"].exists()
    # the blog's own arm: the Euler-Lagrange and screw routes agree identically and numerically
    assert out["routes_identical"] is True
    assert out["routes_max_diff"] < 1e-12
    source = next(f for f in out["c_files"] if f.suffix == ".c")
    compiled = subprocess.run(["gcc", "-std=c99", "-Wall", "-Werror", "-pedantic", "-c", "-o", str(tmp_path / "blog.o"),
                               str(source)], capture_output=True, text=True)
    assert compiled.returncode == 0, compiled.stderr


@pytest.mark.slow
def test_learn_gains(tmp_path):
    """A policy closing over the traced gains and a module-level initial state: the gradient agrees with
    central differences and Adam lowers the tracking loss."""
    out = load("learn_gains").main(tmp_path, iterations=20)
    assert out["gradient_error"] < 1e-6
    assert out["losses"][-1] < 0.6 * out["losses"][0]
    assert np.all(out["kp"] > 0) and np.all(out["kd"] > 0) and out["file"].exists()
