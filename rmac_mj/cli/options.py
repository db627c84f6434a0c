"""The ``rmac-mj`` command line: the parser of every command (each command's options are in
:mod:`rmac_mj.cli.run_options` and :mod:`rmac_mj.cli.view_options`)."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from typing import Any

from rmac_mj import __version__
from rmac_mj.cli import run_options, view_options
from rmac_mj.cli.arguments import HelpFormatter, OneLineErrorParser
from rmac_mj.cli.common import PROG
from rmac_mj.cli.run_options import PROTOCOL_OPTIONS

__all__ = ["DESCRIPTION", "PROTOCOL_OPTIONS", "build_parser"]

DESCRIPTION = "The rmac-mj command: reproduce the paper's comparison, draw its figures, render videos, benchmark."


def build_parser(reproduce_defaults: Mapping[str, Any] | None = None) -> argparse.ArgumentParser:
    """The parser of every command. ``reproduce_defaults``: defaults of ``reproduce``'s options that
    replace its own (the settings of a ``--config`` file or of a directory being resumed), by dest."""
    parser = OneLineErrorParser(
        prog=PROG,
        description=DESCRIPTION,
        epilog="Run 'rmac-mj COMMAND --help' for a command's options.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    commands = parser.add_subparsers(
        dest="command", metavar="COMMAND", title="commands", parser_class=OneLineErrorParser
    )
    run_options.add_reproduce(commands, reproduce_defaults)
    run_options.add_sweep(commands)
    run_options.add_panel(commands)
    view_options.add_compare(commands)
    view_options.add_policy(commands)
    view_options.add_optimal(commands)
    view_options.add_render(commands)
    view_options.add_bench(commands)
    return parser
