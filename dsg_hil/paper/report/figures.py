"""The creep figures of Section V.B (Figs. 8-12) from a decoded log, the paper's numbers marked on them as Figs. 3-5
mark theirs; the sensitivity map and the configurations' timelines. matplotlib is imported here only."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...common.units import CV
from ..plots import require_matplotlib
from ..reference import (CREEP_MU_CH, CREEP_P_CH_MPA, CREEP_SLIP_TIME_S, CREEP_T_CL_AT_FIRST_CH_LIMIT_C,
                         CREEP_T_ONCOMING_AT_STOP_C, CREEP_TIME_S, SAFETY_TEMPERATURE_C)
from ...results.summary import TORQUE_MIN
from .log import CreepRecord

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .model import ModelChecks

__all__ = ["COLOR", "DARK", "SHADE", "comparison_figures", "creep_figures"]

# the paper's numbers, marked as Figs. 3-5 mark theirs
PAPER_MARK: dict[str, Any] = {"marker": "o", "ms": 8, "mfc": "white", "mew": 2, "ls": "none"}

COLOR = {"CL": "tab:blue", "CH": "tab:orange"}
DARK = {"CL": "navy", "CH": "saddlebrown"}
SHADE = {"CL": "#dbe8f6", "CH": "#fde6cf"}


def _frame(ax: Axes, record: CreepRecord, ylabel: str) -> None:
    """Phase shading (which clutch slips), handovers, the stop; labels and grid."""
    m = record.metrics
    for p in m["phases"]:
        ax.axvspan(p["start_s"], p["end_s"], color=SHADE[p["clutch"]], lw=0, zorder=0)
    for p in m["phases"][1:]:
        ax.axvline(p["start_s"], color="0.45", lw=0.8, ls=":", zorder=1)
    if m["stop_time_s"] is not None:
        ax.axvline(m["stop_time_s"], color="tab:red", lw=1.2, ls="--", zorder=1)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.set_xlim(0.0, float(record.column("t")[-1]))


def _phase_legend(record: CreepRecord) -> list:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    handles: list[Patch | Line2D] = [Patch(color=SHADE[c], label=f"{c} slips") for c in ("CL", "CH")]
    handles.append(Line2D([], [], color="0.45", lw=0.8, ls=":", label="handover"))
    if record.metrics["stop_time_s"] is not None:
        handles.append(Line2D([], [], color="tab:red", lw=1.2, ls="--", label="vehicle stopped"))
    return handles


def _save(fig: Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path)
    return path


def _paper_points(ax: Axes, kinds: tuple[str, ...], record: CreepRecord | None = None) -> None:
    """The paper's Section V.B numbers on a creep figure: its stop (174 s) always; ``T``: the on-coming CL's 246 °C
    at the stop and CL's 205.5 °C when CH first reaches the limit; ``mu``/``P``: mu_CH and P_CH at the start and
    end of the first CH slip, placed at this run's first CH phase (the paper gives no times for them)."""
    ax.axvline(CREEP_TIME_S, color="tab:red", lw=1.0, ls="-.", alpha=0.8, label=f"paper: stop at {CREEP_TIME_S:g} s")
    if "T" in kinds:
        ax.plot([CREEP_TIME_S], [CREEP_T_ONCOMING_AT_STOP_C], color=COLOR["CL"], **PAPER_MARK,
                label=f"paper: on-coming CL {CREEP_T_ONCOMING_AT_STOP_C:g} °C at the stop")
        ax.axhline(CREEP_T_CL_AT_FIRST_CH_LIMIT_C, color=COLOR["CL"], lw=1.0, ls=(0, (1, 3)),
                   label=f"paper: CL {CREEP_T_CL_AT_FIRST_CH_LIMIT_C:g} °C when CH first reaches the limit")
    for kind, (start, end), unit in (("mu", CREEP_MU_CH, ""), ("P", CREEP_P_CH_MPA, " MPa")):
        if kind not in kinds:
            continue
        first = next((p for p in record.metrics["phases"] if p["clutch"] == "CH"), None) if record else None
        label = f"paper: {kind}_CH {start:g} → {end:g}{unit}, first CH slip"
        if first is None:
            for value in (start, end):
                ax.axhline(value, color=COLOR["CH"], lw=1.0, ls=(0, (1, 3)), label=label)
                label = "_"
        else:
            ax.plot([first["start_s"], first["end_s"]], [start, end], color=COLOR["CH"], **PAPER_MARK, label=label)


def creep_figures(record: CreepRecord, outdir: Path) -> list[Path]:
    """Figs. 8 (heat flux), 9 (plate temperatures), 10 (mu), 11 (pressures), 12 (vehicle speed) into outdir."""
    plt = require_matplotlib()
    outdir.mkdir(parents=True, exist_ok=True)
    col = record.column
    t = col("t")
    written = []
    source = Path(record.source).name

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), dpi=110, sharex=True)
    truth = np.isfinite(col("Q_CL")).any() or np.isfinite(col("Q_CH")).any()
    for ax, c in zip(axes, ("CL", "CH")):
        _frame(ax, record, "heat flux [kW]")
        if truth:
            ax.plot(t, col(f"Q_{c}") / CV.KW_TO_W, color=COLOR[c], lw=1.3, label=f"generated (friction), {c}")
            ax.plot(t, col(f"Q_diss_{c}") / CV.KW_TO_W, color="k", lw=1.0,
                    label=f"dissipated (leaving the plates), {c}")
        else:
            ax.text(0.5, 0.5, "no SIM_HEAT frames in this log: the heat fluxes are the simulator's truth,\n"
                              "not on a vehicle bus (a log of a real ECU or without SIM_* has none)",
                    transform=ax.transAxes, ha="center", va="center", fontsize=9, color="0.3")
        _paper_points(ax, ())
        ax.set_title(f"clutch {c}", fontsize=10)
        ax.set_ylim(top=ax.get_ylim()[1] * 1.45)  # room for the legend above the curves
        ax.legend(handles=ax.get_legend_handles_labels()[0] + _phase_legend(record), fontsize=8,
                  loc="upper right", ncol=3)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Fig. 8 - heat flux generated and dissipated per clutch ({source})", fontsize=11)
    written.append(_save(fig, outdir / "fig8_heat_flux.png"))
    plt.close(fig)

    for name, title, ylabel, draw, loc, kinds in (
            ("fig9_plate_temperatures", "Fig. 9 - plate temperatures of both clutches", "plate temperature [°C]",
             _temperatures, "lower right", ("T",)),
            ("fig10_mu", "Fig. 10 - friction coefficient of both clutches", "μ [-]", _mu, "lower right", ("mu",)),
            ("fig11_pressures", "Fig. 11 - clutch pressures, commanded and measured", "pressure [MPa]", _pressures,
             "upper right", ("P",)),
            ("fig12_vehicle_speed", "Fig. 12 - vehicle speed against its target", "vehicle speed [m/s]", _speed,
             "lower left", ())):
        fig, ax = plt.subplots(figsize=(9, 5 if name.startswith("fig9") else 4.5), dpi=110)
        _frame(ax, record, ylabel)
        draw(ax, record)
        _paper_points(ax, kinds, record)
        ax.set_xlabel("time [s]")
        ax.set_title(f"{title} ({source})", fontsize=11)
        ax.legend(handles=ax.get_legend_handles_labels()[0] + _phase_legend(record), fontsize=8, loc=loc,
                  ncol=2)
        written.append(_save(fig, outdir / f"{name}.png"))
        plt.close(fig)
    return written


def _temperatures(ax: Axes, record: CreepRecord) -> None:
    col = record.column
    for c in ("CL", "CH"):
        ax.plot(col("t"), col(f"T_{c}"), color=COLOR[c], lw=2, label=f"T_{c} (plant truth)")
        pred = col(f"T_{c}_pred")
        if np.isfinite(pred).any():  # only a TCU that sends TCU_STATUS predicts
            ax.plot(col("t"), pred, color=DARK[c], lw=1.0, ls="--", label=f"T_{c} predicted by the TCU")
    ax.axhline(SAFETY_TEMPERATURE_C, color="tab:red", lw=1.5, label=f"safety limit {SAFETY_TEMPERATURE_C:g} °C")


def _mu(ax: Axes, record: CreepRecord) -> None:
    col = record.column
    for c in ("CL", "CH"):
        transmits = np.abs(col(f"M_{c}")) > TORQUE_MIN
        ax.plot(col("t"), np.where(transmits, col(f"mu_{c}"), np.nan), color=COLOR[c], lw=1.5,
                label=f"μ_{c} (while it transmits torque)")


def _pressures(ax: Axes, record: CreepRecord) -> None:
    col = record.column
    for c in ("CL", "CH"):
        ax.plot(col("t"), col(f"P_{c}") / CV.MPA_TO_PA, color=COLOR[c], lw=3.0, alpha=0.55, label=f"P_{c} measured")
        ax.plot(col("t"), col(f"P_{c}_cmd") / CV.MPA_TO_PA, color=DARK[c], lw=0.9, ls="--",
                label=f"P_{c} commanded (TCU_CMD)")
    ax.set_ylim(top=ax.get_ylim()[1] * 1.3)  # room for the legend above the curves


def _speed(ax: Axes, record: CreepRecord) -> None:
    col = record.column
    target = np.where(col("creep_request") >= 0.5, col("desired_speed_mps"), np.nan)
    ax.plot(col("t"), target, color="k", lw=1.2, ls="--", label="desired creep speed (DRIVER)")
    ax.plot(col("t"), col("v"), color="tab:green", lw=1.5, label="vehicle speed")
    ax.axhline(0.0, color="0.3", lw=0.6)


def comparison_figures(record: CreepRecord, table1: CreepRecord | None, checks: ModelChecks, outdir: Path,
                       name: str = "fitted") -> list[Path]:
    """The sensitivity map of the Section V.B numbers and the configurations' timelines beside the paper's
    (``name``: the configuration of ``record``)."""
    return [_sensitivity_map(checks, outdir / "fig13_sensitivity.png"),
            _configurations(record, table1, outdir / "fig14_configurations.png", name)]


def _sensitivity_map(checks: ModelChecks, path: Path) -> Path:
    """Elasticities as a heat map: rows the V.B numbers, columns the calibrated then the influential assumed
    quantities; each cell annotated, colours clipped at +-3."""
    plt = require_matplotlib()
    s = checks.sensitivity
    data = np.array(s.elasticity, dtype=float)
    fig, ax = plt.subplots(figsize=(1.6 + 0.75 * len(s.quantities), 1.2 + 0.45 * len(s.numbers)), dpi=110)
    image = ax.imshow(np.clip(data, -3.0, 3.0), cmap="RdBu_r", vmin=-3.0, vmax=3.0, aspect="auto")
    for i, row in enumerate(data):
        for j, e in enumerate(row):
            text = "–" if np.isnan(e) else f"{e:.2f}"
            ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white" if abs(e) > 2 else "black")
    ax.set_xticks(range(len(s.quantities)))
    ax.set_xticklabels([q + ("" if c else " (assumed)") for q, c in zip(s.quantities, s.calibrated)], rotation=35,
                       ha="right", fontsize=8)
    ax.set_yticks(range(len(s.numbers)))
    ax.set_yticklabels(s.numbers, fontsize=8)
    calibrated = sum(s.calibrated)
    if calibrated < len(s.quantities):
        ax.axvline(calibrated - 0.5, color="k", lw=1.5)
    fig.colorbar(image, ax=ax, label="d ln(number) / d ln(quantity)", shrink=0.8)
    ax.set_title("Sensitivity of Section V.B's numbers (reduced model): calibrated | assumed", fontsize=10)
    return _close(plt, fig, path)


def _configurations(record: CreepRecord, table1: CreepRecord | None, path: Path, name: str) -> Path:
    """Plate temperatures of both configurations on the loop, and their phases beside the paper's totals."""
    plt = require_matplotlib()
    fig, (top, bars) = plt.subplots(2, 1, figsize=(9, 6.5), dpi=110, sharex=True,
                                    gridspec_kw={"height_ratios": [3, 1.3]})
    runs: list[tuple[str, CreepRecord, str]] = [(name, record, "-")]
    if table1 is not None:
        runs.append(("table1", table1, "--"))
    for label, rec, ls in runs:
        for c in ("CL", "CH"):
            top.plot(rec.column("t"), rec.column(f"T_{c}"), color=COLOR[c], ls=ls, lw=1.6, label=f"T_{c}, {label}")
    top.axhline(SAFETY_TEMPERATURE_C, color="tab:red", lw=1.2, label=f"limit {SAFETY_TEMPERATURE_C:g} °C")
    _paper_points(top, ("T",))
    top.set_ylabel("plate temperature [°C]")
    top.grid(alpha=0.3)
    top.legend(fontsize=8, ncol=3, loc="lower right")
    top.set_title(f"Section V.B: configuration {name} and table1 on the real loop, and the paper", fontsize=10)
    rows: list[tuple[str, CreepRecord | None]] = [("paper", None)] + [(label, rec) for label, rec, _ in runs]
    for y, (_, bar) in enumerate(rows):
        if bar is None:  # the paper publishes the totals, not each phase
            bars.barh(y, CREEP_SLIP_TIME_S["CL"], left=0.0, color=COLOR["CL"], alpha=0.5)
            bars.barh(y, CREEP_SLIP_TIME_S["CH"], left=CREEP_SLIP_TIME_S["CL"], color=COLOR["CH"], alpha=0.5)
            bars.plot([CREEP_TIME_S], [y], "v", color="tab:red", ms=9)
            bars.text(2.0, y, "totals: CL 43.5 s, CH 130.5 s (in turns CL, CH, CL, CH)", va="center", fontsize=7)
            continue
        for p in bar.metrics["phases"]:
            bars.barh(y, p["end_s"] - p["start_s"], left=p["start_s"], color=COLOR[p["clutch"]])
        slip = bar.metrics["slip_time_s"]
        bars.text(2.0, y + 0.38, f"slip time CL {slip['CL']:.1f} s, CH {slip['CH']:.1f} s (phases: runs of 0.5 s "
                  "or more)", va="bottom", fontsize=7)
        if bar.metrics["stop_time_s"] is not None:
            bars.plot([bar.metrics["stop_time_s"]], [y], "v", color="tab:red", ms=9)
    bars.set_yticks(range(len(rows)))
    bars.set_yticklabels([r[0] for r in rows], fontsize=8)
    bars.invert_yaxis()
    bars.set_xlabel("time [s] (▼ the stop)")
    bars.grid(alpha=0.3, axis="x")
    return _close(plt, fig, path)


def _close(plt: Any, fig: Figure, path: Path) -> Path:
    _save(fig, path)
    plt.close(fig)
    return path
