"""The coil driver's parameters: actuation model, interlocks, backends; read and checked in one place."""

from __future__ import annotations

from typing import Any, Mapping

from cosim import ComponentError
from cosim.contract.params import Param, read_params
from cosim_plugins.coil_driver.backends import BACKENDS, uses
from cosim_plugins.coil_driver.daq_backend import samples_per_tick
from cosim_plugins.coil_driver.visa_backend import check_addresses

PARAMS = {
    # actuation model
    "field_mT": Param(3.0, "rotating field amplitude at the swimmer [mT]", 0.0, 50.0),
    "turns": Param(795.0, "turns per coil", 1.0, 1e5),
    "r_inner_mm": Param(180.0, "coil inner radius [mm]", 1.0, 1e4),
    "r_outer_mm": Param(215.0, "coil outer radius [mm]", 1.0, 1e4),
    "z_near_mm": Param(150.0, "distance from the centre to the coil's inner face [mm]", 0.0, 1e4),
    "thickness_mm": Param(40.0, "axial winding thickness [mm]", 0.0, 1e4),
    "r_ohm": Param(12.9, "coil resistance [ohm]", 0.0, 1e4),
    "l_h": Param(0.411, "coil inductance [H]", 0.0, 100.0),
    "c_f": Param(430e-6, "series capacitor [F]", 1e-12, 100.0),
    "f_min_hz": Param(0.05, "below this spin frequency the field is off [Hz]", 0.0, 100.0),
    # shaping limits: the command is scaled down, all coils together
    "v_max": Param(40.0, "coil voltage amplitude limit [V] (two +-20 V supplies in series); "
                         "above it all coils are scaled down together", 0.0, 1e4),
    "i_max_a": Param(3.0, "coil current amplitude limit [A]; above it all coils are scaled down together",
                     0.0, 1e3),
    "slew_v_per_s": Param(2000.0, "fastest rise of a coil's voltage amplitude [V/s]; a faster rise is scaled "
                                  "down (falls are not limited; the default, 40 V per 20 ms tick, never "
                                  "binds at the default v_max)", 0.0, 1e9),
    # trips: a named fault stops the run
    "f_limit_hz": Param(60.0, "a command above this spin frequency trips 'unsafe_command' [Hz]", 0.0, 1e4),
    "thermal_budget_j": Param(3000.0, "energy a coil may dissipate (I^2 R) within the thermal window before "
                                      "'thermal_budget' trips [J]", 0.0, 1e9),
    "thermal_window_s": Param(60.0, "sliding window of the thermal budget [s]", 0.0, 1e6),
    "watchdog_ticks": Param(5, "no new command for more than this many ticks trips 'watchdog' [ticks]", 1, 10**6),
    "watchdog_clock": Param("auto", "the watchdog's clock: 'sim' (step times; deterministic), 'wall' "
                                    "(monotonic wall clock, also checked between steps), 'auto' ('wall' with "
                                    "hardware, else 'sim')"),
    "i_trip_a": Param(3.6, "a supply's measured current magnitude above this trips 'overcurrent' [A]; "
                           "also each supply's CURR:PROT limit (visa)", 0.0, 1e3),
    "ramp_s": Param(0.1, "on a fault or stop the reference ramps to zero over this time before the "
                         "outputs go off [s] (daq)", 0.0, 10.0),
    # backends
    "backend": Param("fmu", "where the voltages go: 'fmu' (the ports only: the simulated plant), 'daq' "
                            "(NI analog reference), 'visa' (Kepco supplies over SCPI), 'visa+daq' (the rig)"),
    "visa_resources": Param([], "VISA addresses of the supplies, coil-major: coil +x's supplies first, "
                                "then -x, +y, -y, +z, -z (visa)"),
    "supplies_per_coil": Param(2, "supplies in series per coil (visa)", 1, 8),
    "visa_library": Param("", "pyvisa's VISA library: '' for the default, 'FILE.yaml@sim' for pyvisa-sim (visa)"),
    "visa_idn": Param("BOP 20-50", "text every supply's *IDN? answer must contain (visa)"),
    "visa_timeout_ms": Param(500, "a supply's answer timeout [ms] (visa)", 1, 60000),
    "readback_ticks": Param(12, "each supply's current and error queue are read once every this many "
                                "ticks, spread over the ticks [ticks] (visa)", 1, 10**6),
    "daq_channels": Param("Dev1/ao0:5", "NI-DAQmx analog outputs, one per coil in coil order (daq)"),
    "daq_rate_hz": Param(10000.0, "sample rate [Hz]; a whole number of samples per tick (daq)", 1.0, 1e7),
    "daq_gain_v_per_v": Param(4.0, "coil volts per reference volt [V/V]: each supply's external gain "
                                   "(+-10 V in, +-20 V out: 2) times the supplies in series (daq)", 1e-6, 1e6),
    "daq_ao_max_v": Param(10.0, "the outputs' range, +- [V] (daq)", 0.0, 100.0),
    "daq_prefill_chunks": Param(2, "ticks of zeros written before the clock starts: the output lag [ticks] (daq)",
                                1, 100),
}

CLOCKS = ("auto", "sim", "wall")


def read(params: Mapping[str, Any]) -> dict[str, Any]:
    """Parameters with defaults, checked against each other; raises :class:`ComponentError` naming the problem.

    Touches no hardware (used by ``cosim validate`` too).
    """
    p = read_params(params, PARAMS)
    for key in ("watchdog_ticks", "supplies_per_coil", "visa_timeout_ms", "readback_ticks", "daq_prefill_chunks"):
        if p[key] != int(p[key]):
            raise ComponentError(f"parameter {key}={p[key]!r}: expected a whole number")
        p[key] = int(p[key])
    for key in ("backend", "watchdog_clock", "visa_library", "visa_idn", "daq_channels"):
        if not isinstance(p[key], str):
            raise ComponentError(f"parameter {key}={p[key]!r}: expected text")
    if p["r_outer_mm"] <= p["r_inner_mm"]:
        raise ComponentError("r_outer_mm must exceed r_inner_mm")
    if p["backend"] not in BACKENDS:
        raise ComponentError(f"backend {p['backend']!r} unknown; known: {', '.join(BACKENDS)}")
    if p["watchdog_clock"] not in CLOCKS:
        raise ComponentError(f"watchdog_clock {p['watchdog_clock']!r} unknown; known: {', '.join(CLOCKS)}")
    if p["i_trip_a"] < p["i_max_a"]:
        raise ComponentError(f"i_trip_a={p['i_trip_a']:g} A is below i_max_a={p['i_max_a']:g} A: "
                             "a command within the limit would trip")
    dt = float(params.get("dt", 0.02))
    try:
        if uses(p["backend"], "visa"):
            check_addresses(p["visa_resources"], p["supplies_per_coil"])
        if uses(p["backend"], "daq"):
            samples_per_tick(p["daq_rate_hz"], dt)
    except ValueError as exc:
        raise ComponentError(str(exc)) from None
    if uses(p["backend"], "daq"):
        if p["v_max"] / p["daq_gain_v_per_v"] > p["daq_ao_max_v"]:
            raise ComponentError(f"v_max={p['v_max']:g} V needs a {p['v_max'] / p['daq_gain_v_per_v']:g} V "
                                 f"reference, beyond daq_ao_max_v={p['daq_ao_max_v']:g} V")
    return p
