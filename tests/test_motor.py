"""DC motors driving rollouts (jaxskid.DCMotors) against closed forms, central differences and the forward
dynamics.

One revolute joint about the vertical axis (no gravity torque), a point mass and an armature (inertia J) and
viscous friction b, driven through a gear of ratio r by a motor: with x = (q, qd, i),

    J qdd + b qd = r k_t i,    L di/dt + R i + k_e r qd = V,

is linear, dx/dt = A x + B V, and the exact solution over a step of held voltage is given by the matrix
exponential (scipy.linalg.expm of the augmented system). The quasi-static motor (L = None) makes qd a
first-order lag with the closed form qd(t) = qd_inf (1 - exp(-t / tau_m)).
"""

from __future__ import annotations

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

import jaxskid
from helpers import ROBOTS_DIR, rel_err
from jaxskid import Drive, Joint, Robot, pose, screw, spatial_inertia
from jaxskid._errors import RequestError, ShapeError

MASS, ARM, IA, B = 2.0, 0.3, 0.02, 0.05          # kg, m, kg m^2, N m s
J = MASS * ARM**2 + IA                            # the joint's inertia: point mass + armature
MOTOR = dict(R=1.2, L=0.01, k_t=0.05, k_e=0.05, ratio=10.0)   # ohm, H, N m/A, V s/rad; L/R = 8.3 ms


def _robot() -> Robot:
    joint = Joint("hinge", "revolute", -1, pose(), screw("revolute", (0, 0, 1)),
                  spatial_inertia(MASS, (ARM, 0, 0)), "arm", Drive(armature=IA, viscous=B))
    return Robot.create("motor_hinge", [joint], (0, 0, -9.81), [], [], {})


@pytest.fixture(scope="module")
def dyn():
    return jaxskid.lower(_robot(), ["mass_matrix", "inverse_dynamics"])


def _system(R, L, k_t, k_e, ratio):
    """(A, B) of dx/dt = A x + B V for x = (q, qd, i)."""
    a = np.array([[0.0, 1.0, 0.0], [0.0, -B / J, ratio * k_t / J], [0.0, -k_e * ratio / L, -R / L]])
    return a, np.array([0.0, 0.0, 1.0 / L])


def _exact(voltages, dt, x0=(0.0, 0.0, 0.0), motor=MOTOR):
    """The exact states at t_k = k dt, the voltage ``voltages[k]`` held over each step: (steps + 1, 3)."""
    a, b = _system(**motor)
    out = [np.asarray(x0, float)]
    for v in voltages:
        aug = np.zeros((4, 4))
        aug[:3, :3], aug[:3, 3] = a, b * v
        out.append((scipy.linalg.expm(aug * dt) @ np.append(out[-1], 1.0))[:3])
    return np.array(out)


def _states(motors, traj):
    """(q, qd, i) at the saved states of a rollout of the 1-joint robot."""
    return np.concatenate([np.asarray(traj.x), np.asarray(motors.currents(traj))], axis=-1)


# ------------------------------------------------------------------------------------- step responses
@pytest.mark.parametrize("form", ["array", "function"])
def test_voltage_step_matches_the_matrix_exponential(dyn, form):
    """A 6 V step from rest: q, qd and the current against expm; the applied torque is r k_t i."""
    motors, dt, steps, volts = jaxskid.DCMotors(**MOTOR), 1e-3, 400, 6.0
    controls = motors.drive(np.full((steps, 1), volts) if form == "array" else (lambda t, x: jnp.full((1,), volts)))
    traj = jaxskid.rollout(dyn, np.zeros(2), controls, dt, steps)
    got, ref = _states(motors, traj), _exact([volts] * steps, dt)
    assert got.shape == (steps + 1, 3)
    for k in range(3):
        assert np.abs(got[:, k] - ref[:, k]).max() <= 1e-5 * np.abs(ref[:, k]).max(), k
    i = got[:-1, 2]
    np.testing.assert_allclose(np.asarray(traj.tau)[:, 0], MOTOR["ratio"] * MOTOR["k_t"] * i, rtol=1e-12, atol=1e-14)
    w_inf = MOTOR["ratio"] * MOTOR["k_t"] * volts / (MOTOR["R"] * B + MOTOR["ratio"] ** 2 * MOTOR["k_t"] * MOTOR["k_e"])
    assert 0.3 * w_inf < ref[-1, 1] < w_inf  # the reference itself: on its way to the steady speed


@pytest.mark.slow
def test_held_voltages_every_stage_sees_its_step(dyn):
    """Voltages that jump every 4 ms, held over each step (every RK4 stage of step k sees V[k]): against the
    piecewise exact solution, for a batch of two sequences and initial states, with the error of order 4
    measured from dt = 2 ms to 1 ms (a stage seeing the next step's voltage would make it order 1)."""
    motors, hold, intervals = jaxskid.DCMotors(**MOTOR), 4e-3, 40
    volts = np.random.default_rng(7).uniform(-12.0, 12.0, (2, intervals))
    x0 = np.array([[0.0, 0.0], [0.3, -1.0]])
    errors = []
    for per in (2, 4):
        v = volts.repeat(per, axis=1)
        traj = jaxskid.rollout(dyn, x0, motors.drive(v[..., None]), hold / per, intervals * per)
        got = _states(motors, traj)
        assert got.shape == (2, intervals * per + 1, 3)
        errs = [rel_err(got[b], _exact(v[b], hold / per, (*x0[b], 0.0))) for b in range(2)]
        assert max(errs) <= 3e-5, errs
        errors.append(errs[0])
    assert np.log2(errors[0] / errors[1]) > 3.5, errors


def test_quasi_static_motor_is_a_first_order_lag(dyn):
    """L = None: qd(t) = qd_inf (1 - exp(-t/tau_m)), q its integral, i = (V - k_e r qd) / R."""
    m = {**MOTOR, "L": None}
    motors, dt, steps, volts = jaxskid.DCMotors(**m), 4e-3, 1000, 8.0
    r, kt, ke, res = m["ratio"], m["k_t"], m["k_e"], m["R"]
    damping = B + r * r * kt * ke / res
    tau_m, w_inf = J / damping, r * kt * volts / (res * damping)
    traj = jaxskid.rollout(dyn, np.zeros(2), motors.drive(np.full((steps, 1), volts)), dt, steps)
    t = np.asarray(traj.t)
    qd_ref = w_inf * (1.0 - np.exp(-t / tau_m))
    q_ref = w_inf * (t - tau_m * (1.0 - np.exp(-t / tau_m)))
    assert traj.z == () and t[-1] > 5 * tau_m
    assert rel_err(np.asarray(traj.qd)[:, 0], qd_ref) <= 1e-9
    assert rel_err(np.asarray(traj.q)[:, 0], q_ref) <= 1e-9
    i = np.asarray(motors.currents(traj))[:, 0]
    assert i.shape == (steps,) and rel_err(i, (volts - ke * r * qd_ref[:-1]) / res) <= 1e-9


@pytest.mark.slow
def test_adaptive_diffrax_solve_matches_the_matrix_exponential(dyn):
    """A diffrax solver with adaptive steps stops at the voltage jumps: the exact piecewise solution."""
    motors, dt, steps = jaxskid.DCMotors(**MOTOR), 0.02, 10
    volts = np.array([6.0, 6.0, -3.0, -3.0, 10.0, 0.0, 0.0, 4.0, 4.0, 4.0])
    traj = jaxskid.rollout(dyn, np.zeros(2), motors.drive(volts[:, None]), dt, steps, diffrax.Tsit5(),
                           stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-12))
    assert rel_err(_states(motors, traj), _exact(volts, dt)) <= 1e-7


# -------------------------------------------------------------------------------------------- gradients
def test_gradient_with_respect_to_motor_parameters(dyn):
    """d/d(R, k_t, L) of a rollout's end state and current against central differences."""
    volts, dt, steps = np.full((200, 1), 6.0), 1e-3, 200

    def loss(params):
        motors = jaxskid.DCMotors(params[0], params[2], params[1], MOTOR["k_e"], MOTOR["ratio"])
        traj = jaxskid.rollout(dyn, jnp.zeros(2), motors.drive(volts), dt, steps)
        return traj.x[-1, 0] + traj.x[-1, 1] + 0.1 * motors.currents(traj)[-1, 0]

    p0 = jnp.array([MOTOR["R"], MOTOR["k_t"], MOTOR["L"]])
    grad = np.asarray(jax.jit(jax.grad(loss))(p0))
    value = jax.jit(loss)
    for k, h in enumerate((1e-5, 1e-6, 1e-6)):
        e = np.eye(3)[k] * h
        fd = (value(p0 + e) - value(p0 - e)) / (2 * h)
        assert abs(grad[k] - fd) <= 1e-6 * abs(fd), (k, grad[k], fd)
    assert np.all(grad[:2] != 0)


# ------------------------------------------------------------------------------- joints without motors
def test_a_joint_without_motor_takes_its_input_as_a_torque():
    """2R arm, motor on the elbow only: the vector field's accelerations are the forward dynamics of
    (u_0, r k_t i), and the current's derivative is (V - R i - k_e r qd_1) / L."""
    dyn2 = jaxskid.lower(jaxskid.load(ROBOTS_DIR / "arm_2r.yaml"), ["mass_matrix", "inverse_dynamics"])
    motors = jaxskid.DCMotors(**MOTOR, joints=[1])
    u = np.array([[0.7, 5.0]])
    field = jaxskid.vector_field(dyn2, motors.drive(u), dt=0.01)
    x, i = np.array([0.2, -0.4, 0.5, 1.5]), np.array([0.8])
    dx, di = jax.jit(field)(0.0, (x, i), None)
    r, kt = MOTOR["ratio"], MOTOR["k_t"]
    tau = np.array([0.7, r * kt * i[0]])
    assert rel_err(dx[2:], jaxskid.forward_dynamics(dyn2, x[:2], x[2:], tau)) <= 1e-12
    assert rel_err(dx[:2], x[2:]) == 0.0
    di_ref = (5.0 - MOTOR["R"] * i[0] - MOTOR["k_e"] * r * x[3]) / MOTOR["L"]
    assert abs(di[0] - di_ref) <= 1e-12 * abs(di_ref)


# ------------------------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("kwargs, error, words", [
    ({**MOTOR, "R": 0.0}, RequestError, "R: expected values > 0"),
    ({**MOTOR, "L": -1.0}, RequestError, "L=None"),
    ({**MOTOR, "ratio": 0.0}, RequestError, "non-zero"),
    ({**MOTOR, "k_t": "a"}, RequestError, "k_t: expected a number"),
    ({**MOTOR, "R": [1.0, 2.0], "k_t": [1.0, 2.0, 3.0]}, ShapeError, "one value per joint"),
    ({**MOTOR, "R": [1.0, 2.0], "joints": [0]}, ShapeError, "1 values"),
    ({**MOTOR, "joints": [0, 0]}, RequestError, "distinct joint indices"),
])
def test_bad_motor_parameters_are_named(kwargs, error, words):
    with pytest.raises(error, match=words):
        jaxskid.DCMotors(**kwargs)


def test_bad_voltages_are_named(dyn):
    motors = jaxskid.DCMotors(**MOTOR)
    with pytest.raises(ShapeError, match=r"expected shape \(steps, n\)"):
        motors.drive(np.ones(5))
    with pytest.raises(ShapeError, match=r"controls: expected shape \(5, 1\)"):
        jaxskid.rollout(dyn, np.zeros(2), motors.drive(np.ones((5, 2))), 0.01, 5)
    with pytest.raises(ShapeError, match=r"the voltages: expected shape \(1,\)"):
        jaxskid.rollout(dyn, np.zeros(2), motors.drive(lambda t, x: jnp.ones(3)), 0.01, 5)
    with pytest.raises(ShapeError, match="the robot has 1 joint"):
        jaxskid.rollout(dyn, np.zeros(2), jaxskid.DCMotors(**MOTOR, joints=[2]).drive(np.ones((5, 1))), 0.01, 5)
