"""``dsg-hil report``: the paper's figures and numbers beside dsg-hil's (validation rig and creep run)."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from ..common.errors import InputError
from . import command_help
from ..common.files import check_output_path
from .busopts import add_verbosity_options, setup_logging
from .common import add_params_option, params_from, progress

if TYPE_CHECKING:
    from ..sim.run import RunConfig

__all__ = ["CREEP_LOG", "TABLE1_DIR", "add_subparser", "model_checks", "run_validation"]

CREEP_LOG = "creep.log"
TABLE1_DIR = "table1"  # DIR/table1/: the Table-I configuration's creep run


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "report", help=command_help("report"),
        description="Run the Section III.C validation and the creep scenario (Section V.B) with the plant and the "
                    "TCU (ecu-stub) in lockstep on python-can's virtual bus, recording the traffic (candump -L) "
                    "into DIR, and again with the Table-I configuration (--params table1) into DIR/table1; then "
                    "write the paper's figures (Figs. 3-5, 8-12), report.md with the table 'paper vs dsg-hil' (each "
                    "number fitted or predicted), the hold-out check and sensitivity of the Section V.B "
                    "calibrations, the configurations side by side, and report.json. The creep part is always "
                    "computed from the decoded log: --from-log takes any recorded log instead (candump -L, .asc, "
                    ".blf, ...), e.g. of a run with another ECU; then nothing is run on the loop.")
    parser.add_argument("--out", metavar="DIR", default="dsg-hil-report", help="output directory "
                        "(default: ./dsg-hil-report)")
    parser.add_argument("--from-log", metavar="FILE", help="build the creep part from this log instead of a run")
    parser.add_argument("--scenario", metavar="FILE", help="creep scenario TOML (default: the shipped one)")
    parser.add_argument("--duration", type=float, metavar="S", help="override the scenario's duration [s]")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: dbc/dsg_hil.dbc shipped with dsg-hil)")
    parser.add_argument("--binding", metavar="FILE",
                        help="binding TOML of the DBC: which signal carries each quantity of the plant (default: "
                             "dbc/dsg_hil.binding.toml, the shipped DBC's)")
    add_verbosity_options(parser)
    add_params_option(parser)
    parser.set_defaults(func=_do_report)


def run_validation(params, **kwargs):
    """:func:`dsg_hil.paper.validation.run_validation`, imported when the report runs (numpy, scipy)."""
    from ..paper.validation import run_validation as run  # noqa: PLC0415

    return run(params, **kwargs)


def model_checks(params, scenario, **kwargs):
    """:func:`dsg_hil.paper.report.model.model_checks` (hold-out, sensitivity), imported when the report runs."""
    from ..paper.report.model import model_checks as checks  # noqa: PLC0415

    return checks(params, scenario, **kwargs)


def _writable(out: Path) -> None:
    """Make ``--out`` (checked before: :func:`check_output_path`) and make sure a file can be written in it."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise InputError(f"--out {out}: not a writable directory ({exc.strerror or exc})") from None


def _run_creep(config: RunConfig) -> Path:
    """The real loop, as ``dsg-hil run`` with no interface configured: plant and ecu-stub in lockstep on
    python-can's virtual bus, the traffic recorded to DIR/creep.log, the run's summary to DIR/summary.json."""
    from ..sim.run import open_run  # noqa: PLC0415 - the plant when the run starts

    with open_run(config) as run:
        progress(f"creep run: {run.scenario.name}, {run.scenario.duration_s:g} s, lockstep on {run.interface}")
        run.run()
    progress(f"wrote {config.summary}")
    assert config.log is not None
    return Path(config.log)


def _do_report(args: argparse.Namespace) -> int:
    """Every input is checked before anything is written or run: --out, matplotlib, the DBC, --params, the
    scenario and --duration, --from-log; then the validation, the creep run (unless --from-log) and the report."""
    from ..paper.plots import require_matplotlib  # noqa: PLC0415 - numpy, matplotlib when the report runs
    from ..paper.report import Comparison, write_report  # noqa: PLC0415
    from ..paper.report.log import read_log  # noqa: PLC0415
    from ..protocol import load_dbc  # noqa: PLC0415
    from ..protocol.binding import load_binding  # noqa: PLC0415
    from ..protocol.codec import Codec, ProtocolError  # noqa: PLC0415
    from ..sim.plant_io import SHIPPED, from_binding  # noqa: PLC0415
    from ..protocol.bus import VIRTUAL_CHANNEL  # noqa: PLC0415
    from ..sim.run import RunConfig, resolve_scenario  # noqa: PLC0415

    out = Path(args.out)
    check_output_path("--out", args.out, directory=True)
    setup_logging(args.verbose, args.quiet)
    require_matplotlib()
    db = load_dbc(args.dbc)
    binding = None if args.binding is None else load_binding(args.binding, db=db)
    io, protection = (None, None) if binding is None else (from_binding(binding), binding.protection)
    try:  # the messages and signals the plant sends and reads, as the creep run and the log's decoding need them
        Codec(db, (io or SHIPPED).uses)
    except ProtocolError as exc:
        raise ProtocolError(f"{args.dbc or 'the shipped DBC'}: {exc}") from None
    params = params_from(args)
    record = read_log(args.from_log, db, io, protection) if args.from_log else None
    scenario = resolve_scenario(args.scenario, args.duration)
    runs = {} if record is not None else {  # the given configuration, then Table I's (DIR/table1/)
        name: RunConfig(scenario=scenario, params=config, dbc=db, binding=args.binding, bus={"interface": "virtual",
                        "channel": f"{VIRTUAL_CHANNEL}_report{suffix}"}, log=where / CREEP_LOG,
                        summary=where / "summary.json", progress=progress)
        for name, config, where, suffix in (("main", params, out, ""), (TABLE1_DIR, TABLE1_DIR, out / TABLE1_DIR,
                                                                        "_table1"))}
    _writable(out)
    cases = run_validation(params, progress=progress)
    checks = model_checks(params, scenario, progress=progress)
    table1 = None
    if record is None:
        record = read_log(_run_creep(runs["main"]), db, io, protection)
        (out / TABLE1_DIR).mkdir(exist_ok=True)
        table1 = read_log(_run_creep(runs[TABLE1_DIR]), db, io, protection)
    progress(f"creep: decoded {record.frames['decoded']} frames of {record.source}")
    name = "fitted" if args.params in (None, "fitted") else Path(args.params).name
    comparison = Comparison(checks, table1, params, scenario, name + (" + --set" if args.set else ""))
    data = write_report(out, record, cases, progress, comparison)
    progress(f"paper vs dsg-hil: {data['summary_line']} (see {out / 'report.md'})")
    holdout = data["model_checks"]["holdout"]
    progress(f"hold-out (V.B number left out of its calibration, then predicted): "
             f"{sum(h['within_band'] for h in holdout)} of {len(holdout)} within their band")
    return 0
