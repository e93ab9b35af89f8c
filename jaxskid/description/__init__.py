"""Robot descriptions: readers (URDF; Skidy's YAML/JSON schema: file, value forms, schema, wrenches), the
writer, templates for new descriptions, and reports (tables and a tree drawing) of a model."""

from ._report import describe, draw_tree
from ._templates import render_template
from ._urdf import read_urdf
from ._yaml_schema import DescriptionExtras, parse_description, parse_extras, read_description, read_extras
from ._yaml_writer import robot_to_dict, round_robot, write_description

__all__ = [
    "DescriptionExtras",
    "describe",
    "draw_tree",
    "parse_description",
    "parse_extras",
    "read_description",
    "read_extras",
    "read_urdf",
    "render_template",
    "robot_to_dict",
    "round_robot",
    "write_description",
]
