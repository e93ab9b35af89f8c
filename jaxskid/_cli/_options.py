"""Options that several commands share for reading a description as a Skidy user writes it: the dialect
(``--dialect skidy``) and end-effectors placed on a file's links (``--ee NAME=LINK@X,Y,Z[,R,P,Y]``)."""

from __future__ import annotations

import click

DIALECTS = ("jaxskid", "skidy")

DIALECT = click.option(
    "--dialect", type=click.Choice(DIALECTS), default="jaxskid", show_default=True,
    help="How a .yaml/.json file is read: jaxskid (strict) or skidy (as Skidy reads it: a serial chain unless both "
         "parent and support are given, frame: com carried over to later bodies, assignments of assignments, "
         "unknown keys and a prismatic joint's vec ignored with a warning). A .urdf reads the same in both.")


def _parse_end_effectors(ctx, param, values) -> dict[str, tuple[str, object]]:
    """``NAME=LINK`` or ``NAME=LINK@X,Y,Z`` or ``NAME=LINK@X,Y,Z,ROLL,PITCH,YAW`` -> ``{NAME: (LINK, pose)}``."""
    out: dict[str, tuple[str, object]] = {}
    for item in values:
        name, sep, rest = item.partition("=")
        link, at, numbers = rest.partition("@")
        parts = [p.strip() for p in numbers.split(",")] if at else []
        if not sep or not name.strip() or not link.strip() or (at and len(parts) not in (3, 6)) or "" in parts:
            raise click.BadParameter(f"expected NAME=LINK, NAME=LINK@X,Y,Z or NAME=LINK@X,Y,Z,ROLL,PITCH,YAW, got {item!r}",
                                     ctx, param)
        if name.strip() in out:
            raise click.BadParameter(f"end-effector {name.strip()!r} given twice", ctx, param)
        pose = None if not at else {"translation": parts} if len(parts) == 3 else {"xyzrpy": parts}
        out[name.strip()] = (link.strip(), pose)
    return out


END_EFFECTORS = click.option(
    "--ee", "end_effectors", multiple=True, callback=_parse_end_effectors, metavar="NAME=LINK[@X,Y,Z[,R,P,Y]]",
    help="An end-effector NAME on the frame of LINK, offset by the translation X,Y,Z and the rotation "
         "Rz(Y) Ry(P) Rx(R) (numbers or expressions such as pi/2); repeat for several. They replace the file's "
         "own end-effectors (for a URDF: its leaf links).")


URDF_FLAGS = {
    "mimic": "URDF input: couple the <mimic> joints (else they are read as independent joints, with a warning).",
    "floating_base": "URDF input: make the root link a free-flyer base body (7 + n positions, 6 + n velocities).",
    "balance_inertia": "URDF input: make each inertia that no rigid body has isotropic with the same trace "
                       "(MuJoCo's balanceinertia), with a warning naming the links.",
}
"""The URDF reader's switches (``jaxskid.load``'s options) as flags of every command that reads a robot."""
URDF_META = "jaxskid.urdf"


def urdf_options(command):
    """The flags of :data:`URDF_FLAGS`, kept in the click context for ``load_robot`` (no argument of their own)."""
    def remember(ctx, param, value):
        if value:
            ctx.meta.setdefault(URDF_META, {})[param.name] = True

    for name, text in reversed(URDF_FLAGS.items()):
        command = click.option(f"--{name.replace('_', '-')}", name, is_flag=True, expose_value=False,
                               callback=remember, help=text)(command)
    return command
