"""The ``cosim`` command: :mod:`~cosim.cli.main` builds the parser from the
framework's own commands (:mod:`~cosim.cli.commands`: run, validate, schema,
plugins, replay, node, certs) and those plugins add through the
``cosim_register_commands`` hook, and turns a user's error into one line.
"""

from cosim.cli.main import main

__all__ = ["main"]
