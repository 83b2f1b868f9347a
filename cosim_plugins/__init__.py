"""Built-in plugins of the swimmer project (import name ``cosim_plugins``).

Each subpackage is one pluggy plugin, registered by :mod:`cosim.contract.plugins`
exactly like an external plugin.
"""
