"""Reader and writer of the collision part of an SRDF (MoveIt's Semantic Robot Description Format).

An SRDF is an XML file whose root is ``<robot name="...">``. Of what it may hold, one element
decides which pairs of links a collision checker queries::

    <disable_collisions link1="PELVIS_S" link2="R_HIP_Y_S" reason="Adjacent"/>

MoveIt's setup assistant writes one per pair it disables, with the reason it found
(``Adjacent``, ``Default``, ``Always``, ``Never``, or ``User``); pinocchio's
``removeCollisionPairs`` reads the same elements (by link name; a link the model does not have is
passed over). The rest of an SRDF does not change the pairs and is ignored here: ``group``,
``group_state``, ``end_effector``, ``virtual_joint``, ``passive_joint``, ``link_sphere_approximation``
and pinocchio's own ``rotor_params`` and ``specificities``. Two newer elements of srdfdom (2.x) do
change the pairs, ``disable_default_collisions`` (a link disabled against every other) and
``enable_collisions`` (a pair re-enabled); none of example-robot-data's files has them, and this
reader refuses a file that has them (ValueError) rather than read it wrong.

Link names are the URDF's link names. A pair is unordered.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

DISABLE = "disable_collisions"
UNSUPPORTED = ("disable_default_collisions", "enable_collisions")  # elements that change the pairs, not read here


def read_srdf(path) -> list[tuple[str, str, str]]:
    """The disabled link pairs of the SRDF file ``path``: (link1, link2, reason) per
    ``<disable_collisions>`` element, in file order, a pair listed twice (in either order) kept once
    (its first reason). reason is '' when the element has none.

    ValueError for a missing or unreadable file, XML that is not well formed, a root element other
    than ``<robot>``, an element without link1 or link2 (or with an empty one), or an element this
    reader does not support (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"SRDF file not found: {path}")
    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as exc:
        raise ValueError(f"SRDF {path} is not well-formed XML: {exc}") from None
    except OSError as exc:
        raise ValueError(f"SRDF {path} cannot be read: {exc}") from None
    if root.tag != "robot":
        raise ValueError(f"SRDF {path}: the root element must be <robot>, got <{root.tag}>")
    for tag in UNSUPPORTED:
        if root.find(tag) is not None:
            raise ValueError(f"SRDF {path} has <{tag}> elements, which change the collision pairs and which this "
                             f"reader does not support (it reads only <{DISABLE}>)")
    out, seen = [], set()
    for k, element in enumerate(root.findall(DISABLE)):
        links = []
        for attribute in ("link1", "link2"):
            value = element.get(attribute)
            if value is None or not value.strip():
                raise ValueError(f"SRDF {path}: <{DISABLE}> number {k + 1} has no {attribute} attribute "
                                 f"(attributes: {dict(element.attrib)}); link1 and link2 must name links")
            links.append(value.strip())
        key = frozenset(links)
        if key in seen:
            continue
        seen.add(key)
        out.append((links[0], links[1], element.get("reason", "").strip()))
    return out


def write_srdf(path, robot_name: str, pairs, comment: str | None = None) -> Path:
    """Write an SRDF holding ``<robot name=robot_name>`` and one ``<disable_collisions link1 link2
    reason/>`` per entry of ``pairs`` (each (link1, link2, reason), or (link1, link2) for reason ''),
    in the given order; ``comment`` (optional) goes into an XML comment at the top. Returns the path.

    ValueError for an empty robot name, an entry that is not 2 or 3 strings, or an empty link name."""
    if not isinstance(robot_name, str) or not robot_name.strip():
        raise ValueError(f"robot_name must be a non-empty string; got {robot_name!r}")
    root = ElementTree.Element("robot", name=robot_name)
    if comment:
        root.append(ElementTree.Comment(f" {comment.replace('--', '- -')} "))
    for k, entry in enumerate(pairs):
        try:
            link1, link2, *rest = entry
        except (TypeError, ValueError):
            raise ValueError(f"pairs[{k}] must be (link1, link2[, reason]); got {entry!r}") from None
        if len(rest) > 1 or not all(isinstance(s, str) for s in (link1, link2, *rest)):
            raise ValueError(f"pairs[{k}] must be (link1, link2[, reason]) strings; got {entry!r}")
        if not link1.strip() or not link2.strip():
            raise ValueError(f"pairs[{k}] names an empty link: {entry!r}")
        ElementTree.SubElement(root, DISABLE, link1=link1, link2=link2, reason=rest[0] if rest else "")
    tree = ElementTree.ElementTree(root)
    ElementTree.indent(tree, space="  ")
    path = Path(path)
    tree.write(path, encoding="utf-8", xml_declaration=True)
    with open(path, "a", encoding="utf-8") as f:
        f.write("\n")
    return path
