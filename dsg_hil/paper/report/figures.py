"""The creep figures of Section V.B (Figs. 8-12) from a decoded log; matplotlib is imported here only."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ...common.units import CV
from ..plots import require_matplotlib
from ..reference import SAFETY_TEMPERATURE_C
from ...results.summary import TORQUE_MIN
from .log import CreepRecord

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["COLOR", "DARK", "SHADE", "creep_figures"]

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


def creep_figures(record: CreepRecord, outdir: Path) -> list[Path]:
    """Figs. 8 (heat flux), 9 (plate temperatures), 10 (mu), 11 (pressures), 12 (vehicle speed) into outdir."""
    plt = require_matplotlib()
    outdir.mkdir(parents=True, exist_ok=True)
    col = record.column
    t = col("t")
    written = []
    source = Path(record.source).name

    fig, axes = plt.subplots(2, 1, figsize=(9, 6), dpi=110, sharex=True)
    for ax, c in zip(axes, ("CL", "CH")):
        _frame(ax, record, "heat flux [kW]")
        ax.plot(t, col(f"Q_{c}") / CV.KW_TO_W, color=COLOR[c], lw=1.3, label=f"generated (friction), {c}")
        ax.plot(t, col(f"Q_diss_{c}") / CV.KW_TO_W, color="k", lw=1.0, label=f"dissipated (leaving the plates), {c}")
        ax.set_title(f"clutch {c}", fontsize=10)
        ax.set_ylim(top=ax.get_ylim()[1] * 1.45)  # room for the legend above the curves
        ax.legend(handles=ax.get_legend_handles_labels()[0] + _phase_legend(record), fontsize=8,
                  loc="upper right", ncol=3)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Fig. 8 - heat flux generated and dissipated per clutch ({source})", fontsize=11)
    written.append(_save(fig, outdir / "fig8_heat_flux.png"))
    plt.close(fig)

    for name, title, ylabel, draw, loc in (
            ("fig9_plate_temperatures", "Fig. 9 - plate temperatures of both clutches", "plate temperature [°C]",
             _temperatures, "lower right"),
            ("fig10_mu", "Fig. 10 - friction coefficient of both clutches", "μ [-]", _mu, "lower right"),
            ("fig11_pressures", "Fig. 11 - clutch pressures, commanded and measured", "pressure [MPa]", _pressures,
             "upper right"),
            ("fig12_vehicle_speed", "Fig. 12 - vehicle speed against its target", "vehicle speed [m/s]", _speed,
             "lower left")):
        fig, ax = plt.subplots(figsize=(9, 5 if name.startswith("fig9") else 4.5), dpi=110)
        _frame(ax, record, ylabel)
        draw(ax, record)
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
