"""``dsg-hil plot run.log -o run.png``: one recorded run at a glance (speed, pressures, plate temperatures), from
the log alone, decoded with the DBC; no Python to write, no whole report to build."""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from ..common.errors import InputError, LogError
from ..common.files import check_output_path
from . import command_help
from .common import progress

if TYPE_CHECKING:
    from ..protocol.binding import Binding

__all__ = ["PANELS", "add_subparser", "carriers", "plot_log", "series"]

# (title, y label, [(MESSAGE.Signal, legend)]): what a panel shows of the log, each signal when the log has it
PANELS = (
    ("vehicle speed", "m/s", [("PLANT_VEHICLE.VehicleSpeed", "vehicle"), ("DRIVER.DesiredCreepSpeed", "desired")]),
    ("clutch pressures", "MPa", [("TCU_CMD.P_CL_Cmd", "CL commanded"), ("PLANT_PRESSURE.P_CL", "CL"),
                                 ("TCU_CMD.P_CH_Cmd", "CH commanded"), ("PLANT_PRESSURE.P_CH", "CH")]),
    ("plate temperatures", "degC", [("SIM_TRUTH_CL.T_Plate", "CL (plant truth)"), ("TCU_STATUS.T_CL_Pred",
                                     "CL (TCU estimate)"), ("SIM_TRUTH_CH.T_Plate", "CH (plant truth)"),
                                    ("TCU_STATUS.T_CH_Pred", "CH (TCU estimate)")]),
)


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "plot", help=command_help("plot"),
        description="Plot one recorded run from its log (candump -L .log, .asc, .blf, .mf4 ..., decoded with the "
                    "DBC): vehicle and desired speed, commanded and measured clutch pressures, plate temperatures "
                    "(the plant's truth where the log has SIM_TRUTH frames, and the TCU's estimate). Needs the "
                    "'plots' extra (pip install 'dsg-hil[plots]').")
    parser.add_argument("log", metavar="LOG", help="the recorded run")
    parser.add_argument("-o", "--output", metavar="FILE",
                        help="the image (by extension: .png, .pdf, .svg ...; default: LOG with .png)")
    parser.add_argument("--dbc", metavar="FILE", help="DBC file (default: dbc/dsg_hil.dbc shipped with dsg-hil)")
    parser.add_argument("--binding", metavar="FILE",
                        help="binding TOML of the DBC: the log is of another matrix (its frames checked by the "
                             "binding's protection, e.g. AUTOSAR E2E), each quantity plotted from the signal that "
                             "carries it, in the units above (default: the shipped DBC's signals)")
    parser.set_defaults(func=_do_plot)


def series(log: str | Path, db: object, binding: Binding | None = None) -> dict[str, tuple[list[float], list[float]]]:
    """Every signal of :data:`PANELS` the log holds: ``MESSAGE.Signal`` -> (times [s] from the first frame, values
    in the DBC's units); read whole first, so a bad log fails before anything is drawn. ``binding`` (a loaded
    binding of ``db``): the log is of that matrix; each of :data:`PANELS`' signals is the one that carries its
    quantity there, converted to the shipped signal's unit (:func:`carriers`)."""
    from ..protocol.logs import decoded_frames, log_codec  # noqa: PLC0415 - cantools when the command runs

    wanted = {key for _, _, signals in PANELS for key, _ in signals}
    if binding is None:
        codec, convert = log_codec(db), {key: (key, 1.0, 0.0) for key in wanted}  # type: ignore[arg-type]
    else:
        codec, convert = log_codec(binding.db, binding.protection), carriers(binding, wanted)
    out: dict[str, tuple[list[float], list[float]]] = {}
    t0: float | None = None
    for timestamp, frame in decoded_frames(log, codec):
        if frame is None:
            continue
        t0 = timestamp if t0 is None else t0
        for name, value in frame.values.items():
            found = convert.get(f"{frame.name}.{name}")
            if found is not None:
                key, k, c = found
                times, values = out.setdefault(key, ([], []))
                times.append(timestamp - t0)
                values.append(float(value) * k + c)
    if not out:
        shown = sorted(convert) if binding is not None else sorted(wanted)
        raise LogError(f"{log}: none of the signals plotted ({', '.join(shown)}): not a run of this DBC")
    return out


def carriers(binding: Binding, wanted: Iterable[str]) -> dict[str, tuple[str, float, float]]:
    """By ``MESSAGE.Signal`` of ``binding``'s matrix that carries the quantity of one of the shipped signals
    ``wanted``: (that shipped signal, k, c), its value times k plus c in the shipped signal's unit (both signals'
    conversions to SI composed)."""
    from ..protocol.binding import shipped_binding  # noqa: PLC0415

    shipped = shipped_binding()
    where = {quantity: key for key, (quantity, _) in binding.signals.items()}
    found: dict[str, tuple[str, float, float]] = {}
    for (message, signal), (quantity, f_shipped) in shipped.signals.items():
        key = f"{message}.{signal}"
        if key in set(wanted) and quantity in where:
            f_other = binding.signals[where[quantity]][1]
            o_other, o_shipped = binding.offsets.get(where[quantity], 0.0), shipped.offsets.get((message, signal), 0.0)
            found[".".join(where[quantity])] = (key, f_other / f_shipped, (o_other - o_shipped) / f_shipped)
    return found


def plot_log(data: dict[str, tuple[list[float], list[float]]], title: str, output: Path) -> None:
    """Draw the panels of :data:`PANELS` from ``data`` (see :func:`series`) into ``output``."""
    from ..paper.plots import require_matplotlib  # noqa: PLC0415 - matplotlib when the command runs

    plt = require_matplotlib()
    fig, axes = plt.subplots(len(PANELS), 1, sharex=True, figsize=(9, 8), constrained_layout=True)
    for ax, (name, unit, signals) in zip(axes, PANELS):
        drawn = _draw(ax, data, signals)
        ax.set_title(name if drawn else f"{name}: not in this log", loc="left", fontsize=10)
        ax.set_ylabel(unit)
        if drawn:
            ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time from the first frame [s]")
    fig.suptitle(title, fontsize=11)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=120)
    plt.close(fig)


def _draw(ax: object, data: dict[str, tuple[list[float], list[float]]], signals: Iterable[tuple[str, str]]) -> int:
    drawn = 0
    for key, label in signals:
        if key in data:
            times, values = data[key]
            style = "--" if "commanded" in label or "estimate" in label or label == "desired" else "-"
            color = "C3" if label.startswith("CH") else "C1" if label == "desired" else "C0"  # a colour a clutch
            ax.plot(times, values, style, color=color, lw=1.0, label=label)  # type: ignore[attr-defined]
            drawn += 1
    return drawn


def _do_plot(args: argparse.Namespace) -> int:
    from ..paper.plots import require_matplotlib  # noqa: PLC0415
    from ..protocol import load_dbc  # noqa: PLC0415
    from ..protocol.binding import load_binding  # noqa: PLC0415

    output = args.output if args.output is not None else str(Path(args.log).with_suffix(".png"))
    check_output_path("--output" if args.output is not None else "LOG.png", output)
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 - the backend savefig uses

    kinds = FigureCanvasAgg.get_supported_filetypes()  # png, pdf, svg ...: checked before the log is decoded
    if Path(output).suffix.lower().removeprefix(".") not in kinds:
        raise InputError(f"{'--output' if args.output is not None else 'LOG.png'} {output}: the image's extension "
                         f"is one of {', '.join(f'.{kind}' for kind in sorted(kinds))}")
    db = load_dbc(args.dbc)
    binding = None if args.binding is None else load_binding(args.binding, db=db)
    data = series(args.log, db, binding)
    plot_log(data, Path(args.log).name, Path(output))
    progress(f"wrote {output}")
    return 0
