"""The paper's experiments: its dataset (:mod:`~cosim_plugins.paper.dataset`), its tables and
figures regenerated on the simulated lab (:mod:`~cosim_plugins.paper.reproduce`, laid out by
:mod:`~cosim_plugins.paper.report_format`), and their commands ``cosim dataset`` and
``cosim reproduce`` (:mod:`~cosim_plugins.paper.commands`).
"""

from cosim import hookimpl


@hookimpl
def cosim_register_commands(register):
    from cosim_plugins.paper import commands

    register(commands.add_commands)
