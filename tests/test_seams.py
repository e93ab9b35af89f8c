"""The typed seams between the stages: the lowered quantities as functions with their own signatures and
docstrings, the generated module as a frozen object, the native C printed from the program representation
into templates shipped with the package, and the RK4 tableau written once."""

from __future__ import annotations

import dataclasses
import inspect
import pydoc

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import sympy as sp

import jaxskid
from helpers import ROBOTS_DIR
from pinref import to_pinocchio

QUANTITIES = ["mass_matrix", "coriolis_matrix", "inverse_dynamics", "external_torques", "regressor"]


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    robot = jaxskid.load(ROBOTS_DIR / "arm_3dof.yaml")
    return robot, jaxskid.lower(robot, QUANTITIES, cache_dir=tmp_path_factory.mktemp("seams"))


def test_quantities_are_attributes_with_their_signatures(arm):
    _, dyn = arm
    listed = set(dir(dyn))
    assert set(dyn.quantities) <= listed
    assert str(inspect.signature(dyn.mass_matrix)) == "(q, params=None, *, out=None)"
    assert str(inspect.signature(dyn.coriolis_matrix)) == "(q, qd, params=None, *, out=None)"
    assert str(inspect.signature(dyn.inverse_dynamics)) == "(q, qd, qdd, params=None, *, wrench=None, out=None)"
    assert str(inspect.signature(dyn.external_torques)) == "(q, wrench, params=None, *, out=None)"
    assert "mass_matrix" in vars(dyn)  # an attribute of the object, not made by __getattr__ on each access


def test_help_shows_equation_shapes_and_units(arm):
    _, dyn = arm
    text = pydoc.render_doc(dyn.mass_matrix, renderer=pydoc.plaintext)
    assert "mass_matrix(q, params=None, *, out=None)" in text
    assert "M(q) = J^T diag(M_i) J" in text
    assert "q: (3,)" in text and "rad (revolute)" in text
    assert "(3, 3) per state" in text and "kg m^2" in text
    text = pydoc.render_doc(dyn.inverse_dynamics, renderer=pydoc.plaintext)
    assert "wrench: end-effector wrenches (n_ee, 6)" in text and "N m" in text


def test_every_calling_convention_against_pinocchio(arm):
    """Parameters positional or by keyword (dict or vector), a batch, a wrench by keyword: all give what
    Pinocchio gives."""
    robot, dyn = arm
    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    rng = np.random.default_rng(3)
    q, qd, qdd = rng.normal(size=(3, 3))
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    for got in (dyn.mass_matrix(q), dyn.mass_matrix(q, None), dyn.mass_matrix(q, dyn.default_params()),
                dyn.mass_matrix(q, params=dyn.param_vector()), dyn.mass_matrix(q=q)):
        np.testing.assert_allclose(got, mass, rtol=1e-10, atol=1e-12)
    batch = dyn.mass_matrix(np.stack([q, q]))
    np.testing.assert_allclose(batch, np.stack([mass, mass]), rtol=1e-10, atol=1e-12)
    tau = pin.rnea(model, data, q, qd, qdd)
    np.testing.assert_allclose(dyn.inverse_dynamics(q, qd, qdd), tau, rtol=1e-10, atol=1e-12)
    wrench = rng.normal(size=(len(dyn.end_effectors), 6))
    np.testing.assert_allclose(dyn.inverse_dynamics(q, qd, qdd, wrench=wrench),
                               tau + dyn.external_torques(q, wrench), rtol=1e-10, atol=1e-12)
    with pytest.raises(TypeError, match=r"expected inverse_dynamics\(q, qd, qdd, params=None, \*, wrench=None"):
        dyn.inverse_dynamics(q, qd, qdd, torque=1.0)


def test_the_generated_module_is_typed_and_frozen(arm):
    _, dyn = arm
    module = dyn.module
    assert isinstance(module, jaxskid._generated.GeneratedModule)
    assert tuple(module.quantities) == dyn.quantities and module.source == dyn.source
    mass = module.quantities["mass_matrix"]
    assert (mass.args, mass.shape) == (("q",), (3, 3))
    with pytest.raises(dataclasses.FrozenInstanceError):
        module.source = ""
    # the entries form, asked for by name: the nonzero entries of the assembled matrix
    q, p = jnp.asarray([0.3, -0.4, 0.5]), dyn.param_vector()
    entries = mass.entries()(q, p)
    full = np.asarray(mass.single()(q, p)).ravel()
    assert set(np.flatnonzero(full)) <= set(entries)  # the structurally nonzero ones: every nonzero among them
    np.testing.assert_array_equal([entries[k] for k in sorted(entries)], full[sorted(entries)])


def test_native_c_comes_from_templates_and_the_program(arm):
    """Every placeholder of the templates is filled; the kernels over vectors of states are printed from the
    program representation: sine, cosine and sign lane-wise, numbers lifted, and no vector form where a body
    calls anything else."""
    import re

    from jaxskid.codegen._c import VectorPrinter, vector_kernel
    from jaxskid.codegen._common import Program
    from jaxskid.lowering._ffi import glue_source
    from jaxskid.lowering._templates import template

    _, dyn = arm
    for native in dyn.module.native:
        glue, _ = glue_source(native)
        assert not re.findall(r"@[A-Z][A-Z0-9_]*@", glue)
    assert "XLA_FFI_Error *jaxskid_@NAME@(" in template("ffi_quantity.c")
    x, y = sp.symbols("x y", real=True)
    printer = VectorPrinter()
    ok = vector_kernel(Program("f", ("q",), (3,), "", "", ((x, "q", 0),), ((y, sp.sin(x) * sp.sign(x)),),
                               (y, sp.Integer(0), 2 * x ** 2)), printer)
    assert [(s.kind, s.value) for s in ok.statements] == [
        ("unused", ""), ("input", "q[0]"), ("define", "@V@sign(x)*@V@sin(x)"), ("output", "y"),
        ("output", "@V@LIFT(0.0)"), ("output", "2.0*x*x")]
    assert ok.zeros == (1,) and ok.statements[3].reads == ("y",) and ok.statements[2].reads == ("x",)
    assert vector_kernel(Program("g", ("q",), (1,), "", "", ((x, "q", 0),), (), (sp.sqrt(x),)), printer) is None


def test_rk4_has_one_tableau():
    """RK4's step on y' = lambda y is the degree-4 Taylor polynomial of exp(h lambda) (Hairer, Norsett &
    Wanner, I, sec. II.1), and the runtime's one-call steps use the same tableau."""
    from jaxskid._tableau import RK4_TABLEAU
    from jaxskid.runtime import _rk4

    z = -0.7

    def f(t, y):
        return jax.tree.map(lambda v: -0.7 * v, y), ()

    y1, _ = jaxskid.RK4().step(f, 0.0, (jnp.asarray(1.0),), 1.0)
    np.testing.assert_allclose(y1[0], 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24, rtol=1e-14)
    assert (_rk4.B, _rk4.C) == (RK4_TABLEAU.b, RK4_TABLEAU.c)
    assert jaxskid.RK4().tableau is RK4_TABLEAU


def test_deprecated_names_warn():
    with pytest.warns(DeprecationWarning, match="check_model"):
        assert jaxskid.model.validate is jaxskid.model.check_model
    with pytest.warns(DeprecationWarning, match="Program"):
        assert jaxskid.codegen.Kernel is jaxskid.codegen.Program
