"""The work behind ``jaxskid generate``: derive once, emit every target, time, self-check, write, and
typeset the LaTeX document with pdflatex when it is installed."""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import click

from ._errors import BadInput

PDFLATEX_TIMEOUT_S = 120
PDFLATEX_MISSING = ("PDF not made: pdflatex is not installed "
                    "(apt-get install texlive-latex-base); the .tex is written")


def generate_files(model, targets, wanted, out, *, options, style, check, force, pdf) -> None:
    """Derive once; emit every target's files (presented in ``style``, a :class:`jaxskid.codegen.CodeStyle`);
    lower the same equations for the timing and the self-check; write the files last, all or none; then make
    the PDF of the LaTeX document if asked."""
    import jaxskid

    t0 = time.perf_counter()
    eqs = jaxskid.derive(model, wanted, options=options, progress=sys.stderr.isatty())
    t_derive = time.perf_counter() - t0
    out_dir = Path(out) if out else Path("generated") / jaxskid.codegen.stem(model.name)
    files: dict[str, str] = {}
    layout = jaxskid.codegen.Layout(eqs, tuple(eqs.quantities), style=style)
    for target in targets:
        files.update(jaxskid.codegen.emit(layout, target))
    tex = [f for f in files if f.endswith(".tex")] if pdf else []
    outputs = [*files, *(str(Path(f).with_suffix(".pdf")) for f in tex)]
    existing = [str(out_dir / f) for f in outputs if (out_dir / f).exists()]
    if existing and not force:
        raise BadInput(f"{', '.join(existing)} already exist{'s' if len(existing) == 1 else ''}; "
                       "use --force to overwrite")
    t0 = time.perf_counter()
    dyn = jaxskid.lower(eqs)
    t_lower = time.perf_counter() - t0
    click.echo(f"robot {model.name}: {model.n_dof} joint(s), {len(model.parameters)} symbolic parameter(s)")
    if options != jaxskid.Options():
        click.echo(f"options: cse={options.cse}, simplify={options.simplify}, trig={options.trig}, "
                   f"coriolis={options.coriolis}")
    if style != jaxskid.codegen.CodeStyle():
        click.echo(f"style: shapes={style.shapes}, landscape={style.landscape}, project={style.project}")
    click.echo(f"{'quantity':<22} {'arguments':<22} {'shape':<12} {'operations':>10}")
    for k in layout.programs:  # the shapes of the generated files (Skidy's columns with style.shapes)
        shape = "(" + ", ".join(map(str, k.shape)) + ("," if len(k.shape) == 1 else "") + ")"
        click.echo(f"{k.name:<22} {', '.join((*k.args, 'p')):<22} {shape:<12} {eqs.operation_count([k.name]):>10}")
    values, drawn = check_values(model)
    click.echo(f"derive {t_derive:.2f} s, lower {t_lower:.2f} s (JAX module), compile "
               f"{_first_calls(dyn, values):.2f} s (jit, first call)")
    if check:
        _self_check(dyn, values, drawn)
    paths = jaxskid.codegen.write(files, out_dir, force=force)
    paths += [p for f in tex if (p := make_pdf(out_dir / f)) is not None]
    click.echo(f"wrote {len(paths)} file(s) to {out_dir}:")
    for p in paths:
        click.echo(f"  {p.name}")


def check_values(model, seed: int = 0) -> tuple[dict[str, float], dict[str, float]]:
    """``(values, drawn)``: a value for every parameter of ``model`` to run the self-check with, its default or,
    for a parameter without one (``drawn``), a random positive value, uniform in 0.5..1.5. A body's rotational
    inertia must be positive definite about its centre of mass: the parameters only on the diagonal of a body's
    rotational inertia are scaled by k and those only off it by k / 100, with k = 1, 10, 100, ... until every
    body's inertia is (then its diagonal dominates)."""
    import numpy as np
    import sympy as sp

    from ..model._validate import check_mass_inertia, symbol

    defaults = model.default_params()
    missing = [p for p in model.parameters if p not in defaults]
    if not missing:
        return defaults, {}
    inertias = [j.inertia for j in model.joints] + ([model.base_inertia] if model.floating_base else [])
    diagonal, off = set(), set()
    for m6 in inertias:
        def names(entries):
            return {s.name for e in entries for s in sp.sympify(e).free_symbols}
        other = names([m6[5, 5], *m6[:3, 3:]])  # mass and first moment
        diagonal |= names([m6[k, k] for k in range(3)]) - other
        off |= names([m6[r, c] for r in range(3) for c in range(3) if r != c]) - other - diagonal
    base = np.random.default_rng(seed).uniform(0.5, 1.5, len(missing))
    for k in (1.0, 10.0, 100.0, 1e3, 1e4):
        drawn = {p: float(b * (k if p in diagonal else k / 100 if p in off else 1.0)) for p, b in zip(missing, base)}
        values = {**defaults, **drawn}
        try:
            for m6 in inertias:
                check_mass_inertia(m6, {symbol(n): v for n, v in values.items()}, "mass_inertia")
        except Exception:  # noqa: BLE001  (a ModelError, or a value no number is made of)
            continue
        break
    return values, drawn


def _first_calls(dyn, values) -> float:
    """Seconds to call every quantity once at zero state (jit compilation, mostly), with parameters ``values``."""
    import numpy as np

    t0 = time.perf_counter()
    for name in dyn.quantities:
        args, _ = dyn.signature(name)
        state = [np.zeros(dyn.argument_shape(a)) for a in args]
        value = getattr(dyn, name)(*state, values)
        for leaf in (value.values() if isinstance(value, dict) else [value]):
            leaf.block_until_ready()
    return time.perf_counter() - t0


def _self_check(dyn, values: dict[str, float], drawn: dict[str, float]) -> None:
    from ..apps._selfcheck import self_check

    if drawn:
        shown = ", ".join(f"{k}={v:.4g}" for k, v in drawn.items())
        click.echo(f"self-check with random positive values for the {len(drawn)} parameter(s) without a default: {shown}")
    rows = self_check(dyn, values)
    if not rows:
        click.echo("self-check: nothing to compare for these quantities")
        return
    click.echo(f"{'self-check':<44} {'max error':>10} {'tolerance':>10}  result")
    for row in rows:
        click.echo(f"{row.name:<44} {row.error:>10.2e} {row.tolerance:>10.1e}  {'ok' if row.ok else 'FAILED'}")
    failed = [r.name for r in rows if not r.ok]
    if failed:
        raise click.ClickException(f"self-check failed: {', '.join(failed)}")


def make_pdf(tex: Path) -> Path | None:
    """Typeset ``tex`` with pdflatex in a temporary folder and write the PDF next to it.

    Returns the PDF's path, or None (after printing one line) when pdflatex is not installed. A failure
    or a run past :data:`PDFLATEX_TIMEOUT_S` keeps pdflatex's log next to the .tex and raises
    :class:`BadInput` naming it.
    """
    exe = shutil.which("pdflatex")
    if exe is None:
        click.echo(PDFLATEX_MISSING)
        return None
    log, pdf = tex.with_suffix(".log"), tex.with_suffix(".pdf")
    with tempfile.TemporaryDirectory(prefix="jaxskid-latex-") as tmp:
        shutil.copyfile(tex, Path(tmp) / tex.name)
        try:
            proc = subprocess.run([exe, "-interaction=nonstopmode", "-halt-on-error", "-no-shell-escape", tex.name],
                                  cwd=tmp, stdin=subprocess.DEVNULL, capture_output=True,
                                  timeout=PDFLATEX_TIMEOUT_S)
            problem = None if proc.returncode == 0 else f"exit code {proc.returncode}"
        except subprocess.TimeoutExpired:
            problem = f"no result after {PDFLATEX_TIMEOUT_S} s"
        made = Path(tmp) / pdf.name
        if problem is None and made.is_file():
            shutil.copyfile(made, pdf)
            return pdf
        if (Path(tmp) / log.name).is_file():
            shutil.copyfile(Path(tmp) / log.name, log)
            raise BadInput(f"pdflatex failed on {tex} ({problem or 'no PDF'}); see {log}")
        raise BadInput(f"pdflatex failed on {tex} ({problem or 'no PDF'}) and wrote no log")
