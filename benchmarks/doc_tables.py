"""The Markdown tables that the documentation includes: each benchmark script that prints a table takes
``--markdown PATH`` and writes the same figures there, followed by the command that wrote them, the date and
the machine. The pages of ``docs/`` include these files (``docs/performance/*.md``) unedited, so every figure
in the documentation names the run that measured it.

    python benchmarks/core.py --markdown docs/performance/core.md
"""

from __future__ import annotations

import datetime
import importlib.metadata
import os
import platform
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def add_option(parser) -> None:
    """``--markdown PATH`` on a script's argument parser."""
    parser.add_argument("--markdown", type=Path, default=None, metavar="PATH",
                        help="also write the table as Markdown to PATH (with this command, the date and the machine)")


class Lines(list):
    """Table lines, printed as they come and kept for :func:`write`: ``out = Lines(); out("| a | b |")``."""

    def __call__(self, line: str = "", **_) -> None:
        print(line, flush=True)
        self.append(line)


def duration(seconds: float) -> str:
    """A time with three significant digits in ns, µs, ms or s."""
    for unit, scale in (("ns", 1e-9), ("µs", 1e-6), ("ms", 1e-3)):
        if seconds < 1000 * scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds:.3g} s"


def ratio(x: float) -> str:
    """A ratio such as a speed-up, with two significant digits below 10."""
    return f"{x:.2g}x" if x < 10 else f"{x:.0f}x"


def table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table's lines."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]


def command() -> str:
    """The command line that runs this process, from the repository root; ``taskset -c CPUS`` first where the
    process may run on fewer cores than the machine has (XLA's threads and the native kernels' follow), and
    jaxskid's switches where the environment sets them (``JAXSKID_NATIVE=0``)."""
    script = Path(sys.argv[0]).resolve()
    try:
        script = script.relative_to(ROOT)
    except ValueError:
        pass
    words = ["python", script.as_posix(), *sys.argv[1:]]
    if hasattr(os, "sched_getaffinity") and len(os.sched_getaffinity(0)) < (os.cpu_count() or 1):
        words = ["taskset", "-c", ",".join(map(str, sorted(os.sched_getaffinity(0)))), *words]
    switches = [f"{k}={os.environ[k]}" for k in ("JAXSKID_NATIVE", "JAXSKID_SYNC_DISPATCH", "JAXSKID_MALLOC",
                                                 "JAXSKID_RECYCLE")
                if k in os.environ]
    return shlex.join([*switches, *words]) if switches else shlex.join(words)


def _version(name: str) -> str | None:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


def machine() -> str:
    """The processor, the cores this process may use, the accelerator JAX runs on, and the versions."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    parts = [f"{cpu}, {cores} core{'' if cores == 1 else 's'} available"]
    if hasattr(os, "getloadavg"):  # other work on the machine moves the figures: say how busy it was
        parts[0] += f" (load average {os.getloadavg()[0]:.1f} when written)"
    if "jax" in sys.modules:
        import jax

        device = jax.devices()[0]
        if device.platform != "cpu":
            parts.append(f"{jax.device_count()} x {device.device_kind}")
    versions = [f"{name} {v}" for name in ("jax", "jaxlib", "pin") if (v := _version(name))]
    parts.append(", ".join(versions).replace("pin ", "Pinocchio "))
    return "; ".join(parts)


def write(path: Path | None, lines: list[str], notes: str = "") -> None:
    """Write ``lines`` (a table, or several with blank lines between) to ``path``, then ``notes`` and a line
    with the command, the date and the machine. Nothing happens when ``path`` is None."""
    if path is None:
        return
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = "\n".join(lines) + "\n\n"
    if notes:
        text += notes.strip() + "\n\n"
    text += f"Written by `{command()}` on {stamp}; {machine()}.\n"
    path.write_text(text)
    print(f"wrote {path}")
