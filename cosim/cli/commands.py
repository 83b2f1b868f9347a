"""The framework's commands: run, validate, scenarios, schema, plugins, replay, node, certs."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

from cosim import api
from cosim.contract.errors import UserError
from cosim.contract.params import IDEAL
from cosim.contract.plugins import kinds, registry
from cosim.runtime.check import check_runs
from cosim.runtime.wiring import connection_table
from cosim.scale.options import add_jobs_argument, parse_jobs
from cosim.scenario.catalog import resolve_scenario, shipped_scenarios
from cosim.scenario.schema import json_schema, load_scenario, sweep_overrides

# The bus (zenoh), the web viewer and the certificates' tools are imported by the commands that use
# them, so `cosim scenarios` or `cosim plugins` does not load them.

SCENARIO_HELP = "a scenario YAML file, or the name of a shipped one (listed by `cosim scenarios`)"


def add_commands(sub) -> None:
    """Add the framework's subcommands to the ``cosim`` parser's ``sub`` (argparse subparsers)."""
    p = sub.add_parser("run", help="run a scenario (or its sweep) and record it")
    p.add_argument("scenario", help=SCENARIO_HELP)
    p.add_argument("--out", type=Path, default=None, help="output folder (default: runs/<scenario name>)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario field by dotted path, "
                        "e.g. duration_s=10 or components.NAME.params.PARAM=VALUE")
    p.add_argument("--processes", action="store_true",
                   help="run every component as its own `cosim node` process over zenoh TCP on loopback")
    p.add_argument("--node-cpus", default=None, metavar="auto|none|LIST",
                   help="with --processes: CPUs for the nodes (auto: all on one CPU, the fastest "
                        "placement for a lockstep chain; none: the OS places them; or e.g. 1 or 0,2-3)")
    p.add_argument("--realtime", nargs="?", type=float, const=1.0, default=None, metavar="FACTOR",
                   help="pace the ticks on the wall clock (FACTOR times real time, default 1); late ticks "
                        "are skipped and counted in summary.json's 'realtime'")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary lines (errors only)")
    p.add_argument("--until-stopped", action="store_true",
                   help="run until Ctrl-C, SIGTERM, a fault or the end of a replayed input (duration_s: null); "
                        "the record is finished as a timed run's")
    p.add_argument("--rotate", type=float, default=None, metavar="HOURS",
                   help="start a new recording part (part-000/, part-001/, ...: recording, trace, log) every "
                        "HOURS of simulated time; `cosim replay` opens the parts together")
    p.add_argument("--hosts", type=Path, default=None, metavar="HOSTS.yaml",
                   help="with --processes: place the nodes on machines (host, endpoint, CPUs per component; "
                        "launched over ssh or printed to start by hand; mutual TLS between machines)")
    add_jobs_argument(p, "a sweep's runs at a time, each in a worker process")
    p.add_argument("--executor", default=None, metavar="local|dask|dask://tls://HOST:PORT",
                   help="where a sweep's runs execute: local worker processes (default), a local Dask "
                        "cluster of --jobs workers, or the Dask scheduler at HOST:PORT over mutual TLS "
                        "(dask://HOST:PORT, plain TCP, on loopback only; needs the cluster extra)")
    p.add_argument("--tls-ca", type=Path, default=None, metavar="PEM",
                   help="with --executor dask://tls://...: the CA certificate the scheduler's must be signed by")
    p.add_argument("--tls-cert", type=Path, default=None, metavar="PEM", help="this client's certificate")
    p.add_argument("--tls-key", type=Path, default=None, metavar="PEM", help="this client's private key")
    p.add_argument("--run-timeout", type=float, default=None, metavar="S",
                   help="a sweep's run still going after S seconds of wall time is stopped and counted failed")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("validate", help="check a scenario as a run would and print its wiring as a table")
    p.add_argument("scenario", help=SCENARIO_HELP)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("scenarios", help="list the scenarios the installed packages ship, to run by name")
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser("schema", help="print the JSON Schema of the scenario format (for editors)")
    p.set_defaults(func=cmd_schema)

    p = sub.add_parser("plugins", help="list what the installed plugins register, by kind (components, paths, ...)")
    p.set_defaults(func=cmd_plugins)

    p = sub.add_parser("replay", help="open a run's recording in the rerun viewer (--web: in a browser)")
    p.add_argument("run_dir", type=Path, help="a run's output folder (or an .rrd file)")
    p.add_argument("--web", action="store_true",
                   help="serve rerun's web viewer instead of opening a window (no display needed; open the "
                        "address it prints in a browser, through an SSH tunnel from another machine)")
    p.add_argument("--port", type=int, default=0,
                   help="the web viewer's HTTP port with --web (default: a free port)")
    p.add_argument("--bind", default="127.0.0.1", metavar="ADDRESS",
                   help="the address the web viewer listens on with --web (default 127.0.0.1: this machine only; "
                        "0.0.0.0 opens it to the network, unauthenticated)")
    p.add_argument("--parts", default=None, metavar="N|A-B",
                   help="of a run recorded in parts (cosim run --rotate): open only these (e.g. 3 or 2-4; "
                        "default all), so a long run need not be loaded at once")
    p.add_argument("--memory-limit", default=None, metavar="SIZE",
                   help="the desktop viewer drops the oldest data beyond this much memory (e.g. 2GB or 25%%; "
                        "rerun's --memory-limit)")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("node", help="serve one component of a scenario in this process (used by --processes)")
    p.add_argument("component", help="component name in the scenario")
    p.add_argument("scenario", help=SCENARIO_HELP)
    p.add_argument("--run-id", required=True)
    p.add_argument("--connect", action="append", required=True, metavar="ENDPOINT",
                   help="zenoh endpoint of the scheduler, e.g. tcp/127.0.0.1:7447, and (repeated) of "
                        "every node started before this one")
    p.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help="endpoint the nodes started after this one connect to, e.g. tcp/0.0.0.0:7448")
    p.add_argument("--cpus", default=None, metavar="LIST",
                   help="run on these CPUs (e.g. 1 or 0,2-3) under SCHED_BATCH (see cosim.runtime.placement)")
    p.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                   help="the run's output folder, for a component that writes files of its own")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--fingerprint", default=None, metavar="SCENARIO.CODE.ARTIFACTS",
                   help="the run's fingerprint: refuse to join (exit status 2) when this node's differs")
    p.add_argument("--tls-ca", type=Path, default=None, metavar="PEM", help="the run's CA certificate (mutual TLS)")
    p.add_argument("--tls-cert", type=Path, default=None, metavar="PEM", help="this host's certificate")
    p.add_argument("--tls-key", type=Path, default=None, metavar="PEM", help="this host's private key")
    p.add_argument("--rights", default=None, metavar="SCHED;HOST=COMP,...",
                   help="with TLS: the components each host runs, by its certificate's name (cosim.runtime.rights); "
                        "what a peer may publish and subscribe to here")
    p.set_defaults(func=cmd_node)

    p = sub.add_parser("certs", help="make a run's CA, one certificate per host of a HOSTS.yaml and one per "
                                     "component placed there (mutual TLS)")
    p.add_argument("hosts", type=Path, help="the hosts file; the files go where its tls.ca and hosts.*.cert/key say")
    p.add_argument("--days", type=int, default=365, help="validity of the certificates (default 365)")
    p.add_argument("--force", action="store_true", help="replace existing files")
    p.set_defaults(func=cmd_certs)


def cmd_run(args) -> int:
    """``cosim run``: run a scenario or its sweep; 1 when a sweep run failed, 130 when stopped."""
    args.scenario = resolve_scenario(args.scenario)
    if args.until_stopped:
        args.overrides = [*args.overrides, "duration_s=null"]
    if args.rotate is not None and not args.rotate > 0:
        raise UserError(f"--rotate {args.rotate:g}: the hours per part must be > 0")
    out = args.out or Path("runs") / api.load_scenario(args.scenario, args.overrides).name
    if args.realtime is not None and not args.realtime > 0:
        raise UserError(f"--realtime {args.realtime:g}: the factor must be > 0 (1: real time)")
    if args.node_cpus is not None and not args.processes:
        raise UserError(f"--node-cpus {args.node_cpus}: only applies with --processes (the nodes' CPUs)")
    jobs = parse_jobs(args.jobs, default=1 if args.executor in (None, "local") else "auto")
    if jobs > 1 and args.processes and args.node_cpus not in (None, "auto", "none"):
        raise UserError(f"--node-cpus {args.node_cpus} with --jobs {args.jobs}: every parallel run's nodes would "
                        "share these CPUs; use auto (each run's nodes on CPUs of their own) or none")
    if args.hosts is not None and not args.processes:
        raise UserError(f"--hosts {args.hosts}: only applies with --processes (it places the nodes)")
    if args.hosts is not None and (jobs > 1 or args.executor):
        raise UserError(f"--hosts {args.hosts}: a run over machines takes the endpoints its hosts file names, "
                        "so its sweep runs one at a time (no --jobs, no --executor)")
    if args.run_timeout is not None and not args.run_timeout > 0:
        raise UserError(f"--run-timeout {args.run_timeout:g}: the time must be > 0 [s]")
    tls_args = (args.tls_ca, args.tls_cert, args.tls_key)
    if any(tls_args) and not all(tls_args):
        raise UserError("--tls-ca, --tls-cert and --tls-key go together (mutual TLS needs all three)")
    if any(tls_args) and not (args.executor or "").startswith("dask://tls://"):
        raise UserError("--tls-ca, --tls-cert and --tls-key are for --executor dask://tls://HOST:PORT (a run "
                        "over machines takes its certificates from its hosts file)")
    from cosim.runtime.bus import TlsFiles

    request = api.RunRequest(args.scenario, out, args.overrides, args.processes, not args.quiet,
                             args.node_cpus or "auto", args.realtime, hosts=args.hosts,
                             rotate_s=None if args.rotate is None else args.rotate * 3600.0)
    sweep = api.SweepOptions(jobs=jobs, executor=args.executor, run_timeout_s=args.run_timeout,
                             executor_tls=TlsFiles(*tls_args) if all(tls_args) else None)
    summary = api.run(request, sweep)
    if not args.quiet:
        _print_run(summary, out)
    if summary.get("status") == "interrupted":
        print(f"cosim run: {summary.get('error') or 'stopped'}; everything recorded until then is kept",
              file=sys.stderr)
        return 130
    failed = [row for row in summary.get("sweep", []) if row["status"] != "ok"]
    if failed:
        print(f"cosim run: {len(failed)} of {len(summary['sweep'])} sweep runs did not finish: "
              + ", ".join(f"{row['dir']} ({row['status']})" for row in failed), file=sys.stderr)
    return 1 if failed else 0


def _print_run(summary: dict, out: Path) -> None:
    if "sweep" not in summary:
        err = summary["tracking_error_mm"]
        if err:
            print(f"tracking error: {err['mean']:.2f} ± {err['std']:.2f} mm (max {err['max']:.2f} mm)")
        print(f"{summary['steps']} steps, {summary['sim_time_s']:.1f} s simulated in "
              f"{summary['wall_time_s']:.1f} s ({summary['realtime_factor'] or 0:.0f}x real time)")
        rt = summary.get("realtime")
        if rt:
            print(f"real-time pacing x{rt['factor']:g}: {rt['missed']} of {rt['ticks'] + rt['missed']} ticks "
                  f"missed, lateness p99 {rt['lateness_ms']['p99']} ms (max {rt['lateness_ms']['max']} ms)")
    parts = summary.get("files", {}).get("parts")
    if "sweep" in summary:  # every run's folder (and recording) is listed in the table
        print(f"table:     {out / 'summary.md'}")
    else:
        print(f"recording: {out if parts else out / 'recording.rrd'}"
              + (f" ({len(parts)} parts: {parts[0]}/ .. {parts[-1]}/)" if parts else ""))
    print(f"summary:   {out / 'summary.json'}")


def cmd_validate(args) -> int:
    """``cosim validate``: check a scenario as a run would and print its wiring."""
    args.scenario = resolve_scenario(args.scenario)
    scenario = load_scenario(args.scenario, args.overrides)
    wiring = check_runs(scenario, args.scenario, args.overrides)  # what `cosim run` checks before it starts
    print(connection_table(scenario, wiring))
    if scenario.sweep:
        print(f"sweep: {len(sweep_overrides(scenario))} runs over {', '.join(scenario.sweep)}")
    return 0


def cmd_scenarios(args) -> int:
    """``cosim scenarios``: the shipped scenarios, one line each with its description."""
    found = shipped_scenarios()
    if not found:
        print("no installed package ships scenarios")
        return 0
    width = max(map(len, found)) + 2
    for name, item in sorted(found.items()):
        print(textwrap.fill(item.doc or "(no description)", width=110, initial_indent=f"{name:{width}s}",
                            subsequent_indent=" " * width))
    print(f"\nrun one by name: cosim run NAME (they are in {_common_folder(found)})")
    return 0


def _common_folder(found: dict) -> str:
    return os.path.commonpath([str(item.path.parent) for item in found.values()])


def cmd_schema(args) -> int:
    """``cosim schema``: the scenario format's JSON Schema on stdout."""
    print(json.dumps(json_schema(), indent=2))
    return 0


def cmd_plugins(args) -> int:
    """``cosim plugins``: what the installed plugins register, by kind, each with its first sentence."""
    for kind in kinds():
        entries = registry(kind)
        if kind == "profile":
            entries.setdefault("ideal", IDEAL)
        print(f"{kind}s:")
        for name, obj in sorted(entries.items()):
            own_doc = None if isinstance(obj, (dict, list, tuple)) else getattr(obj, "__doc__", None)  # not dict's
            doc = " ".join((getattr(obj, "doc", None) or own_doc or "").split())
            first = re.split(r"\.\s+(?=[A-Z])", doc, maxsplit=1)[0].rstrip(".") + "." if doc else ""
            print(textwrap.fill(first, width=110, initial_indent=f"  {name:24s} ", subsequent_indent=" " * 27)
                  if first else f"  {name}")
    return 0


def recording_files(run_dir: Path, parts: str | None = None) -> list[Path]:
    """The .rrd files of a run, to open together: ``recording.rrd`` or, of a run recorded in parts
    (``--rotate``), each ``part-NNN/recording.rrd`` (``parts``: ``N`` or ``A-B``, only those), then the
    parts components recorded themselves (``recording.<component>.rrd``). ``run_dir`` may be an .rrd."""
    if not run_dir.is_dir():
        if not run_dir.is_file():
            raise UserError(f"no recording at {run_dir}")
        return [run_dir]
    rotated = sorted(run_dir.glob("part-[0-9][0-9][0-9]/recording.rrd"))
    if parts is not None:
        if not rotated:
            raise UserError(f"--parts {parts}: {run_dir} was not recorded in parts (cosim run --rotate)")
        match = re.fullmatch(r"(\d+)(?:-(\d+))?", parts.strip())
        if not match:
            raise UserError(f"--parts {parts}: expected a part number N or a range A-B")
        first, last = int(match[1]), int(match[2] or match[1])
        rotated = [f for f in rotated if first <= int(f.parent.name.split("-")[1]) <= last]
        if not rotated:
            raise UserError(f"--parts {parts}: {run_dir} has parts 0-{len(list(run_dir.glob('part-*'))) - 1}")
    main = rotated or [run_dir / "recording.rrd"]
    if not main[0].is_file():
        raise UserError(f"no recording at {main[0]}")
    # the parts components recorded themselves (recording.<component>.rrd): one recording in the viewer
    return [*main, *sorted(run_dir.glob("recording.*.rrd"))]


def cmd_replay(args) -> int:
    """``cosim replay``: open a run's recording (all its parts) in the rerun viewer, or serve it to a browser
    (``--web``)."""
    found = recording_files(args.run_dir, args.parts)
    rrd = found[0]
    files = [str(f) for f in found]
    viewer = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    if not Path(viewer).exists():
        raise UserError("the rerun viewer is not installed (pip install rerun-sdk)")
    if args.web:
        from cosim.record.web_viewer import serve_web

        return serve_web(viewer, files, args.bind, args.port)
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise UserError(f"no display to open the viewer on ($DISPLAY and $WAYLAND_DISPLAY are unset): "
                        f"`cosim replay {args.run_dir} --web` serves it to a browser instead, and "
                        f"`rerun rrd stats {rrd}` lists what the recording holds")
    print(f"opening {', '.join(files)} in the rerun viewer")
    return _call_viewer([viewer, *(["--memory-limit", args.memory_limit] if args.memory_limit else []), *files])


def _call_viewer(command: list[str], env: dict | None = None) -> int:
    """Run the viewer until it ends; Ctrl-C ends it (and is not an error)."""
    try:
        return subprocess.call(command, env=env)
    except KeyboardInterrupt:
        return 0


def cmd_node(args) -> int:
    """``cosim node``: serve one component of a scenario in this process until the run ends."""
    tls_args = (args.tls_ca, args.tls_cert, args.tls_key)
    if any(tls_args) and not all(tls_args):
        raise UserError("--tls-ca, --tls-cert and --tls-key go together (mutual TLS needs all three)")
    try:
        expected = api.Fingerprint.decode(args.fingerprint) if args.fingerprint else None
    except ValueError as exc:
        raise UserError(f"--fingerprint: {exc}") from None
    from cosim.runtime.bus import TlsFiles
    from cosim.runtime.rights import parse_rights

    rights = parse_rights(args.rights) if args.rights else None
    if rights is not None and not all(tls_args):
        raise UserError("--rights applies to TLS links: give --tls-ca, --tls-cert and --tls-key too")
    return api.serve_node(args.scenario, args.component, args.run_id, args.connect, args.listen, args.overrides,
                          args.cpus, args.run_dir, expected, TlsFiles(*tls_args) if all(tls_args) else None, rights)


def cmd_certs(args) -> int:
    """``cosim certs``: a run's CA, one certificate per host of a hosts file and one per placed component."""
    from cosim.scale.certs import make_certificates

    if args.days < 1:
        raise UserError(f"--days {args.days}: expected a whole number >= 1")
    files = make_certificates(args.hosts, args.days, args.force)
    print("wrote " + ", ".join(map(str, files)))
    print(f"copy to each host its own .pem and .key files (its components' too) and the CA certificate "
          f"{files[0]}; keep the CA's key "
          f"{files[1]} on none of them (it signs certificates that admit a peer to the run)")
    return 0
