"""Plant FMU speed: 290 s of simulated time at 20 ms macro steps through fmpy.

Drives a field rotating about x at 10 Hz (y and z coil pairs in quadrature,
~3 mT) so the swimmer actually swims, setting the inputs, stepping and
reading every output each macro step with the low-level fmpy API.
Prints JSON: {"sim_s", "wall_s" (median of the repeats), "fmu", "dt_internal_s", "repeats"}.
Budget (DESIGN.md): wall_s <= 1.0.

    .venv/bin/python benchmarks/plant.py [--repeats 5] [--fmu path]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import statistics
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from cosim_plugins.plant.build import ensure_fmu

SIM_S = 290.0
DT = 0.02
DRIVE_HZ = 10.0
INPUTS = [f"V_amp_{i}" for i in range(1, 7)] + [f"V_phase_{i}" for i in range(1, 7)] + ["freq"]
OUTPUTS = (
    ["p_x", "p_y", "p_z", "v_x", "v_y", "v_z", "axis_x", "axis_y", "axis_z", "spin_rate"]
    + [f"I_amp_{i}" for i in range(1, 7)]
    + ["B_x", "B_y", "B_z"]
)


def rotating_about_x(f_hz: float, volts: float = 20.0) -> list[float]:
    """Coil voltages for a field rotating about +x: y pair leads the z pair by 90 deg."""
    amps = [0.0, 0.0, volts, volts, volts, volts]
    phases = [0.0, 0.0, 0.0, 0.0, -math.pi / 2, -math.pi / 2]
    return amps + phases + [f_hz]


def run_once(fmu_path: str, unzip_dir: str, md) -> float:
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip_dir,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.setReal([vr["p0_x"]], [-0.06])
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    in_vr = [vr[n] for n in INPUTS]
    out_vr = [vr[n] for n in OUTPUTS]
    values = rotating_about_x(DRIVE_HZ)
    n_steps = int(round(SIM_S / DT))
    t = 0.0
    start = time.perf_counter()
    for k in range(n_steps):
        fmu.setReal(in_vr, values)
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=DT)
        t = (k + 1) * DT
        out = fmu.getReal(out_vr)
    wall = time.perf_counter() - start
    fmu.terminate()
    fmu.freeInstance()
    if not all(math.isfinite(x) for x in out):
        raise RuntimeError("non-finite plant output")
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--fmu", default=None, help="FMU path (default: build it if needed)")
    args = parser.parse_args()
    fmu_path = str(ensure_fmu(args.fmu))
    md = read_model_description(fmu_path)
    dt_internal = next(float(v.start) for v in md.modelVariables if v.name == "dt_internal")
    unzip_dir = extract(fmu_path)
    try:
        walls = [run_once(fmu_path, unzip_dir, md) for _ in range(args.repeats)]
    finally:
        shutil.rmtree(unzip_dir, ignore_errors=True)
    print(json.dumps({
        "sim_s": SIM_S,
        "wall_s": round(statistics.median(walls), 4),
        "fmu": fmu_path,
        "dt_internal_s": dt_internal,
        "repeats": args.repeats,
    }))


if __name__ == "__main__":
    main()
