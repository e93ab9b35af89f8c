"""What identification does with data that cannot determine the parameters: dependent columns are an error
that names them, nearly dependent ones a warning, and base parameters come from any regressor (the lowered
one, a function, or samples with columns of the user's own). Ranks are checked against the SVD."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import jaxskid
from helpers import load


@pytest.fixture(scope="module")
def arm():
    robot = load("arm_3dof")
    dyn = jaxskid.lower(robot, ["regressor", "inverse_dynamics"])
    q, qd, qdd = np.random.default_rng(3).uniform(-2, 2, size=(3, 200, robot.n_dof))
    y = np.asarray(dyn.regressor(q, qd, qdd))
    pi = jaxskid.standard_params(robot)
    tau = np.einsum("snp,p->sn", y, pi)
    names = jaxskid.standard_parameter_names(robot)
    return robot, dyn, (q, qd, qdd), y, tau, names


def _rank(y):
    return int(np.linalg.matrix_rank(y.reshape(-1, y.shape[-1])))


def test_least_squares_on_the_full_regressor_names_the_dependent_columns(arm):
    robot, dyn, _, y, tau, names = arm
    with pytest.raises(jaxskid.IdentificationError, match=r"rank (\d+) < 30 columns: .*reduce it to base parameters") as err:
        jaxskid.identify(y, tau, names=names)
    rank = int(str(err.value).split("rank ")[1].split(" ")[0])
    assert rank == _rank(y)
    assert sum(name in str(err.value) for name in names) >= 2 and "column 0" not in str(err.value)  # names
    with pytest.raises(jaxskid.IdentificationError, match=r"column \d+"):
        jaxskid.identify(y, tau)  # without names: column indices


def test_a_rotor_column_collinear_with_a_link_inertia(arm):
    """The waist's rotor inertia acts exactly like the first link's Izz: an error, not a huge estimate."""
    robot, dyn, (q, qd, qdd), y, tau, names = arm
    base = jaxskid.base_parameters(y, names=names)
    yb = base.reduce(y)
    rotor = np.zeros((*y.shape[:2], 1))
    rotor[:, 0, 0] = qdd[:, 0]
    augmented = np.concatenate([yb, rotor], axis=2)
    labels = [*(names[k] for k in base.independent), "waist_Ia"]
    with pytest.raises(jaxskid.IdentificationError, match="waist_Ia|column_Izz"):
        jaxskid.identify(augmented, tau, names=labels)
    # base parameters of the augmented samples: the rotor merges, the count is the SVD rank
    merged = jaxskid.base_parameters(augmented, names=labels)
    assert merged.n_base == base.n_base == _rank(augmented)
    assert any("waist_Ia" in line for line in merged.describe())


def test_nearly_dependent_columns_warn(arm):
    robot, dyn, (q, qd, qdd), y, tau, names = arm
    base = jaxskid.base_parameters(y, names=names)
    yb = np.asarray(base.reduce(y))
    near = yb[:, :, :1] * (1 + 1e-9 * np.random.default_rng(0).standard_normal(yb[:, :, :1].shape))
    with pytest.warns(jaxskid.IdentificationWarning, match="condition number"):
        jaxskid.identify(np.concatenate([yb, near], axis=2), tau)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        est = jaxskid.identify(yb, tau)  # the base regressor itself is well conditioned: no warning
    np.testing.assert_allclose(est.params, base.project(jaxskid.standard_params(robot)), rtol=1e-8, atol=1e-10)


def test_base_parameters_from_any_regressor(arm):
    robot, dyn, _, y, _, names = arm
    from_dyn = jaxskid.base_parameters(dyn, names=names)
    from_samples = jaxskid.base_parameters(y, names=names)
    from_rows = jaxskid.base_parameters(y.reshape(-1, y.shape[-1]), names=names)
    from_function = jaxskid.base_parameters(lambda q, qd, qdd: dyn.regressor(q, qd, qdd), n_dof=robot.n_dof, names=names)
    for b, same in ((from_function, from_dyn), (from_rows, from_samples)):  # the same samples: the same answer
        np.testing.assert_array_equal(b.independent, same.independent)
        np.testing.assert_allclose(b.projection, same.projection, atol=1e-8)
    # other samples may pivot on other columns, but the identifiable combinations span the same space
    assert from_dyn.n_base == from_samples.n_base == _rank(y)
    assert np.linalg.matrix_rank(np.vstack([from_dyn.projection, from_samples.projection]), tol=1e-8) == _rank(y)
    with pytest.raises(jaxskid.RequestError, match="n_dof"):
        jaxskid.base_parameters(lambda q, qd, qdd: dyn.regressor(q, qd, qdd))
    with pytest.raises(jaxskid.ShapeError, match="expected a regressor"):
        jaxskid.base_parameters(np.zeros(5))
