"""``cosim dataset`` and ``cosim reproduce``: the paper's dataset and its experiments, regenerated."""

from __future__ import annotations

import sys
from pathlib import Path

from cosim.api import add_jobs_argument, parse_jobs
from cosim.contract.errors import UserError


def add_commands(sub) -> None:
    """Add ``cosim dataset`` and ``cosim reproduce`` to the ``cosim`` parser's ``sub``."""
    add_dataset_command(sub)
    add_reproduce_command(sub)


def add_dataset_command(sub) -> None:
    """Add ``cosim dataset`` to ``sub``."""
    p = sub.add_parser("dataset", help="generate (or reuse) the paper's training, test and validation logs")
    p.add_argument("--quick", action="store_true", help="40 s runs instead of 290 s each")
    p.add_argument("--out", type=Path, default=None, help="folder (default: the cache, $COSIM_CACHE or ./cache)")
    p.add_argument("--force", action="store_true", help="regenerate even if the cache is current")
    p.add_argument("--profile", default="ideal", help="run the scenarios on this profile (ideal, lab, ...); "
                   "its logs are cached apart, and models named by kind in a scenario on it train on them")
    add_jobs_argument(p, "runs at a time, each in a worker process")
    p.set_defaults(func=cmd_dataset)


def cmd_dataset(args) -> int:
    """``cosim dataset``: generate (or reuse) the paper's logs and print where they are."""
    from cosim_plugins.paper.dataset import ensure_dataset

    ds = ensure_dataset(quick=args.quick, folder=args.out, force=args.force, jobs=parse_jobs(args.jobs),
                        profile=args.profile)
    for split in ("training", "test", "validation"):
        files = getattr(ds, split)
        print(f"{split} ({len(files)} logs):")
        for f in files:
            print(f"  {f}")
    return 0


def add_reproduce_command(sub) -> None:
    """Add ``cosim reproduce`` to ``sub``."""
    p = sub.add_parser("reproduce", help="regenerate every table and figure of the paper in simulation")
    p.add_argument("--out", type=Path, required=True, help="report folder")
    p.add_argument("--quick", action="store_true", help="shortened experiments (a few minutes in all)")
    p.add_argument("--docs", "--readme", dest="page", type=Path, default=None, metavar="PAGE.md",
                   help="also put the tables into this page's results block, e.g. docs/results.md (plots go "
                        "to the folder results/ beside it)")
    add_jobs_argument(p, "each sweep's runs at a time, each in a worker process")
    p.set_defaults(func=cmd_reproduce)


def cmd_reproduce(args) -> int:
    """``cosim reproduce``: every table and figure of the paper, and the docs' results page on request."""
    from cosim_plugins.paper.report_format import filled
    from cosim_plugins.paper.reproduce import reproduce

    if args.page and not args.page.is_file():
        raise UserError(f"--docs {args.page} does not exist")

    digest = None
    if args.page:  # the code the results are made from, before a change during the run could alter it
        from cosim_plugins.paper.code_digest import results_digest

        digest = results_digest()
    report = reproduce(args.out, quick=args.quick, jobs=parse_jobs(args.jobs))
    print(f"report: {args.out / 'report.md'} (and report.html, report.json); {report['wall_time_s']:.0f} s")
    empty = filled((args.out / "report.md").read_text())
    if empty:
        print(f"warning: {len(empty)} table rows have missing figures", file=sys.stderr)
    if args.page:
        from cosim_plugins.paper.reproduce import update_results

        update_results(args.out, args.page, args.page.parent / "results", digest)
        print(f"updated the results in {args.page}")
    return 0
