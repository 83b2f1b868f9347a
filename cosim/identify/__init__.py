"""System identification: datasets from raw logs, the Model contract, fit and compare.

Models are plugins (hook ``cosim_register_models``); the paper's four live in
``cosim_plugins.models``. See :mod:`cosim.identify.model` for the contract.
"""

from cosim.identify.dataset import Dataset
from cosim.identify.model import Model, load_model

__all__ = ["Dataset", "Model", "load_model"]
