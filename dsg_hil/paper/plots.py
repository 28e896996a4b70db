"""PNG figures like the paper's Figs. 3-5 (matplotlib, no screen needed)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..common.errors import RunError
from ..common.units import CV
from .reference import RIG_DURATION_S, RIG_T_START_C

if TYPE_CHECKING:
    from ..physics.params import Friction
    from .reference import RigReference
    from .validation import CaseResult

__all__ = ["COLORS", "friction_map_figure", "require_matplotlib", "validation_figures"]

COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


def require_matplotlib():
    try:
        import matplotlib
    except ImportError:
        raise RunError("--plots needs matplotlib: pip install 'dsg-hil[plots]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _label(ref: RigReference) -> str:
    return f"{ref.case}: {ref.pressure_mpa} MPa, {ref.speed_rpm:g} r/min"


def validation_figures(results: list[CaseResult], outdir: Path) -> list[Path]:
    """Figs. 3 (temperature), 4 (torque) and 5 (friction coefficient) of Section III.C, paper values marked."""
    plt = require_matplotlib()
    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    specs = (
        ("fig3_temperature.png", "Fig. 3 - plate temperature, clutch slipping at constant P and speed",
         "temperature [°C]", lambda t: t.T_CL),
        ("fig4_torque.png", "Fig. 4 - friction torque", "torque [N·m]", lambda t: t.torque),
        ("fig5_mu.png", "Fig. 5 - friction coefficient", "μ [-]", lambda t: t.mu),
    )
    for name, title, ylabel, series in specs:
        fig, ax = plt.subplots(figsize=(7.5, 4.8), dpi=120)
        for color, r in zip(COLORS, results):
            ax.plot(r.trace.t, series(r.trace), color=color, lw=2, label=f"dsg-hil {_label(r.reference)}")
            ref = r.reference
            if name.startswith("fig3"):
                end = RIG_T_START_C + ref.temperature_rise_c
                ax.plot([RIG_DURATION_S], [end], "o", color=color, ms=8, mfc="white", mew=2)
                ax.annotate(f"paper {end:g}", (RIG_DURATION_S, end), xytext=(-62, 4), textcoords="offset points",
                            color=color, fontsize=8)
            published = {"fig4": (ref.torque_start_nm, ref.torque_end_nm), "fig5": (ref.mu_start, ref.mu_end)}
            pair = published.get(name[:4])
            if pair and pair[0] is not None:
                ax.plot([0.0, RIG_DURATION_S], pair, "o", color=color, ms=8, mfc="white", mew=2,
                        label=f"paper, case {ref.case}")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=11)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left" if name.startswith("fig3") else "lower right")
        fig.tight_layout()
        path = outdir / name
        fig.savefig(path)
        plt.close(fig)
        written.append(path)
    return written


def friction_map_figure(friction: Friction, outpath: Path) -> Path:
    """mu over slip speed for several temperatures and pressures: the reading of formula (6) in use."""
    from ..physics.friction import friction_coefficient_grid
    plt = require_matplotlib()
    n = np.linspace(0.0, 400.0, 401)  # the paper's units: r/min, MPa
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), dpi=120, sharey=True)
    for ax, P in zip(axes, (0.3, 0.75)):
        for T in (20, 40, 80, 114, 160, 250, 300):
            mu = friction_coefficient_grid(n * CV.RPM_TO_RAD_S, T, P * CV.MPA_TO_PA, friction)
            ax.plot(n, mu, label=f"{T} °C")
        ax.set_title(f"μ(n, T) at {P} MPa")
        ax.set_xlabel("slip speed [r/min]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("μ [-]")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    outpath.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(outpath)
    plt.close(fig)
    return outpath
