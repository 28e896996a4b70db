"""``dsg-hil report``: the paper's figures and numbers beside dsg-hil's (validation rig and creep run)."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from ..common.errors import InputError
from . import command_help
from .busopts import setup_logging
from .common import add_params_option, params_from, progress

CREEP_LOG = "creep.log"


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "report", help=command_help("report"),
        description="Run the Section III.C validation and the creep scenario (Section V.B) with the plant and the "
                    "TCU (ecu-stub) in lockstep on python-can's virtual bus, recording the traffic (candump -L) "
                    "into DIR; then write the paper's figures (Figs. 3-5, 8-12), report.md with the table 'paper "
                    "vs dsg-hil' and report.json. The creep part is always computed from the decoded log: "
                    "--from-log takes any recorded log instead (candump -L, .asc, .blf, ...), e.g. of a run with "
                    "another ECU.")
    parser.add_argument("--out", metavar="DIR", default="dsg-hil-report", help="output directory "
                        "(default: ./dsg-hil-report)")
    parser.add_argument("--from-log", metavar="FILE", help="build the creep part from this log instead of a run")
    parser.add_argument("--scenario", metavar="FILE", help="creep scenario TOML (default: the shipped one)")
    parser.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration [s]")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: dbc/dsg_hil.dbc shipped with dsg-hil)")
    parser.add_argument("-v", "--verbose", action="store_true", help="log protocol events (rejected frames ...)")
    add_params_option(parser)
    parser.set_defaults(func=_do_report)


def run_validation(params, **kwargs):
    """:func:`dsg_hil.paper.validation.run_validation`, imported when the report runs (numpy, scipy)."""
    from ..paper.validation import run_validation as run  # noqa: PLC0415

    return run(params, **kwargs)


def _writable(out: Path) -> None:
    """Fail now, not after minutes of simulation."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise InputError(f"--out {out}: not a writable directory ({exc.strerror or exc})") from None


def _run_creep(args: argparse.Namespace, out: Path) -> Path:
    """The real loop, as ``dsg-hil run`` with no interface configured: plant and ecu-stub in lockstep on
    python-can's virtual bus, the traffic recorded to DIR/creep.log, the run's summary to DIR/summary.json."""
    from ..protocol.bus import VIRTUAL_CHANNEL  # noqa: PLC0415 - python-can when the run starts
    from ..sim.run import RunConfig, open_run, resolve_scenario  # noqa: PLC0415

    log = out / CREEP_LOG
    setup_logging(args.verbose)
    config = RunConfig(scenario=resolve_scenario(args.scenario, args.duration), params=args.params, dbc=args.dbc,
                       bus={"interface": "virtual", "channel": f"{VIRTUAL_CHANNEL}_report"}, log=log,
                       summary=out / "summary.json", progress=progress)
    with open_run(config) as run:
        progress(f"creep run: {run.scenario.name}, {run.scenario.duration_s:g} s, lockstep on {run.interface}")
        run.run()
    progress(f"wrote {config.summary}")
    return log


def _do_report(args: argparse.Namespace) -> int:
    from ..paper.plots import require_matplotlib
    from ..protocol import load_dbc
    from ..paper.report import write_report
    from ..paper.report.log import read_log
    out = Path(args.out)
    _writable(out)
    require_matplotlib()
    db = load_dbc(args.dbc)
    record = read_log(args.from_log, db) if args.from_log else None  # a bad log fails before the runs
    cases = run_validation(params_from(args), progress=progress)
    if record is None:
        record = read_log(_run_creep(args, out), db)
    progress(f"creep: decoded {record.frames['decoded']} frames of {record.source}")
    data = write_report(out, record, cases, progress)
    rows = data["paper_vs_dsg_hil"]
    tally = {k: sum(r["result"] == k for r in rows) for k in ("pass", "miss", "n/a")}
    progress(f"paper vs dsg-hil: {tally['pass']} pass, {tally['miss']} miss, {tally['n/a']} n/a "
             f"(see {out / 'report.md'})")
    return 0
