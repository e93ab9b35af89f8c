"""What a careful library refuses, warns about or names: degenerate inertias at load, impossible parameter
values and NaN at call time, misspelt names, and one broadcasting rule for every argument.

Each error is checked for its exact type and for naming what the user wrote (the file, the key, the argument
and its first bad index, the parameter). Fuzzed values: tests/test_fuzz_inputs.py.
"""

import re
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import ERD, ROBOTS_DIR, URDFS, load_example

UR5 = URDFS["ur5"]


def _urdf_with(tmp_path, link: str, mass: float, inertia: tuple) -> str:
    """The UR5's URDF with ``link``'s mass and principal moments replaced."""
    text = UR5.read_text()
    block = re.search(r'<link name="%s">.*?</link>' % link, text, re.S).group(0)
    new = re.sub(r'<mass value="[^"]*"\s*/>', f'<mass value="{mass}"/>', block)
    ixx, iyy, izz = inertia
    new = re.sub(r"<inertia [^/]*/>", f'<inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/>', new)
    path = tmp_path / f"ur5_{link}.urdf"
    path.write_text(text.replace(block, new))
    return str(path)


@pytest.fixture(scope="module")
def ur5():
    return jaxskid.lower(jaxskid.load(UR5), ["mass_matrix", "inverse_dynamics", "forward_dynamics"])


# ---------------------------------------------------------------- at load


def test_massless_leaf_on_a_moving_joint_is_an_error_naming_file_link_and_joint(tmp_path):
    path = _urdf_with(tmp_path, "wrist_3_link", 0.0, (0.0, 0.0, 0.0))
    with pytest.raises(jaxskid.ModelError) as err:
        jaxskid.load(path)
    message = str(err.value)
    assert path in message and "wrist_3_link" in message and "'wrist_3_joint'" in message
    assert "singular" in message


def test_massless_leaf_can_be_locked(tmp_path):
    """The remedy the message names: a locked joint carries its massless body as part of its parent."""
    robot = jaxskid.load(_urdf_with(tmp_path, "wrist_3_link", 0.0, (0.0, 0.0, 0.0)), lock={"wrist_3_joint": 0.0})
    assert robot.n_dof == 5


def test_a_real_robot_with_massless_finger_links_names_the_joint():
    with pytest.raises(jaxskid.ModelError, match=r"romeo\.urdf: link 'LFinger21Link' <inertial>: joint 'LFinger21'"):
        jaxskid.load(ERD / "romeo_description/urdf/romeo.urdf")


@pytest.mark.parametrize("mass, moments, what", [
    (0.0, (0.01, 0.01, 0.01), "zero mass with a nonzero rotational inertia"),
    (1.0, (0.001, 0.001, 0.01), "triangle inequality"),
])
def test_inconsistent_bodies_warn_naming_file_and_link(tmp_path, mass, moments, what):
    path = _urdf_with(tmp_path, "wrist_3_link", mass, moments)
    with pytest.warns(jaxskid.PhysicalConsistencyWarning, match=what) as record:
        jaxskid.load(path)
    assert path in str(record[0].message) and "wrist_3_link" in str(record[0].message)


def test_consistent_robots_load_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxskid.PhysicalConsistencyWarning)
        for path in (UR5, URDFS["panda"], URDFS["solo12"], ROBOTS_DIR / "arm_3dof.yaml"):
            jaxskid.load(path)


# ---------------------------------------------------------------- at call time


def test_negative_mass_names_the_parameter(ur5):
    q = np.zeros(ur5.n_dof)
    with pytest.raises(jaxskid.InputError, match=r"params: upper_arm_link_m gives body 'upper_arm_link' the mass -9"):
        ur5.mass_matrix(q, params={"upper_arm_link_m": -9.0})
    vector = ur5.param_vector()
    bad = np.asarray(vector).copy()
    bad[ur5.parameters.index("forearm_link_m")] = -1.0
    with pytest.raises(jaxskid.InputError, match="forearm_link_m"):
        ur5.inverse_dynamics(q, q, q, bad)


def test_indefinite_inertia_names_the_body(ur5):
    """A negative moment about the centre of mass: M is not positive definite. The triangle inequality is not
    asked for at call time (identified parameters break it and still fit)."""
    q = np.zeros(ur5.n_dof)
    with pytest.raises(jaxskid.InputError, match=r"body 'forearm_link': forearm_link_Ixx.*positive semi-definite"):
        ur5.mass_matrix(q, params={"forearm_link_Ixx": -1.0})
    ur5.mass_matrix(q, params={"forearm_link_Izz": 10.0})  # positive definite, breaks I1 + I2 >= I3: runs


@pytest.mark.parametrize("value, what", [("heavy", "expected a number"), (float("nan"), "is nan"),
                                         (float("inf"), "is inf"), (None, "expected a number")])
def test_bad_parameter_values_name_the_parameter(ur5, value, what):
    with pytest.raises(jaxskid.InputError, match=rf"params: (upper_arm_link_m)?.*{what}"):
        ur5.mass_matrix(np.zeros(ur5.n_dof), params={"upper_arm_link_m": value})


def test_nan_in_a_state_names_the_argument_and_index(ur5):
    n = ur5.n_dof
    q = np.zeros((4, n))
    q[2, 3] = np.nan
    with pytest.raises(jaxskid.InputError, match=r"mass_matrix: q\[2, 3\] is nan"):
        ur5.mass_matrix(q)
    with pytest.raises(jaxskid.InputError, match=r"inverse_dynamics: qdd\[1\] is inf"):
        ur5.inverse_dynamics(np.zeros(n), np.zeros(n), np.array([0, np.inf, 0, 0, 0, 0.0]))
    with pytest.raises(jaxskid.InputError, match=r"forward_dynamics: tau\[0\] is nan"):
        ur5.forward_dynamics(np.zeros(n), np.zeros(n), jnp.full(n, jnp.nan))


def test_rollout_from_nan_refuses(ur5):
    n = ur5.n_dof
    with pytest.raises(jaxskid.InputError, match=r"rollout: x0\[1\] is nan"):
        jaxskid.rollout(ur5, np.r_[0, np.nan, np.zeros(2 * n - 2)], np.zeros((5, n)), 1e-3, 5)
    u = np.zeros((5, n))
    u[3, 2] = np.nan
    with pytest.raises(jaxskid.InputError, match=r"rollout: controls\[3, 2\] is nan"):
        jaxskid.rollout(ur5, np.zeros(2 * n), u, 1e-3, 5)


def test_identify_names_the_bad_sample():
    y = np.ones((6, 2, 3))
    tau = np.ones((6, 2))
    tau[4, 1] = np.nan
    with pytest.raises(jaxskid.InputError, match=r"identify: tau\[4, 1\] is nan"):
        jaxskid.identify(y, tau)


def test_checks_are_skipped_inside_a_trace_and_when_turned_off(ur5):
    """Under jit the values are tracers: nothing is checked, NaN flows as IEEE arithmetic says."""
    q = jnp.zeros(ur5.n_dof).at[2].set(jnp.nan)  # M depends on q[1:], not on the vertical first joint
    assert np.isnan(np.asarray(jax.jit(ur5.mass_matrix)(q))).any()
    plain = jaxskid.lower(jaxskid.load(UR5), ["mass_matrix", "inverse_dynamics", "forward_dynamics"], checks=False)
    assert np.isnan(np.asarray(plain.mass_matrix(q))).any()
    plain.mass_matrix(np.zeros(ur5.n_dof), params={"upper_arm_link_m": -9.0})  # no check: runs


# ---------------------------------------------------------------- names and shapes


def test_misspelt_names_get_a_suggestion(ur5):
    robot = jaxskid.load(ROBOTS_DIR / "arm_2r.yaml")
    with pytest.raises(jaxskid.RequestError, match=r"unknown quantity 'mass_matrx' \(did you mean 'mass_matrix'"):
        jaxskid.lower(robot, ["mass_matrx"])
    name = robot.parameters[0]
    with pytest.raises(jaxskid.ModelError, match=rf"did you mean '{name}'"):
        jaxskid.lower(robot, ["mass_matrix"], symbolic=[name[:-1] + "x" + name[-1]])
    with pytest.raises(TypeError, match=r"mass_matrix: unexpected keyword argument 'parms' \(did you mean 'params'"):
        ur5.mass_matrix(np.zeros(ur5.n_dof), parms=None)


def test_one_velocity_broadcasts_against_a_batch_of_positions(ur5):
    n, rng = ur5.n_dof, np.random.default_rng(1)
    q, qd, qdd = rng.standard_normal((5, n)), rng.standard_normal(n), rng.standard_normal((1, n))
    tau = np.asarray(ur5.inverse_dynamics(q, qd, qdd))
    each = np.stack([np.asarray(ur5.inverse_dynamics(q[i], qd, qdd[0])) for i in range(5)])
    np.testing.assert_allclose(tau, each, rtol=1e-13, atol=1e-12)
    with pytest.raises(jaxskid.ShapeError, match=r"qd: batch \(3,\) does not broadcast with the batch \(5,\)"):
        ur5.inverse_dynamics(q, rng.standard_normal((3, n)), qdd)


def test_repr_of_a_robot_is_one_short_line():
    text = repr(jaxskid.load(UR5))
    assert "\n" not in text and len(text) < 200
    assert "'ur5'" in text and "n_dof=6" in text and "6 revolute" in text and "parameters=60" in text


# ---------------------------------------------------------------- rollout health


@pytest.mark.slow
def test_an_unstable_step_warns_and_the_step_it_names_settles():
    """solo12 dropped on compliant ground with joint PD (the quadruped example's gains) at 1 ms: the feet's
    sticking contact at rest is outside RK4's stability region, the robot chatters and never settles, and the
    rollout says so, naming the rollouts and a step; at that step, measured, every drop settles (the normal forces
    carry the weight within 5 %) and nothing is said."""
    example = load_example("quadruped_drop")
    from jaxskid.apps.simulation._contact import NEEDED

    robot = jaxskid.load(URDFS["solo12"], floating_base=True)
    dyn = jaxskid.lower(robot, ["forward_dynamics", *NEEDED])
    stand = jnp.asarray(example.STAND)

    def hold(t, x):
        q, v = x[:robot.nq], x[robot.nq:]
        return jnp.concatenate([jnp.zeros(6), example.KP * (stand - q[7:]) - example.KD * v[6:]])

    contact = jaxskid.GroundContact(dyn, inner=hold)
    x0 = example.initial_states(robot, 8, np.random.default_rng(0))
    weight = 9.81 * sum(v for k, v in robot.default_params().items() if k.endswith("_m"))
    with pytest.warns(jaxskid.RolloutWarning, match=r"dt = 0.001 s .* of rollouts 0, 1, .* dt <= ") as record:
        traj = jaxskid.rollout(dyn, x0, contact, 1e-3, 2000, saveat=jaxskid.SaveAt(every=100))
    assert np.abs(np.asarray(traj.x[:, -1, robot.nq:])).max() > 0.1  # still moving after 2 s
    dt = float(re.search(r"dt <= ([0-9.e-]+) s", str(record[0].message)).group(1))
    assert 2e-4 < dt < 1e-3
    steps = int(np.ceil(2.0 / dt))
    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxskid.RolloutWarning)
        traj = jaxskid.rollout(dyn, x0, contact, dt, steps, saveat=jaxskid.SaveAt(t1=True, t0=False))
    xf = traj.x[:, -1]
    normal = np.asarray(jax.vmap(lambda x: contact.forces(x[:robot.nq], x[robot.nq:])[1][:, 2].sum())(xf))
    assert np.all(np.abs(normal / weight - 1) < 0.05), normal / weight
    assert np.abs(np.asarray(xf[:, robot.nq:])).max() < 1e-2


def test_step_stability_of_a_damped_joint_against_the_closed_form():
    """The pendulum hanging at rest under a damper: ``m qdd + kd qd + k_g q = 0`` has the eigenvalues
    ``(-a -+ sqrt(a^2 - 4 b)) / 2`` with ``a = kd / m = 2000`` 1/s and ``b = k_g / m`` (gravity's stiffness); RK4 is
    stable for ``h |lambda| < 2.7853`` on the real axis; step_stability finds the fast one and that step."""
    robot = jaxskid.load(ROBOTS_DIR / "single_pendulum.yaml")
    dyn = jaxskid.lower(robot, ["forward_dynamics"])
    m = float(np.asarray(dyn.mass_matrix(np.zeros(1)))[0, 0])
    k_g = float(jax.jacfwd(lambda q: dyn.inverse_dynamics(q, jnp.zeros(1), jnp.zeros(1)))(jnp.zeros(1))[0, 0])
    kd = 2000.0 * m

    def pd(t, x):
        return -kd * x[1:]

    a, b = 2000.0, k_g / m
    fast = (-a - np.sqrt(a * a - 4 * b)) / 2
    check = jaxskid.step_stability(dyn, pd, np.zeros(2), 2e-3)
    assert abs(check.fastest.real - fast) < 1e-9 * a
    assert check.amplification > 1  # 2e-3 * 2000 = 4 > 2.785
    assert abs(float(check.stable_dt) * abs(fast) - 2.785293563) < 1e-6  # RK4's real stability limit
    assert jaxskid.step_stability(dyn, pd, np.zeros(2), 1e-3).amplification <= 1


def test_base_parameters_are_named_by_default():
    """``base_parameters(dyn)`` names its combinations with the standard parameters' names, as when given
    ``names=standard_parameter_names(robot)``."""
    robot = jaxskid.load(ROBOTS_DIR / "arm_2r.yaml", drives=True)
    dyn = jaxskid.lower(robot, ["regressor"])
    assert dyn.standard_names == jaxskid.standard_parameter_names(robot)
    named = jaxskid.base_parameters(dyn).describe()
    assert named == jaxskid.base_parameters(dyn, names=jaxskid.standard_parameter_names(robot)).describe()
    assert any("link2_m" in d for d in named) and not any("pi[" in d for d in named)


@pytest.mark.parametrize("value", ["abc", None, [[0.1, 0.2], [0.3]], object()], ids=["str", "None", "ragged", "object"])
def test_a_state_that_is_no_array_of_numbers_names_the_argument(ur5, value):
    with pytest.raises(jaxskid.InputError, match=r"^inverse_dynamics: qd: expected an array of numbers, got "):
        ur5.inverse_dynamics(np.zeros(6), value, np.zeros(6))


def test_complex_steps_pass_through_every_call(ur5):
    """Complex states and parameters (a dict entry or the vector) keep their imaginary part, so that
    Im f(x + i h e_k) / h is the derivative: checked against central differences of the real calls."""
    rng = np.random.default_rng(7)
    q, qd, qdd = rng.uniform(-1, 1, (3, 6))
    params = ur5.default_params()
    names = list(ur5.parameters)
    h, e = 1e-30, 1e-6
    calls = {"mass_matrix": lambda q, p: ur5.mass_matrix(q, p),
             "inverse_dynamics": lambda q, p: ur5.inverse_dynamics(q, qd, qdd, p),
             "forward_dynamics": lambda q, p: ur5.forward_dynamics(q, qd, qdd, p)}
    k, name = 2, names[13]  # a joint, and a parameter of the third body
    vector = np.array([params[n] for n in names])
    for call in calls.values():
        dq = e * np.eye(6)[k]
        central_q = (np.asarray(call(q + dq, params)) - np.asarray(call(q - dq, params))) / (2 * e)
        step_q = np.imag(np.asarray(call(q + 1j * h * np.eye(6)[k], params))) / h
        np.testing.assert_allclose(step_q, central_q, rtol=1e-6, atol=1e-6 * np.abs(central_q).max())
        bump = e * np.eye(len(names))[names.index(name)]
        central_p = (np.asarray(call(q, vector + bump)) - np.asarray(call(q, vector - bump))) / (2 * e)
        step_dict = np.imag(np.asarray(call(q, {**params, name: params[name] + 1j * h}))) / h
        step_vector = np.imag(np.asarray(call(q, vector + 1j * h * bump / e))) / h
        for step in (step_dict, step_vector):
            np.testing.assert_allclose(step, central_p, rtol=1e-6, atol=1e-6 * np.abs(central_p).max())


def test_a_diverging_rollout_warns_naming_when_and_a_step_that_holds(ur5):
    """Joint dampers of 50 N m s on the UR5's light wrist put a fast damped mode into the closed loop, which RK4 at
    2 ms amplifies until the state overflows: the warning names the first saved state that is not finite, as the
    trajectory has it, and a step at which the same rollout, measured, stays finite and says nothing."""
    n = ur5.n_dof
    x0 = jnp.zeros(2 * n).at[1].set(0.4)

    def damped(t, x):
        return -200.0 * x[:n] - 50.0 * x[n:]

    with pytest.warns(jaxskid.RolloutWarning, match=r"the state of the rollout is not finite from t = ") as record:
        traj = jaxskid.rollout(ur5, x0, damped, 2e-3, 300)
    x = np.asarray(traj.x)
    first = int(np.argmax(~np.isfinite(x).all(-1)))
    message = str(record[0].message)
    assert f"(saved state {first})" in message and f"t = {float(traj.t[first]):.4g} s" in message
    dt = float(re.search(r"dt <= ([0-9.e-]+) s", message).group(1))
    assert dt < 2e-3
    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxskid.RolloutWarning)
        held = jaxskid.rollout(ur5, x0, damped, dt, int(np.ceil(0.6 / dt)))
        assert np.isfinite(np.asarray(held.x)).all()
        quiet = jaxskid.rollout(ur5, x0, damped, 2e-3, 300, health=False)  # asked not to look
    assert not np.isfinite(np.asarray(quiet.x)).all()


def test_a_complex_step_in_a_parameter_runs_through_a_rollout(ur5):
    """Real initial state, complex parameters: the states become complex and the time stays real; the derivative
    of the final state equals central differences of the real rollout."""
    names = list(ur5.parameters)
    k, h, e = names.index(names[13]), 1e-30, 1e-6
    vector = np.array([ur5.default_params()[n] for n in names])
    x0 = jnp.zeros(12).at[1].set(0.4)

    def final(p):
        traj = jaxskid.rollout(ur5, x0, lambda t, x: -2.0 * x[6:], 1e-3, 50, params=p)
        return np.asarray(traj.x[-1]), np.asarray(traj.t)

    bump = np.eye(len(names))[k]
    stepped, t = final(vector + 1j * h * bump)
    assert np.iscomplexobj(stepped) and not np.iscomplexobj(t)
    central = (final(vector + e * bump)[0] - final(vector - e * bump)[0]) / (2 * e)
    np.testing.assert_allclose(np.imag(stepped) / h, central, rtol=1e-6, atol=1e-6 * np.abs(central).max())
