"""The report page (Markdown): the table "paper vs dsg-hil", the figures, the creep numbers."""

from __future__ import annotations

from pathlib import Path

__all__ = ["write_page"]


def _num(x: float | None, digits: int = 4) -> str:
    return "–" if x is None else f"{x:.{digits}g}"


def _model_sections(m: dict) -> list[str]:
    """Hold-out, sensitivity and the configurations, from report.json's model_checks and configurations."""
    checks, conf = m["model_checks"], m["configurations"]
    lines = ["", "## Hold-out check of the Section V.B calibrations (leave-one-out, reduced model)", "",
             "Each V.B number re-fitted away: its calibration re-run on the others (the other calibrations as in "
             "the parameter file), then the number predicted. Where the others cannot determine every free quantity "
             "(zero residual degrees of freedom), the one the left-out number is most sensitive to is fixed at its "
             "prior, the `table1` configuration's value, and named. 174 s is the sum of the two slip times, so "
             "leaving out one of those three is predicted by the other two. Wall time "
             f"{checks['wall_time_s']['holdout']} s.", "",
             "| number | calibration | paper | predicted without it | error | band | within | fixed at its prior |",
             "|---|---|---:|---:|---:|---:|---|---|"]
    for h in checks["holdout"]:
        fixed = ", ".join(f"{f['quantity']} = {f['value']:.4g}" for f in h["fixed_at_prior"]) or "–"
        within = "yes" if h["within_band"] else "**no**"
        lines.append(f"| {h['key']} | {h['calibration']} | {h['published']:g} | {_num(h['predicted'])} | "
                     f"{_num(h['error'], 3)} | ±{h['band']:.3g} | {within} | {fixed} |")
    s = checks["sensitivity"]
    lines += ["", "## Sensitivity of the Section V.B numbers (reduced model)", "",
              f"Elasticity d ln(number) / d ln(quantity) by central differences (±{s['step']:.0%}): every calibrated "
              f"quantity, then every assumed parameter (of {s['screened_assumed']} screened) that moves some number by "
              f"an elasticity of 0.1 or more. Temperatures in °C. Wall time {checks['wall_time_s']['sensitivity']} s. "
              "Figure: `fig13_sensitivity`.", "",
              "| number | " + " | ".join(q + ("" if c else " *(assumed)*") for q, c in zip(s["quantities"],
                                                                                     s["calibrated"])) + " |",
              "|---|" + "---:|" * len(s["quantities"])]
    for name, row in zip(s["numbers"], s["elasticity"]):
        lines.append(f"| {name} | " + " | ".join("–" if e is None else f"{e:.2f}" for e in row) + " |")
    t1 = conf["table1"]
    lines += ["", f"## Configurations: {conf['main']} vs table1 vs the paper (Section V.B)", "",
              "`table1`: Table I and stated assumptions alone, no Section V.B number consumed (identical clutch packs "
              "with N and steel mass from Table I's radii, one cooling flow for both, (6) without its first term, "
              "mesh losses; each value's reason in `dsg_hil/data/params_table1.toml`; `--params table1`). The "
              "scenario is the same for both; its creep speed was itself chosen with the Stribeck fit (the CH slip "
              "of Section V.B).",
              ""]
    if t1 is None:
        lines += ["table1 was not run on the loop (`--from-log`); its reduced model is shown.", ""]
    else:
        lines += [f"table1 on the loop: `{t1['log']}`; phases (runs of 0.5 s or more): "
                  f"{', '.join(p['clutch'] for p in t1['phases']) or 'none'}.", ""]
    lines += [f"Why: {conf['why']}", ""]
    lines += [f"| number | paper | {conf['main']}, loop | table1, loop | table1, reduced model | "
              f"{conf['main']}, reduced model | why table1 differs |", "|---|---:|---:|---:|---:|---:|---|"]
    for r in conf["section_vb"]:
        lines.append(f"| {r['key']} | {r['paper']:g} | {_num(r['given_loop'])} | {_num(r['table1_loop'])} | "
                     f"{_num(r['table1_reduced'])} | {_num(r['given_reduced'])} | {r['reason']} |")
    return lines


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
             f"**{m['summary_line']}.**", "",
             "A number is *fitted* when a calibration of the parameters consumed it (`dsg_hil/paper/calibration.py`, "
             "`CALIBRATIONS`): matching it shows the fit holds on the real loop, not that the model predicts it. "
             "With zero residual degrees of freedom any nearby published value would have been matched as well. "
             "Only *predicted* numbers test the model.", "",
             "| quantity | paper | dsg-hil | band | result | status | where | reason for a gap |",
             "|---|---:|---:|---|---|---|---|---|"]
    for r in m["paper_vs_dsg_hil"]:
        paper = "under 250 °C" if r["paper"] is None else f"{_fmt(r['paper'], r['unit'])} {r['unit']}".strip()
        sim = f"{_fmt(r['dsg_hil'], r['unit'])} {r['unit']}".strip() if r["dsg_hil"] is not None else "–"
        result = {"pass": "pass", "miss": "**miss**", "n/a": "n/a"}[r["result"]]
        status = "predicted" if r["status"] == "predicted" else f"fitted ({r['fitted_by']})"
        lines.append(f"| {r['quantity']} | {paper} | {sim} | {r['band']} | {result} | {status} | {r['where']} | "
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
    if "model_checks" in m:
        lines += _model_sections(m)
    lines += ["", "## Figures", ""]
    for fig in figures:
        lines += [f"![{fig.stem}]({fig.relative_to(path.parent).as_posix()})", ""]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
