"""From noisy measurements to a validated model: derivative estimates against analytic derivatives (error
bounds from the filter's frequency response and the noise level, or from least-squares theory), zero phase,
weighted against ordinary least squares, the physically consistent fit against least squares, and the
validation errors against a direct computation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

import jaxskid
from helpers import ROBOTS_DIR

F0, HARMONICS = 0.1, 10  # a sum of sines of period 10 s, up to 1 Hz
FS = 500.0
NOISE = 2e-4  # rad, white
STEP = 2 * np.pi / 2**14  # encoder resolution; its rounding error has std STEP / sqrt(12)


def sum_of_sines(t, seed=0, joints=3):
    """q, qd, qdd of a random sum of sines, each (len(t), joints), and the amplitudes (joints, harmonics)."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * F0 * np.arange(1, HARMONICS + 1)
    a, b = rng.normal(size=(2, joints, HARMONICS)) * 0.5 / np.arange(1, HARMONICS + 1)
    s, c = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = s @ a.T + c @ b.T
    return (q, (c * w) @ a.T - (s * w) @ b.T, -(s * w**2) @ a.T - (c * w**2) @ b.T), np.hypot(a, b), w


def measured(q, seed=1):
    rng = np.random.default_rng(seed)
    return jaxskid.quantize(q + NOISE * rng.normal(size=q.shape), STEP)


def rms(x, axis=0):
    return np.sqrt(np.mean(np.square(x), axis=axis))


# ------------------------------------------------------------------------------------------ derivatives
def test_butterworth_derivatives_within_the_filter_and_noise_prediction():
    """Error of q, qd, qdd (interior) against the prediction from the filter's response: the bias of gain
    ``|H|^(2(m+1)) sinc(w dt)^m`` on each harmonic (filtered forward and backward after each of m central
    differences) and the white noise ``sigma^2 + STEP^2 / 12`` passed through the same chain."""
    cutoff, order = 8.0, 4
    dt = 1 / FS
    t = np.arange(int(20 * FS)) * dt
    (q, qd, qdd), amp, w = sum_of_sines(t)
    est = jaxskid.estimate_derivatives(t, measured(q), cutoff=cutoff, order=order)
    sos = scipy.signal.butter(order, cutoff, fs=FS, output="sos")
    edge = int(2 * FS / cutoff)
    inner = slice(edge, -edge)
    grid = np.linspace(0, np.pi, 20001)  # digital frequency
    h2 = np.abs(scipy.signal.sosfreqz(sos, worN=grid)[1]) ** 2  # forward-backward gain
    _, h2_signal = scipy.signal.sosfreqz(sos, worN=w * dt)
    h2_signal = np.abs(h2_signal) ** 2
    sigma2 = NOISE**2 + STEP**2 / 12
    for m, (x, ref) in enumerate(zip(est, (q, qd, qdd))):
        gain = h2_signal ** (m + 1) * (np.sin(w * dt) / (w * dt)) ** m
        bias = np.sqrt(np.sum((amp * w**m * (1 - gain)) ** 2 / 2, axis=1))
        noise_gain = (h2 ** (m + 1) * (np.sin(grid) / dt) ** m) ** 2
        noise = np.sqrt(sigma2 * np.trapezoid(noise_gain, grid) / np.pi)
        predicted = np.sqrt(bias**2 + noise**2)
        err = rms(x[inner] - ref[inner])
        assert np.all(err < 1.5 * predicted) and np.all(err > 0.5 * predicted), (m, err, predicted)
        assert np.all(err < 0.02 * rms(ref)), (m, err / rms(ref))  # and a useful estimate
    assert np.all(rms(est[0][inner] - q[inner]) < 0.5 * np.sqrt(sigma2))  # the filter removed most of the noise


def test_fourier_derivatives_within_least_squares_theory():
    """With the true period and harmonics the fit is unbiased; its error has the covariance
    ``sigma^2 (A^T A)^-1`` of least squares, mapped through the derivative of the basis."""
    t = np.arange(int(20 * FS)) / FS
    (q, qd, qdd), _, w = sum_of_sines(t, seed=3)
    est = jaxskid.estimate_derivatives(t, measured(q, 4), method="fourier", period=1 / F0, harmonics=HARMONICS)
    c, s = np.cos(np.outer(t, w)), np.sin(np.outer(t, w))
    bases = (np.hstack([np.ones((t.size, 1)), c, s]), np.hstack([np.zeros((t.size, 1)), -s * w, c * w]),
             np.hstack([np.zeros((t.size, 1)), -c * w**2, -s * w**2]))
    cov = np.linalg.inv(bases[0].T @ bases[0]) * (NOISE**2 + STEP**2 / 12)
    for x, ref, basis in zip(est, (q, qd, qdd), bases):
        predicted = np.sqrt(np.mean(np.einsum("tk,kl,tl->t", basis, cov, basis)))
        err = rms(x - ref)
        assert np.all(err < 2.0 * predicted) and np.all(err > 0.3 * predicted), (err, predicted)
    # the cutoff picks the same harmonics: those below it
    again = jaxskid.estimate_derivatives(t, measured(q, 4), method="fourier", period=1 / F0, cutoff=1.05)
    np.testing.assert_allclose(again[2], est[2], rtol=1e-10, atol=1e-12)


def test_forward_backward_filtering_has_no_lag():
    """A 0.5 Hz sine through the estimator keeps its phase (to 1e-3 rad); the same filter run forward only
    delays it by its group delay (the measure sees a lag when there is one)."""
    t = np.arange(int(20 * FS)) / FS
    f = 0.5
    q = np.sin(2 * np.pi * f * t + 0.3)
    noisy = measured(q[:, None], 5)[:, 0]
    inner = slice(500, -500)

    def phase(x):
        basis = np.stack([np.sin(2 * np.pi * f * t[inner]), np.cos(2 * np.pi * f * t[inner])], 1)
        a, b = np.linalg.lstsq(basis, x[inner], rcond=None)[0]
        return np.arctan2(b, a)

    qf, qd, qdd = jaxskid.estimate_derivatives(t, noisy, cutoff=5.0)
    assert abs(phase(qf) - 0.3) < 1e-3
    assert abs(phase(qd) - (0.3 + np.pi / 2)) < 1e-3
    assert abs(phase(-qdd) - 0.3) < 1e-3
    causal = scipy.signal.sosfilt(scipy.signal.butter(4, 5.0, fs=FS, output="sos"), noisy)
    assert phase(causal) < 0.3 - 0.05  # a forward filter lags
    lags = np.arange(-20, 21)
    corr = [np.dot(qf[inner], np.roll(q, k)[inner]) for k in lags]
    assert lags[int(np.argmax(corr))] == 0


def test_quantize_and_signal_errors():
    q = np.linspace(-1, 1, 101)
    out = jaxskid.quantize(q, 0.01)
    assert np.all(np.abs(out - q) <= 0.005 + 1e-12)
    np.testing.assert_allclose(out / 0.01, np.round(out / 0.01), atol=1e-9)
    t = np.arange(200) / 100.0
    x = np.sin(t)
    with pytest.raises(jaxskid.IdentificationError, match="NaN.*sample 7"):
        jaxskid.estimate_derivatives(t, np.where(np.arange(200) == 7, np.nan, x), cutoff=5)
    with pytest.raises(jaxskid.IdentificationError, match="uniformly sampled"):
        jaxskid.estimate_derivatives(t ** 1.1, x, cutoff=5)
    with pytest.raises(jaxskid.IdentificationError, match="more than .* samples"):
        jaxskid.estimate_derivatives(t[:12], x[:12], cutoff=5)
    with pytest.raises(jaxskid.RequestError, match="Nyquist frequency 50 Hz"):
        jaxskid.estimate_derivatives(t, x, cutoff=60)
    with pytest.raises(jaxskid.RequestError, match="cutoff="):
        jaxskid.estimate_derivatives(t, x)
    with pytest.raises(jaxskid.RequestError, match="period="):
        jaxskid.estimate_derivatives(t, x, method="fourier", harmonics=3)
    with pytest.raises(jaxskid.RequestError, match="unknown method"):
        jaxskid.estimate_derivatives(t, x, method="spline", cutoff=5)
    with pytest.raises(jaxskid.ShapeError, match="same N"):
        jaxskid.estimate_derivatives(t, x[:-1], cutoff=5)
    with pytest.raises(jaxskid.RequestError, match="step must be positive"):
        jaxskid.quantize(q, 0.0)


def test_parallel_filter_keeps_tau_equal_y_pi():
    """Filtering y and tau alike keeps tau = y pi exactly (the filter is linear), and removes a torque ripple
    above the cutoff."""
    rng = np.random.default_rng(6)
    t = np.arange(4000) / 1000.0
    y = np.cumsum(rng.normal(size=(4000, 2, 3)), axis=0) * 1e-2
    pi = np.array([0.5, -1.0, 2.0])
    ripple = 0.3 * np.sin(2 * np.pi * 60 * t)[:, None]
    t2, yf, tf = jaxskid.parallel_filter(t, y, y @ pi + ripple, cutoff=5.0, decimate=10)
    assert t2.shape == (400,) and yf.shape == (400, 2, 3) and tf.shape == (400, 2)
    inner = slice(50, -50)
    assert rms((tf - yf @ pi)[inner]).max() < 1e-3 * 0.3
    with pytest.raises(jaxskid.RequestError, match="Nyquist"):
        jaxskid.parallel_filter(t, y, y @ pi, cutoff=60.0, decimate=10)  # above 1000 / 20 Hz


# ------------------------------------------------------------------------------------------ identification
@pytest.fixture(scope="module")
def arm():
    """The 3-DOF arm with drives (one with no Coulomb friction and no rotor), its regressor and true values."""
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml", drives=True)
    params = robot.default_params()
    for joint, (ia, fv, fc, fo) in {"waist": (0.05, 0.2, 0.3, 0.1), "shoulder": (0.08, 0.3, 0.2, -0.1),
                                    "elbow": (0.0, 0.1, 0.0, 0.05)}.items():
        params.update({f"{joint}_Ia": ia, f"{joint}_fv": fv, f"{joint}_fc": fc, f"{joint}_fo": fo})
    dyn = jaxskid.lower(robot, ["regressor", "inverse_dynamics"])
    base = jaxskid.base_parameters(dyn, params)
    rng = np.random.default_rng(7)
    q, qd, qdd = rng.uniform(-2, 2, size=(3, 300, 3))
    y = np.asarray(dyn.regressor(q, qd, qdd, params))
    pi = jaxskid.standard_params(robot, params)
    return robot, dyn, params, base, (q, qd, qdd), y, pi


def _pseudo_inertia(body):
    """J = [[tr(I)/2 1 - I, m c], [m c^T, m]] from (m, mc, Ixx, Ixy, Iyy, Ixz, Iyz, Izz) about the body origin."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = body
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    j = np.zeros((4, 4))
    j[:3, :3] = np.trace(inertia) / 2 * np.eye(3) - inertia
    j[:3, 3] = j[3, :3] = (hx, hy, hz)
    j[3, 3] = m
    return j


def test_nearest_consistent_clips_the_pseudo_inertia_eigenvalues():
    """Per body the projection keeps J's eigenvectors and raises its eigenvalues to at least margin times the
    largest (the nearest positive semidefinite matrix in the Frobenius norm, Higham 1988); drives' Ia, fv, fc to 0."""
    rng = np.random.default_rng(9)
    pi = np.concatenate([rng.normal(size=20), [-0.1, 0.2, -0.3, -0.4]])  # 2 bodies, one drive
    out = jaxskid.nearest_consistent(pi, drives=1, margin=1e-6)
    for k in range(2):
        lam, vec = np.linalg.eigh(_pseudo_inertia(pi[10 * k:10 * k + 10]))
        expected = np.maximum(lam, 1e-6 * lam[-1])
        np.testing.assert_allclose(np.linalg.eigvalsh(_pseudo_inertia(out[10 * k:10 * k + 10])), expected, atol=1e-12)
        np.testing.assert_allclose(_pseudo_inertia(out[10 * k:10 * k + 10]), (vec * expected) @ vec.T, atol=1e-12)
    np.testing.assert_allclose(out[20:], [0.0, 0.2, 0.0, -0.4])
    assert jaxskid.physically_consistent(out, drives=1).all() and not jaxskid.physically_consistent(pi, drives=1).all()


def test_weighted_least_squares_beats_ordinary_on_unequal_noise(arm):
    """Squared errors in units of each base parameter's ordinary least-squares variance (the sandwich
    ``G^-1 Y^T S Y G^-1``, ``G = Y^T Y``, ``S`` the joints' noise variances): their sum has expectation
    ``n_base`` for ordinary least squares; weighting by the joints' noise lowers every variance."""
    _, _, _, base, _, y, pi = arm
    yb, truth = np.asarray(base.reduce(y)), base.project(pi)
    tau = y @ pi
    sigma = np.array([0.5, 0.02, 0.004])
    a = yb.reshape(-1, base.n_base)
    g = np.linalg.inv(a.T @ a)
    var_ols = np.diag(g @ (a.T * np.tile(sigma**2, len(yb))) @ a @ g)
    errors = {"ols": [], "wls": [], "known": []}
    ratio = []
    for seed in range(6):
        noisy = tau + sigma * np.random.default_rng(100 + seed).normal(size=tau.shape)
        for key, method in (("ols", jaxskid.LeastSquares()), ("wls", jaxskid.WeightedLeastSquares()),
                            ("known", jaxskid.WeightedLeastSquares(sigma))):
            est = jaxskid.identify(yb, noisy, method)
            errors[key].append(np.sum((est.params - truth) ** 2 / var_ols))
            if key == "known":
                ratio.append(est.residual_std**2 / sigma**2)
    ols, wls, known = (np.mean(errors[k]) for k in ("ols", "wls", "known"))
    assert 0.5 * base.n_base < ols < 1.6 * base.n_base  # the reference scale is right
    assert wls < 0.6 * ols and known < 0.6 * ols  # expected 0.2 here (sum of var_wls / var_ols: 5)
    assert wls < 1.5 * known  # estimating the noise costs little
    # the residual variance, corrected by each joint's leverage, is unbiased for the known weights
    # (mean of 6 x 300 squared residuals per joint: standard error about 3.3 %)
    np.testing.assert_allclose(np.mean(ratio, axis=0), 1.0, atol=0.1)


@pytest.mark.slow
def test_physically_consistent_fit_reaches_least_squares(arm):
    """Consistent noisy data: the fit's base parameters are as accurate as least squares, every pseudo-inertia
    is positive definite (eigenvalues) and Ia, fv, fc >= 0; where least squares puts the elbow's Coulomb
    friction (truly 0, a base parameter of its own) below zero, the fit holds it at 0."""
    robot, _, _, base, _, y, pi = arm
    drives = len(robot.driven)
    yb, truth = np.asarray(base.reduce(y)), base.project(pi)
    tau = y @ pi
    elbow_fc = jaxskid.standard_parameter_names(robot).index("elbow_fc")
    column = list(base.independent).index(elbow_fc)
    ls_err, pc_err, clipped = [], [], 0
    for seed in range(3):
        noisy = tau + 0.02 * np.random.default_rng(200 + seed).normal(size=tau.shape)
        ls = jaxskid.identify(yb, noisy, jaxskid.LeastSquares())
        est = jaxskid.identify(y, noisy, jaxskid.PhysicallyConsistent(drives=drives))
        ls_err.append(np.linalg.norm(ls.params - truth))
        pc_err.append(np.linalg.norm(base.project(est.params) - truth))
        bodies, rest = est.params[:30].reshape(3, 10), est.params[30:].reshape(3, 4)
        assert all(np.linalg.eigvalsh(_pseudo_inertia(b))[0] > 0 for b in bodies)
        assert np.all(rest[:, :3] >= 0)  # Ia, fv, fc
        if ls.params[column] < 0:
            assert est.params[elbow_fc] == 0
            clipped += 1
        assert est.history[-1] <= est.history[0]
    assert np.mean(pc_err) < 1.5 * np.mean(ls_err)
    assert clipped > 0  # the bound was tested


def test_gradient_fit_from_least_squares_stays_physical(arm):
    robot, _, _, base, _, y, pi = arm
    drives = len(robot.driven)
    tau = y @ pi + 0.02 * np.random.default_rng(300).normal(size=(y.shape[0], 3))
    ls = jaxskid.identify(np.asarray(base.reduce(y)), tau)
    est = jaxskid.identify(y, tau, jaxskid.GradientFit("lstsq", jaxskid.LogCholesky(drives), jaxskid.Adam(1e-3),
                                                      steps=1000))
    assert jaxskid.physically_consistent(est.params, drives=drives).all()
    assert np.all(est.params[30:].reshape(3, 4)[:, :3] >= 0)
    truth = base.project(pi)
    assert np.linalg.norm(base.project(est.params) - truth) < 2.0 * np.linalg.norm(ls.params - truth)
    with pytest.raises(jaxskid.RequestError, match="lstsq"):
        jaxskid.identify(y, tau, jaxskid.GradientFit("least squares"))


def test_validate_against_a_direct_computation(arm, tmp_path):
    robot, dyn, params, base, _, _, pi = arm
    rng = np.random.default_rng(8)
    q, qd, qdd = rng.uniform(-2, 2, size=(3, 300, 3))
    tau = np.asarray(dyn.inverse_dynamics(q, qd, qdd, params)) + 0.05 * rng.normal(size=(300, 3))
    wrong = dict(params, m3=1.2 * params["m3"])  # a model with the forearm's mass off
    direct = np.asarray(dyn.inverse_dynamics(q, qd, qdd, wrong))  # the route without the regressor
    expected = np.sqrt(np.mean((direct - tau) ** 2, axis=0))
    pi_wrong = jaxskid.standard_params(robot, wrong)
    y = np.asarray(dyn.regressor(q, qd, qdd, params))
    for result in (jaxskid.validate(dyn, pi_wrong, q, qd, qdd, tau),
                   jaxskid.validate(dyn, wrong, q, qd, qdd, tau),
                   jaxskid.validate(y, base.project(pi_wrong), tau, base=base)):
        np.testing.assert_allclose(result.rms, expected, rtol=1e-9)
        np.testing.assert_allclose(result.relative, expected / np.sqrt(np.mean(tau**2, axis=0)), rtol=1e-9)
    good = jaxskid.validate(dyn, pi, q, qd, qdd, tau)
    np.testing.assert_allclose(good.rms, 0.05, rtol=0.2)  # the noise alone
    path = jaxskid.plot_validation(good, tmp_path / "validation.png", t=np.arange(300) * 0.01,
                                   names=["waist", "shoulder", "elbow"])
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000
    with pytest.raises(jaxskid.ShapeError, match="expected 42 standard parameters"):
        jaxskid.validate(dyn, pi[:-1], q, qd, qdd, tau)
    with pytest.raises(jaxskid.RequestError, match=r"validate\(y, params, tau\)"):
        jaxskid.validate(y, pi, q, tau)
