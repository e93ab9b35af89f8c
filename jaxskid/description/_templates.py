"""Starting points for new robot descriptions: ``jaxskid template -S RRP robot.yaml`` (or ``.json``, ``.py``).

A template is a serial chain with one joint per letter of the structure string (``R`` revolute, ``P``
prismatic), every length, mass and inertia a named parameter with a plausible default, so that it loads,
derives and lowers with no edits. Two forms of the kinematics:

* ``screws`` (Skidy's ``joint_screw_coord`` and ``body_ref_config``): the first joint turns about (or slides
  along) the world z axis; every later revolute joint turns about its body's y axis and every later prismatic
  joint slides along its body's x axis; link i is ``L<i>`` long along its body's x axis, with its centre of
  mass in the middle.
* ``dh`` (a ``dh:`` table, standard convention, :mod:`._dh`): a revolute row is ``a = L<i>, alpha = 0``,
  except the first, ``d = L1, alpha = pi/2`` (a base column; RRR is Spong's elbow manipulator); a prismatic
  row is ``d = L<i>, alpha = theta = pi/2`` (so that consecutive prismatic joints slide along perpendicular
  axes: PPP is a Cartesian robot). Link i is the segment from DH origin i-1 to origin i, with its centre of
  mass in the middle; the end-effector is DH frame n.

With ``drives=True`` (``jaxskid template --drives``) every joint also has a drive (:class:`~jaxskid.Drive`,
the ``drives:`` key of :mod:`._yaml_drives`): ``Ia qdd + fv qd + fc sign(qd) + fo`` added to its force, with
the parameters ``joint<i>_Ia, joint<i>_fv, joint<i>_fc, joint<i>_fo`` (the names ``jaxskid.load(...,
drives=True)`` gives) and defaults among the assignments; a Python template calls ``Robot.with_drives``.
"""

from __future__ import annotations

import json
import re

import sympy as sp

from .._errors import RequestError
from ..model._drive import drive_parameter_names

FORMATS = ("yaml", "json", "py")
KINEMATICS = ("screws", "dh")
_STRUCTURE = re.compile(r"[RrPp]{1,64}")


def check_structure(structure: str) -> None:
    """Raise :class:`RequestError` unless ``structure`` is 1 to 64 letters R and P."""
    if not isinstance(structure, str) or not _STRUCTURE.fullmatch(structure):
        raise RequestError(
            f"expected 1 to 64 letters R and P (R revolute, P prismatic), such as RRP, got {structure!r}"
        )


def _joints(structure: str) -> list[dict]:
    check_structure(structure)
    out = []
    for i, letter in enumerate(structure.upper()):
        k = i + 1
        kind = "revolute" if letter == "R" else "prismatic"
        axis = [0, 0, 1] if i == 0 else ([0, 1, 0] if kind == "revolute" else [1, 0, 0])
        out.append({"k": k, "type": kind, "axis": axis, "offset": [0, 0, 0] if i == 0 else [f"L{i}", 0, 0]})
    return out


def _assignments(n: int) -> dict[str, float]:
    values: dict[str, float] = {}
    for k in range(1, n + 1):
        values[f"L{k}"] = 0.5
        values[f"m{k}"] = 1.0
        values[f"Ixx{k}"] = 0.001          # slender rod along x: small inertia about its own axis
        values[f"Iyy{k}"] = 0.0208         # about y and z: m L^2 / 12
        values[f"Izz{k}"] = 0.0208
    values["g"] = 9.81
    return values


DRIVE_DEFAULTS = {"Ia": 0.01, "fv": 0.1, "fc": 0.05, "fo": 0.0}
"""A template drive's default armature (kg m^2; kg for a prismatic joint), viscous friction (N m s; N s/m),
Coulomb friction (N m; N) and torque offset (N m; N), by the suffix of its parameter names."""


def _flag(drives: bool) -> str:
    return " --drives" if drives else ""


def _with_drives(data: dict) -> dict:
    """``data`` with a ``drives`` list (one drive of named parameters per joint) and their defaults."""
    entries, values = [], {}
    for joint in data["joint_names"]:
        names = dict(zip(("armature", "viscous", "coulomb", "offset"), drive_parameter_names(joint)))
        entries.append(names)
        values.update({name: DRIVE_DEFAULTS[name.rsplit("_", 1)[1]] for name in names.values()})
    return {**data, "drives": entries, "assignments": {**data["assignments"], **values}}


def template_data(structure: str, name: str | None = None, drives: bool = False) -> dict:
    """The template as a description mapping (Skidy's schema, body-fixed representation); with ``drives``, a
    drive per joint (module docstring)."""
    joints = _joints(structure)
    n = len(joints)
    data: dict = {"name": name or structure.lower(), "representation": "body_fixed", "gravity": [0, 0, "-g"]}
    data["joint_names"] = [f"joint{j['k']}" for j in joints]
    data["link_names"] = [f"link{j['k']}" for j in joints]
    data["joint_screw_coord"] = [{"type": j["type"], "axis": j["axis"]} for j in joints]
    data["body_ref_config"] = [{"translation": j["offset"]} for j in joints]
    data["ee"] = {"translation": [f"L{n}", 0, 0]}
    data["ee_names"] = ["ee"]
    data["mass_inertia"] = [
        {"mass": f"m{j['k']}", "com": [f"L{j['k']}/2", 0, 0],
         "inertia": [f"Ixx{j['k']}", 0, 0, f"Iyy{j['k']}", 0, f"Izz{j['k']}"], "frame": "com"}
        for j in joints
    ]
    data["assignments"] = _assignments(n)
    return _with_drives(data) if drives else data


def _flow(values) -> str:
    return "[" + ", ".join(str(v) for v in values) + "]"


def _yaml(structure: str, name: str | None, drives: bool = False) -> str:
    data = template_data(structure, name, drives)
    joints = _joints(structure)
    n = len(joints)
    lines = [
        f"# {structure.upper()} robot: template written by `jaxskid template{_flag(drives)} -S {structure.upper()}`.",
        "# Skidy's YAML schema (body-fixed representation): edit the geometry and the assignments, then",
        "#   jaxskid info this.yaml        # joints, bodies, parameters, tree",
        "#   jaxskid generate this.yaml    # derive, lower, self-check, write code",
        "---",
        f"name: {data['name']}",
        "representation: body_fixed      # screws in each body's frame, poses relative to the parent body",
        "gravity: [0, 0, -g]             # gravitational acceleration in the world frame",
        "",
        f"joint_names: {_flow(data['joint_names'])}",
        f"link_names: {_flow(data['link_names'])}",
        "",
        "joint_screw_coord:               # per joint: type and unit axis in its body's frame",
    ]
    for j in joints:
        lines.append(f"  - {{type: {j['type']}, axis: {_flow(j['axis'])}}}")
    lines += ["", "body_ref_config:                 # per body: its frame in the parent's frame at q = 0"]
    for j in joints:
        lines.append(f"  - {{translation: {_flow(j['offset'])}}}")
    lines += ["", "ee:                              # end-effector frame on the last body",
              f"  translation: [L{n}, 0, 0]", "ee_names: [ee]", "",
              "mass_inertia:                    # per body: mass, centre of mass and inertia about it"]
    return "\n".join(lines + _yaml_inertias_and_assignments(data)) + "\n"


def _yaml_inertias_and_assignments(data: dict) -> list[str]:
    """The ``mass_inertia`` entries (after their key), the ``drives`` block if any and the ``assignments``
    block, as YAML lines."""
    lines = [f"  - {{mass: {m['mass']}, com: {_flow(m['com'])}, inertia: {_flow(m['inertia'])}, frame: {m['frame']}}}"
             for m in data["mass_inertia"]]
    if "drives" in data:
        lines += ["", "drives:                          # per joint (null: none): Ia qdd + fv qd + fc sign(qd) + fo "
                  "added to its force;",
                  "                                 # armature may be given as gear_ratio and rotor_inertia "
                  "(gear_ratio^2 rotor_inertia)"]
        lines += ["  - {" + ", ".join(f"{key}: {value}" for key, value in d.items()) + "}" for d in data["drives"]]
    lines += ["", "assignments:                     # default values of the parameters (SI units)"]
    return lines + [f"  {key}: {value}" for key, value in data["assignments"].items()]


def _json(structure: str, name: str | None, drives: bool = False) -> str:
    return json.dumps(template_data(structure, name, drives), indent=2) + "\n"


def _dh_json(structure: str, name: str | None, drives: bool = False) -> str:
    return json.dumps(dh_template_data(structure, name, drives), indent=2) + "\n"


def _python_drives(data: dict) -> list[str]:
    """The lines that give every joint of a Python template's ``robot`` its drive (``Robot.with_drives``)."""
    if "drives" not in data:
        return []
    values = {p: data["assignments"][p] for d in data["drives"] for p in d.values()}
    return ["",
            "# Drives: Ia qdd + fv qd + fc sign(qd) + fo added to each joint's force (armature Ia, viscous and Coulomb",
            "# friction fv and fc, offset fo), with the parameters <joint>_Ia, <joint>_fv, <joint>_fc, <joint>_fo.",
            f"robot = robot.with_drives({values!r})"]


def _python(structure: str, name: str | None, drives: bool = False) -> str:
    joints = _joints(structure)
    n = len(joints)
    data = template_data(structure, name, drives)
    lines = [
        f'"""{structure.upper()} robot: template written by `jaxskid template{_flag(drives)} -S {structure.upper()}`.',
        "",
        "Edit the geometry and the defaults, then run it (derives, lowers and prints M at q = 0), or use it",
        "wherever jaxskid's command line takes a robot: `jaxskid info this.py`, `jaxskid generate this.py`;",
        "the command line reads the variable `robot`.",
        '"""',
        "",
        "import sympy as sp",
        "",
        "import jaxskid",
        "from jaxskid import Frame, Joint, Robot, pose, screw, spatial_inertia",
        "",
    ]
    for k in range(1, n + 1):
        names = f"L{k} m{k} Ixx{k} Iyy{k} Izz{k}"
        lines.append(f"{', '.join(names.split())} = sp.symbols({names!r}, real=True)")
    lines += ["g = sp.Symbol('g', real=True)", "", "joints = ["]
    for j in joints:
        k = j["k"]
        parent = k - 2
        offset = "(0, 0, 0)" if k == 1 else f"(L{k - 1}, 0, 0)"
        lines += [
            "    Joint(",
            f"        name='joint{k}', type={j['type']!r}, parent={parent}, link='link{k}',",
            f"        origin=pose(translation={offset}),  # body frame in the parent's frame at q = 0",
            f"        screw=screw({j['type']!r}, {tuple(j['axis'])!r}),  # unit axis in the body's frame",
            f"        inertia=spatial_inertia(m{k}, com=(L{k} / 2, 0, 0), inertia=(Ixx{k}, 0, 0, Iyy{k}, 0, Izz{k})),",
            "    ),",
        ]
    lines += [
        "]",
        "",
        "robot = Robot.create(",
        f"    {data['name']!r},",
        "    joints,",
        "    gravity=(0, 0, -g),",
        f"    frames=[Frame('ee', {n - 1}, pose(translation=(L{n}, 0, 0)))],",
        "    end_effectors=['ee'],",
        f"    defaults={_inertial(data['assignments'])!r},",
        ")",
    ]
    return "\n".join(lines + _python_drives(data) + _PYTHON_MAIN)


def _inertial(values: dict) -> dict:
    """The assignments without the drives' parameters (a Python template gives those to ``with_drives``)."""
    return {k: v for k, v in values.items() if k.rsplit("_", 1)[-1] not in DRIVE_DEFAULTS}


_PYTHON_MAIN = [
    "",
    "",
    "if __name__ == '__main__':",
    "    import numpy as np",
    "",
    "    dyn = jaxskid.lower(robot, progress=True)",
    "    print(dyn)",
    "    print('M(0) =')",
    "    print(np.asarray(dyn.mass_matrix(np.zeros(robot.n_dof))))",
    "",
]


def urdf_script(urdf: str, *, name: str | None = None, command: str = "") -> str:
    """A Python script that loads the URDF file ``urdf`` (a path relative to the script's folder, or an
    absolute one), names the robot ``name`` if given, and when run derives, lowers and prints M at q = 0."""
    lines = [
        f'"""Robot from a URDF file: template written by `{command or "jaxskid template --urdf"}`.',
        "",
        "Edit the loading options (lock joints, numeric inertia, gravity, end-effectors; see jaxskid.load), then",
        "run it (derives, lowers and prints M at q = 0), or use it wherever jaxskid's command line takes a robot:",
        "`jaxskid info this.py`, `jaxskid generate this.py`; the command line reads the variable `robot`.",
        '"""',
        "",
        "from pathlib import Path",
        "",
        "import jaxskid",
        "",
        f"URDF = Path(__file__).resolve().parent / {urdf!r}" if not urdf.startswith("/") else f"URDF = Path({urdf!r})",
        "",
        "robot = jaxskid.load(",
        "    URDF,",
        "    lock=None,               # e.g. {'finger_joint': 0.0}: fix joints at a position",
        "    symbolic_inertia=True,   # each body's 10 inertial parameters are symbols, the URDF values defaults",
        ")",
    ]
    if name is not None:
        lines += ["robot = robot.renamed(" + repr(name) + ")"]
    lines += [
        "",
        "",
        "if __name__ == '__main__':",
        "    import numpy as np",
        "",
        "    dyn = jaxskid.lower(robot, ['mass_matrix', 'inverse_dynamics'], progress=True)",
        "    print(dyn)",
        "    print('M(0) =')",
        "    print(np.asarray(dyn.mass_matrix(np.zeros(robot.n_dof))))",
        "",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------- DH tables
def _dh_links(structure: str) -> list[dict]:
    """Per joint: its DH row (SymPy entries), the centre of mass of its link in DH frame i and the axis
    (0: x, 1: y) the link lies along. Standard DH with theta = 0 or pi/2: origin i-1 sits at
    ``-Rx(alpha)^T (a, 0, d) = -(a, d sin alpha, d cos alpha)`` in frame i, whatever theta."""
    check_structure(structure)
    out = []
    for i, letter in enumerate(structure.upper()):
        k = i + 1
        length = sp.Symbol(f"L{k}")
        if letter == "R" and i > 0:
            row = {"type": "revolute", "a": length, "alpha": sp.Integer(0), "d": sp.Integer(0), "theta": sp.Integer(0)}
            com, axis = (-length / 2, 0, 0), 0
        else:
            row = {"type": "revolute" if letter == "R" else "prismatic", "a": sp.Integer(0), "alpha": sp.pi / 2,
                   "d": length, "theta": sp.Integer(0) if letter == "R" else sp.pi / 2}
            com, axis = (0, -length / 2, 0), 1
        out.append({"k": k, "row": row, "com": com, "axis": axis})
    return out


def _dh_assignments(links: list[dict]) -> dict[str, float]:
    values: dict[str, float] = {}
    for link in links:
        k = link["k"]
        values.update({f"L{k}": 0.5, f"m{k}": 1.0})
        for a, key in enumerate(("Ixx", "Iyy", "Izz")):  # a slender rod: small inertia about its own axis
            values[f"{key}{k}"] = 0.001 if a == link["axis"] else 0.0208
    values["g"] = 9.81
    return values


def _value(e):
    return int(e) if sp.sympify(e).is_Integer else str(e)


def dh_template_data(structure: str, name: str | None = None, drives: bool = False) -> dict:
    """The DH template as a description mapping (a ``dh:`` table in the standard convention); with
    ``drives``, a drive per joint (module docstring)."""
    links = _dh_links(structure)
    data: dict = {"name": name or structure.lower(), "gravity": [0, 0, "-g"]}
    data["joint_names"] = [f"joint{link['k']}" for link in links]
    data["link_names"] = [f"link{link['k']}" for link in links]
    data["dh"] = {"convention": "standard",
                  "joints": [{key: _value(v) if key != "type" else v for key, v in link["row"].items()}
                             for link in links]}
    data["ee"] = {"translation": [0, 0, 0]}
    data["ee_names"] = ["ee"]
    data["mass_inertia"] = [
        {"mass": f"m{k}", "com": [_value(c) for c in link["com"]],
         "inertia": [f"Ixx{k}", 0, 0, f"Iyy{k}", 0, f"Izz{k}"], "frame": "com"}
        for link in links for k in [link["k"]]
    ]
    data["assignments"] = _dh_assignments(links)
    return _with_drives(data) if drives else data


def _dh_yaml(structure: str, name: str | None, drives: bool = False) -> str:
    data = dh_template_data(structure, name, drives)
    letters = structure.upper()
    lines = [
        f"# {letters} robot: template written by `jaxskid template --dh{_flag(drives)} -S {letters}`.",
        "# A Denavit-Hartenberg table; edit it and the assignments, then",
        "#   jaxskid info this.yaml        # joints, bodies, parameters, tree",
        "#   jaxskid generate this.yaml    # derive, lower, self-check, write code",
        "---",
        f"name: {data['name']}",
        "gravity: [0, 0, -g]             # gravitational acceleration in the world frame",
        "",
        f"joint_names: {_flow(data['joint_names'])}",
        f"link_names: {_flow(data['link_names'])}",
        "",
        "dh:",
        "  convention: standard          # frame i = frame i-1 Rz(theta) Tz(d) Tx(a) Rx(alpha); or modified",
        "                                # (Craig): Rx(alpha) Tx(a) Rz(theta) Tz(d), a row holding a_{i-1},",
        "                                # alpha_{i-1}, d_i, theta_i",
        "  joints:                       # q adds to theta (revolute) or d (prismatic); body i's frame is DH frame i",
    ]
    for row in data["dh"]["joints"]:
        lines.append("    - {" + ", ".join(f"{key}: {value}" for key, value in row.items()) + "}")
    lines += ["", "ee:                              # end-effector: DH frame n, on the last body",
              "  translation: [0, 0, 0]", "ee_names: [ee]", "",
              "mass_inertia:                    # per body, in its DH frame: mass, centre of mass, inertia about it"]
    return "\n".join(lines + _yaml_inertias_and_assignments(data)) + "\n"


def _dh_python(structure: str, name: str | None, drives: bool = False) -> str:
    links = _dh_links(structure)
    data = dh_template_data(structure, name, drives)
    letters, n = structure.upper(), len(links)
    lines = [
        f'"""{letters} robot: template written by `jaxskid template --dh{_flag(drives)} -S {letters}`.',
        "",
        "A Denavit-Hartenberg table in the standard convention: frame i = frame i-1 Rz(theta) Tz(d) Tx(a) Rx(alpha),",
        "the joint variable added to theta (revolute) or d (prismatic); body i's frame is DH frame i. Edit the",
        "table and the defaults, then run it (derives, lowers and prints M at q = 0), or use it wherever jaxskid's",
        "command line takes a robot: `jaxskid info this.py`, `jaxskid generate this.py`; the command line reads",
        "the variable `robot`.",
        '"""',
        "",
        "import sympy as sp",
        "from sympy import pi",
        "",
        "import jaxskid",
        "from jaxskid import DH, Frame, dh_robot, pose, spatial_inertia",
        "",
    ]
    for link in links:
        names = " ".join(f"{p}{link['k']}" for p in ("L", "m", "Ixx", "Iyy", "Izz"))
        lines.append(f"{', '.join(names.split())} = sp.symbols({names!r}, real=True)")
    lines += ["g = sp.Symbol('g', real=True)", "",
              "rows = [  # type, a, alpha, d, theta (standard DH; 'modified' for Craig's convention)"]
    for link in links:
        r = link["row"]
        lines.append(f"    DH({r['type']!r}, a={r['a']}, alpha={r['alpha']}, d={r['d']}, theta={r['theta']}),")
    lines += ["]", "", "inertias = [  # per body, in its DH frame: mass, centre of mass, inertia about it"]
    for link in links:
        k, com = link["k"], ", ".join(str(c) for c in link["com"])
        lines.append(f"    spatial_inertia(m{k}, com=({com}), inertia=(Ixx{k}, 0, 0, Iyy{k}, 0, Izz{k})),")
    lines += [
        "]",
        "",
        f"robot = dh_robot({data['name']!r}, rows, inertias, convention='standard', gravity=(0, 0, -g),",
        f"                 joint_names={data['joint_names']!r},",
        f"                 link_names={data['link_names']!r},",
        f"                 frames=[Frame('ee', {n - 1}, pose())],  # the end-effector: DH frame n",
        "                 end_effectors=['ee'],",
        f"                 defaults={_inertial(data['assignments'])!r})",
    ]
    return "\n".join(lines + _python_drives(data) + _PYTHON_MAIN)


def render_template(structure: str, fmt: str, *, name: str | None = None, kinematics: str = "screws",
                    drives: bool = False) -> str:
    """The text of a robot template.

    Args:
        structure: joint types from base to tip, ``R`` revolute and ``P`` prismatic (``"RRP"``).
        fmt: ``"yaml"``, ``"json"`` or ``"py"``.
        name: the robot's name (default: the structure in lower case).
        kinematics: ``"screws"`` (``joint_screw_coord`` and ``body_ref_config``) or ``"dh"`` (a
            Denavit–Hartenberg table, ``jaxskid.dh_robot`` in Python).
        drives: give every joint a drive of named parameters with defaults (module docstring).
    """
    if fmt not in FORMATS:
        raise RequestError(f"unknown template format {fmt!r}; expected one of {', '.join(FORMATS)}")
    if kinematics not in KINEMATICS:
        raise RequestError(f"unknown template kinematics {kinematics!r}; expected one of {', '.join(KINEMATICS)}")
    if name is not None and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", name):
        raise RequestError(f"expected a robot name of letters, digits, _ and -, got {name!r}")
    if kinematics == "dh":
        return {"yaml": _dh_yaml, "json": _dh_json, "py": _dh_python}[fmt](structure, name, drives)
    return {"yaml": _yaml, "json": _json, "py": _python}[fmt](structure, name, drives)
