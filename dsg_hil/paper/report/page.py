"""The report page (Markdown): the table "paper vs dsg-hil", the figures, the creep numbers."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write_page"]


def _fmt(x: float | None, unit: str) -> str:
    if x is None:
        return "–"
    if unit in ("", "MPa"):
        return f"{x:.4g}" if unit == "" else f"{x:.3f}"
    return f"{x:.1f}"


def write_page(path: Path, report: dict, figures: list[Path]) -> Path:
    m = report
    lines = ["# dsg-hil report: paper vs dsg-hil", "",
             f"Creep log: `{m['log']['path']}` ({m['log']['frames']['decoded']} frames decoded, "
             f"{m['log']['frames']['rejected']} rejected, {m['log']['frames']['unknown']} unknown IDs; "
             f"TCU_STATUS {'present' if m['log']['tcu_status'] else 'absent'}). Definitions of the creep numbers: "
             "`dsg_hil/results/summary.py`; bands and paper numbers: `dsg_hil/paper/report/paper.py`.", "",
             "| quantity | paper | dsg-hil | band | result | where | reason for a gap |",
             "|---|---:|---:|---|---|---|---|"]
    for r in m["paper_vs_dsg_hil"]:
        paper = "under 250 °C" if r["paper"] is None else f"{_fmt(r['paper'], r['unit'])} {r['unit']}".strip()
        sim = f"{_fmt(r['dsg_hil'], r['unit'])} {r['unit']}".strip() if r["dsg_hil"] is not None else "–"
        result = {"pass": "pass", "miss": "**miss**", "n/a": "n/a"}[r["result"]]
        lines.append(f"| {r['quantity']} | {paper} | {sim} | {r['band']} | {result} | {r['where']} | "
                     f"{r['reason']} |")
    lines += ["", "## Creep run (Section V.B)", "",
              f"Creep time {m['creep_time_s']} s (driver requests creep, vehicle moving), standstill while creep "
              f"was requested {m['standstill_time_s']} s; slip time CL {m['slip_time_s']['CL']} s, CH "
              f"{m['slip_time_s']['CH']} s (crossovers counted once, overlap {m['slip_overlap_s']} s); stop: "
              f"{m['stop_reason']} at {m['stop_time_s']} s; time above 250 °C: CL {m['time_above_limit_s']['CL']} s,"
              f" CH {m['time_above_limit_s']['CH']} s; roll-back {m['rollback_mps']} m/s, {m['rollback_m']} m.", "",
              "| phase | clutch | start [s] | end [s] | T_CL at end [°C] | T_CH at end [°C] | μ start → end | "
              "P start → end [MPa] |", "|---|---|---:|---:|---:|---:|---|---|"]
    for i, p in enumerate(m["phases"], 1):
        lines.append(f"| {i} | {p['clutch']} | {p['start_s']} | {p['end_s']} | {p['T_CL_end_c']} | "
                     f"{p['T_CH_end_c']} | {p['mu']['start']} → {p['mu']['end']} | "
                     f"{p['P_mpa']['start']} → {p['P_mpa']['end']} |")
    lines += ["", "## Figures", ""]
    for fig in figures:
        lines += [f"![{fig.stem}]({fig.relative_to(path.parent).as_posix()})", ""]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
