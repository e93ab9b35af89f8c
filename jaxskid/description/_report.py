"""Reports on a robot model: tables of its joints, bodies, frames and parameters (:func:`describe`), and a
picture of its kinematic tree (:func:`draw_tree`). ``jaxskid info`` and ``jaxskid graph`` print and draw them.
"""

from __future__ import annotations

import os

import sympy as sp

from ..model._robot import Robot, symbol


def _tree(robot) -> dict[int, list[tuple[str, int | str]]]:
    """Children of every body (-1: the base): ("body", index) or ("frame", name), in model order."""
    children: dict[int, list] = {i: [] for i in range(-1, robot.n_bodies)}
    for i, j in enumerate(robot.joints):
        children[j.parent].append(("body", i))
    for f in robot.frames:
        children[f.body].append(("frame", f.name))
    return children


def _numeric(robot):
    """A formatter of expressions at the robot's default parameter values (symbolic when some have none)."""
    subs = {symbol(k): sp.Float(v) for k, v in robot.default_params().items()}

    def value(e, fmt="{:.6g}"):
        e = sp.sympify(e).xreplace(subs)
        if e.free_symbols:
            return str(e)
        return fmt.format(float(e))

    return value


def _table(header: tuple, rows: list[tuple]) -> list[str]:
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return ["  " + fmt.format(*header).rstrip(), *("  " + fmt.format(*map(str, r)).rstrip() for r in rows)]


def describe(robot: Robot) -> str:
    """A text report of ``robot``: tables of its joints, bodies (masses and centres of mass at the default
    parameters), frames and parameters, then the kinematic tree drawn with box characters
    (``jaxskid info``)."""
    value = _numeric(robot)
    gravity = ", ".join(value(g) for g in robot.gravity)
    lines = [f"robot {robot.name}: {robot.n_dof} joint(s), {len(robot.frames)} extra frame(s), "
             f"{len(robot.parameters)} parameter(s); {'floating ' if robot.floating_base else ''}base {robot.base!r}; "
             f"gravity ({gravity})", "", "joints"]
    rows = []
    for i, j in enumerate(robot.joints):
        parent = robot.base if j.parent < 0 else robot.joints[j.parent].link
        kind = j.type if j.mimic is None else f"{j.type} (mimics {j.mimic.joint})"
        rows.append((i + 1, j.name, kind, parent, j.link, "(" + ", ".join(value(x, "{:.4g}") for x in j.screw) + ")"))
    lines += _table(("#", "joint", "type", "parent body", "body", "screw (omega, v), body frame"), rows)
    lines += ["", "bodies (at the default parameters)"]
    rows = []
    bodies = [(i + 1, j.link, j.inertia) for i, j in enumerate(robot.joints)]
    if robot.floating_base:  # the floating base is body 0
        bodies.insert(0, (0, robot.base, robot.base_inertia))
    for i, link, inertia in bodies:
        m6 = sp.Matrix(inertia)
        mass = m6[5, 5]
        com = [m6[2, 4], m6[0, 5], m6[1, 3]]  # m c~ block: (m c)_x = M[2,4], (m c)_y = M[0,5], (m c)_z = M[1,3]
        com_text = "-" if mass == 0 else "(" + ", ".join(value(c / mass, "{:.4g}") for c in com) + ")"
        unknown = link in robot.without_inertia  # kinematics only: no mass_inertia in the description
        rows.append((i, link, "unknown" if unknown else value(mass), "-" if unknown else com_text))
    lines += _table(("#", "body", "mass", "centre of mass, body frame"), rows)
    if robot.frames:
        lines += ["", "frames"]
        rows = [(f.name, robot.base if f.body < 0 else robot.joints[f.body].link,
                 "yes" if f.name in robot.end_effectors else "") for f in robot.frames]
        lines += _table(("frame", "on body", "end-effector"), rows)
    if robot.constraints:
        lines += ["", "constraints (world axes)"]
        rows = [(k, type(c).__name__, f"{c.frames[0]} - {c.frames[1] or 'its anchor'}", ", ".join(c.axes))
                for k, c in enumerate(robot.constraints)]
        lines += _table(("#", "constraint", "holds", "axes"), rows)
    lines += ["", "parameters"]
    defaults = robot.default_params()
    if robot.parameters:
        lines += _table(("name", "default"), [(p, repr(defaults[p]) if p in defaults else "(none)")
                                              for p in robot.parameters])
    else:
        lines.append("  (none: every value is a number)")
    lines += ["", "kinematic tree", robot.base]
    children = _tree(robot)

    def walk(body: int, prefix: str):
        items = children[body]
        for k, (kind, ref) in enumerate(items):
            last = k == len(items) - 1
            branch = "└── " if last else "├── "
            if kind == "body":
                j = robot.joints[ref]
                lines.append(f"{prefix}{branch}{j.link}  [{j.name}: {j.type}]")
                walk(ref, prefix + ("    " if last else "│   "))
            else:
                tag = "end-effector" if ref in robot.end_effectors else "frame"
                lines.append(f"{prefix}{branch}{ref}  ({tag})")

    walk(-1, "")
    return "\n".join(lines)


def draw_tree(robot: Robot, path: str | os.PathLike) -> None:
    """Draw the kinematic tree of ``robot`` (bodies, joints and frames) to ``path`` (``.svg``, ``.png``,
    ``.pdf``: matplotlib picks the format), laid out top-down: leaves spaced evenly, parents centred
    (``jaxskid graph``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    children = _tree(robot)
    pos: dict = {}
    next_x = [0.0]

    def place(node, depth):
        kind, ref = node
        kids = children[ref] if kind == "body" else []
        if kids:
            xs = [place(c, depth + 1) for c in kids]
            x = (xs[0] + xs[-1]) / 2
        else:
            x = next_x[0]
            next_x[0] += 1.0
        pos[node] = (x, -depth)
        return x

    root = ("body", -1)
    place(root, 0)
    width = max(next_x[0], 1.0)
    depth = -min(y for _, y in pos.values()) + 1
    fig, ax = plt.subplots(figsize=(max(4.0, 2.2 * width), max(3.0, 1.3 * depth)))
    for node, (x, y) in pos.items():
        kind, ref = node
        if kind == "body":
            for child in children[ref]:
                cx, cy = pos[child]
                ax.plot([x, cx], [y, cy], color="0.4", lw=1.2, zorder=1,
                        ls="-" if child[0] == "body" else ":")
                if child[0] == "body":
                    j = robot.joints[child[1]]
                    ax.text(0.35 * x + 0.65 * cx, 0.35 * y + 0.65 * cy, f"{j.name}\n({j.type})", fontsize=7, ha="center",
                            va="center", color="0.2", bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none"),
                            zorder=2)
        if kind == "body":
            label = robot.base if ref < 0 else robot.joints[ref].link
            style = dict(boxstyle="round,pad=0.3", fc="#dbe8f6" if ref >= 0 else "#e0e0e0", ec="#3a6ea5")
        else:
            label = ref
            ee = ref in robot.end_effectors
            style = dict(boxstyle="round,pad=0.25", fc="#fdebd0" if ee else "white", ec="#b9770e", ls="--")
        ax.text(x, y, label, fontsize=8, ha="center", va="center", bbox=style, zorder=3)
    ax.set_xlim(-0.8, width - 0.2)
    ax.set_ylim(-depth + 0.5, 0.6)
    ax.set_title(f"{robot.name}: kinematic tree ({robot.n_dof} joint(s); dotted: fixed frames)", fontsize=9)
    ax.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
