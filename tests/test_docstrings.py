"""Every public class says what each argument of its constructor is: ``help(jaxskid.X)`` names them all."""

import inspect
import re

import pytest

import jaxskid

UNDOCUMENTED_HERE: dict[str, set[str]] = {}
"""Arguments a class's docstring may leave to another's (none)."""

CLASSES = sorted(name for name in jaxskid.__all__ if inspect.isclass(getattr(jaxskid, name)))


def constructor_arguments(cls) -> list[str]:
    """The named arguments of the constructor, private ones (a leading underscore) left out; none for a class whose
    constructor is a builtin's (the exceptions and warnings)."""
    try:
        signature = inspect.signature(cls)
    except (TypeError, ValueError):
        return []
    return [p.name for p in signature.parameters.values()
            if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and not p.name.startswith("_")]


@pytest.mark.parametrize("name", CLASSES)
def test_docstring_names_every_constructor_argument(name):
    cls = getattr(jaxskid, name)
    doc = "\n".join(filter(None, [inspect.getdoc(cls), inspect.getdoc(cls.__init__) if "__init__" in vars(cls) else ""]))
    missing = [a for a in constructor_arguments(cls)
               if not re.search(rf"(?<![\w.]){re.escape(a)}(?!\w)", doc) and a not in UNDOCUMENTED_HERE.get(name, ())]
    assert doc.strip() and not missing, f"jaxskid.{name}'s docstring does not say what {', '.join(missing)} is"


def test_computed_torque_says_what_reference_is():
    doc = inspect.getdoc(jaxskid.ComputedTorque)
    assert re.search(r"reference: the desired joint positions, a function ``q_d\(t\)", doc)
