"""The code the README and the getting-started page show runs: every ```python block of each file, in order,
in one namespace per file, from the repository root (the blocks load ``robots/...`` by relative path), under
the suite's strict JAX settings. A block that raises, or an ``assert`` in a block that fails, fails the test."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = ["README.md", "docs/getting-started.md"]
BLOCK = re.compile(r"^```python\n(.*?)^```", flags=re.S | re.M)


def python_blocks(path: Path) -> list[str]:
    """The ```python blocks of a Markdown file, in order."""
    return BLOCK.findall(path.read_text(encoding="utf-8"))


def test_the_pages_have_code():
    for page in PAGES:
        assert python_blocks(REPO / page), f"{page}: no ```python block"


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES)
def test_code_blocks_run(page, monkeypatch):
    monkeypatch.chdir(REPO)
    namespace = {"__name__": f"docs:{page}"}
    for k, block in enumerate(python_blocks(REPO / page)):
        exec(compile(block, f"{page} (python block {k + 1})", "exec"), namespace)  # noqa: S102
