"""The native single-call path (jaxskid.compile_native): the generated C, built as its own extension module
(capi), with cffi or with ctypes and called from Python, computes what the JAX lowering and Pinocchio compute, takes parameters by the one
rule (defaults fill in, unknown names are errors), and is built once per machine."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from pinref import to_pinocchio
from test_codegen import Case, close, load


@pytest.fixture(scope="module", params=["arm_2r", "hopping_leg", "panda"])
def case(request, tmp_path_factory):
    return Case(request.param, tmp_path_factory.mktemp(f"native-{request.param}"))


@pytest.mark.parametrize("backend", ["capi", "cffi", "ctypes"])
def test_native_matches_jax_and_pinocchio(case, backend):
    native = jaxskid.compile_native(case.eqs, backend=backend)
    assert native.backend == backend and native.quantities == tuple(case.names)
    model, _ = to_pinocchio(case.robot, case.robot.default_params())
    data = model.createData()
    for name in case.names:
        for s, (state, ref) in enumerate(zip(case.states, case.ref[name])):
            got = getattr(native, name)(*(state[a] for a in case.args(name)))
            if name == "forward_kinematics":
                got = np.stack([got[f] for f in native.frame_names])
            close(got, ref, f"{name} state {s}")
    for state in case.states:
        tau = pin.rnea(model, data, state["q"], state["qd"], state["qdd"])
        close(native.inverse_dynamics(state["q"], state["qd"], state["qdd"]), tau, "rnea")


def test_native_arguments_and_parameters():
    robot = load("hopping_leg")
    dyn = jaxskid.lower(robot, ["inverse_dynamics", "mass_matrix"])
    for backend in ("capi", "cffi", "ctypes"):
        native = jaxskid.compile_native(robot, ["inverse_dynamics", "mass_matrix"], backend=backend)
        q, qd, qdd = np.array([0.1, -0.7, 1.2]), np.array([0.5, 1.0, -2.0]), np.array([1.0, 0.0, -0.5])
        params = {**robot.default_params(), "m2": 0.4, "L1": 0.3}
        ref = np.asarray(dyn.inverse_dynamics(q, qd, qdd, params=params))
        close(native.inverse_dynamics(q, qd, qdd, params=params), ref, "dict params")
        close(native.inverse_dynamics(q, qd, qdd, params=native.param_vector(params)), ref, "vector params")
        close(native.inverse_dynamics(q, qd, qdd, params={"m2": 0.4, "L1": 0.3}), ref, "partial dict: defaults fill in")
        strided = np.repeat(q, 2)[::2]  # not contiguous
        assert not strided.flags.c_contiguous
        close(native.inverse_dynamics(strided, list(qd), tuple(qdd), params=params), ref, "converted inputs")
        q32 = q.astype(np.float32)
        close(native.mass_matrix(q32), dyn.mass_matrix(q32.astype(np.float64)), "float32 input")
        with pytest.raises(jaxskid.ShapeError, match=r"inverse_dynamics: q: expected shape \(3,\), got \(4,\)"):
            native.inverse_dynamics(np.zeros(4), qd, qdd)
        with pytest.raises(jaxskid.ShapeError, match="params"):
            native.inverse_dynamics(q, qd, qdd, params=np.zeros(2))
        with pytest.raises(jaxskid.RequestError, match=r"unknown parameter 'm22' \(did you mean 'm2'"):
            native.inverse_dynamics(q, qd, qdd, params={"m22": 1.0})
        with pytest.raises(jaxskid.RequestError, match="was not compiled"):
            native.gravity_torques(q)
        with pytest.raises(AttributeError):
            native.no_such_thing  # noqa: B018


def test_native_metadata_is_the_lowered_one():
    robot = load("arm_2r")
    names = ["inverse_dynamics", "external_torques", "forward_kinematics"]
    dyn = jaxskid.lower(robot, names)
    native = jaxskid.compile_native(robot, names, backend="ctypes")
    for attr in ("robot_name", "joint_names", "frame_names", "end_effectors", "parameters", "defaults", "n_dof"):
        assert getattr(native, attr) == getattr(dyn, attr), attr
    # lower() brings what reverse mode differentiates inverse dynamics with; compile_native what was asked
    assert set(native.quantities) == set(names) < set(dyn.quantities)
    assert native.end_effectors, "the arm has an end-effector: the wrench argument is exercised"
    for name in names:
        assert native.signature(name) == dyn.signature(name), name
    assert native.default_params() == dyn.default_params() == robot.default_params()
    np.testing.assert_array_equal(native.param_vector(), np.asarray(dyn.param_vector()))
    q, wrench = np.array([0.4, -0.2]), np.arange(6.0)[None, :].repeat(len(native.end_effectors), 0)
    close(native.external_torques(q, wrench), dyn.external_torques(q, wrench), "wrench argument")
    assert native.param_vector().dtype == np.float64 and not native.param_vector().flags.writeable


def test_native_from_equations_takes_a_subset():
    robot = load("arm_2r")
    eqs = jaxskid.derive(robot, ["gravity_torques", "mass_matrix"])
    native = jaxskid.compile_native(eqs, "mass_matrix", backend="ctypes")
    assert native.quantities == ("mass_matrix",)
    with pytest.raises(jaxskid.RequestError, match="not derived"):
        jaxskid.compile_native(eqs, ["coriolis_matrix"])
    with pytest.raises(jaxskid.RequestError, match="unknown backend"):
        jaxskid.compile_native(eqs, backend="fortran")


def test_native_build_is_cached(tmp_path):
    robot = load("arm_2r")
    first = jaxskid.compile_native(robot, ["gravity_torques"], backend="ctypes", cache_dir=tmp_path)
    stamp = first.path.stat().st_mtime_ns
    second = jaxskid.compile_native(robot, ["gravity_torques"], backend="ctypes", cache_dir=tmp_path)
    assert second.path == first.path and second.path.stat().st_mtime_ns == stamp
    assert [p.name for p in tmp_path.iterdir()] == [first.path.parent.name]  # no leftover build folders
    q = np.array([0.4, -0.2])
    close(second.gravity_torques(q), first.gravity_torques(q), "cached library")


def test_capi_calling_convention():
    """The extension's methods: params by position or keyword, None for the defaults, clear errors for a wrong
    number of arguments or an unknown keyword, docstrings and names of their own, a fresh array per call."""
    robot = load("hopping_leg")
    native = jaxskid.compile_native(robot, ["inverse_dynamics", "kinetic_energy"], backend="capi")
    ref = jaxskid.compile_native(robot, ["inverse_dynamics", "kinetic_energy"], backend="ctypes")
    q, qd, qdd = np.array([0.1, -0.7, 1.2]), np.array([0.5, 1.0, -2.0]), np.array([1.0, 0.0, -0.5])
    p = native.param_vector({"m2": 0.4})
    expected = ref.inverse_dynamics(q, qd, qdd, p)
    for got in (native.inverse_dynamics(q, qd, qdd, p), native.inverse_dynamics(q, qd, qdd, params=p),
                native.inverse_dynamics(q, qd, qdd, params={"m2": 0.4})):
        close(got, expected, "params")
    a, b = native.inverse_dynamics(q, qd, qdd), native.inverse_dynamics(q, qd, qdd)
    assert a is not b and a.flags.c_contiguous and a.dtype == np.float64
    energy = native.kinetic_energy(q, qd)
    assert energy.shape == () and np.isclose(energy, ref.kinetic_energy(q, qd), rtol=1e-14, atol=0)
    assert native.inverse_dynamics.__name__ == "inverse_dynamics"
    assert native.inverse_dynamics.__doc__.startswith("inverse_dynamics(q, qd, qdd, params=None) -> (3,)")
    with pytest.raises(TypeError, match=r"inverse_dynamics\(\) takes 3 state arguments"):
        native.inverse_dynamics(q, qd)
    with pytest.raises(TypeError, match="unexpected keyword argument 'parms'"):
        native.inverse_dynamics(q, qd, qdd, parms=p)
    with pytest.raises(jaxskid.ShapeError, match=r"inverse_dynamics: qd: expected shape \(3,\), got \(2, 3\)"):
        native.inverse_dynamics(q, np.zeros((2, 3)), qdd)
