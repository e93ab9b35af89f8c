"""Skidy's end-effector wrenches (WEE, WDEE, W2DEE) and their conversion to jaxskid's convention.

Skidy applies WEE at the origin of the end-effector's parent body, in that body's frame: Q_ext = J_p^T W.
jaxskid's ``wrench`` acts at the end-effector frame. The converted wrenches of :func:`jaxskid.read_extras`,
passed to jaxskid's ``external_torques``, must give Skidy's J_p^T W, written out here by hand for a planar
2R arm whose end-effectors sit away from their parent bodies (turned and shifted).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import jaxskid
from jaxskid import symbol
from jaxskid.description._yaml_schema import parse_description, parse_extras

L1 = 0.4
WRENCH_NAMES = ("Mx", "My", "Mz", "Fx", "Fy", "Fz")
# two end-effectors: "grip" on body 2, turned (rpy) and shifted off the link; "probe" on body 1
EES = {
    "ee": [{"rotation": {"rpy": [0.3, -0.5, 0.7]}, "translation": [0.3, 0.1, -0.05]},
           {"rotation": {"axis": [1, 0, 0], "angle": "pi/2"}, "translation": [0.2, 0, 0.1]}],
    "ee_parent": [2, 1],
    "ee_names": ["grip", "probe"],
}


def arm(representation: str, **extra) -> dict:
    """A planar 2R arm about z: body 1 at the shoulder (the world origin), body 2 at the elbow (L1, 0, 0)."""
    if representation == "body_fixed":
        screws = [[0, 0, 1, 0, 0, 0]] * 2
    else:  # spatial: the elbow's axis passes through (L1, 0, 0) at q = 0
        screws = [[0, 0, 1, 0, 0, 0], {"type": "revolute", "axis": [0, 0, 1], "vec": [L1, 0, 0]}]
    poses = [{}, {"translation": [L1, 0, 0]}]  # the same in both: body 1 is the world frame at q = 0
    return {"representation": representation, "gravity": [0, -9.81, 0], "joint_screw_coord": screws,
            "body_ref_config": poses, "mass_inertia": [{"mass": 1, "inertia": 0.1}] * 2, **EES, **extra}


def skidy_generalized_forces(q, w_grip, w_probe) -> np.ndarray:
    """Skidy's Q_ext = J_2^T W_grip + J_1^T W_probe, with each wrench (moment, force) at its parent body's
    origin in that body's frame. Body Jacobians (twist (omega, v) of the body in its own frame):
    body 1 turns about its own origin, J_1 = [e_z; 0] for q1; body 2's origin, the elbow, moves with
    q1 at l1 (-sin q1, cos q1, 0) in the world, which is l1 (sin q2, cos q2, 0) in body 2's axes."""
    _, q2 = q  # body 2's Jacobian in its own frame depends on the relative angle only
    j2 = np.array([[0, 0], [0, 0], [1, 1], [L1 * np.sin(q2), 0], [L1 * np.cos(q2), 0], [0, 0]])
    j1 = np.array([[0, 0], [0, 0], [1, 0], [0, 0], [0, 0], [0, 0]])
    return j2.T @ np.asarray(w_grip, float) + j1.T @ np.asarray(w_probe, float)


@pytest.mark.parametrize("representation", ["body_fixed", "spatial"])
def test_converted_wee_gives_skidys_jacobian_transpose_wrench(representation):
    w_grip = [0.3, -1.2, 0.5, 2.0, -0.7, 1.1]
    w_probe = [-0.4, 0.9, 1.3, -0.6, 0.8, -1.5]
    extras = parse_extras(arm(representation, WEE=[w_grip, w_probe]), source="arm.yaml")
    assert extras.end_effectors == ("grip", "probe")
    np.testing.assert_array_equal(np.array(extras.wrench_skidy, dtype=float), [w_grip, w_probe])
    robot = parse_description(arm(representation), source="arm.yaml")
    dyn = jaxskid.lower(robot, ["external_torques"])
    wrench = np.array(extras.wrench, dtype=float)
    assert not np.allclose(wrench, [w_grip, w_probe])  # the offsets do change the wrenches
    qs = np.random.default_rng(0).uniform(-np.pi, np.pi, (16, 2))
    got = np.asarray(dyn.external_torques(qs, np.broadcast_to(wrench, (16, 2, 6))))
    expected = np.stack([skidy_generalized_forces(q, w_grip, w_probe) for q in qs])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)


def test_symbolic_wee_and_its_derivatives_convert_by_hand():
    """One symbolic wrench for both end-effectors (Skidy broadcasts it), and its time derivatives.

    For "probe" (R = Rx(pi/2), p = (0.2, 0, 0.1)) the conversion W_e = (R^T (n - p x f), R^T f) by hand:
    p x f = (-0.1 Fy, 0.1 Fx - 0.2 Fz, 0.2 Fy), and R^T (a, b, c) = (a, c, -b)."""
    mx, my, mz, fx, fy, fz = w = [symbol(s) for s in WRENCH_NAMES]
    d = [symbol("d" + s) for s in WRENCH_NAMES]
    extras = parse_extras(arm("body_fixed", WEE=list(WRENCH_NAMES), WDEE=["d" + s for s in WRENCH_NAMES]),
                          source="arm.yaml")
    assert extras.wrench_skidy == (tuple(w),) * 2 and extras.wrench_d_skidy == (tuple(d),) * 2
    tenth, fifth = sp.Rational(1, 10), sp.Rational(1, 5)
    n = [mx + tenth * fy, my - tenth * fx + fifth * fz, mz - fifth * fy]
    by_hand = [n[0], n[2], -n[1], fx, fz, -fy]
    assert sp.simplify(sp.Matrix(extras.wrench[1]) - sp.Matrix(by_hand)).is_zero_matrix
    at_d = {a: b for a, b in zip(w, d)}
    assert sp.simplify(sp.Matrix(extras.wrench_d[1]) - sp.Matrix(by_hand).xreplace(at_d)).is_zero_matrix
    assert extras.wrench_2d == ((0,) * 6,) * 2  # absent: zeros
    # the symbolic conversion, evaluated, against Skidy's J^T W through jaxskid's external_torques
    robot = parse_description(arm("body_fixed"), source="arm.yaml")
    dyn = jaxskid.lower(robot, ["external_torques"])
    rng = np.random.default_rng(1)
    for _ in range(3):
        values = dict(zip(w, rng.normal(size=6)))
        wrench = np.array([[float(e.xreplace(values)) for e in row] for row in extras.wrench])
        q = rng.uniform(-np.pi, np.pi, 2)
        raw = [values[s] for s in w]
        np.testing.assert_allclose(np.asarray(dyn.external_torques(q, wrench)),
                                   skidy_generalized_forces(q, raw, raw), rtol=0, atol=1e-12)


def test_wee_on_an_end_effector_at_its_parents_origin_is_unchanged():
    d = arm("body_fixed", WEE=["Mx", 0, 0, "Fx", 0, 0])
    d.update(ee={"translation": [0, 0, 0]}, ee_parent=2, ee_names=["tip"])
    extras = parse_extras(d, source="arm.yaml")
    assert extras.wrench == extras.wrench_skidy == ((symbol("Mx"), 0, 0, symbol("Fx"), 0, 0),)


def test_converted_wee_holds_when_the_parent_body_is_locked_away():
    """Locking the elbow merges body 2 into body 1; the end-effector frames, and so the converted wrenches,
    are the same, and jaxskid's external_torques is the first row of Skidy's J^T W at that elbow angle."""
    w_grip = [0.3, -1.2, 0.5, 2.0, -0.7, 1.1]
    w_probe = [-0.4, 0.9, 1.3, -0.6, 0.8, -1.5]
    extras = parse_extras(arm("body_fixed", WEE=[w_grip, w_probe]), source="arm.yaml")
    robot = parse_description(arm("body_fixed"), source="arm.yaml", lock={"q2": 0.6})
    assert robot.n_dof == 1 and robot.end_effectors == extras.end_effectors
    dyn = jaxskid.lower(robot, ["external_torques"])
    wrench = np.array(extras.wrench, dtype=float)
    for q1 in (-2.0, 0.3, 1.4):
        expected = skidy_generalized_forces([q1, 0.6], w_grip, w_probe)[:1]
        np.testing.assert_allclose(np.asarray(dyn.external_torques(np.array([q1]), wrench)), expected,
                                   rtol=0, atol=1e-12)
