"""A Griffe extension for the API reference: the docstrings' Sphinx roles (``:func:`load```,
``:class:`~jaxskid.Robot```) become cross-references to the documented object, plain code where the target
is not documented (a private module, say), so the roles read as names and never as broken links."""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:func|class|meth|attr|mod|data|exc|obj|const):`(~?)([^`]+?)`")


def _reference(match: re.Match) -> str:
    short, target = match.group(1), match.group(2).strip()
    text = target.rsplit(".", 1)[-1] if short else target
    identifier = target if target.startswith("jaxskid") else f"jaxskid.{target}"
    return f'<autoref optional identifier="{identifier}"><code>{text}</code></autoref>'


class SphinxRoles(griffe.Extension):
    """Rewrite the roles of every docstring as it is loaded."""

    def on_instance(self, *, obj: griffe.Object, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = ROLE.sub(_reference, obj.docstring.value)
