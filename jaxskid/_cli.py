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
import time
from pathlib import Path

import click

TARGET_NAMES = ("jax", "python", "c", "cpp", "cython", "julia", "matlab", "latex")
ROBOT_SUFFIXES = (".urdf", ".yaml", ".yml", ".json", ".py")


class BadInput(click.ClickException):
    """Bad input (exit code 1), as opposed to bad usage (exit code 2)."""

    exit_code = 1


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


def _robot_path(ctx, param, value):
    if value is not None and Path(value).suffix.lower() not in ROBOT_SUFFIXES:
        raise click.BadParameter(f"expected a {', '.join(ROBOT_SUFFIXES)} file, got {value!r}", ctx, param)
    return value


ROBOT = click.argument("robot", type=click.Path(exists=True, dir_okay=False), callback=_robot_path)
LOCK = click.option("--lock", "lock", multiple=True, callback=_parse_lock, metavar="JOINT=POSITION",
                    help="Fix a joint at a position (repeat for several joints).")
FORCE = click.option("--force", is_flag=True, help="Overwrite existing files.")


# ---------------------------------------------------------------------------------------------- loading
def load_robot(path: str, lock: dict[str, float] | None = None):
    """A Robot from a description file, or from the variable ``robot`` of a Python file."""
    import jaxskid

    p = Path(path)
    if p.suffix.lower() != ".py":
        return jaxskid.load(p, lock=lock or None)
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
    return robot.lock(lock) if lock else robot


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
@click.option("--symbolic", "symbolic", default=None, metavar="P1,P2,...",
              help="Parameters that stay inputs; every other one becomes its default value. "
                   "'' makes all of them numbers [default: all stay symbolic].")
@click.option("--check/--no-check", default=True, show_default=True, help="Run the numeric self-check.")
@FORCE
def generate(robot, targets, quantities, out, lock, symbolic, check, force):
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
    """
    import jax

    model = load_robot(robot, lock)
    if symbolic is not None:
        model = model.keep_symbolic([s.strip() for s in symbolic.split(",") if s.strip()], where="--symbolic")
    wanted = _merge(quantities)
    wanted = "all" if wanted and "all" in wanted else wanted
    with jax.enable_x64(True):  # the generated code and the self-check run in float64
        _generate(model, _merge(targets) or ("jax",), wanted, out, check, force)


def _generate(model, targets, wanted, out, check, force) -> None:
    """Derive once; emit every target's files; lower the same equations for the timing and the self-check;
    write the files last, all or none."""
    import jaxskid

    t0 = time.perf_counter()
    eqs = jaxskid.derive(model, wanted, progress=sys.stderr.isatty())
    t_derive = time.perf_counter() - t0
    out_dir = Path(out) if out else Path("generated") / jaxskid.codegen.stem(model.name)
    files: dict[str, str] = {}
    for target in targets:
        files.update(jaxskid.codegen.emit(eqs, target))
    existing = [str(out_dir / f) for f in files if (out_dir / f).exists()]
    if existing and not force:
        raise BadInput(f"{', '.join(existing)} already exist{'s' if len(existing) == 1 else ''}; "
                       "use --force to overwrite")
    t0 = time.perf_counter()
    dyn = jaxskid.lower(eqs)
    t_lower = time.perf_counter() - t0
    click.echo(f"robot {model.name}: {model.n_dof} joint(s), {len(model.parameters)} symbolic parameter(s)")
    click.echo(f"{'quantity':<22} {'arguments':<22} {'shape':<12} {'operations':>10}")
    for name, q in eqs.quantities.items():
        shape = "(" + ", ".join(map(str, q.shape)) + ("," if len(q.shape) == 1 else "") + ")"
        click.echo(f"{name:<22} {', '.join((*q.args, 'p')):<22} {shape:<12} {eqs.operation_count([name]):>10}")
    defaults_known = set(model.parameters) <= set(model.default_params())
    compile_text = f"{_first_calls(dyn):.2f} s (jit, first call)" if defaults_known else \
        "skipped (parameters without defaults)"
    click.echo(f"derive {t_derive:.2f} s, lower {t_lower:.2f} s (JAX module), compile {compile_text}")
    if check:
        _self_check(dyn, defaults_known)
    paths = jaxskid.codegen.write(files, out_dir, force=force)
    click.echo(f"wrote {len(paths)} file(s) to {out_dir}:")
    for p in paths:
        click.echo(f"  {p.name}")


def _first_calls(dyn) -> float:
    """Seconds to call every quantity once at zero state (jit compilation, mostly)."""
    import numpy as np

    t0 = time.perf_counter()
    for name in dyn.quantities:
        args, _ = dyn.signature(name)
        state = [np.zeros((len(dyn.end_effectors), 6) if a.startswith("wrench") else dyn.n_dof) for a in args]
        value = getattr(dyn, name)(*state)
        for leaf in (value.values() if isinstance(value, dict) else [value]):
            leaf.block_until_ready()
    return time.perf_counter() - t0


def _self_check(dyn, defaults_known: bool) -> None:
    if not defaults_known:
        click.echo("self-check: skipped (some parameters have no default value)")
        return
    from .apps._selfcheck import self_check

    rows = self_check(dyn)
    if not rows:
        click.echo("self-check: nothing to compare for these quantities")
        return
    click.echo(f"{'self-check':<44} {'max error':>10} {'tolerance':>10}  result")
    for row in rows:
        click.echo(f"{row.name:<44} {row.error:>10.2e} {row.tolerance:>10.1e}  {'ok' if row.ok else 'FAILED'}")
    failed = [r.name for r in rows if not r.ok]
    if failed:
        raise click.ClickException(f"self-check failed: {', '.join(failed)}")


@cli.command()
@click.option("-S", "--structure", required=True, metavar="LETTERS",
              help="Joint types from base to tip: R revolute, P prismatic (e.g. RRP).")
@click.argument("output", type=click.Path(dir_okay=False))
@click.option("--name", default=None, help="The robot's name [default: the file name].")
@FORCE
def template(structure, output, name, force):
    """Write a robot template to OUTPUT (.yaml, .yml, .json or .py) that loads, derives and lowers as it is.

    The chain has one joint per letter; every length, mass and inertia is a parameter with a default.

    \b
    Examples:
      jaxskid template -S RRP robot.yaml
      jaxskid template -S RRRRRR arm6.json --name arm6
      jaxskid template -S PRR leg.py && python leg.py
    """
    import re

    from jaxskid import RequestError

    from .description._templates import check_structure, render_template

    suffix = Path(output).suffix.lower()
    fmt = {".yaml": "yaml", ".yml": "yaml", ".json": "json", ".py": "py"}.get(suffix)
    if fmt is None:
        raise click.BadParameter(f"expected a .yaml, .yml, .json or .py file name, got {output!r}",
                                 param_hint="OUTPUT")
    try:
        check_structure(structure)
    except RequestError as exc:
        raise click.BadParameter(str(exc), param_hint="'-S' / '--structure'") from None
    if name is None:
        name = re.sub(r"[^A-Za-z0-9_]+", "_", Path(output).stem).strip("_") or "robot"
        if name[0].isdigit():
            name = f"robot_{name}"
    text = render_template(structure, fmt, name=name)
    _write_new(Path(output), text, force)
    click.echo(f"wrote {output}: {len(structure)}-joint {structure.upper()} template '{name}'")


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
@click.option("--round", "round_tol", type=click.FloatRange(min=0, max=0.1), default=None, metavar="TOL",
              help="Round numbers within TOL of 0, 1 or -1 to exactly that (e.g. 1e-10: cos(pi/2) -> 0).")
@LOCK
@FORCE
def convert(source, output, symbolic_inertia, round_tol, lock, force):
    """Convert SOURCE (.urdf, .yaml, .json or .py) to OUTPUT in Skidy's YAML/JSON schema.

    The output is in the body-fixed representation with 6x6 mass-inertia matrices; it loads back into
    the same model (jaxskid.load). The format follows OUTPUT's extension (.yaml, .yml or .json).

    \b
    Examples:
      jaxskid convert panda.urdf panda.yaml --round 1e-10
      jaxskid convert ur5.urdf ur5.json --symbolic-inertia
      jaxskid convert arm.yaml arm.json
    """
    import jaxskid

    from .description._yaml_writer import round_robot

    if Path(output).suffix.lower() not in (".yaml", ".yml", ".json"):
        raise click.BadParameter(f"expected a .yaml, .yml or .json file name, got {output!r}", param_hint="OUTPUT")
    if Path(output).exists() and not force:
        raise BadInput(f"{output} already exists; use --force to overwrite it")
    if Path(source).suffix.lower() == ".urdf":
        robot = jaxskid.load(source, lock=lock or None, symbolic_inertia=symbolic_inertia)
    else:
        robot = load_robot(source, lock)
    if round_tol:
        robot = round_robot(robot, round_tol)
    try:
        jaxskid.write_description(robot, output, force=force)
    except FileExistsError:
        raise BadInput(f"{output} already exists; use --force to overwrite it") from None
    click.echo(f"wrote {output}: {robot.name}, {robot.n_dof} joint(s), {len(robot.parameters)} parameter(s)")


@cli.command()
@ROBOT
@LOCK
def info(robot, lock):
    """Print ROBOT's joints, bodies, frames, parameters and kinematic tree.

    \b
    Examples:
      jaxskid info robots/hopping_leg.yaml
      jaxskid info panda.urdf --lock panda_finger_joint1=0 --lock panda_finger_joint2=0
    """
    import jaxskid

    click.echo(jaxskid.describe(load_robot(robot, lock)))


@cli.command()
@ROBOT
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="The picture to write: .svg, .png or .pdf.")
@LOCK
@FORCE
def graph(robot, output, lock, force):
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

    model = load_robot(robot, lock)
    jaxskid.draw_tree(model, output)
    click.echo(f"wrote {output}: kinematic tree of {model.name} ({model.n_dof} joint(s))")


# ---------------------------------------------------------------------------------------------- entry point
def main(argv=None) -> None:
    """Console entry point: run the command line, turning every expected error into one line on stderr."""
    from ._errors import JaxskidError

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
