"""The joint order of a URDF: a depth-first walk of its link tree, and a floating joint from the root read as the
floating base (:mod:`jaxskid.description._urdf`)."""

from __future__ import annotations

import numpy as np

from .._errors import ModelError


def walk_tree(links, joints) -> tuple[list, str, bool]:
    """``(joints, root link, floating)``: the joints in depth-first order from the single root link, children in
    the order of their names (urdfdom's). A ``floating`` joint from the root (``world`` -> base; the root's one
    joint, which the document's check ensures) is left out, its child then the root and ``floating`` True."""
    order, root = _walk(links, joints)
    if not order or order[0].type != "floating":
        return order, root, False
    _identity_origin(order[0])
    return order[1:], order[0].child, True


def _identity_origin(joint) -> None:
    """A floating root joint places the base by its coordinates alone: its ``<origin>`` must be the identity."""
    if joint.origin is not None and not np.allclose(np.asarray(joint.origin, dtype=float), np.eye(4), atol=1e-12):
        raise ModelError("expected no <origin> (or the identity) on a floating joint from the root link: the base "
                         "pose is its coordinates", where=f"joint[name={joint.name}].origin")


def _walk(links, joints) -> tuple[list, str]:
    """The joints in depth-first order from the single root link, children in the order of their names."""
    parent_joint: dict = {}
    for j in joints:
        if j.child in parent_joint:
            raise ModelError(
                f"expected each link to have one parent joint, got link {j.child!r} also the child of joint "
                f"{parent_joint[j.child].name!r}",
                where=f"joint[name={j.name}].child",
            )
        parent_joint[j.child] = j
    roots = [link.name for link in links if link.name not in parent_joint]
    if len(roots) > 1:
        raise ModelError(
            f"expected exactly one root link (a link that is no joint's child), got {len(roots)}: {', '.join(roots)}",
            where="robot",
        )
    children: dict[str, list] = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j)
    for c in children.values():
        c.sort(key=lambda j: j.name.encode())  # std::string order, as urdfdom's std::map
    order: list = []
    if roots:
        stack = list(reversed(children.get(roots[0], [])))
        while stack:
            j = stack.pop()
            order.append(j)
            stack.extend(reversed(children.get(j.child, [])))
    if len(order) < len(joints):  # a link whose parent chain never reaches the root lies on a cycle
        reached = {j.name for j in order}
        link = next(j.child for j in joints if j.name not in reached)
        chain: list[str] = []
        while link not in chain:
            chain.append(link)
            link = parent_joint[link].parent
        cycle = [parent_joint[x].name for x in chain[chain.index(link):]]
        raise ModelError(
            f"expected a tree, got a cycle of joints {' -> '.join([*reversed(cycle), cycle[-1]])}",
            where=f"joint[name={cycle[-1]}]",
        )
    return order, roots[0]
