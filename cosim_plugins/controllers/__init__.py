"""Controller plugins: pure pursuit reference + PI (MRAC and MPC follow the same contract)."""

from cosim import hookimpl
from cosim_plugins.controllers.mpc import MPCController
from cosim_plugins.controllers.mrac import MRACController
from cosim_plugins.controllers.pi import PIController


@hookimpl
def cosim_register_components(register):
    register("controller.pi", PIController)
    register("controller.mrac", MRACController)
    register("controller.mpc", MPCController)
