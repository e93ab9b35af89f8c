"""The installed ``jaxskid`` command, run as a subprocess: help, every subcommand, bad usage (exit 2), bad
input (exit 1), one-line errors and the refusal to overwrite files.

Numbers are checked against independent references: templates and converted models against Pinocchio
(``pinref.to_pinocchio``) or against the source model's own lowering, generated code against
``jaxskid.lower``.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
import yaml

import jaxskid
from helpers import ERD, PANDA, URDFS, pinocchio_urdf_model
from pinref import to_pinocchio

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "robots" / "arm_2r.yaml"
LEG = ROOT / "robots" / "hopping_leg.yaml"
LEG_URDF = ROOT / "tests" / "data" / "urdf" / "hopping_leg.urdf"
RIGHT_ANGLES = ROOT / "tests" / "data" / "urdf" / "right_angles.urdf"  # rpy pi/2, pi/4, pi/6; 0.0825, 0.107
COMMANDS = ("generate", "template", "convert", "info", "graph")


def _exe() -> str:
    exe = shutil.which("jaxskid")
    assert exe, "the jaxskid console script is not installed (pip install -e .)"
    return exe


def jaxskid_cmd(*args, cwd=None, check_rc=None):
    proc = subprocess.run([_exe(), *map(str, args)], capture_output=True, text=True, cwd=cwd)
    if check_rc is not None:
        assert proc.returncode == check_rc, f"rc={proc.returncode}\nstdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    return proc


def jaxskid_many(*commands) -> list[subprocess.CompletedProcess]:
    """Run several independent commands at once (each start imports JAX, which takes a few seconds)."""
    procs = [subprocess.Popen([_exe(), *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for args in commands]
    done = []
    for args, proc in zip(commands, procs):
        out, err = proc.communicate(timeout=600)
        done.append(subprocess.CompletedProcess(args, proc.returncode, out, err))
    return done


def one_line_error(proc, rc: int, *fragments: str) -> str:
    assert proc.returncode == rc, f"rc={proc.returncode}, expected {rc}\n{proc.stderr}"
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got:\n{proc.stderr}"
    assert "Traceback" not in proc.stderr and lines[0].startswith("Error: ")
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    return lines[0]


def raw(dyn, name, *state):
    """The lowered JAX function, op by op (no jit compile: ``dyn.raw`` is jitted, so jit is turned off)."""
    with jax.disable_jit():
        return np.asarray(dyn.raw(name)(*(jnp.asarray(s) for s in state), dyn.param_vector()))


def pinocchio_dynamics(robot, q, qd, qdd):
    model, _ = to_pinocchio(robot, robot.default_params())
    data = model.createData()
    m = pin.crba(model, data, q)
    return np.triu(m) + np.triu(m, 1).T, pin.rnea(model, data, q, qd, qdd)


# ------------------------------------------------------------------------------------------ help
def test_help_lists_commands_with_examples():
    top, version, *subs = jaxskid_many(["--help"], ["--version"], *([name, "--help"] for name in COMMANDS))
    assert top.returncode == 0
    for name in COMMANDS:
        assert name in top.stdout
    assert "Examples" in top.stdout
    for name, sub in zip(COMMANDS, subs):
        assert sub.returncode == 0, sub.stderr
        assert f"Usage: jaxskid {name}" in sub.stdout and "Examples:" in sub.stdout
    assert version.returncode == 0 and jaxskid.__version__ in version.stdout


# ------------------------------------------------------------------------------------------ template
@pytest.mark.parametrize("ext", ["yaml", "json", "py"])
def test_template_loads_derives_and_lowers_unedited(tmp_path, ext):
    path = tmp_path / f"rrp_arm.{ext}"
    proc = jaxskid_cmd("template", "-S", "RRP", path, check_rc=0)
    assert path.exists() and "RRP" in proc.stdout
    if ext == "py":
        run = subprocess.run([sys.executable, str(path)], capture_output=True, text=True, cwd=tmp_path)
        assert run.returncode == 0, run.stderr
        assert "M(0) =" in run.stdout
        spec = importlib.util.spec_from_file_location("rrp_template", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        robot = module.robot
        info = jaxskid_cmd("info", path, check_rc=0)
        assert "joint3" in info.stdout and "prismatic" in info.stdout
    else:
        robot = jaxskid.load(path)
        if ext == "json":
            assert json.loads(path.read_text())["name"] == "rrp_arm"
    assert robot.name == "rrp_arm" and robot.joint_types == ("revolute", "revolute", "prismatic")
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, qd, qdd = rng.uniform(-2, 2, (3, 3))
        m_ref, tau_ref = pinocchio_dynamics(robot, q, qd, qdd)
        np.testing.assert_allclose(raw(dyn, "mass_matrix", q), m_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(raw(dyn, "inverse_dynamics", q, qd, qdd), tau_ref, rtol=1e-12, atol=1e-12)


def test_template_refuses_to_overwrite_and_checks_usage(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text("mine")
    refused, bad_letters, bad_suffix, no_structure = jaxskid_many(
        ["template", "-S", "RRR", path], ["template", "-S", "RXP", tmp_path / "x.yaml"],
        ["template", "-S", "RR", tmp_path / "x.txt"], ["template", tmp_path / "x.yaml"])
    one_line_error(refused, 1, "already exists", "--force")
    assert path.read_text() == "mine"
    one_line_error(bad_letters, 2, "R and P")
    one_line_error(bad_suffix, 2, ".yaml")
    one_line_error(no_structure, 2, "--structure")
    jaxskid_cmd("template", "-S", "RRR", path, "--force", check_rc=0)
    assert jaxskid.load(path).n_dof == 3


def test_template_dof_is_a_revolute_chain_and_needs_exactly_one_source(tmp_path):
    dof, letters = tmp_path / "arm4.yaml", tmp_path / "rrrr.yaml"
    made, same, both, neither, zero, too_many, urdf_and_s, urdf_yaml = jaxskid_many(
        ["template", "--dof", 4, dof], ["template", "-S", "RRRR", letters],
        ["template", "--dof", 2, "-S", "RR", tmp_path / "x.yaml"], ["template", tmp_path / "x.yaml"],
        ["template", "--dof", 0, tmp_path / "x.yaml"], ["template", "--dof", 65, tmp_path / "x.yaml"],
        ["template", "--urdf", LEG_URDF, "-S", "R", tmp_path / "x.py"], ["template", "--urdf", LEG_URDF, tmp_path / "x.yaml"])
    assert made.returncode == 0 and same.returncode == 0, made.stderr + same.stderr
    assert "4-joint RRRR template 'arm4'" in made.stdout
    robot = jaxskid.load(dof)
    assert robot.joint_types == ("revolute",) * 4
    assert robot.renamed("rrrr") == jaxskid.load(letters)
    dyn = jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics"])
    q, qd, qdd = np.random.default_rng(5).uniform(-2, 2, (3, 4))
    m_ref, tau_ref = pinocchio_dynamics(robot, q, qd, qdd)
    np.testing.assert_allclose(raw(dyn, "mass_matrix", q), m_ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(raw(dyn, "inverse_dynamics", q, qd, qdd), tau_ref, rtol=1e-12, atol=1e-12)
    one_line_error(both, 2, "exactly one of", "-S/--structure and --dof")
    one_line_error(neither, 2, "exactly one of")
    one_line_error(zero, 2, "--dof", "1<=x<=64")
    one_line_error(too_many, 2, "--dof", "1<=x<=64")
    one_line_error(urdf_and_s, 2, "exactly one of", "--urdf")
    one_line_error(urdf_yaml, 2, ".py")
    assert not (tmp_path / "x.yaml").exists() and not (tmp_path / "x.py").exists()


@pytest.mark.parametrize("urdf", [LEG_URDF, URDFS["ur5"]], ids=["hopping_leg", "ur5"])
def test_template_urdf_writes_a_script_that_loads_it(tmp_path, urdf):
    script = tmp_path / "scripts" / "robot_script.py"
    script.parent.mkdir()
    if urdf == LEG_URDF:
        (tmp_path / "urdf").mkdir()
        urdf = Path(shutil.copy(LEG_URDF, tmp_path / "urdf"))
    jaxskid_cmd("template", "--urdf", urdf, script, "--name", "my_robot", check_rc=0)
    text = script.read_text()
    if urdf.name == LEG_URDF.name:  # near the script: a relative path; far away (site-packages): an absolute one
        assert "jaxskid.load(" in text and "'../urdf/hopping_leg.urdf'" in text and str(urdf) not in text
    else:
        assert str(urdf) in text
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=ROOT / "robots")
    assert run.returncode == 0, run.stderr
    spec = importlib.util.spec_from_file_location("urdf_template", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    reference = jaxskid.load(urdf)
    assert module.robot == reference.renamed("my_robot")
    m0 = pinocchio_dynamics(reference, *np.zeros((3, reference.n_dof)))[0]
    printed = run.stdout.split("M(0) =", 1)[1]
    np.testing.assert_allclose(np.array(printed.replace("[", " ").replace("]", " ").split(), dtype=float).reshape(m0.shape),
                               m0, rtol=1e-5, atol=1e-6)  # printed as float32
    assert "my_robot" in jaxskid_cmd("info", script, check_rc=0).stdout
    one_line_error(jaxskid_cmd("template", "--urdf", urdf, script), 1, "already exists")


# ------------------------------------------------------------------------------------------ convert
def test_convert_panda_round_trip(tmp_path):
    out, rounded, symbolic = tmp_path / "panda.yaml", tmp_path / "panda_rounded.json", tmp_path / "panda_symbolic.yaml"
    procs = jaxskid_many(["convert", PANDA, out], ["convert", PANDA, rounded, "--round", "1e-10"],
                         ["convert", PANDA, symbolic, "--symbolic-inertia"], ["convert", ARM, tmp_path / "arm.json"])
    for proc in procs:
        assert proc.returncode == 0, proc.stderr
    assert "9 joint(s)" in procs[0].stdout
    data = json.loads(rounded.read_text())
    poses = data["body_ref_config"]  # rotations with angles k*pi/q as {rpy}
    assert all(isinstance(pose, dict) for pose in poses) and ["pi/2", 0, 0] in [p.get("rotation", {}).get("rpy") for p in poses]
    entries = [x for pose in poses for x in pose["translation"]]
    assert all(abs(x) > 1e-10 or x == 0 for x in entries if isinstance(x, (int, float)))
    assert 0 in entries and not any(0 < abs(x) < 1e-10 for x in entries if isinstance(x, float))
    assert "panda_link1_m" in yaml.safe_load(symbolic.read_text())["assignments"]

    names = ["mass_matrix", "gravity_torques", "inverse_dynamics"]
    reference = jaxskid.lower(jaxskid.load(PANDA, symbolic_inertia=False), names)
    rng = np.random.default_rng(11)
    states = [rng.uniform(-1.5, 1.5, (3, 9)) for _ in range(3)]
    for path in (out, rounded, symbolic):
        dyn = jaxskid.lower(jaxskid.load(path), names)
        assert dyn.joint_names == reference.joint_names
        for q, qd, qdd in states:
            for name, args in (("mass_matrix", (q,)), ("gravity_torques", (q,)), ("inverse_dynamics", (q, qd, qdd))):
                got, ref = raw(dyn, name, *args), raw(reference, name, *args)
                assert np.max(np.abs(got - ref)) <= 1e-12 * max(1.0, np.max(np.abs(ref))), (path.name, name)
    assert jaxskid.load(tmp_path / "arm.json").parameters == jaxskid.load(ARM).parameters
    exists, bad_suffix, bad_round = jaxskid_many(["convert", PANDA, out], ["convert", PANDA, tmp_path / "panda.txt"],
                                                 ["convert", PANDA, tmp_path / "p.yaml", "--round", "2"])
    one_line_error(exists, 1, "already exists")
    one_line_error(bad_suffix, 2, ".yaml")
    one_line_error(bad_round, 2, "--round")


def assert_same_dynamics(path, reference, n):
    """The robot in ``path`` has ``reference``'s M, Q_grav and tau (1e-12 relative) at random states."""
    names = ["mass_matrix", "gravity_torques", "inverse_dynamics"]
    dyn = jaxskid.lower(jaxskid.load(path), names)
    assert dyn.joint_names == reference.joint_names
    for q, qd, qdd in (np.random.default_rng(k).uniform(-2, 2, (3, n)) for k in range(3)):
        for name, args in (("mass_matrix", (q,)), ("gravity_torques", (q,)), ("inverse_dynamics", (q, qd, qdd))):
            got, ref = raw(dyn, name, *args), raw(reference, name, *args)
            assert np.max(np.abs(got - ref)) <= 1e-12 * max(1.0, np.max(np.abs(ref))), (path.name, name)


def test_convert_round_writes_fractions_and_multiples_of_pi(tmp_path):
    from jaxskid.description._yaml_writer import snap

    exact = {0.5: "1/2", 0.333333333333: "1/3", 1.5707963267948966: "pi/2", 0.7853981633974483: "pi/4",
             -2.0943951023931953: "-2*pi/3", 0.7071067811865476: "sqrt(2)/2", 6.123233995736766e-17: "0", 1.0: "1"}
    for x, text in exact.items():
        assert str(snap(x, 1e-10)) == text, x
    for x in (0.0825, 0.107, 0.33333, 1.5708, 0.7854, 9.81, 0.0001):
        assert snap(x, 1e-10) is None, x
    rounded, symbols, plain = tmp_path / "rounded.yaml", tmp_path / "symbols.yaml", tmp_path / "plain.yaml"
    for proc in jaxskid_many(["convert", RIGHT_ANGLES, rounded, "--round", "1e-10"],
                             ["convert", RIGHT_ANGLES, symbols, "--symbolify", "--round", "1e-10"],
                             ["convert", RIGHT_ANGLES, plain]):
        assert proc.returncode == 0, proc.stderr
    data = yaml.safe_load(rounded.read_text())
    assert [pose["rotation"]["rpy"] for pose in data["body_ref_config"]] == [[0, 0, "pi/2"], ["pi/4", 0, 0]]
    assert data["body_ref_config"][1]["translation"] == [0.0825, 0, "1/2"]  # 0.0825 is a measured number
    assert data["body_ref_config"][0]["translation"] == [0, 0, 0.107]
    assert data["ee"] == [{"translation": ["1/3", 0, 0], "rotation": {"rpy": [0, "pi/6", 0]}}]
    assert isinstance(yaml.safe_load(plain.read_text())["body_ref_config"][0], list)  # 4x4 matrices without --round
    reference = jaxskid.lower(jaxskid.load(RIGHT_ANGLES, symbolic_inertia=False),
                              ["mass_matrix", "gravity_torques", "inverse_dynamics"])
    for path in (rounded, symbols, plain):
        assert_same_dynamics(path, reference, 2)
    sym = yaml.safe_load(symbols.read_text())
    assert sym["body_ref_config"][1]["translation"] == ["j2_x", 0, "j2_z"]
    assert sym["assignments"]["j2_x"] == 0.0825 and sym["assignments"]["tip_x"] == 1 / 3
    assert sym["assignments"]["l1_m"] == 1.5 and len(jaxskid.load(symbols).parameters) == 4 + 2 * 10
    # against Pinocchio's own reading of the URDF
    robot = jaxskid.load(symbols)
    model, _ = to_pinocchio(robot, robot.default_params())
    pin_ref = pinocchio_urdf_model(RIGHT_ANGLES)
    q = np.array([0.4, -1.1])
    np.testing.assert_allclose(pin.crba(model, model.createData(), q), pin.crba(pin_ref, pin_ref.createData(), q),
                               rtol=1e-12, atol=1e-12)


def test_convert_symbolify_leg_and_name_clashes(tmp_path):
    out = tmp_path / "leg.json"
    jaxskid_cmd("convert", LEG_URDF, out, "--symbolify", check_rc=0)
    robot = jaxskid.load(out)
    assert all(isinstance(x, str) or x == 0 for pose in json.loads(out.read_text())["body_ref_config"]
               for x in (pose[0][3], pose[1][3], pose[2][3]))
    assert_same_dynamics(out, jaxskid.lower(jaxskid.load(LEG_URDF), ["mass_matrix", "gravity_torques",
                                                                     "inverse_dynamics"]), robot.n_dof)
    clash = tmp_path / "clash.yaml"
    clash.write_text(ARM.read_text().replace("assignments:", "assignments:\n  shoulder_x: 1.0", 1))
    data = yaml.safe_load(clash.read_text())
    data["gravity"] = [0, "-shoulder_x*g", 0]
    data["body_ref_config"][0] = [[1, 0, 0, 0.25], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    clash.write_text(yaml.safe_dump(data))
    jaxskid.load(clash)
    one_line_error(jaxskid_cmd("convert", clash, tmp_path / "c.yaml", "--symbolify"), 1, "shoulder_x", "taken")


# ------------------------------------------------------------------------------------------ info and graph
def test_info_tables_and_tree():
    proc = jaxskid_cmd("info", LEG, check_rc=0)
    text = proc.stdout
    for fragment in ("robot hopping_leg: 3 joint(s)", "rail", "prismatic", "knee", "slider", "thigh", "shank",
                     "L1", "0.205", "kinematic tree", "└── foot  (end-effector)"):
        assert fragment in text, fragment
    # the body table shows the masses at their default values
    assert any(line.split()[1:3] == ["thigh", "0.6"] for line in text.splitlines() if line.strip().startswith("2"))
    locked = jaxskid_cmd("info", LEG, "--lock", "knee=0.5", check_rc=0)
    assert "robot hopping_leg: 2 joint(s)" in locked.stdout


def test_urdf_flags_reach_the_reader():
    """--balance-inertia loads TIAGo (two antenna links with indefinite inertias), which is refused without it
    with the option named; --floating-base makes the root a free-flyer."""
    tiago = ERD / "tiago_description/robots/tiago_no_hand.urdf"
    one_line_error(jaxskid_cmd("info", tiago), 1, "base_antenna_left_link", "balance_inertia=True")
    balanced = jaxskid_cmd("info", tiago, "--balance-inertia", check_rc=0)
    assert "robot tiago: 12 joint(s)" in balanced.stdout and "base_antenna_right_link" in balanced.stderr
    floating = jaxskid_cmd("info", URDFS["solo12"], "--floating-base", check_rc=0)
    assert "floating base 'base_link'" in floating.stdout


def test_reports_are_public_functions(tmp_path):
    robot = jaxskid.load(LEG, lock={"knee": 0.5})
    text = jaxskid.describe(robot)
    assert text.startswith("robot hopping_leg: 2 joint(s)") and "shank  (frame)" in text
    jaxskid.draw_tree(robot, tmp_path / "leg.svg")
    assert "<svg" in (tmp_path / "leg.svg").read_text()


def test_graph_writes_a_picture(tmp_path):
    svg, png = tmp_path / "tree.svg", tmp_path / "tree.png"
    png.write_text("mine")
    made, refused, forced, bad = jaxskid_many(["graph", LEG, "-o", svg], ["graph", LEG, "-o", png],
                                              ["graph", PANDA, "-o", tmp_path / "panda.png", "--force"],
                                              ["graph", LEG, "-o", tmp_path / "tree.gif"])
    assert made.returncode == 0 and forced.returncode == 0, made.stderr + forced.stderr
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text and "knee" in text and "shank" in text
    assert (tmp_path / "panda.png").read_bytes().startswith(b"\x89PNG")
    one_line_error(refused, 1, "already exists")
    assert png.read_text() == "mine"
    one_line_error(bad, 2, ".svg")


# ------------------------------------------------------------------------------------------ generate
def test_generate_writes_checks_and_refuses_to_overwrite(tmp_path):
    out = tmp_path / "arm"
    proc = jaxskid_cmd("generate", ARM, "-t", "c,python", "--target", "latex", "-q", "mass_matrix,inverse_dynamics",
                       "-o", out, check_rc=0)
    text = proc.stdout
    for fragment in ("robot arm_2r", "mass_matrix", "(2, 2)", "inverse_dynamics", "derive", "lower", "compile",
                     "self-check", "M symmetric", "wrote 5 file(s)"):
        assert fragment in text, fragment
    assert "FAILED" not in text
    assert {p.name for p in out.iterdir()} == {"arm_2r.c", "arm_2r.h", "arm_2r.tex", "arm_2r.pdf", "arm_2r_numpy.py"}
    spec = importlib.util.spec_from_file_location("cli_arm_numpy", out / "arm_2r_numpy.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    dyn = jaxskid.lower(jaxskid.load(ARM), ["mass_matrix", "inverse_dynamics"])
    q, qd, qdd = np.array([0.3, -0.8]), np.array([1.0, 0.5]), np.array([-0.2, 0.7])
    np.testing.assert_allclose(module.inverse_dynamics(q, qd, qdd), raw(dyn, "inverse_dynamics", q, qd, qdd),
                               rtol=1e-12)
    (out / "arm_2r.c").write_text("edited")
    one_line_error(jaxskid_cmd("generate", ARM, "-t", "c", "-o", out), 1, "already exist", "--force")
    assert (out / "arm_2r.c").read_text() == "edited"
    jaxskid_cmd("generate", ARM, "-t", "c", "-o", out, "--force", "--no-check", check_rc=0)
    assert "arm_2r_inverse_dynamics" in (out / "arm_2r.c").read_text()


def test_generate_with_lock_and_symbolic_parameters(tmp_path):
    proc = jaxskid_cmd("generate", LEG, "-t", "python", "-q", "gravity_torques", "--lock", "knee=0.3",
                       "--symbolic", "m2,L1", "-o", tmp_path, check_rc=0)
    assert "2 joint(s), 2 symbolic parameter(s)" in proc.stdout
    spec = importlib.util.spec_from_file_location("cli_leg_numpy", tmp_path / "hopping_leg_numpy.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert set(module.PARAMETERS) == {"m2", "L1"}
    robot = jaxskid.load(LEG, lock={"knee": 0.3})
    dyn = jaxskid.lower(robot, ["gravity_torques"], symbolic=["m2", "L1"])
    assert module.PARAMETERS == dyn.parameters
    q = np.array([0.05, 0.9])
    p = np.array([{"m2": 0.5, "L1": 0.3}[k] for k in dyn.parameters])
    np.testing.assert_allclose(module.gravity_torques(q, p), np.asarray(dyn.gravity_torques(q, p)), rtol=1e-12)
    # and the model it was locked from: the locked knee at 0.3 carries the shank
    full = jaxskid.lower(jaxskid.load(LEG), ["gravity_torques"])
    np.testing.assert_allclose(module.gravity_torques(q)[1], np.asarray(full.gravity_torques(np.array([0.05, 0.9, 0.3])))[1],
                               rtol=1e-12)


C_DRIVER = """#include <stdio.h>
#include "two_link.h"
int main(void)
{
    const double q[2] = {0.3, -0.8}, qd[2] = {1.0, 0.5}, qdd[2] = {-0.2, 0.7};
    double tau[TWO_LINK_INVERSE_DYNAMICS_SIZE];
    two_link_inverse_dynamics(q, qd, qdd, two_link_default_params, tau);
    printf("%.17g %.17g\\n", tau[0], tau[1]);
    return 0;
}
"""


def test_generate_options_and_name(tmp_path):
    out = tmp_path / "named"
    proc = jaxskid_cmd("generate", ARM, "-t", "c,python", "-q", "mass_matrix,inverse_dynamics", "--name", "two_link",
                       "--simplify", "expand", "--cse", "none", "--trig", "inline", "-o", out, check_rc=0)
    assert "options: cse=none, simplify=expand, trig=inline" in proc.stdout and "FAILED" not in proc.stdout
    assert {p.name for p in out.iterdir()} == {"two_link.c", "two_link.h", "two_link_numpy.py"}
    header = (out / "two_link.h").read_text()
    assert "#ifndef JAXSKID_TWO_LINK_H" in header and "void two_link_inverse_dynamics(" in header
    exe = tmp_path / "driver"
    (tmp_path / "driver.c").write_text(C_DRIVER)
    cc = subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", f"-I{out}", "-o", exe,
                         tmp_path / "driver.c", out / "two_link.c", "-lm"], capture_output=True, text=True)
    assert cc.returncode == 0, cc.stderr
    tau_c = np.array(subprocess.run([exe], capture_output=True, text=True, check=True).stdout.split(), dtype=float)
    reference = jaxskid.lower(jaxskid.load(ARM), ["mass_matrix", "inverse_dynamics"])  # default options
    q, qd, qdd = np.array([0.3, -0.8]), np.array([1.0, 0.5]), np.array([-0.2, 0.7])
    tau_ref = raw(reference, "inverse_dynamics", q, qd, qdd)
    np.testing.assert_allclose(tau_c, tau_ref, rtol=1e-12, atol=1e-12)
    spec = importlib.util.spec_from_file_location("two_link_numpy", out / "two_link_numpy.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    np.testing.assert_allclose(module.mass_matrix(q), raw(reference, "mass_matrix", q), rtol=1e-12, atol=1e-12)
    eqs = jaxskid.derive(jaxskid.load(ARM), ["mass_matrix"], options=jaxskid.Options(cse="none"))
    assert not eqs.assignments  # --cse none is Skidy's form: one tree per entry, as the module prints
    cases = [(("--simplify", "bogus"), ("--simplify", "none, expand, trigsimp")), (("--cse", "yes"), ("--cse", "tape")),
             (("--trig", "x"), ("--trig",)), (("--name", "9lives"), ("--name", "robot_9lives")),
             (("--name", "Arm"), ("--name", "'arm'")), (("--name", "double"), ("--name",))]
    for (args, fragments), bad in zip(cases, jaxskid_many(*(["generate", ARM, *a, "-o", tmp_path / "x"] for a, _ in cases))):
        one_line_error(bad, 2, *fragments)
    assert not (tmp_path / "x").exists()


def test_generate_latex_makes_a_pdf_when_pdflatex_is_installed(tmp_path):
    assert shutil.which("pdflatex"), "pdflatex is required: apt-get install -y texlive-latex-base"
    proc = jaxskid_cmd("generate", ARM, "-t", "latex", "-q", "mass_matrix", "--no-check", "-o", tmp_path, check_rc=0)
    assert "arm_2r.pdf" in proc.stdout and "wrote 2 file(s)" in proc.stdout
    assert (tmp_path / "arm_2r.pdf").read_bytes().startswith(b"%PDF")
    assert not (tmp_path / "arm_2r.log").exists() and {p.name for p in tmp_path.iterdir()} == {"arm_2r.tex", "arm_2r.pdf"}
    (tmp_path / "arm_2r.tex").unlink()  # the PDF alone still blocks a rewrite
    one_line_error(jaxskid_cmd("generate", ARM, "-t", "latex", "-q", "mass_matrix", "-o", tmp_path), 1, "arm_2r.pdf")
    no_pdf = jaxskid_cmd("generate", ARM, "-t", "latex", "-q", "mass_matrix", "--no-check", "--no-pdf", "-o",
                         tmp_path / "tex", check_rc=0)
    assert "pdflatex" not in no_pdf.stdout and {p.name for p in (tmp_path / "tex").iterdir()} == {"arm_2r.tex"}


def test_generate_latex_without_or_with_a_failing_pdflatex(tmp_path, monkeypatch, capsys):
    from jaxskid._cli import main

    bare = tmp_path / "bin"
    bare.mkdir()
    monkeypatch.setenv("PATH", str(bare))  # no pdflatex on this PATH
    args = ["generate", str(ARM), "-t", "latex", "-q", "mass_matrix", "--no-check", "-o"]
    with pytest.raises(SystemExit) as done:
        main([*args, str(tmp_path / "a")])
    assert done.value.code == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "pdflatex" in line]
    assert lines == ["PDF not made: pdflatex is not installed (apt-get install texlive-latex-base); the .tex is written"]
    assert {p.name for p in (tmp_path / "a").iterdir()} == {"arm_2r.tex"}
    fake = bare / "pdflatex"  # a pdflatex that fails, leaving a log
    fake.write_text('#!/bin/sh\nfor a; do f=$a; done\necho "! Undefined control sequence." > "${f%.tex}.log"\nexit 1\n')
    fake.chmod(0o755)
    with pytest.raises(SystemExit) as done:
        main([*args, str(tmp_path / "b")])
    assert done.value.code == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pdflatex failed" in err[0] and str(tmp_path / "b" / "arm_2r.log") in err[0], err
    assert "Undefined control sequence" in (tmp_path / "b" / "arm_2r.log").read_text()
    assert not (tmp_path / "b" / "arm_2r.pdf").exists()


# ------------------------------------------------------------------------------------------ errors
BAD_USAGE = [
    (("generate", ARM, "--bogus"), "No such option"),
    (("generate", ARM, "-t", "fortran"), "fortran"),
    (("generate", ARM, "-q", "mass_matrix,jerk"), "jerk"),
    (("generate",), "Missing argument"),
    (("generate", "no_such_robot.yaml"), "does not exist"),
    (("info", ARM, "--lock", "elbow"), "JOINT=POSITION"),
    (("info", ROOT / "pyproject.toml"), ".urdf"),
    (("info", ARM, "--mimic"), "--mimic reads a .urdf file"),
    (("frobnicate",), "No such command"),
]


def test_bad_usage_exits_2_with_one_line():
    for (args, fragment), proc in zip(BAD_USAGE, jaxskid_many(*(args for args, _ in BAD_USAGE))):
        one_line_error(proc, 2, fragment)


def test_bad_input_exits_1_with_one_line(tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text("joint_screw_coord: [\n")
    missing = tmp_path / "missing.yaml"
    missing.write_text(ARM.read_text().replace("mass_inertia:", "mass_inertia_typo:"))
    no_robot = tmp_path / "empty.py"
    no_robot.write_text("x = 1\n")
    failing = tmp_path / "failing.py"
    failing.write_text("raise RuntimeError('boom')\n")
    cases = [
        (("info", broken), ("broken.yaml", "invalid YAML")),
        (("generate", missing, "-o", tmp_path / "out"), ("missing.yaml",)),
        (("info", ARM, "--lock", "wrist=0.1"), ("wrist",)),
        (("generate", ARM, "--symbolic", "mass9", "-o", tmp_path / "o"), ("mass9",)),
        (("info", no_robot), ("robot",)),
        (("info", failing), ("RuntimeError: boom",)),
    ]
    for (args, fragments), proc in zip(cases, jaxskid_many(*(args for args, _ in cases))):
        one_line_error(proc, 1, *fragments)
    assert not (tmp_path / "out").exists() and not (tmp_path / "o").exists()
