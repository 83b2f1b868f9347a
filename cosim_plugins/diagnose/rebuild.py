"""A diagnosis's model rebuilt on a fresh copy of its plain host, with other effects or parameters."""

from __future__ import annotations

from cosim_plugins.identify.joint import JointModel


def rebuilt(jm: JointModel, effects=None, base_params: dict | None = None) -> JointModel:
    """A new model on a fresh copy of ``jm``'s plain host (its options and step) holding ``effects`` (default:
    ``jm``'s) started at ``base_params`` (default: ``jm``'s parameters). The host is rebuilt, not reused: a
    JointModel's host already holds its force effects as terms, which would be added twice."""
    host = type(jm.host)(**jm.host.options)
    host.dt_s = jm.dt_s
    return JointModel(host, jm.effects if effects is None else effects,
                      base_params=jm.params() if base_params is None else base_params)
