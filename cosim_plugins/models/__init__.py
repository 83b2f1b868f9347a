"""Built-in dynamics models: the paper's four (Sec. II-A..C).

``physical`` (Eq. 1-9), ``sindy-linear`` and ``sindy-nonlinear`` (SINDYc,
polynomial order 1 and 2) and ``mlp`` (9-10-10-6). All follow
:class:`cosim_plugins.identify.model.Model`.
"""

from cosim import hookimpl


@hookimpl
def cosim_register_models(register):
    from cosim_plugins.models.mlp import MLPModel
    from cosim_plugins.models.physical import PhysicalModel
    from cosim_plugins.models.sindy import SindyLinear, SindyNonlinear

    for cls in (PhysicalModel, SindyLinear, SindyNonlinear, MLPModel):
        register(cls.name, cls)
