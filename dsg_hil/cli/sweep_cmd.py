"""``dsg-hil sweep``: many runs over a space of scenarios on Dask distributed (or a search for a violation), a
Parquet table, a page with figures, and the verdict (exit 3 when a run violates, 1 when none does but a run could
not be judged: it failed)."""

from __future__ import annotations

import argparse

from ..common.errors import EXIT_OK, EXIT_OUT_OF_BAND, EXIT_RUN_FAILED
from ..common.files import check_output_path
from . import command_help
from .common import positive_int, progress, set_overrides

__all__ = ["add_subparser"]


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "sweep", help=command_help("sweep"),
        description="Run the scenarios a space file describes (distributions over scenario fields, parameters, "
                    "driver behaviours and faults; a seeded Latin hypercube or Sobol sampler) against the "
                    "controller under test on Dask distributed: a LocalCluster of worker processes by default, or "
                    "an existing cluster (--scheduler, DASK_SCHEDULER_ADDRESS). Each run is judged on the plant's "
                    "truth (plate temperature, roll-back, overspeed, FAULT, standstill while creep requested). "
                    "Writes OUT/table/*.parquet, OUT/runs/*.json, OUT/sweep.md with figures and the 'dsg-hil run' "
                    "reproducing each violation. Exit 3 when a run violates; 1 when none does but some runs failed "
                    "(an error in the run or the controller: not judged, so not a pass; each row's 'error' says "
                    "why); 0 when every run was judged and none violates. Needs pip install 'dsg-hil[sweep]'.")
    parser.add_argument("space", metavar="SPACE", help="the space file (TOML), e.g. dsg_hil/data/sweeps/safety.toml")
    parser.add_argument("--out", metavar="DIR", help="results directory (default: ./sweep-<space name>)")
    parser.add_argument("--n", type=positive_int, metavar="N", help="runs (--search: its budget); "
                        "default: the space's n")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, metavar="N",
                       help="worker processes of the local cluster (default: one per core)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask cluster's scheduler "
                       "(tcp://HOST:8786; default: DASK_SCHEDULER_ADDRESS, else a local cluster)")
    parser.add_argument("--resume", action="store_true",
                        help="keep the runs already in --out, run the rest (without --n: the sweep's own n; a larger "
                             "--n extends a Sobol sweep, a Latin hypercube needs the same --n; --search: the stored "
                             "trials count against the budget and are told to the optimiser first)")
    parser.add_argument("--search", action="store_true", help="search (Optuna TPE) for a violation instead of "
                        "sampling: stops at the first, writes OUT/counterexample/")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="fix one parameter in every run, by its dotted key as 'dsg-hil params' lists it, in "
                             "the unit listed there (a parameter the space draws: change it in the file); "
                             "repeatable")
    parser.add_argument("--keep-logs", action="store_true", help="keep every run's log (default: failing runs')")
    parser.set_defaults(func=_do_sweep)


def _do_sweep(args: argparse.Namespace) -> int:
    from ..sweep import load_space, run_search, run_sweep, write_page  # noqa: PLC0415 - Dask when it runs
    from ..sweep.code import code_digest, code_note  # noqa: PLC0415
    from ..sweep.controllers import check_importable  # noqa: PLC0415
    from ..sweep.engine import scheduler_address  # noqa: PLC0415
    from ..sweep.results import ResultStore  # noqa: PLC0415
    from ..sweep.verdict import latent_counts  # noqa: PLC0415

    space = load_space(args.space)
    overrides = set_overrides(args)
    if overrides:  # checked (key, unit, range) on the shipped parameters, then fixed in every run
        from ..physics.params import load_params, value_of, with_overrides  # noqa: PLC0415

        checked = with_overrides(load_params(), overrides, origin="--set")
        space = space.with_parameters({k: value_of(checked, k, "--set") for k in overrides})
    out = args.out or f"sweep-{space.name}"
    check_output_path("--out", out, directory=True)
    if space.controller["kind"] == "python" and scheduler_address(args.scheduler) is None:
        check_importable(space)  # the local cluster's workers import it alike: found now, not in every run
    options = {"workers": args.workers or None, "scheduler": args.scheduler, "resume": args.resume,
               "keep_logs": args.keep_logs, "progress": progress}
    if args.search:
        result = run_search(space, out, budget=args.n, **options)
    else:
        result = run_sweep(space, out, n=args.n, **options)
    page = write_page(space, result, ResultStore(out, resume=True).record)
    progress(f"wrote {page}, {out}/table ({len(result.rows)} rows)")
    if (note := code_note(result.rows, code_digest())) is not None:
        progress(f"warning: {note}")
    violating, failed = result.violations, [r for r in result.rows if r.get("verdict") == "error"]
    latent = latent_counts(violating) if violating else ""
    progress(f"verdict: {len(violating)} of {len(result.rows)} runs violate"
             + (f" ({', '.join(sorted({v for r in violating for v in r['violations'].split(',')}))})"
                if violating else "")
             + (f": {latent}" if latent else "")
             + (f"; {len(failed)} failed, not judged (first: {failed[0].get('error')})" if failed else "")
             + f"; {result.wall_s:.0f} s wall")
    if violating:
        return EXIT_OUT_OF_BAND
    return EXIT_RUN_FAILED if failed else EXIT_OK
