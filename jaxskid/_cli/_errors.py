"""The command line's error for bad input (exit code 1); bad usage is click's ``UsageError`` (exit code 2)."""

from __future__ import annotations

import click


class BadInput(click.ClickException):
    """Bad input (exit code 1), as opposed to bad usage (exit code 2)."""

    exit_code = 1
