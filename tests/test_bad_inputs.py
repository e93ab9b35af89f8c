"""The corpus of malformed descriptions in tests/data/bad/: one clear ModelError each, and exit code 1 from the CLI.

Every file differs from a valid description (a 2-DOF arm in YAML, a two-link URDF) in one thing. Loading it must
raise a single :class:`jaxskid.ModelError` whose message is one line ``"<file>: <key path>: <what was expected>"``,
with no exception of sympy, jax, yourdfpy, lxml or PyYAML chained to it (a chained exception prints its own
traceback under ours). This corpus complements the generated cases of test_yaml.py and test_urdf.py with files on
disk, JSON, ``.yml``, non-UTF-8 bytes and URDF variants.
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

import jaxskid
from jaxskid import JaxskidError, ModelError

BAD = Path(__file__).parent / "data" / "bad"

# file -> (key path or None for the whole file, part of the message)
CASES = {
    # ---- YAML / JSON: missing keys
    "missing_joint_screw_coord.yaml": ("joint_screw_coord", "required key is missing"),
    "missing_gravity.yml": ("gravity", "required key is missing"),
    "missing_mass_key.yaml": ("mass_inertia[1].mass", "required key is missing"),
    "missing_screw_axis.yaml": ("joint_screw_coord[0].axis", "required key is missing"),
    # wrong types
    "wrong_type_screws_mapping.yaml": ("joint_screw_coord", "expected a non-empty list (one entry per joint), got a mapping"),
    "wrong_type_gravity_string.yaml": ("gravity", "expected a list of 3 values, got the string 'down'"),
    "wrong_type_mass_list.yaml": ("mass_inertia[0].mass", "expected a number or an expression, got a list of 2 items"),
    "wrong_type_parent_float.yaml": ("parent[1]", "expected a body index in 0..2 (0 is the world), got the number 1.5"),
    "wrong_type_boolean_com.yaml": ("mass_inertia[0].com[1]", "expected a number or an expression, got true"),
    "top_level_list.json": (None, "expected a mapping of keys at the top level, got a list of 1 item"),
    # wrong sizes
    "wrong_size_screw.yaml": ("joint_screw_coord[0]", "expected 6 values, got 5"),
    "wrong_size_pose_row.yaml": ("body_ref_config[0][2]", "expected 4 values, got 3"),
    "wrong_size_mass_inertia_rows.yaml": ("mass_inertia[0]", "expected a 6x6 matrix with 6 rows, got 5 rows"),
    "wrong_size_body_count.yaml": ("body_ref_config", "expected 2 entries (one per joint in joint_screw_coord), got 1"),
    "wrong_size_gravity.yaml": ("gravity", "expected 3 values, got 2"),
    # NaN and inf
    "nan_mass.yaml": ("mass_inertia[0].mass", "expected a finite value, got nan"),
    "inf_com.yaml": ("mass_inertia[0].com[1]", "expected a finite value, got inf"),
    "nan_string_pose.yaml": ("body_ref_config[0].translation[2]", "expected a finite value, got 'nan'"),
    "inf_expression.yaml": ("body_ref_config[0].translation[2]", "expected a finite value, got '1/0'"),
    "json_infinity.json": ("mass_inertia[0].mass", "expected a finite value, got inf"),
    "json_nan_screw.json": ("joint_screw_coord[0][2]", "expected a finite value, got nan"),
    # masses and inertias
    "negative_mass_6x6.yaml": ("mass_inertia[0]", "expected a non-negative mass (entry [5][5]), got -2"),
    "assignment_of_assignment.yaml": ("assignments.m2", "expected a number, got 'm1/2', which depends on m1"),
    "negative_mass_assignment.yaml": ("mass_inertia[1].mass", "expected a non-negative mass, got -0.8"),
    "inertia_not_positive_definite.yaml": ("mass_inertia[0]", "expected a positive definite rotational inertia"),
    "inertia_not_symmetric.yaml": ("mass_inertia[0].inertia", "expected a symmetric 3x3 inertia"),
    # screws and poses
    "non_unit_screw_axis.yaml": ("joint_screw_coord[0]", "expected a unit rotation axis omega, got norm 2"),
    "non_unit_prismatic_axis.yaml": ("joint_screw_coord[1]", "expected a unit translation axis"),
    "non_unit_axis_mapping.yaml": ("joint_screw_coord[0].axis", "expected a unit axis, got norm 1.41421"),
    "zero_screw.yaml": ("joint_screw_coord[1]", "got norm 0"),
    "helical_screw.yaml": ("joint_screw_coord[0]", "(a helical joint)"),
    "unknown_joint_type.yaml": ("joint_screw_coord[0].type", "unknown joint type 'spherical'; expected revolute or prismatic"),
    "rotation_not_orthonormal.yaml": ("body_ref_config[0].rotation", "expected a rotation matrix (orthonormal, determinant +1)"),
    "quaternion_not_unit.yaml": ("body_ref_config[0].rotation.Q", "expected a unit quaternion"),
    "pose_last_row.yaml": ("body_ref_config[0][3]", "expected the last row of a pose to be [0, 0, 0, 1]"),
    # the tree
    "parent_cycle.yaml": ("parent", "the parent indices form a cycle: body 1 -> body 2 -> body 1"),
    "parent_forward_reference.yaml": ("parent[0]", "body 1's parent is body 2, which comes after it"),
    "parent_out_of_range.yaml": ("parent[1]", "expected a body index in 0..2 (0 is the world), got the number 5"),
    "support_disagrees.yaml": ("support[1]", "expected [1, 2] (the bodies from the root to body 2 given by parent)"),
    # names and keys
    "duplicate_joint_name.yaml": ("joint_names[1]", "duplicate name 'shoulder' (also joint_names[0])"),
    "duplicate_link_name.yaml": ("link_names[1]", "duplicate name 'arm' (also link_names[0])"),
    "duplicate_key.yaml": (None, "line 13, column 1: invalid YAML: duplicate key 'gravity'"),
    "duplicate_key.json": (None, "invalid JSON: duplicate key 'gravity'"),
    "unknown_key.yaml": (None, "unknown key 'joint_screw_coords'; expected one of joint_screw_coord,"),
    # expressions
    "unknown_function.yaml": ("body_ref_config[0].translation[2]", "unknown function 'height' in 'height(l1)'"),
    "code_injection.yaml": ("body_ref_config[0].translation[2]", "expected an arithmetic expression of numbers and parameter names"),
    "unsupported_function.yaml": ("mass_inertia[0].mass", "unsupported function 'Max' in 'Max(m1, 1)'; expressions"),
    "unsupported_term.yaml": ("gravity[2]", "unsupported term 'Integral' in '-Integral(g, g)'"),
    "power_tower.yaml": ("mass_inertia[0].mass", "got '10**10**10' (beyond the range of a double)"),
    "exponential_tower.yaml": ("mass_inertia[1].mass", "got 'exp(exp(exp(100)))' (beyond the range of a double)"),
    "not_real_at_defaults.yaml": ("mass_inertia[0]", "expected finite real values at the parameters' defaults"),
    "subnormal_mass.yaml": ("mass_inertia[1].mass", "expected a mass of 0 or at least 1e-30 (check the units)"),
    # syntax, empty and binary files
    "broken_indentation.yaml": (None, "line 4, column 2: invalid YAML"),
    "broken_trailing_comma.json": (None, "line 3, column 44: invalid JSON"),
    "empty.yaml": (None, "the file is empty; expected a robot description"),
    "whitespace_only.yml": (None, "the file is empty; expected a robot description"),
    "empty.json": (None, "the file is empty; expected a robot description"),
    "binary.yaml": (None, "expected a text file (YAML or JSON), found binary data"),
    "binary.json": (None, "expected a text file (YAML or JSON), found binary data"),
    "latin1.yaml": (None, "expected UTF-8 text, found an invalid byte at offset 10"),
    "nested_too_deep.yaml": (None, "nested too deeply to read"),
    "tag_not_a_value.yaml": (None, "invalid YAML: a value its tag cannot be made of"),
    # ---- URDF
    "urdf_inertial_without_mass.urdf": ("link[name=l2].inertial.mass", 'expected a <mass value="..."/> element'),
    "urdf_inertial_without_inertia.urdf": ("link[name=l1].inertial.inertia", "expected an <inertia ixx="),
    "urdf_inertia_missing_attribute.urdf": ("link[name=l1].inertial.inertia.iyz", "expected a number, got nothing"),
    "urdf_negative_inertia.urdf": ("link[name=l1].inertial.inertia", "expected a positive semi-definite inertia"),
    "urdf_mass_overflow.urdf": ("link[name=l1].inertial.mass", "expected a finite number, got '1e400'"),
    "urdf_negative_mass.urdf": ("link[name=l2].inertial.mass", "expected a non-negative mass, got -1"),
    "urdf_unknown_parent_link.urdf": ("joint[name=j2].parent", "expected the name of a link, got 'l_one'"),
    "urdf_no_joint_parent.urdf": ("joint[name=j1].parent", 'expected a <parent link="..."/> element'),
    "urdf_two_roots.urdf": ("robot", "expected exactly one root link (a link that is no joint's child), got 2: base, tool_base"),
    "urdf_joint_to_itself.urdf": ("joint[name=j2].child", "expected each link to have one parent joint"),
    "urdf_duplicate_link.urdf": ("link[name=l1].name", "expected unique link names, got 'l1' twice"),
    "urdf_broken_unclosed_tag.urdf": (None, "expected well-formed XML, got a syntax error at line 12"),
    "urdf_broken_attribute.urdf": (None, "expected well-formed XML, got a syntax error at line 4"),
    "urdf_floating_joint.urdf": ("joint[name=j2].type", "got unsupported type 'floating' below the root"),
    "urdf_planar_joint.urdf": ("joint[name=j2].type", "got unsupported type 'planar' (trees of revolute"),
    "urdf_unknown_joint_type.urdf": ("joint[name=j1].type", "expected one of revolute, continuous, prismatic, fixed, got unknown type 'ball'"),
    "urdf_axis_nan.urdf": ("joint[name=j1].axis", "expected finite numbers, got '0 nan 1'"),
    "urdf_origin_four_values.urdf": ("joint[name=j1].origin.xyz", "expected 3 numbers, got '0 0 0.1 0'"),
    "urdf_xacro_expression.urdf": ("joint[name=j1].origin.xyz", "expected 3 numbers, got '${length} 0 0'"),
    "urdf_limit_not_a_number.urdf": ("joint[name=j1].limit.effort", "expected a number, got 'lots'"),
    "urdf_number_with_underscore.urdf": ("link[name=arm].inertial.mass", "expected a number, got '1_0'"),
    "urdf_number_in_another_script.urdf": ("link[name=arm].inertial.mass", "expected a number, got '\u0661'"),
    "urdf_com_beyond_any_unit.urdf": ("link[name=arm].inertial.origin.xyz", "expected magnitudes of at most 1e+30"),
    "urdf_rod_along_its_axis.urdf": ("link 'rod' <inertial>", "('rod': no mass off the axis and no moment of inertia"),
    "urdf_coaxial_joints_massless_link.urdf": (None, "the mass matrix is singular in every configuration tried: "
                                                     "'j0' and 'j1' can move together"),
    "urdf_massless_floating_base.urdf": (None, "singular in every configuration tried: the floating base and 'j1'"),
    "sdf_root.urdf": ("robot", "expected the root element <robot>, got <sdf>"),
    "empty.urdf": (None, "expected a URDF (XML) document, got an empty file"),
    "binary.urdf": (None, "expected a URDF (XML) text file, got binary data"),
}
LIBRARIES = ("sympy", "jax", "jaxlib", "yourdfpy", "lxml", "yaml", "numpy", "trimesh")


def test_the_corpus_is_complete():
    on_disk = {p.name for p in BAD.iterdir()}
    assert len(CASES) >= 40
    warned = {"urdf_mimic.urdf", "urdf_mimic_unknown_joint.urdf"}  # loaded with a warning (test_urdf_repairs.py)
    assert on_disk == set(CASES) | warned, "every file of the corpus has an expectation here"


def _chain(err: BaseException):
    """The exceptions Python prints under ``err``: its cause, or its context unless suppressed."""
    out, seen = [], {id(err)}
    while True:
        nxt = err.__cause__ if err.__cause__ is not None else (None if err.__suppress_context__ else err.__context__)
        if nxt is None or id(nxt) in seen:
            return out
        out.append(nxt)
        seen.add(id(nxt))
        err = nxt


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_file_gives_one_clear_model_error(name):
    path = BAD / name
    where, message = CASES[name]
    with pytest.raises(JaxskidError) as info:
        jaxskid.load(path)
    err = info.value
    assert type(err) is ModelError
    assert err.source == str(path)
    assert err.where == where
    assert message in err.message
    text = str(err)
    assert text == f"{path}: {where}: {err.message}" if where else text == f"{path}: {err.message}"
    assert "\n" not in text and "Traceback" not in text
    for chained in _chain(err):  # nothing from a library prints a traceback under ours
        module = type(chained).__module__.split(".")[0]
        assert module not in LIBRARIES, f"{name}: {type(chained).__module__}.{type(chained).__name__} is chained"
        assert module == "builtins" or isinstance(chained, JaxskidError)


def test_mimic_joint_is_read_as_independent_with_a_warning_naming_file_and_joint():
    path = BAD / "urdf_mimic.urdf"
    with pytest.warns(jaxskid.DescriptionWarning) as record:
        robot = jaxskid.load(path)
    assert robot.joint_names == ("j1", "j2") and robot.n_dof == 2  # as Pinocchio's default (mimic=False)
    warnings = [str(w.message) for w in record if issubclass(w.category, jaxskid.DescriptionWarning)]
    assert len(warnings) == 1
    assert warnings[0].startswith(f"{path}: joint[name=j2].mimic: ")
    assert "'j1'" in warnings[0] and "mimic=True" in warnings[0]


SAMPLE = ["missing_gravity.yml", "json_nan_screw.json", "binary.yaml",
          "urdf_inertial_without_mass.urdf", "urdf_two_roots.urdf", "empty.urdf", "latin1.yaml"]


@pytest.mark.slow
def test_cli_exits_with_code_1_and_one_line():
    script = Path(sysconfig.get_path("scripts")) / "jaxskid"
    command = [str(script)] if script.exists() else [sys.executable, "-m", "jaxskid._cli"]
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    procs = {name: subprocess.Popen([*command, "info", str(BAD / name)], stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True, env=env)
             for name in SAMPLE}
    for name, proc in procs.items():
        out, err = proc.communicate(timeout=300)
        where, message = CASES[name]
        assert proc.returncode == 1, (name, proc.returncode, err[-800:])
        assert out == ""
        lines = err.strip().splitlines()
        assert len(lines) == 1, (name, err)
        expected = f"Error: {BAD / name}: {where + ': ' if where else ''}"
        assert lines[0].startswith(expected), (name, lines[0])
        assert message in lines[0]
