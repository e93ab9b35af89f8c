"""Contact points from a URDF's collision geometry, for :class:`jaxskid.GroundContact`.

:func:`collision_points` reads the ``<collision>`` elements of a URDF's links and returns points fixed to the
links that stand for their shapes against a plane:

* ``<sphere radius="r">``: its centre, with the radius ``r`` (exact: a sphere touches a plane at the point
  ``r`` below its centre, whatever its orientation);
* a ``<capsule radius="r" length="l">`` (a common extension, axis along z): the centres of its two end spheres,
  with the radius ``r`` (exact as well);
* ``<box size="a b c">``: its 8 corners (exact: a convex polyhedron touches a plane at a vertex, an edge or a
  face, each held by its corners);
* ``<cylinder radius="r" length="l">``: ``rim`` points spaced evenly on each end circle (a cylinder lying on its
  side sinks at most ``r (1 - cos(pi / rim))`` between two of them);
* ``<mesh filename="..." scale="...">``: the 8 corners of the mesh's axis-aligned bounding box in its own
  frame, read with trimesh (a ``package://`` name is found as ROS and yourdfpy find it, in a folder of that
  name above the URDF). A mesh that cannot be read is a :class:`ModelError` naming the link and the file.

Each point is placed by its element's ``<origin>`` in the frame of its link. The result,
:class:`ContactPoints`, gives them as end-effector definitions ``{name: (link, 4x4 pose)}``, which
``jaxskid.load(path, end_effectors=...)`` takes (with any other end-effectors merged in: they replace the file's
own), and their radii, which ``GroundContact(dyn, points.radius)`` takes::

    points = jaxskid.collision_points(urdf, links=["base_link"])
    robot = jaxskid.load(urdf, floating_base=True, end_effectors={**feet, **points.frames})
    ground = jaxskid.GroundContact(dyn, {**dict.fromkeys(feet, 0.0), **points.radius})
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._errors import ModelError, unknown_names


class ContactPoints(NamedTuple):
    """:func:`collision_points`' result.

    ``frames``: ``{name: (link, pose)}``, each point a 4x4 pose (identity rotation) in its link's frame, named
    ``{link}_collision{i}_{j}`` (the ``j``-th point of the link's ``i``-th collision element), the form
    ``jaxskid.load(..., end_effectors=...)`` takes; ``radius``: ``{name: r}`` [m], the distance from each point
    to the surface it stands for (a sphere's or capsule's radius; 0 for corners and rims), the form
    :class:`jaxskid.GroundContact`'s ``frames`` takes.
    """

    frames: dict
    radius: dict


def collision_points(path: str | os.PathLike, links: Sequence[str] | None = None, *, rim: int = 8) -> ContactPoints:
    """The contact points of the collision geometry of ``links`` of the URDF at ``path`` (module docstring).

    Args:
        path: a ``.urdf`` file.
        links: the links whose collision elements are read (default: every link that has one). A link named
            here must have at least one.
        rim: the number of points on each end circle of a cylinder (at least 3).

    Raises:
        ModelError: naming the file and the link: an unknown link, a link without collision geometry, a
            geometry that is missing or has invalid dimensions, a mesh that cannot be read.
    """
    from lxml import etree

    source = str(path)
    if not isinstance(rim, int) or isinstance(rim, bool) or rim < 3:
        raise ModelError(f"collision_points: rim: expected a whole number >= 3, got {rim!r}", source=source)
    try:
        root = etree.parse(source, etree.XMLParser(resolve_entities=False, no_network=True)).getroot()
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ModelError(f"expected a readable URDF, got {type(exc).__name__}: {exc}", source=source) from None
    elements = {link.get("name"): link.findall("collision") for link in root.findall("link")}
    if links is None:
        chosen = [name for name, found in elements.items() if found]
    else:
        chosen = [links] if isinstance(links, str) else list(links)
        unknown = [name for name in chosen if name not in elements]
        if unknown:
            named, listed = unknown_names(unknown, list(elements))
            raise ModelError(f"unknown link {named}; the links are {listed}", where="links", source=source)
    frames, radius = {}, {}
    for link in chosen:
        if not elements[link]:
            raise ModelError("expected <collision> geometry on this link (links= names the links to read)",
                             where=f"link[name={link}]", source=source)
        for i, element in enumerate(elements[link]):
            where = f"link[name={link}].collision[{i}]"
            origin = _origin(element.find("origin"), where, source)
            for j, (point, r) in enumerate(_shape_points(element.find("geometry"), rim, where, source)):
                name = f"{link}_collision{i}_{j}"
                pose = np.eye(4)
                pose[:3, 3] = origin[:3, :3] @ point + origin[:3, 3]
                frames[name], radius[name] = (link, pose), float(r)
    return ContactPoints(frames, radius)


def _numbers(element, attribute: str, count: int, where: str, source: str, default=None) -> np.ndarray:
    text = element.get(attribute) if element is not None else None
    if text is None:
        if default is not None:
            return np.asarray(default, float)
        raise ModelError(f"expected the attribute {attribute!r}", where=where, source=source)
    try:
        values = np.asarray([float(v) for v in text.split()], float)
    except ValueError:
        values = np.array([])
    if values.shape != (count,) or not np.isfinite(values).all():
        raise ModelError(f"expected {count} finite number(s), got {text!r}", where=f"{where}.{attribute}", source=source)
    return values


def _origin(element, where: str, source: str) -> np.ndarray:
    """The 4x4 pose of an ``<origin xyz rpy>``: ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the URDF convention)."""
    xyz = _numbers(element, "xyz", 3, f"{where}.origin", source, (0.0, 0.0, 0.0))
    roll, pitch, yaw = _numbers(element, "rpy", 3, f"{where}.origin", source, (0.0, 0.0, 0.0))
    c, s = np.cos([roll, pitch, yaw]), np.sin([roll, pitch, yaw])
    rx = np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
    ry = np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
    rz = np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rz @ ry @ rx, xyz
    return pose


def _corners(low: np.ndarray, high: np.ndarray) -> list[np.ndarray]:
    return [np.array([(low, high)[a][0], (low, high)[b][1], (low, high)[c][2]])
            for a in (0, 1) for b in (0, 1) for c in (0, 1)]


def _positive(element, attribute: str, count: int, where: str, source: str) -> np.ndarray:
    values = _numbers(element, attribute, count, where, source)
    if not (values > 0).all():
        raise ModelError(f"expected positive dimensions, got {element.get(attribute)!r}", where=f"{where}.{attribute}",
                         source=source)
    return values


def _shape_points(geometry, rim: int, where: str, source: str) -> list[tuple[np.ndarray, float]]:
    """``[(point, radius)]`` in the geometry's own frame."""
    shapes = [] if geometry is None else [child for child in geometry if isinstance(child.tag, str)]
    if len(shapes) != 1:
        raise ModelError("expected one shape in <geometry> (box, sphere, cylinder, capsule or mesh)",
                         where=f"{where}.geometry", source=source)
    shape, at = shapes[0], f"{where}.geometry.{shapes[0].tag}"
    if shape.tag == "sphere":
        return [(np.zeros(3), float(_positive(shape, "radius", 1, at, source)[0]))]
    if shape.tag == "box":
        half = 0.5 * _positive(shape, "size", 3, at, source)
        return [(c, 0.0) for c in _corners(-half, half)]
    if shape.tag in ("cylinder", "capsule"):
        r, length = (float(_positive(shape, k, 1, at, source)[0]) for k in ("radius", "length"))
        if shape.tag == "capsule":
            return [(np.array([0.0, 0.0, z]), r) for z in (-length / 2, length / 2)]
        angles = 2 * math.pi * np.arange(rim) / rim
        return [(np.array([r * math.cos(a), r * math.sin(a), z]), 0.0) for z in (-length / 2, length / 2) for a in angles]
    if shape.tag == "mesh":
        low, high = _mesh_bounds(shape, at, source)
        return [(c, 0.0) for c in _corners(low, high)]
    raise ModelError(f"unknown shape <{shape.tag}>; expected box, sphere, cylinder, capsule or mesh",
                     where=f"{where}.geometry", source=source)


def _mesh_bounds(shape, where: str, source: str) -> tuple[np.ndarray, np.ndarray]:
    """The scaled axis-aligned bounding box ``(low, high)`` of a ``<mesh>`` in its own frame."""
    import trimesh
    import yourdfpy

    filename = shape.get("filename")
    if not filename:
        raise ModelError("expected the attribute 'filename'", where=where, source=source)
    scale = _numbers(shape, "scale", 3, where, source, (1.0, 1.0, 1.0))
    found = yourdfpy.filename_handler_magic(filename, dir=str(Path(source).parent))
    try:
        mesh = trimesh.load(found, force="mesh")
        bounds = np.asarray(mesh.bounds, float)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types for a missing or unreadable file
        raise ModelError(f"the mesh {filename!r} (looked for at {found}) could not be read ({type(exc).__name__}: "
                         f"{exc}); leave this link out of links= and place its points with end_effectors=",
                         where=where, source=source) from None
    if bounds.shape != (2, 3) or not np.isfinite(bounds).all():
        raise ModelError(f"the mesh {filename!r} has no vertices", where=where, source=source)
    corners = np.sort(bounds * scale, axis=0)  # a negative scale mirrors
    return corners[0], corners[1]
