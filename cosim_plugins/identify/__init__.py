"""The swimmer's identification: datasets from raw logs, the Model and Effect contracts, fitting and
comparing models, and their commands (``cosim fit``, ``convert``, ``compare``); ``cosim diagnose``
has its own package, :mod:`cosim_plugins.diagnose`.

Models and effects are plugins of their own kinds: this package adds the hooks
``cosim_register_models`` and ``cosim_register_effects`` (:mod:`~cosim_plugins.identify.hookspecs`);
the paper's four models live in ``cosim_plugins.models``, the named effects in
``cosim_plugins.effects``. See :mod:`cosim_plugins.identify.model` for the Model contract.
"""

from cosim import hookimpl
from cosim_plugins.identify.dataset import Dataset
from cosim_plugins.identify.model import Model, load_model

__all__ = ["Dataset", "Model", "load_model"]


@hookimpl
def cosim_addhooks(pluginmanager):
    from cosim_plugins.identify import hookspecs

    pluginmanager.add_hookspecs(hookspecs)


@hookimpl
def cosim_register_environment(register):
    register("COSIM_DATASET")  # quick: models trained on demand use the short dataset (identify.cache)


@hookimpl
def cosim_register_commands(register):
    from cosim_plugins.identify import cli

    register(cli.add_commands)
