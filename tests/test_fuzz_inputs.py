"""Fuzzed bad inputs (hypothesis): every parameter value and every URDF inertia that no rigid body has gets a
clear error of its exact type naming the parameter, or the file and link, and everything else runs.

What is impossible is decided here from the definitions, independently of jaxskid's checks: a value that is
not a number, NaN or inf; a negative mass; no mass with a first moment ``m c``; a rotational inertia about the
centre of mass ``I_C = I_O + S(h) S(h) / m`` (``h = m c``, ``S`` the cross-product matrix) that is not positive
semi-definite. For URDFs, which give ``I_C`` directly: a negative mass or moment is refused, and zero mass with
a rotational inertia or principal moments that break the triangle inequality warn (the loader's documented
choice: published robots carry them, and every algorithm runs).
"""

import math
import warnings

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxskid
from helpers import URDFS

FUZZ = settings(max_examples=80, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
BAD_VALUES = st.one_of(
    st.floats(max_value=0.0), st.just(0.0), st.just(-0.0), st.just(float("nan")), st.just(float("inf")),
    st.just(-float("inf")), st.text(max_size=5), st.none(), st.floats(min_value=-1e3, max_value=1e3),
)
STANDARD = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


@pytest.fixture(scope="module")
def ur5():
    return jaxskid.lower(jaxskid.load(URDFS["ur5"]), ["mass_matrix"])


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def impossible(values: dict) -> str | None:
    """What a body's standard parameters ``{suffix: value}`` (about its link's origin) break, or None; ``"?"``
    within a relative 1e-6 of the boundary (either answer is right there)."""
    m, h = values["m"], np.array([values[k] for k in ("mcx", "mcy", "mcz")])
    xx, xy, yy, xz, yz, zz = (values[k] for k in STANDARD[4:])
    about_origin = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    if m < 0:
        return "mass"
    if m == 0 and np.any(h != 0):
        return "first moment"
    about_com = about_origin + (_skew(h) @ _skew(h) / m if m > 0 else 0)
    low, scale = np.linalg.eigvalsh(about_com)[0], np.abs(about_origin).max()
    if abs(low) <= 1e-6 * max(scale, 1e-12):
        return "?"
    return "inertia" if low < 0 else None


@FUZZ
@given(data=st.data())
def test_fuzzed_parameter_values_get_a_named_error_exactly_when_impossible(ur5, data):
    """One parameter of the UR5 given a negative, zero, NaN, infinite, string, None or random value: InputError
    naming the parameter where the value is not a finite number or makes its body impossible, else a finite
    symmetric M."""
    masses = [n for n in ur5.parameters if n.endswith("_m")]
    name = data.draw(st.one_of(st.sampled_from(masses), st.sampled_from(ur5.parameters)))
    value = data.draw(BAD_VALUES)
    body, suffix = name.rsplit("_", 1)
    q = np.linspace(-1.0, 1.0, ur5.n_dof)
    if not isinstance(value, float) or not math.isfinite(value):
        what = "expected a number" if not isinstance(value, float) else f"{name} is {value}"
        with pytest.raises(jaxskid.InputError, match=rf"^params: {name}\b.*{what}|^params: {name} is"):
            ur5.mass_matrix(q, params={name: value})
        return
    values = {k: ur5.defaults[f"{body}_{k}"] for k in STANDARD} | {suffix: value}
    broken = impossible(values)
    if broken == "?":
        return
    if broken is None:
        m = np.asarray(ur5.mass_matrix(q, params={name: value}))
        assert np.isfinite(m).all() and np.allclose(m, m.T)
        return
    with pytest.raises(jaxskid.InputError) as err:
        ur5.mass_matrix(q, params={name: value})
    message = str(err.value)
    assert message.startswith("params: ") and name in message and f"'{body}'" in message, message


def test_no_mass_with_a_first_moment_names_the_body(ur5):
    """The forearm's centre of mass is off its origin (its URDF's <inertial><origin>): with m = 0 its first
    moment m c stays that of the defaults, which no body without mass has."""
    h = [ur5.defaults[f"forearm_link_{k}"] for k in ("mcx", "mcy", "mcz")]
    assert impossible({k: ur5.defaults[f"forearm_link_{k}"] for k in STANDARD} | {"m": 0.0}) == "first moment"
    assert np.abs(h).max() > 0
    with pytest.raises(jaxskid.InputError, match=r"^params: forearm_link_m, .* give body 'forearm_link' the mass 0 "
                                                 r"with a first moment of mass"):
        ur5.mass_matrix(np.zeros(ur5.n_dof), params={"forearm_link_m": 0.0})


TWO_LINKS = """<robot name="two">
  <link name="base"/>
  <link name="a"><inertial><origin xyz="0 0 0.1"/><mass value="{ma}"/>
    <inertia ixx="{a0}" ixy="0" ixz="0" iyy="{a1}" iyz="0" izz="{a2}"/></inertial></link>
  <link name="b"><inertial><origin xyz="{cb} 0 0"/><mass value="{mb}"/>
    <inertia ixx="{b0}" ixy="0" ixz="0" iyy="{b1}" iyz="0" izz="{b2}"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="3"/></joint>
</robot>"""
MOMENT = st.sampled_from([0.0, 0.0, 1e-3, 0.01, 0.1, -0.01])


def link_state(mass: float, moments: tuple) -> str:
    """``"refused"`` (negative mass or moment), ``"warned"`` (zero mass with moments, or the triangle inequality
    broken, except by a planar model's single moment), ``"massless"`` or ``"fine"``: a link's ``<inertial>``
    (diagonal ``I_C``) judged by the definitions."""
    i = np.asarray(moments)
    if mass < 0 or (i < 0).any():
        return "refused"
    if mass == 0:
        return "warned" if (i > 0).any() else "massless"
    if np.count_nonzero(i) == 1:  # the moment about one axis only: a planar model, let be (documented)
        return "fine"
    return "warned" if any(i[k] > i[(k + 1) % 3] + i[(k + 2) % 3] + 1e-12 for k in range(3)) else "fine"


@FUZZ
@given(ma=st.sampled_from([0.0, 1.0, -1.0]), mb=st.sampled_from([0.0, 0.5, -0.5]),
       cb=st.sampled_from([0.0, 0.3]), a=st.tuples(MOMENT, MOMENT, MOMENT), b=st.tuples(MOMENT, MOMENT, MOMENT))
def test_fuzzed_urdf_inertias_get_a_named_error_or_warning(tmp_path_factory, ma, mb, cb, a, b):
    """Zero, negative or inconsistent masses and moments on a two-link arm: a negative one is a ModelError naming
    the file and the link; an inconsistent one loads with a PhysicalConsistencyWarning naming the file and the
    link; a joint that moves no inertia is a ModelError naming the file, link and joint (every body massless: naming
    them all); a robot that loads has a mass matrix that Pinocchio finds positive definite."""
    path = tmp_path_factory.mktemp("fuzz") / "two.urdf"
    path.write_text(TWO_LINKS.format(ma=ma, mb=mb, cb=cb, a0=a[0], a1=a[1], a2=a[2], b0=b[0], b1=b[1], b2=b[2]))
    states = {"a": link_state(ma, a), "b": link_state(mb, b)}
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always", jaxskid.PhysicalConsistencyWarning)
        try:
            jaxskid.load(path)
        except jaxskid.ModelError as err:
            message = str(err)
            assert message.startswith(str(path)), message
            named = [k for k in states if f"'{k}'" in message or f"name={k}]" in message]
            assert named, message
            if "refused" in states.values():
                assert states[named[0]] == "refused", (states, message)
            elif set(states.values()) == {"massless"}:  # nothing moves any inertia
                assert "every body ('a', 'b') has zero mass and zero inertia" in message, message
            else:  # a joint whose subtree carries no inertia along its axis
                assert "joint 'j" in message and "lock" in message, message
            return
    assert "refused" not in states.values(), states
    warned = [str(w.message) for w in record if issubclass(w.category, jaxskid.PhysicalConsistencyWarning)]
    for link, state in states.items():
        said = [w for w in warned if str(path) in w and f"'{link}'" in w]
        assert bool(said) == (state == "warned"), (link, state, warned)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    for q in np.random.default_rng(0).uniform(-3, 3, (5, 2)):
        m = pin.crba(model, data, q)
        m = np.triu(m) + np.triu(m, 1).T
        assert np.linalg.eigvalsh(m)[0] > 0, (ma, mb, a, b, q)
