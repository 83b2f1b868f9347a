"""Backend ``visa``: the Kepco BOP 20-50MG supplies over SCPI, through pyvisa.

Each coil is driven by ``per_coil`` supplies in series (two +-20 V units for
the +-40 V a coil needs), in voltage mode, following the analog reference at
their external input (see :mod:`cosim_plugins.coil_driver.daq_backend`).
Over SCPI this backend only configures, switches and watches them, with the
commands of Kepco's BOP 1KW-MG operator manual (appendix B, SCPI command reference):

* open: ``*IDN?`` must name the expected model; ``*CLS``, ``OUTP 0``,
  ``FUNC:MODE VOLT`` (voltage mode), ``VOLT:LIM v`` (the main channel's
  software limit), ``CURR:PROT:MODE FIX`` and ``CURR:PROT i`` (the current
  protect limit, set over SCPI rather than the analog port), ``VOLT:MODE EXT``
  (follow the external reference: +-10 V gives the rated +-20 V); then
  ``SYST:ERR?`` must answer ``0,...``;
* start: ``OUTP 1``;
* every tick, a share of the supplies: ``MEAS:CURR?`` and ``SYST:ERR?``, so each
  supply is read once every ``readback_ticks`` ticks and no tick waits on all
  of them; an error code other than 0 is a ``supply_error`` fault;
* stop: ``OUTP 0`` on every supply (each tried even when another fails),
  confirmed by ``OUTP?`` answering 0.

``library``: pyvisa's VISA library, ``""`` for the default one or
``"file.yaml@sim"`` for pyvisa-sim (the tests' simulated supplies).
"""

from __future__ import annotations

from dataclasses import dataclass

from cosim_plugins.coil_driver.interlocks import COIL_NAMES, BackendFault, Fault


def configure_commands(v_limit_v: float, i_prot_a: float) -> list[str]:
    """The SCPI that puts one supply in voltage mode on its external reference, output off, in order."""
    return ["*CLS", "OUTP 0", "FUNC:MODE VOLT", f"VOLT:LIM {v_limit_v:.3f}", "CURR:PROT:MODE FIX",
            f"CURR:PROT {i_prot_a:.3f}", "VOLT:MODE EXT"]


def parse_error(answer: str) -> tuple[int, str]:
    """``SYST:ERR?``'s answer ``code,"message"`` as (code, message); an unreadable answer is code -1."""
    code, _, message = answer.strip().partition(",")
    try:
        return int(code.strip()), message.strip().strip('"')
    except ValueError:
        return -1, f"unreadable error queue answer {answer.strip()!r}"


def check_addresses(addresses, per_coil: int) -> None:
    """Raise ValueError unless ``addresses`` is a list of ``6 * per_coil`` VISA addresses."""
    if not isinstance(addresses, list) or not all(isinstance(a, str) and a for a in addresses):
        raise ValueError(f"visa_resources must be a list of VISA addresses, got {addresses!r}")
    if len(addresses) != 6 * per_coil:
        raise ValueError(f"visa_resources lists {len(addresses)} addresses; 6 coils x {per_coil} "
                         f"supplies_per_coil need {6 * per_coil}")


@dataclass(frozen=True)
class Reading:
    """One supply's measured output current [A] at a tick."""

    coil: int
    supply: int
    address: str
    current_a: float


class KepcoSupplies:
    """The rig's supplies: ``addresses`` coil-major (coil 0's ``per_coil`` supplies first, coil order
    +x -x +y -y +z -z). ``v_limit_v``, ``i_prot_a``: per supply [V, A]."""

    def __init__(self, addresses: list[str], per_coil: int, library: str, v_limit_v: float, i_prot_a: float,
                 idn_match: str, timeout_ms: int, readback_ticks: int):
        check_addresses(addresses, per_coil)
        self.addresses, self.per_coil, self.library = list(addresses), per_coil, library
        self.v_limit_v, self.i_prot_a, self.idn_match = v_limit_v, i_prot_a, idn_match
        self.timeout_ms, self.readback_ticks = timeout_ms, readback_ticks
        self.rm = None
        self.supplies: list = []  # pyvisa resources, in the order of ``addresses``
        self.idn: list[str] = []
        self.on = False

    def label(self, i: int) -> str:
        return f"{self.addresses[i]} (coil {COIL_NAMES[i // self.per_coil]}, supply {i % self.per_coil + 1})"

    def open(self) -> None:
        """Connect, identify and configure every supply, outputs off."""
        try:
            import pyvisa
        except ImportError as exc:
            raise RuntimeError(f"needs the pyvisa package (pip install -e '.[lab]'): {exc}") from exc
        try:
            self.rm = pyvisa.ResourceManager(self.library) if self.library else pyvisa.ResourceManager()
        except (OSError, ValueError, pyvisa.Error) as exc:  # no VISA library, or a bad pyvisa-sim file
            raise RuntimeError(f"VISA library {self.library or '(default)'!r} unusable: {exc}") from exc
        for i, address in enumerate(self.addresses):
            try:
                res = self.rm.open_resource(address, read_termination="\n", write_termination="\n",
                                            timeout=self.timeout_ms)
            except pyvisa.Error as exc:
                raise RuntimeError(f"supply {self.label(i)}: cannot open: {exc}") from exc
            self.supplies.append(res)
            idn = self._query(i, "*IDN?")
            if self.idn_match not in idn:
                raise RuntimeError(f"supply {self.label(i)} identifies as {idn!r}, expected {self.idn_match!r}")
            self.idn.append(idn)
            for command in configure_commands(self.v_limit_v, self.i_prot_a):
                self._write(i, command)
            code, message = parse_error(self._query(i, "SYST:ERR?"))
            if code != 0:
                raise RuntimeError(f"supply {self.label(i)} rejected its configuration: {code},{message}")

    def start(self) -> None:
        """Outputs on (the reference must already be at zero)."""
        for i in range(len(self.supplies)):
            self._write(i, "OUTP 1")
        self.on = True

    def poll(self, tick: int) -> list[Reading]:
        """Read the supplies whose turn ``tick`` is: their current, then their error queue.

        Raises :class:`BackendFault` (``supply_error``) on an error code other than 0.
        """
        readings = []
        for i in range(tick % self.readback_ticks, len(self.supplies), self.readback_ticks):
            answer = self._query(i, "MEAS:CURR?")
            try:
                current = float(answer)
            except ValueError:
                raise BackendFault(Fault("supply_error", f"supply {self.label(i)} answered MEAS:CURR? "
                                                         f"with {answer!r}")) from None
            readings.append(Reading(i // self.per_coil, i % self.per_coil, self.addresses[i], current))
            code, message = parse_error(self._query(i, "SYST:ERR?"))
            if code != 0:
                raise BackendFault(Fault("supply_error", f"supply {self.label(i)} reports {code},\"{message}\""))
        return readings

    def stop(self) -> None:
        """``OUTP 0`` on every supply, each tried; confirmed with ``OUTP?``. Raises the first failure after."""
        failures = []
        for i in range(len(self.supplies)):
            try:
                self._write(i, "OUTP 0")
                state = self._query(i, "OUTP?")
                if state.strip() not in ("0", "OFF"):
                    failures.append(f"supply {self.label(i)} still reports output {state!r} after OUTP 0")
            except BackendFault as exc:
                failures.append(str(exc.fault.message))
        self.on = False
        if failures:
            raise BackendFault(Fault("supply_error", "; ".join(failures)))

    def close(self) -> None:
        for res in self.supplies:
            try:
                res.close()
            except Exception:  # closing a session that is gone already
                pass
        self.supplies = []
        if self.rm is not None:
            self.rm.close()
            self.rm = None

    def _write(self, i: int, command: str) -> None:
        try:
            self.supplies[i].write(command)
        except Exception as exc:  # pyvisa.Error, an I/O error of the bus
            raise BackendFault(Fault("supply_error", f"supply {self.label(i)}: {command!r} failed: {exc}")) from exc

    def _query(self, i: int, command: str) -> str:
        try:
            return self.supplies[i].query(command).strip()
        except Exception as exc:  # a timeout: the supply did not answer
            raise BackendFault(Fault("supply_error",
                                     f"supply {self.label(i)}: {command!r} got no answer: {exc}")) from exc
