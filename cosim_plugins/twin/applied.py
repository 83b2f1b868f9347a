"""Force effects with their parameters, evaluated at one plant state in SI.

:class:`AppliedEffects` sums the forces of a list of force effects
(:class:`cosim_plugins.identify.effect.Effect`, kind ``"force"``) at the plant's
position, velocity and command, and their derivatives with respect to the
position and the velocity (central differences), converted from the effects'
units (mm, mm/s, Hz, uN) to the FMU's (m, m/s, rad/s, N): see :mod:`.units`.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from cosim.contract.errors import UserError
from cosim_plugins.identify.effect import water_params
from cosim_plugins.twin.units import HOST_UNITS, HZ_PER_RAD_S, MM_PER_M, N_PER_UN, N_PER_UN_PER_MM

#: Central-difference steps: position [mm] and velocity [mm/s].
STEP_MM = 1e-3
STEP_MM_S = 1e-3


class AppliedEffects:
    """Force effects with fixed parameters; see the module docstring.

    Args:
        effects: force effects (an input or sensor transform raises a UserError: the plant's
            external input takes forces only).
        values: effect parameters by qualified name (``"wall_drag.c"``); a missing one takes the
            effect's initial value, an unknown one or one outside the effect's bounds raises.
        host: the host model's parameters (``k``, ``Cd0``, ``Cd1``, ``Cl0``, ``Fvs``, ``Fmax``) that
            effects may reuse, in the effects' units (see :data:`.units.HOST_UNITS`).
    """

    def __init__(self, effects: Sequence, values: Mapping[str, float], host: Mapping[str, float]):
        self.effects = list(effects)
        for e in self.effects:
            kind = getattr(e, "kind", "force")
            if kind != "force":
                raise UserError(f"effect {e.name!r} is a {kind} transform, not a force: only force effects can be "
                                "applied to the plant (its transforms act on the command or the camera)")
        missing = sorted(set(HOST_UNITS) - set(host))
        if missing:
            raise UserError(f"host parameters {', '.join(missing)} are missing")
        params = {q: (e, p) for e in self.effects for q, p in zip(e.param_names(), e.params)}
        unknown = sorted(set(values) - set(params))
        if unknown:
            raise UserError(f"unknown effect parameter(s) {', '.join(unknown)}; "
                            f"valid: {', '.join(params) or '(none: no effect given)'}")
        for name, value in values.items():
            p = params[name][1]
            if not (np.isfinite(value) and p.lo <= value <= p.hi):
                raise UserError(f"effect parameter {name}={value!r} is outside the effect's range [{p.lo}, {p.hi}] "
                                f"{p.unit}")
        self.host = {k: float(host[k]) for k in HOST_UNITS}
        self.values = {q: float(values.get(q, p.init)) for q, (_, p) in params.items()}
        water = water_params(self.effects, self.values)  # a flow's water: the other drags act relative to it
        self._own = [{**self.host, **water, **{p.name: self.values[f"{e.name}.{p.name}"] for p in e.params}}
                     for e in self.effects]
        h = np.concatenate([np.zeros((1, 3)), np.eye(3), -np.eye(3)])
        z = np.zeros((7, 3))
        self._dp = np.concatenate([h, z[1:]]) * STEP_MM     # (13, 3) position offsets [mm]
        self._dv = np.concatenate([z[:1], z[1:], h[1:]]) * STEP_MM_S  # (13, 3) velocity offsets [mm/s]

    def force_mm(self, p_mm: np.ndarray, v_mm_s: np.ndarray, u_hz: np.ndarray) -> np.ndarray:
        """Total force [uN], (n, 3), at p (n, 3) [mm], v (n, 3) [mm/s], u (n, 3) [Hz]."""
        f = np.zeros_like(np.asarray(p_mm, dtype=float))
        for effect, prm in zip(self.effects, self._own):
            f = f + np.asarray(effect.force(p_mm, v_mm_s, u_hz, prm), dtype=float)
        return f

    def force_si(self, p_m, v_m_s, omega_rad_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The force and its derivatives at one state, in the FMU's units.

        Args: p_m (3,) position [m], v_m_s (3,) velocity [m/s], omega_rad_s (3,) command [rad/s].
        Returns: (F (3,) [N], dF/dp (3, 3) [N/m], dF/dv (3, 3) [N s/m]), row a, column b = dF_a/dx_b.
        """
        f, dfdp, dfdv = self.force_si_batch(np.reshape(p_m, (1, 3)), np.reshape(v_m_s, (1, 3)),
                                            np.reshape(omega_rad_s, (1, 3)))
        return f[0], dfdp[0], dfdv[0]

    def force_si_batch(self, p_m, v_m_s, omega_rad_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`force_si` at n states at once (one call of each effect).

        Args: p_m, v_m_s, omega_rad_s: (n, 3) [m], [m/s], [rad/s].
        Returns: (F (n, 3) [N], dF/dp (n, 3, 3) [N/m], dF/dv (n, 3, 3) [N s/m]); [i, a, b] = dF_a/dx_b at state i.
        """
        p = np.asarray(p_m, dtype=float) * MM_PER_M
        v = np.asarray(v_m_s, dtype=float) * MM_PER_M
        u = np.asarray(omega_rad_s, dtype=float) * HZ_PER_RAD_S
        n = len(p)
        f = self.force_mm((p[None] + self._dp[:, None]).reshape(-1, 3), (v[None] + self._dv[:, None]).reshape(-1, 3),
                          np.broadcast_to(u, (13, n, 3)).reshape(-1, 3)).reshape(13, n, 3)
        # rows: centre, +-p_x..z, +-v_x..z
        dfdp = (f[1:4] - f[4:7]).transpose(1, 2, 0) / (2.0 * STEP_MM)       # (n, 3, 3) [uN/mm]
        dfdv = (f[7:10] - f[10:13]).transpose(1, 2, 0) / (2.0 * STEP_MM_S)  # (n, 3, 3) [uN s/mm]
        return f[0] * N_PER_UN, dfdp * N_PER_UN_PER_MM, dfdv * N_PER_UN_PER_MM
