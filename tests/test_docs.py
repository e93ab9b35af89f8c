"""The documentation's promises about itself (the site is built by ``mkdocs build --strict`` in .ci/run):

* every public name of ``jaxskid`` has an entry (``::: jaxskid.NAME``) in the API reference;
* every performance table is a file a benchmark script wrote: each file under ``docs/performance/`` ends with
  the command that wrote it (a script of ``benchmarks/`` with ``--markdown`` and this very path, perhaps pinned
  to some cores by ``taskset``), and a page includes it; every include names an existing file;
* no page and not the README types a timing by hand (figures below a millisecond, or speed-up ratios);
* the README stays short, and its test command is the one that runs the tests.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import jaxskid

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
TABLES = DOCS / "performance"
INCLUDE = re.compile(r'^--8<-- "([^"]+)"\s*$', flags=re.M)
WRITTEN = re.compile(r"^Written by `((?:JAXSKID_\w+=\w+ )*(?:taskset -c [\d,]+ )?python benchmarks/[^`]+)` on "
                     r"\d{4}-\d\d-\d\d", flags=re.M)
TIMING = re.compile(r"\d\s?(?:ns|µs|us)\b|\b\d+(?:\.\d+)?x\b")


def pages() -> list[Path]:
    """The documentation's own pages (the included tables and the Griffe extension left out)."""
    return sorted(p for p in DOCS.rglob("*.md") if TABLES not in p.parents)


def test_every_public_name_is_in_the_api_reference():
    entries = set()
    for page in (DOCS / "api").glob("*.md"):
        entries |= set(re.findall(r"^::: jaxskid\.(\w+)\s*$", page.read_text(encoding="utf-8"), flags=re.M))
    missing = sorted(set(jaxskid.__all__) - entries)
    assert not missing, f"public names without an entry in docs/api/: {missing}"
    unknown = sorted(entries - set(jaxskid.__all__))
    assert not unknown, f"docs/api/ documents names jaxskid does not export: {unknown}"


def test_every_table_is_written_by_a_benchmark_and_included():
    included = {TABLES.parent / name for page in pages() for name in INCLUDE.findall(page.read_text(encoding="utf-8"))}
    missing = sorted(str(p.relative_to(REPO)) for p in included if not p.exists())
    assert not missing, f"pages include files that do not exist: {missing}"
    tables = sorted(TABLES.glob("*.md"))
    assert tables, "no benchmark tables under docs/performance/"
    for table in tables:
        rel = table.relative_to(REPO).as_posix()
        assert table in included, f"{rel}: no page includes it"
        found = WRITTEN.findall(table.read_text(encoding="utf-8"))
        assert len(found) == 1, f"{rel}: no line 'Written by `python benchmarks/...` on DATE' (or several)"
        words = shlex.split(found[0])
        words = words[words.index("python"):]  # after the switches and a taskset prefix, if any
        script = REPO / words[1]
        assert script.exists(), f"{rel}: written by {words[1]}, which does not exist"
        assert "--markdown" in script.read_text(encoding="utf-8") or "doc_tables.add_option" in script.read_text(
            encoding="utf-8"), f"{rel}: {words[1]} takes no --markdown"
        assert words[words.index("--markdown") + 1] == rel, f"{rel}: its command writes another file: {found[0]}"


def test_no_timing_typed_into_a_page():
    typed = []
    for path in [REPO / "README.md", *pages()]:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if TIMING.search(line):
                typed.append(f"{path.relative_to(REPO)}:{number}: {line.strip()}")
    assert not typed, "timings typed by hand (include a table a benchmark writes instead):\n" + "\n".join(typed)


def test_the_readme_is_short_and_names_the_test_command():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    assert "\nbash .ci/run\n" in readme
    assert "python -m pytest" in (REPO / ".ci" / "run").read_text(encoding="utf-8")
    assert "mkdocs build --strict" in (REPO / ".ci" / "run").read_text(encoding="utf-8")
