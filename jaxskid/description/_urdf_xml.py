"""Reading a URDF file: its bytes, its XML, and the part of it that yourdfpy reads for the dynamics.

jaxskid checks the document itself (:func:`jaxskid.description._urdf._check_document`) and then lets yourdfpy
read the numbers of the links' ``<inertial>`` and of the joints. Nothing else of the file enters the model, so
yourdfpy is given only that (:func:`dynamics_only`): a ``<visual>`` without geometry, a colour or a mesh origin
that is not three numbers, a ``<transmission>`` or a simulator's plugin do not stop the dynamics from loading,
as Pinocchio's model reader does not read them either. Contact points read the collision geometry on their own
(:mod:`jaxskid.description._collision`).
"""

from __future__ import annotations

import io

from .._errors import ModelError


def read_bytes(source: str) -> bytes:
    """The file's bytes; an error for a missing, unreadable, empty or binary file."""
    try:
        with open(source, "rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        raise ModelError("expected an existing URDF file, got no such file") from None
    except IsADirectoryError:
        raise ModelError("expected a URDF file, got a directory") from None
    except OSError as exc:
        raise ModelError(f"expected a readable URDF file, got {exc.strerror or exc}") from None
    if not data.strip():
        raise ModelError("expected a URDF (XML) document, got an empty file")
    if b"\x00" in data and not data.startswith((b"\xff\xfe", b"\xfe\xff")):  # NUL bytes, no UTF-16 mark
        raise ModelError("expected a URDF (XML) text file, got binary data")
    return data


def parse_xml(data: bytes):
    """The document's root ``<robot>`` element (lxml, no entity expansion, no network)."""
    from lxml import etree

    parser = etree.XMLParser(remove_blank_text=True, resolve_entities=False, no_network=True)
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:
        raise ModelError(f"expected well-formed XML, got a syntax error at line {exc.lineno}: {exc.msg}") from None
    except ValueError as exc:  # e.g. an undecodable encoding declaration
        raise ModelError(f"expected well-formed XML, got {exc}") from None
    tag = etree.QName(root).localname if isinstance(root.tag, str) else str(root.tag)
    if tag != "robot":
        raise ModelError(f"expected the root element <robot>, got <{tag}>", where="robot")
    return root


def load_yourdfpy(data: bytes):
    """yourdfpy's reading of ``data`` (no meshes, no scene graph); what it fails on is a :class:`ModelError`."""
    import yourdfpy

    try:
        return yourdfpy.URDF.load(
            io.BytesIO(data),
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        )
    except Exception as exc:  # noqa: BLE001 - yourdfpy raises bare KeyError/ValueError/... on what we do not check
        raise ModelError(f"expected a URDF that yourdfpy can read, got {type(exc).__name__}: {exc}",
                         where="robot") from None


def dynamics_only(root) -> bytes:
    """The document ``root`` with what the dynamics read: the robot's name, each link's name and ``<inertial>``,
    and the joints (module docstring), a fixed joint without its ``<axis>`` (urdfdom does not read it either).
    Elements are copied by their attributes' values, so that an entity of the file's own DTD arrives expanded."""
    from lxml import etree

    out = etree.Element("robot", name=root.get("name"))
    for el in root:
        if el.tag == "link":
            link = etree.SubElement(out, "link", name=el.get("name"))
            link.extend(_copy(i) for i in el.findall("inertial"))
        elif el.tag == "joint":
            joint = out.makeelement("joint", dict(el.attrib))
            joint.extend(_copy(c) for c in el if isinstance(c.tag, str) and not (
                c.tag == "axis" and el.get("type") == "fixed"))
            out.append(joint)
    return etree.tostring(out)


def _copy(el):
    out = el.makeelement(el.tag, dict(el.attrib))
    out.extend(_copy(c) for c in el if isinstance(c.tag, str))  # elements only: no comments or entity nodes
    return out
