"""``safenav place``: landmark placement from the command line (work in progress)."""

from __future__ import annotations


def register(sub) -> None:
    """Add the ``place`` subcommand to the CLI's subparsers."""
