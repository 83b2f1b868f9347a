"""The ``cosim`` command.

Each command lives in its own module with ``add_commands(subparsers)``,
which adds its subparser(s) and sets ``func`` to a callable taking the
parsed arguments and returning an exit code. Plugins add theirs the same
way through the ``cosim_register_commands`` hook (e.g. ``cosim camera``).
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: Modules contributing subcommands, in help order.
COMMAND_MODULES: tuple[str, ...] = (
    "cosim.commands",
    "cosim.identify.cli",
)


class CLIError(Exception):
    """An error to print as one line and exit with status 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cosim",
        description="Co-simulation and data-driven control of a magnetic swimmer.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_commands(sub)
    from cosim.plugins import command_groups

    for add_commands in command_groups():
        add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        parser = build_parser()
    except Exception as exc:  # a plugin that fails to load or register its commands
        if _is_user_error(exc):
            print(f"cosim: error: {exc}", file=sys.stderr)
            return 2
        raise
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("cosim: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # one clear line for expected errors, see below
        if _is_user_error(exc):
            print(f"cosim {args.command}: error: {exc}", file=sys.stderr)
            return 2
        raise


def _is_user_error(exc: Exception) -> bool:
    """Errors caused by input (files, scenarios, plugins) print one line, not a traceback."""
    from cosim.errors import UserError

    return isinstance(exc, (CLIError, UserError, FileNotFoundError))


if __name__ == "__main__":
    sys.exit(main())
