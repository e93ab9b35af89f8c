"""Reverse mode through the generated quantities by their closed-form pullbacks (jaxskid.runtime._pullback).

``jax.grad`` of M, C, C qd, Q_grav and tau with respect to the parameters and the states runs the lowered
pullbacks (``mass_matrix_vjp``, ...); forward mode differentiates the quantity's own program. The two are
independent routes to the same derivatives, and both are checked against central differences of the
quantity's values: on the Panda, solo12 with a floating base, the Panda with drives, a tree with a mimic
joint on another branch, the G1 (29 DOF) and with native kernels off. Every composition of ``jax.grad``, ``jax.jacfwd``,
``jax.vmap`` and ``jax.jit`` that users write must give the same numbers.
"""

import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import ERD, FINGERS, PANDA, ROBOTS_DIR, URDFS, load, rel_err

QUANTITIES = ["mass_matrix", "coriolis_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics"]
CONTACT = ["ee_pose", "ee_hybrid_twist", "external_torques"]
"""The kinematics a contact model evaluates (:class:`jaxskid.GroundContact`), with their pullbacks too."""


def _states(dyn, batch, seed=0, args=("q", "qd", "qdd")):
    """Random values of the arguments ``args`` (a unit quaternion in a floating base's ``q``)."""
    rng = np.random.default_rng(seed)
    shape = (batch,) if batch else ()
    out = []
    for a in args:
        x = rng.normal(size=(*shape, *dyn.argument_shape(a)))
        if a == "q" and dyn.nq != dyn.nv:
            x[..., 3:7] /= np.linalg.norm(x[..., 3:7], axis=-1, keepdims=True)
        out.append(jnp.asarray(x))
    return out


def _loss(dyn, name, states, weights):
    """A nonlinear scalar of the quantity: sum W * y + (sum W * y)^2 / 2."""
    def loss(p, *x):
        y = getattr(dyn, name)(*x, params=p)
        s = jnp.sum(weights * y)
        return s + 0.5 * s ** 2
    return loss


def _central(f, args, k, direction, h):
    """The directional derivative by central differences, Richardson-extrapolated (error O(h^4))."""
    def diff(h):
        plus = list(args); plus[k] = args[k] + h * direction
        minus = list(args); minus[k] = args[k] - h * direction
        return (f(*plus) - f(*minus)) / (2 * h)
    return (4 * diff(h / 2) - diff(h)) / 3


def _check(dyn, batch=4, names=QUANTITIES, tol=1e-7):
    """Each quantity's gradient (reverse mode, the pullback) along random directions: the directional
    derivative along all arguments at once against forward mode (``jax.jvp`` of the quantity's program) at
    1e-9, and along each argument against Richardson-extrapolated central differences."""
    rng = np.random.default_rng(1)
    p = dyn.param_vector()
    for name in names:
        states = _states(dyn, batch, args=dyn.signature(name)[0])
        shape = getattr(dyn, name)(*states).shape
        loss = _loss(dyn, name, states, jnp.asarray(rng.normal(size=shape)))
        args = (p, *states)
        gradients = jax.jit(jax.grad(loss, argnums=tuple(range(len(args)))))(*args)  # one program for all
        directions = [jnp.asarray(rng.normal(size=a.shape)) for a in args]
        if dyn.nq != dyn.nv:
            directions[1] = directions[1].at[..., 3:7].set(0.0)  # keep the quaternion where it was
        along = [float(jnp.sum(g * d)) for g, d in zip(gradients, directions)]
        forward = float(jax.jvp(loss, args, tuple(directions))[1])  # one forward-mode program for all
        assert abs(sum(along) - forward) <= 1e-9 * (abs(forward) + 1.0), name
        for k in range(len(args)):
            step = 1e-3 * (1.0 + float(jnp.max(jnp.abs(args[k]))))
            reference = _central(loss, args, k, directions[k], step)
            assert abs(along[k] - float(reference)) <= tol * (abs(float(reference)) + 1.0), (name, k)


@pytest.fixture(scope="module")
def panda():
    return jaxskid.lower(jaxskid.load(PANDA, lock=FINGERS), QUANTITIES)


def test_pullbacks_come_with_their_quantities(panda):
    for name in ("mass_matrix", "coriolis_matrix", "coriolis_torques", "gravity_torques"):
        assert f"{name}_vjp" in panda.quantities
    assert {"inverse_dynamics_vjp", "mass_matrix"} <= set(panda.quantities)


def test_panda_gradients(panda):
    _check(panda)


def _primitives(jaxpr) -> list[str]:
    """The names of the primitives of ``jaxpr`` and of the programs it calls."""
    names = []
    for e in jaxpr.eqns:
        names.append(e.primitive.name)
        for v in e.params.values():
            inner = getattr(v, "jaxpr", None)
            if inner is not None:
                names += _primitives(inner if hasattr(inner, "eqns") else inner.jaxpr)
    return names


def test_reverse_mode_runs_the_pullback(panda):
    """The tangent of a quantity is one primitive that reverse mode transposes into the pullback: the
    gradient's program is a small fraction of the one JAX makes by transposing the quantity's program (the
    generated function without the pullback, executed from the module's source)."""
    q = _states(panda, 8)[0]
    p = panda.param_vector()
    _, linear = jax.linearize(lambda p: panda.mass_matrix(q, p), p)
    assert "jaxskid_tangent" in _primitives(jax.make_jaxpr(linear)(p).jaxpr)
    namespace = {}
    exec(panda.source, namespace)
    unwrapped = jax.vmap(namespace["mass_matrix"], (0, None))
    ours = _primitives(jax.make_jaxpr(jax.grad(lambda p: jnp.sum(panda.mass_matrix(q, p) ** 2)))(p).jaxpr)
    plain = _primitives(jax.make_jaxpr(jax.grad(lambda p: jnp.sum(unwrapped(q, p) ** 2)))(p).jaxpr)
    assert 10 * len(ours) < len(plain)


def test_state_jacobians_leave_the_parameters_out(panda):
    """Where the parameters are not differentiated (a controller's Jacobian with respect to the state), reverse
    mode calls the pullback's native kernel without the parameters' part (``<name>_vjp_state``); with them, the
    whole one. Both against forward mode, for tau (its qdd cotangent through M), C qd and Q_grav."""
    q, qd, qdd = _states(panda, None)
    p = panda.param_vector()
    cases = {"inverse_dynamics": lambda x, p: panda.raw("inverse_dynamics")(x[:7], x[7:14], x[14:], p),
             "coriolis_torques": lambda x, p: panda.raw("coriolis_torques")(x[:7], x[7:14], p),
             "gravity_torques": lambda x, p: panda.raw("gravity_torques")(x[:7], p)}
    x = jnp.concatenate([q, qd, qdd])
    for name, f in cases.items():
        state = jax.jit(jax.jacrev(f))
        assert f"jaxskid_{name}_vjp_state" in state.lower(x, p).as_text()
        assert rel_err(state(x, p), jax.jacfwd(f)(x, p)) < 1e-12
        both = jax.jit(jax.jacrev(f, argnums=(0, 1)))
        text = both.lower(x, p).as_text()
        assert f"jaxskid_{name}_vjp_" in text and f"jaxskid_{name}_vjp_state" not in text
        for ours, theirs in zip(both(x, p), jax.jacfwd(f, argnums=(0, 1))(x, p)):
            assert rel_err(ours, theirs) < 1e-12


@pytest.mark.parametrize("robot", ["solo12", "quadruped_contact"])
def test_contact_kinematics(robot):
    """The end-effector poses, hybrid twists and generalized forces of end-effector wrenches that a contact
    model evaluates come with their pullbacks, which give the gradients with respect to q, qd, the wrenches
    and every parameter: solo12 on a floating base, its four feet the end-effectors, and a quadruped whose
    link lengths are parameters too (``robots/quadruped_contact.yaml``)."""
    robot = (jaxskid.load(URDFS["solo12"], floating_base=True) if robot == "solo12"
             else jaxskid.load(ROBOTS_DIR / "quadruped_contact.yaml"))
    dyn = jaxskid.lower(robot, CONTACT)
    assert {f"{name}_vjp" for name in CONTACT} <= set(dyn.quantities)
    assert len(dyn.end_effectors) == 4
    _check(dyn, batch=2, names=CONTACT)


def test_constraint_quantities():
    """The constraint Jacobian, drift and residual come with their pullbacks (the reverse rule of constrained
    dynamics pulls through them): the four-bar, whose link lengths and gravity are parameters."""
    names = ["constraint_jacobian", "constraint_drift", "constraint_residual"]
    dyn = jaxskid.lower(jaxskid.load(ROBOTS_DIR / "four_bar.yaml"), names)
    assert {f"{name}_vjp" for name in names} <= set(dyn.quantities)
    assert dyn.argument_shape("cotangent_constraint") == dyn.signature("constraint_jacobian")[1]
    _check(dyn, batch=3, names=names)
    alone = jaxskid.lower(jaxskid.load(ROBOTS_DIR / "four_bar.yaml"), ["constraint_drift"])  # no Jacobian lowered
    _check(alone, batch=2, names=["constraint_drift"])


@pytest.fixture(scope="module")
def arm():
    return jaxskid.lower(load("arm_3dof"), QUANTITIES)


def test_compositions(arm):
    """grad, jacfwd, hessian, vmap and jit in the orders users compose them, each against forward mode."""
    panda = arm
    q, qd, _ = _states(panda, 3)
    p = panda.param_vector()

    def loss(p, q, qd=qd):
        return jnp.sum(jnp.sin(panda.mass_matrix(q, p))) + jnp.sum(panda.coriolis_matrix(q, qd, p) ** 2)

    reference = jax.jacfwd(loss)(p, q)
    for transform in (jax.grad, lambda f: jax.jit(jax.grad(f)), lambda f: jax.grad(jax.jit(f)),
                      lambda f: jaxskid.jit(jax.grad(f)), jax.jacrev):
        np.testing.assert_allclose(transform(loss)(p, q), reference, rtol=1e-10, atol=1e-10)
    # the same function traced first under forward mode, then under reverse mode, then forward again
    jitted = jax.jit(loss)
    np.testing.assert_allclose(jax.jacfwd(jitted)(p, q), reference, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(jax.grad(jitted)(p, q), reference, rtol=1e-10, atol=1e-10)
    per_state = jax.vmap(jax.grad(lambda p, q, v: loss(p, q[None], v[None])), in_axes=(None, 0, 0))(p, q, qd)
    np.testing.assert_allclose(per_state.sum(0), reference, rtol=1e-10, atol=1e-10)
    hess = jax.hessian(loss)(p, q)
    np.testing.assert_allclose(hess, jax.jacfwd(jax.jacfwd(loss))(p, q), rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(hess, hess.T, rtol=1e-8, atol=1e-8)
    state_hess = jax.jacrev(jax.grad(loss, argnums=1), argnums=1)(p, q)
    np.testing.assert_allclose(state_hess, jax.jacfwd(jax.jacfwd(loss, argnums=1), argnums=1)(p, q),
                               rtol=1e-8, atol=1e-8)


def test_single_state_and_dict_parameters(panda):
    q, qd, qdd = _states(panda, 0)
    defaults = panda.default_params()
    grad = jax.grad(lambda d: jnp.sum(panda.inverse_dynamics(q, qd, qdd, d) ** 2))(defaults)
    p = panda.param_vector()
    vector = jax.jacfwd(lambda p: jnp.sum(panda.inverse_dynamics(q, qd, qdd, p) ** 2))(p)
    np.testing.assert_allclose([grad[k] for k in panda.parameters], vector, rtol=1e-10, atol=1e-10)


def _solo12():
    names = ["mass_matrix", "inverse_dynamics"]
    return jaxskid.lower(jaxskid.load(URDFS["solo12"], floating_base=True), names), names


def _drives():  # armature in M, friction in tau
    return jaxskid.lower(jaxskid.load(PANDA, lock=FINGERS, drives=True), ["inverse_dynamics"]), ["inverse_dynamics"]


def _mimic():  # a mimic joint on another branch of a tree (test_mimic's robot "branch"), with C
    from test_mimic import CASES, write_urdf

    names = ["coriolis_matrix", "inverse_dynamics"]
    path = write_urdf(Path(tempfile.mkdtemp(prefix="jaxskid-mimic-")) / "branch.urdf", CASES["branch"])
    return jaxskid.lower(jaxskid.load(path, mimic=True), names), names


@pytest.mark.slow
@pytest.mark.parametrize("make", [_solo12, _drives, _mimic], ids=["floating_base", "drives", "mimic"])
def test_floating_base_drives_and_mimic(make):
    dyn, names = make()
    _check(dyn, batch=1, names=names)


@pytest.mark.slow
def test_jax_form(monkeypatch):
    """With native kernels off (the form used off CPU) the pullbacks run as JAX programs."""
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    names = ["mass_matrix", "gravity_torques", "inverse_dynamics"]
    dyn = jaxskid.lower(load("panda7"), names)
    assert all(form.startswith("JAX form") for form in dyn.report().values())
    _check(dyn, batch=2, names=names)


def test_pullbacks_deferred_without_native_kernels(monkeypatch, tmp_path):
    """Where no native kernel is built, the pullbacks are a module of their own, made (and cached) when a
    gradient first needs one: listed among the quantities from the start, with the signatures the module then
    gives them, and the gradients checked as above. A second lowering finds both modules and derives nothing."""
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    robot = load("arm_3dof")
    names = ["mass_matrix", "coriolis_matrix", "inverse_dynamics"]
    dyn = jaxskid.lower(robot, names, cache_dir=tmp_path)
    assert {f"{n}_vjp" for n in names} <= set(dyn.quantities)
    assert len(list(tmp_path.glob("*.py"))) == 1  # the quantities' module only
    announced = {n: dyn.signature(f"{n}_vjp") for n in names}
    _check(dyn, batch=2, names=names)
    assert len(list(tmp_path.glob("*.py"))) == 2
    assert {n: dyn.signature(f"{n}_vjp") for n in names} == announced

    def no_derivation(*args, **kwargs):
        raise AssertionError("derived again")

    with monkeypatch.context() as patched:
        patched.setattr(jaxskid._api, "derive", no_derivation)
        again = jaxskid.lower(robot, names, cache_dir=tmp_path)
        q, qd = _states(again, 0, args=("q", "qd"))
        gradient = jax.grad(lambda p: jnp.sum(again.coriolis_matrix(q, qd, p) ** 2))(again.param_vector())
    reference = jax.grad(lambda p: jnp.sum(dyn.coriolis_matrix(q, qd, p) ** 2))(dyn.param_vector())
    np.testing.assert_allclose(gradient, reference, rtol=1e-12, atol=1e-12)
    # asked for, a pullback is lowered with its quantity; with native kernels on, every pullback is
    explicit = jaxskid.lower(robot, ["mass_matrix", "mass_matrix_vjp"], cache_dir=tmp_path / "asked")
    assert explicit.quantities == ("mass_matrix", "mass_matrix_vjp") and explicit.module.quantities.keys() >= {
        "mass_matrix_vjp"}
    monkeypatch.undo()
    native = jaxskid.lower(robot, names, cache_dir=tmp_path / "native")
    assert {f"{n}_vjp" for n in names} <= set(native.module.quantities)


def test_deferred_module_must_match_what_was_announced():
    """A deferred module (a stale or foreign cache entry) whose signatures or parameter order differ from the
    ones announced is refused with a message that says what to do, not used."""
    from jaxskid.runtime._deferred import Deferred

    module = jaxskid.lower(load("arm_3dof"), ["mass_matrix", "mass_matrix_vjp"], cache=False).module
    made = module.metadata
    vjp = {"mass_matrix_vjp": made["quantities"]["mass_matrix_vjp"]}
    assert Deferred(vjp, made["parameters"], lambda: module).module() is module
    wrong_shape = {"mass_matrix_vjp": {**vjp["mass_matrix_vjp"], "shape": [1]}}
    for quantities, parameters in ((wrong_shape, made["parameters"]), (vjp, made["parameters"][::-1])):
        with pytest.raises(RuntimeError, match="clear jaxskid's cache"):
            Deferred(quantities, parameters, lambda: module).module()


@pytest.mark.slow
def test_g1():
    robot = jaxskid.load(ERD / "g1_description/urdf/g1_29dof_rev_1_0.urdf")
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    _check(dyn, batch=2, names=["mass_matrix", "inverse_dynamics"])
