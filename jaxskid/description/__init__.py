"""Robot descriptions: readers (URDF; Skidy's YAML/JSON schema: file, value forms, schema, wrenches;
Denavit–Hartenberg tables), the writers (YAML/JSON, URDF), templates for new descriptions, and reports
(tables and a tree drawing) of a model."""

from ._dh import DH, dh_robot
from ._report import describe, draw_tree
from ._templates import render_template
from ._urdf import read_urdf
from ._urdf_writer import robot_to_urdf, write_urdf
from ._yaml_schema import DescriptionExtras, parse_description, parse_extras, read_description, read_extras
from ._yaml_writer import robot_to_dict, round_robot, write_description

__all__ = [
    "DH",
    "DescriptionExtras",
    "describe",
    "dh_robot",
    "draw_tree",
    "parse_description",
    "parse_extras",
    "read_description",
    "read_extras",
    "read_urdf",
    "render_template",
    "robot_to_dict",
    "robot_to_urdf",
    "round_robot",
    "write_description",
    "write_urdf",
]
