"""The ``jaxskid`` command line: a thin layer over the public API (nothing imports this module).

Subcommands: ``generate``, ``template``, ``convert``, ``info``, ``graph``. A ROBOT is a ``.urdf``,
``.yaml``/``.yml``, ``.json`` or ``.py`` file (a Python file defines the variable ``robot``). Errors are one
line on stderr: exit code 2 for bad usage (unknown option, bad option value, missing file), 1 for bad
input (a malformed description, a file that already exists without ``--force``).
"""

from __future__ import annotations

import logging
import math
import sys
from pathlib import Path

import click

from ._errors import BadInput
from ._options import DIALECT, END_EFFECTORS, URDF_META, urdf_options

TARGET_NAMES = ("jax", "python", "c", "cpp", "cython", "julia", "matlab", "latex")
ROBOT_SUFFIXES = (".urdf", ".yaml", ".yml", ".json", ".py")
MAX_JOINTS = 64  # as many as a template's structure may have (jaxskid.description._templates)

# ---------------------------------------------------------------------------------------------- options
class CommaList(click.ParamType):
    """A comma-separated list of names, checked against ``choices`` (the option may also repeat)."""

    name = "list"

    def __init__(self, choices=None, extra=()):
        self.choices = choices
        self.extra = tuple(extra)

    def convert(self, value, param, ctx):
        if isinstance(value, (list, tuple)):
            return tuple(value)
        items = [v.strip() for v in str(value).split(",") if v.strip()]
        choices = self.choices() if callable(self.choices) else self.choices
        if choices is not None:
            bad = [v for v in items if v not in choices and v not in self.extra]
            if bad:
                self.fail(f"unknown {', '.join(map(repr, bad))}; choose from {', '.join((*self.extra, *choices))}",
                          param, ctx)
        return tuple(items)


def _quantity_names():
    import jaxskid

    return tuple(jaxskid.QUANTITIES)


def _merge(values) -> tuple | None:
    if not values:
        return None
    out: list = []
    for v in values:
        out.extend(v)
    return tuple(dict.fromkeys(out))


def _parse_lock(ctx, param, values) -> dict[str, float]:
    lock: dict[str, float] = {}
    for item in values:
        name, sep, value = item.partition("=")
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not sep or not name.strip() or not math.isfinite(number):
            raise click.BadParameter(f"expected JOINT=POSITION with a finite number, got {item!r}", ctx, param)
        lock[name.strip()] = number
    return lock


def _options_field(ctx, param, value):
    """The value of the :class:`jaxskid.Options` field of the same name, checked by Options itself."""
    import jaxskid

    try:
        jaxskid.Options(**{param.name: value})
    except jaxskid.RequestError as exc:
        raise click.BadParameter(str(exc).replace(f"Options.{param.name}: ", ""), ctx, param) from None
    return value


def _code_name(ctx, param, value):
    """A name for generated code: an identifier that ``jaxskid.codegen.stem`` keeps as it is."""
    if value is None:
        return None
    from jaxskid.codegen import stem

    if stem(value) != value:
        raise click.BadParameter(f"expected a lower-case identifier of at most 40 letters, digits and _ that "
                                 f"is no keyword of a target language, got {value!r} (try {stem(value)!r})",
                                 ctx, param)
    return value


def _robot_path(ctx, param, value):
    if value is not None and Path(value).suffix.lower() not in ROBOT_SUFFIXES:
        raise click.BadParameter(f"expected a {', '.join(ROBOT_SUFFIXES)} file, got {value!r}", ctx, param)
    return value


ROBOT = click.argument("robot", type=click.Path(exists=True, dir_okay=False), callback=_robot_path)
LOCK = click.option("--lock", "lock", multiple=True, callback=_parse_lock, metavar="JOINT=POSITION",
                    help="Fix a joint at a position (repeat for several joints).")
FORCE = click.option("--force", is_flag=True, help="Overwrite existing files.")


# ---------------------------------------------------------------------------------------------- loading
def load_robot(path: str, lock: dict[str, float] | None = None, dialect: str = "jaxskid", end_effectors=None,
               **options):
    """A Robot from a description file (read in ``dialect``), or from the variable ``robot`` of a Python file;
    ``end_effectors``: ``{name: (link, pose)}`` placed on it (``--ee``)."""
    import jaxskid

    p = Path(path)
    ctx = click.get_current_context(silent=True)
    flags = ctx.meta.get(URDF_META, {}) if ctx is not None else {}
    if flags and p.suffix.lower() != ".urdf":
        raise click.UsageError(f"--{next(iter(flags)).replace('_', '-')} reads a .urdf file, got {path}")
    if p.suffix.lower() != ".py":
        return jaxskid.load(p, lock=lock or None, dialect=dialect, end_effectors=end_effectors or None,
                            **flags, **options)
    import runpy

    try:
        ns = runpy.run_path(str(p), run_name="__jaxskid_robot__")
    except jaxskid.JaxskidError:
        raise
    except Exception as exc:  # the user's script failed: report it as bad input, in one line
        raise BadInput(f"{p}: running the file failed: {type(exc).__name__}: {exc}") from None
    robot = ns.get("robot")
    if not isinstance(robot, jaxskid.Robot):
        raise BadInput(f"{p}: expected the file to define a variable `robot` holding a jaxskid.Robot, "
                       f"got {type(robot).__name__ if 'robot' in ns else 'no such variable'}")
    robot = robot.lock(lock) if lock else robot
    if end_effectors:
        from ..description._end_effectors import with_end_effectors

        robot = with_end_effectors(robot, end_effectors, source=str(p))
    return robot


# ---------------------------------------------------------------------------------------------- commands
@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="jaxskid", prog_name="jaxskid")
def cli():
    """jaxskid: closed-form rigid-body equations of motion, derived in SymPy and lowered to JAX, C and more.

    \b
    Examples:
      jaxskid template -S RRP robot.yaml        # start a description
      jaxskid info robot.yaml                   # joints, bodies, parameters, tree
      jaxskid generate robot.yaml -t c,python   # derive, lower, self-check, write code
      jaxskid convert panda.urdf panda.yaml     # URDF -> YAML
      jaxskid graph robot.yaml -o tree.svg      # kinematic tree as a picture

    Run 'jaxskid COMMAND --help' for the options of a command.
    """


@cli.command()
@ROBOT
@click.option("-t", "--target", "targets", multiple=True, type=CommaList(TARGET_NAMES),
              help=f"Comma-separated targets: {', '.join(TARGET_NAMES)} [default: jax].")
@click.option("-q", "--quantities", "quantities", multiple=True, type=CommaList(_quantity_names, extra=("all",)),
              help="Comma-separated quantities (see 'jaxskid info'), or 'all' [default: the standard set].")
@click.option("-o", "--out", "out", type=click.Path(file_okay=False), default=None,
              help="Output folder [default: ./generated/<robot name>].")
@LOCK
@urdf_options
@click.option("--symbolic", "symbolic", default=None, metavar="P1,P2,...",
              help="Parameters that stay inputs; every other one becomes its default value. "
                   "'' makes all of them numbers [default: all stay symbolic].")
@click.option("--simplify", default="none", show_default=True, callback=_options_field, metavar="LEVEL",
              help="Simplify every intermediate: none, expand (sympy.expand) or trigsimp (sympy.trigsimp).")
@click.option("--cse", default="tape", show_default=True, callback=_options_field, metavar="MODE",
              help="Common subexpressions: tape (name and share every intermediate), sympy (also run "
                   "sympy.cse) or none (one expression tree per entry, Skidy's form; large beyond 3-4 joints).")
@click.option("--trig", default="symbols", show_default=True, callback=_options_field, metavar="MODE",
              help="symbols (name sin(q_i), cos(q_i) once) or inline.")
@click.option("--name", "name", default=None, callback=_code_name, metavar="NAME",
              help="Name of the generated files, module, namespace and function prefix, e.g. the C header "
                   "NAME.h with guard JAXSKID_NAME_H and functions NAME_<quantity> [default: the robot's "
                   "name as an identifier].")
@click.option("--coriolis", default=None, type=click.Choice(("christoffel", "skidy")),
              help="The Coriolis matrix's factorisation (C qd is the same): christoffel (dM/dt - 2C skew, "
                   "Pinocchio's) or skidy (Skidy's C) [default: skidy with --dialect skidy, else christoffel].")
@click.option("--skidy-shapes", is_flag=True,
              help="Vector outputs as (n, 1) columns, as Skidy's generated code returns them (the jax target keeps "
                   "(n,)) [default: with --dialect skidy].")
@click.option("--landscape", is_flag=True, help="With -t latex, landscape pages for long equations.")
@click.option("--project", default=None, metavar="NAME", help="A project name, stated in every generated file's header.")
@DIALECT
@END_EFFECTORS
@click.option("--check/--no-check", default=True, show_default=True,
              help="Run the numeric self-check (parameters without a default get random positive values).")
@click.option("--pdf/--no-pdf", default=True, show_default=True,
              help="With -t latex, typeset the .tex with pdflatex (when installed) and write the .pdf beside it.")
@FORCE
def generate(robot, targets, quantities, out, lock, symbolic, simplify, cse, trig, name, coriolis, skidy_shapes,
             landscape, project, dialect, end_effectors, check, pdf, force):
    """Derive and lower ROBOT's equations of motion and write code for the targets.

    Prints the quantities with their shapes and operation counts, the derive, lower and compile times,
    and the numeric self-check (independent routes through the model must agree). Existing files are
    kept unless --force is given.

    \b
    Examples:
      jaxskid generate robots/arm_2r.yaml
      jaxskid generate panda.urdf -t c,cpp -q mass_matrix,inverse_dynamics --lock panda_finger_joint1=0 \\
          --lock panda_finger_joint2=0 -o out/panda
      jaxskid generate robot.yaml -t latex --symbolic m1,m2 --force
      jaxskid generate robot.yaml -t c --name arm --simplify trigsimp --cse sympy
      jaxskid generate skidy_robot.yaml --dialect skidy -t python,latex --landscape --project Demo
      jaxskid generate ur5.urdf -q hybrid_jacobian --ee tool=wrist_3_link@0,0.0823,0
    """
    import jax

    import jaxskid

    from ._generate import generate_files

    model = load_robot(robot, lock, dialect, end_effectors)
    if symbolic is not None:
        model = model.keep_symbolic([s.strip() for s in symbolic.split(",") if s.strip()], where="--symbolic")
    if name is not None:
        model = model.renamed(name)
    wanted = _merge(quantities)
    wanted = "all" if wanted and "all" in wanted else wanted
    skidy = dialect == "skidy"
    options = jaxskid.Options(cse=cse, simplify=simplify, trig=trig,
                              coriolis=coriolis or ("skidy" if skidy else "christoffel"))
    style = jaxskid.codegen.CodeStyle(shapes="skidy" if skidy_shapes or skidy else "jaxskid", landscape=landscape,
                                      project=project)
    with jax.enable_x64(True):  # the generated code and the self-check run in float64
        generate_files(model, _merge(targets) or ("jax",), wanted, out, options=options, style=style,
                       check=check, force=force, pdf=pdf)


@cli.command()
@click.option("-S", "--structure", default=None, metavar="LETTERS",
              help="Joint types from base to tip: R revolute, P prismatic (e.g. RRP).")
@click.option("--dof", type=click.IntRange(1, MAX_JOINTS), default=None, metavar="N",
              help=f"N revolute joints (the structure R...R), 1 to {MAX_JOINTS}.")
@click.option("--urdf", type=click.Path(exists=True, dir_okay=False), default=None, metavar="PATH",
              help="Write a Python script (OUTPUT .py) that loads this URDF file instead of a chain template; "
                   "the path is written relative to OUTPUT's folder when that is short, else absolute.")
@click.option("--dh", is_flag=True,
              help="Describe the chain by a Denavit-Hartenberg table (a dh: block, standard convention; "
                   "jaxskid.dh_robot in a .py) instead of screw coordinates and reference poses.")
@click.option("--drives", is_flag=True,
              help="Give every joint a drive (a drives: block): armature, viscous and Coulomb friction and an offset, "
                   "the parameters joint<i>_Ia, _fv, _fc, _fo with defaults in the assignments.")
@click.argument("output", type=click.Path(dir_okay=False))
@click.option("--name", default=None, help="The robot's name [default: the file name; with --urdf, the URDF's].")
@FORCE
def template(structure, dof, urdf, dh, drives, output, name, force):
    """Write a robot template to OUTPUT (.yaml, .yml, .json or .py) that loads, derives and lowers as it is.

    Give exactly one of -S, --dof or --urdf. The chain has one joint per letter; every length, mass and
    inertia is a parameter with a default. With --dh, its kinematics is a Denavit-Hartenberg table. With
    --drives, every joint has a drive (armature, friction, offset) of parameters with defaults. With
    --urdf, OUTPUT is a Python script that loads the URDF.

    \b
    Examples:
      jaxskid template -S RRP robot.yaml
      jaxskid template --dh -S RRR elbow.yaml
      jaxskid template --drives -S RRP robot.yaml
      jaxskid template --dof 6 arm6.json --name arm6
      jaxskid template -S PRR leg.py && python leg.py
      jaxskid template --urdf ur5.urdf ur5.py && python ur5.py
    """
    import re

    from jaxskid import RequestError

    from ..description._templates import check_structure, render_template

    given = [opt for opt, v in (("-S/--structure", structure), ("--dof", dof), ("--urdf", urdf)) if v is not None]
    if len(given) != 1:
        raise click.UsageError("give exactly one of -S/--structure, --dof and --urdf"
                               + (f", not {' and '.join(given)}" if given else ""))
    suffix = Path(output).suffix.lower()
    fmt = {".yaml": "yaml", ".yml": "yaml", ".json": "json", ".py": "py"}.get(suffix)
    if fmt is None or (urdf is not None and fmt != "py"):
        raise click.BadParameter(f"expected a {'.py' if urdf else '.yaml, .yml, .json or .py'} file name, "
                                 f"got {output!r}", param_hint="OUTPUT")
    if dh and urdf is not None:
        raise click.UsageError("--dh describes a chain of -S/--dof; a --urdf script loads the URDF's own kinematics")
    if drives and urdf is not None:
        raise click.UsageError("--drives adds drives to a chain of -S/--dof; for a URDF, pass drives=True to "
                               "jaxskid.load in the script")
    if urdf is not None:
        _urdf_template(urdf, Path(output), name, force)
        return
    structure = "R" * dof if dof is not None else structure
    try:
        check_structure(structure)
    except RequestError as exc:
        raise click.BadParameter(str(exc), param_hint="'-S' / '--structure'") from None
    if name is None:
        name = re.sub(r"[^A-Za-z0-9_]+", "_", Path(output).stem).strip("_") or "robot"
        if name[0].isdigit():
            name = f"robot_{name}"
    text = render_template(structure, fmt, name=name, kinematics="dh" if dh else "screws", drives=drives)
    _write_new(Path(output), text, force)
    click.echo(f"wrote {output}: {len(structure)}-joint {structure.upper()} {'DH ' if dh else ''}template '{name}'"
               + (" with drives" if drives else ""))


def _urdf_template(urdf: str, output: Path, name: str | None, force: bool) -> None:
    """Write the script that loads ``urdf``; the URDF is read first, so that a bad file fails here."""
    import os

    import jaxskid

    from ..description._templates import urdf_script

    robot = jaxskid.load(urdf)
    target = Path(urdf).resolve()
    relative = os.path.relpath(target, output.resolve().parent)
    ref = relative if Path(relative).parts[:3].count("..") < 3 else str(target)
    text = urdf_script(Path(ref).as_posix(), name=name, command=f"jaxskid template --urdf {Path(urdf).name}")
    _write_new(output, text, force)
    click.echo(f"wrote {output}: script loading {ref} ({name or robot.name}, {robot.n_dof} joint(s))")


def _write_new(path: Path, text: str, force: bool) -> None:
    try:
        with path.open("w" if force else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise BadInput(f"{path} already exists; use --force to overwrite it") from None


@cli.command()
@click.argument("source", type=click.Path(exists=True, dir_okay=False), callback=_robot_path)
@click.argument("output", type=click.Path(dir_okay=False))
@click.option("--symbolic-inertia/--numeric-inertia", default=False, show_default=True,
              help="URDF input: write each body's 10 inertial parameters as symbols with their values as "
                   "defaults (<link>_m, <link>_mcx, ...), or as numbers.")
@click.option("--round", "round_tol", type=click.FloatRange(min=0, max=1e-4), default=None, metavar="TOL",
              help="Replace numbers within TOL (at most 1e-4, Skidy's tolerance) of a simple exact number by it: "
                   "integers, p/q and "
                   "k*pi/q with q <= 12, sqrt(2)/2, sqrt(3)/2 (e.g. 1e-10: 6.1e-17 -> 0, 0.5 -> 1/2, "
                   "1.5707963267948966 -> pi/2; 0.0825 stays), and write rotations with such angles as "
                   "{rpy: [roll, pitch, yaw]}.")
@click.option("--symbolify", is_flag=True,
              help="Make the geometry symbols too: every nonzero number in a joint's or frame's translation "
                   "becomes <joint>_x, <joint>_y or <joint>_z (<frame>_... for frames) with the number as its "
                   "default, and each body's inertia its 10 parameters as --symbolic-inertia does. Rotations "
                   "stay numbers.")
@LOCK
@urdf_options
@DIALECT
@END_EFFECTORS
@FORCE
def convert(source, output, symbolic_inertia, round_tol, symbolify, lock, dialect, end_effectors, force):
    """Convert SOURCE (.urdf, .yaml, .json or .py) to OUTPUT in Skidy's YAML/JSON schema, or to URDF.

    The format follows OUTPUT's extension. YAML and JSON (.yaml, .yml, .json) are in the body-fixed
    representation with 6x6 mass-inertia matrices. A .urdf holds numbers only: every parameter takes its
    default (one without is an error), joints are revolute or prismatic with origin xyz/rpy and axis, and
    each link's inertial is about its centre of mass. Either loads back into the same model (jaxskid.load).

    \b
    Examples:
      jaxskid convert panda.urdf panda.yaml --round 1e-10
      jaxskid convert ur5.urdf ur5.json --symbolic-inertia
      jaxskid convert ur5.urdf ur5_symbols.yaml --symbolify --round 1e-10
      jaxskid convert arm.yaml arm.json
      jaxskid convert puma_dh.yaml puma.urdf
      jaxskid convert hopper.urdf hopper.yaml --round 1e-4 --ee foot=link3@0,0,-0.2
      jaxskid convert skidy_robot.yaml robot.yaml --dialect skidy
    """
    import jaxskid

    from ..description._symbolify import symbolify_robot
    from ..description._yaml_writer import round_robot

    to_urdf = Path(output).suffix.lower() == ".urdf"
    if Path(output).suffix.lower() not in (".yaml", ".yml", ".json", ".urdf"):
        raise click.BadParameter(f"expected a .yaml, .yml, .json or .urdf file name, got {output!r}",
                                 param_hint="OUTPUT")
    if to_urdf and (symbolify or symbolic_inertia):
        raise click.UsageError(f"{'--symbolify' if symbolify else '--symbolic-inertia'} makes parameters, "
                               f"but a .urdf holds numbers only")
    if Path(output).exists() and not force:
        raise BadInput(f"{output} already exists; use --force to overwrite it")
    urdf = {"symbolic_inertia": symbolic_inertia} if Path(source).suffix.lower() == ".urdf" else {}
    robot = load_robot(source, lock, dialect, end_effectors, **urdf)
    if round_tol:
        robot = round_robot(robot, round_tol)
    if symbolify:
        robot = symbolify_robot(robot)
    try:
        if to_urdf:
            jaxskid.write_urdf(robot, output, force=force)
        else:
            jaxskid.write_description(robot, output, force=force, rotations="rpy" if round_tol else "matrix")
    except FileExistsError:
        raise BadInput(f"{output} already exists; use --force to overwrite it") from None
    values = "parameters at their defaults" if to_urdf else f"{len(robot.parameters)} parameter(s)"
    click.echo(f"wrote {output}: {robot.name}, {robot.n_dof} joint(s), {values}")


@cli.command()
@ROBOT
@LOCK
@urdf_options
@DIALECT
@END_EFFECTORS
def info(robot, lock, dialect, end_effectors):
    """Print ROBOT's joints, bodies, frames, parameters and kinematic tree.

    \b
    Examples:
      jaxskid info robots/hopping_leg.yaml
      jaxskid info panda.urdf --lock panda_finger_joint1=0 --lock panda_finger_joint2=0
    """
    import jaxskid

    click.echo(jaxskid.describe(load_robot(robot, lock, dialect, end_effectors)))


@cli.command()
@ROBOT
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The picture to write: .svg, .png or .pdf.")
@LOCK
@urdf_options
@DIALECT
@END_EFFECTORS
@FORCE
def graph(robot, output, lock, dialect, end_effectors, force):
    """Draw ROBOT's kinematic tree (bodies, joints and frames) to a picture.

    \b
    Examples:
      jaxskid graph robots/hopping_leg.yaml -o leg.svg
      jaxskid graph panda.urdf -o panda.png --force
    """
    if Path(output).suffix.lower() not in (".svg", ".png", ".pdf"):
        raise click.BadParameter(f"expected a .svg, .png or .pdf file name, got {output!r}",
                                 param_hint="'-o' / '--output'")
    if Path(output).exists() and not force:
        raise BadInput(f"{output} already exists; use --force to overwrite it")
    import jaxskid

    model = load_robot(robot, lock, dialect, end_effectors)
    jaxskid.draw_tree(model, output)
    click.echo(f"wrote {output}: kinematic tree of {model.name} ({model.n_dof} joint(s))")


# ---------------------------------------------------------------------------------------------- entry point
def main(argv=None) -> None:
    """Console entry point: run the command line, turning every expected error into one line on stderr."""
    from .._errors import JaxskidError

    logging.basicConfig(level=logging.WARNING, format="jaxskid: warning: %(message)s")
    try:
        code = cli.main(args=argv, prog_name="jaxskid", standalone_mode=False)
    except click.UsageError as exc:
        where = exc.ctx.command_path if exc.ctx is not None else "jaxskid"
        message = " ".join(exc.format_message().split())
        click.echo(f"Error: {message} (see '{where} --help')", err=True)
        sys.exit(2)
    except click.ClickException as exc:
        click.echo(f"Error: {' '.join(exc.format_message().split())}", err=True)
        sys.exit(exc.exit_code)
    except click.Abort:
        click.echo("Error: aborted", err=True)
        sys.exit(1)
    except (JaxskidError, OSError) as exc:
        click.echo(f"Error: {' '.join(str(exc).split())}", err=True)
        sys.exit(1)
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
