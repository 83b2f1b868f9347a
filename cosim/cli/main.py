"""The ``cosim`` command.

The framework's commands are in :mod:`cosim.cli.commands`, whose
``add_commands(subparsers)`` adds their subparsers and sets ``func`` to a
callable taking the parsed arguments and returning an exit code. Plugins add
theirs the same way through the ``cosim_register_commands`` hook (a domain's
analyses and tools).
"""

from __future__ import annotations

import argparse
import os
import sys

from cosim.cli import commands
from cosim.contract.errors import RunError, UserError
from cosim.contract.plugins import command_groups


def build_parser() -> argparse.ArgumentParser:
    """The ``cosim`` parser: the framework's commands and those the installed plugins add."""
    parser = argparse.ArgumentParser(
        prog="cosim",
        description="Lockstep co-simulation over zenoh: run, sweep, record and replay scenarios; "
                    "the installed domains add their own commands.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    commands.add_commands(sub)
    for add_commands in command_groups():
        add_commands(sub)
    for command in sub.choices.values():
        command.add_argument("--trust-model-code", action="store_true",
                             help="run Python code carried inside model files (a user effect's source); without "
                                  "it a model whose effect's file is not named refuses to load")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``cosim`` command on ``argv``; its exit status (2 and one line for a user's error)."""
    try:
        parser = build_parser()
    except Exception as exc:  # a plugin that fails to load or register its commands
        if _is_user_error(exc):
            print(f"cosim: error: {exc}", file=sys.stderr)
            return 2
        raise
    args = parser.parse_args(argv)
    if getattr(args, "trust_model_code", False):
        os.environ["COSIM_TRUST_MODEL_CODE"] = "1"  # the processes this command starts inherit it
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("cosim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the output went to a pager or `head` that has quit: not an error
        sys.stdout = open(os.devnull, "w")
        return 0
    except Exception as exc:  # one clear line for expected errors, see below
        if _is_user_error(exc):
            print(f"cosim {args.command}: error: {exc}", file=sys.stderr)
            return 2
        raise


def _is_user_error(exc: Exception) -> bool:
    """Errors of input (files, scenarios, plugins) and of a run that stopped print one line, not a traceback."""
    return isinstance(exc, (UserError, RunError, FileNotFoundError))


if __name__ == "__main__":
    sys.exit(main())
