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


def generate_files(model, targets, wanted, out, *, options, check, force, pdf) -> None:
    """Derive once; emit every target's files; lower the same equations for the timing and the self-check;
    write the files last, all or none; then make the PDF of the LaTeX document if asked."""
    import jaxskid

    t0 = time.perf_counter()
    eqs = jaxskid.derive(model, wanted, options=options, progress=sys.stderr.isatty())
    t_derive = time.perf_counter() - t0
    out_dir = Path(out) if out else Path("generated") / jaxskid.codegen.stem(model.name)
    files: dict[str, str] = {}
    for target in targets:
        files.update(jaxskid.codegen.emit(eqs, target))
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
        click.echo(f"options: cse={options.cse}, simplify={options.simplify}, trig={options.trig}")
    click.echo(f"{'quantity':<22} {'arguments':<22} {'shape':<12} {'operations':>10}")
    for qname, q in eqs.quantities.items():
        shape = "(" + ", ".join(map(str, q.shape)) + ("," if len(q.shape) == 1 else "") + ")"
        click.echo(f"{qname:<22} {', '.join((*q.args, 'p')):<22} {shape:<12} {eqs.operation_count([qname]):>10}")
    defaults_known = set(model.parameters) <= set(model.default_params())
    compile_text = f"{_first_calls(dyn):.2f} s (jit, first call)" if defaults_known else \
        "skipped (parameters without defaults)"
    click.echo(f"derive {t_derive:.2f} s, lower {t_lower:.2f} s (JAX module), compile {compile_text}")
    if check:
        _self_check(dyn, defaults_known)
    paths = jaxskid.codegen.write(files, out_dir, force=force)
    paths += [p for f in tex if (p := make_pdf(out_dir / f)) is not None]
    click.echo(f"wrote {len(paths)} file(s) to {out_dir}:")
    for p in paths:
        click.echo(f"  {p.name}")


def _first_calls(dyn) -> float:
    """Seconds to call every quantity once at zero state (jit compilation, mostly)."""
    import numpy as np

    t0 = time.perf_counter()
    for name in dyn.quantities:
        args, _ = dyn.signature(name)
        state = [np.zeros(dyn.argument_shape(a)) for a in args]
        value = getattr(dyn, name)(*state)
        for leaf in (value.values() if isinstance(value, dict) else [value]):
            leaf.block_until_ready()
    return time.perf_counter() - t0


def _self_check(dyn, defaults_known: bool) -> None:
    if not defaults_known:
        click.echo("self-check: skipped (some parameters have no default value)")
        return
    from ..apps._selfcheck import self_check

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
