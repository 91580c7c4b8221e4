"""The virtual personalisation study's outputs: changes against population models with
95 % intervals, the demonstration-count curve, the stairs-heavy day, and a Markdown
section for the replication report.

Intervals: Student t intervals of the mean per-participant change, over every
participant of every seed (participants of different seeds are different people; within
a seed the leave-one-out population sets share demonstrators, so the participants are
not quite independent and the intervals are, if anything, a little narrow). The mean
change of each seed is given alongside, so seed-to-seed agreement can be read off.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from controller.evaluation.output_folder import OutputFolder, json_ready
from controller.evaluation.personalisation import (
    POPULATION,
    PersonalisationStudy,
    map_condition,
    own_condition,
)
from controller.evaluation.rendering import controller_colour, new_figure, render_figure
from controller.evaluation.study import controller_label
from controller.evaluation.tables import Cell, Table
from controller.intent.personal_models import MIN_PARTICIPANT_DEMOS
from controller.tick_record import CATEGORY_NAMES

LEVEL = 0.95
LAB_METRICS: tuple[tuple[str, str], ...] = (
    ("correct_pct", "correct first lock decisions, % of lifts"),
    ("correct_sq_pct", "correct decisions, squats, %"),
    ("correct_as_pct", "correct decisions, stoops, %"),
    ("wrong", "wrong decisions per trial"),
    ("missed", "missed decisions per trial"),
    ("fp_total", "false positive lock signals per trial (W + SW)"),
)
DAY_CHANGES: tuple[tuple[str, str], ...] = (
    ("fp_stairs", "UMC false positive lock signals in stair bouts, per day"),
    ("fp_stairs_per_h", "UMC stair false positives per hour of stairs"),
    ("fp_walking", "UMC false positive lock signals in walking bouts, per day"),
    ("correct", "correct lift decisions per day"),
    ("wrong", "wrong lift decisions per day"),
    ("missed", "missed lift decisions per day"),
)
SECTION_TITLE = "Personalisation (beyond the paper)"
FORMAT_NAME = "exostudy.personalisation"


def t_interval(x: np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    """(mean, low, high) of a Student t interval of the mean; NaNs ignored; NaN
    interval below two values; constant data give the point itself."""
    a = np.asarray(x, dtype=np.float64)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return math.nan, math.nan, math.nan
    m = float(a.mean())
    if a.size < 2:
        return m, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + level / 2.0, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size))
    return m, m - half, m + half


@dataclass(frozen=True)
class Change:
    """Mean per-participant change of one metric: condition minus reference."""

    controller: str
    condition: str
    reference: str
    metric: str
    n: int
    mean_reference: float
    mean_condition: float
    change: float
    ci_low: float
    ci_high: float
    per_seed: tuple[float, ...]


def _change(study: PersonalisationStudy, controller: str, condition: str, reference: str,
            metric: str, values: Any) -> Change:
    cond = np.array([values(o, condition) for o in study.outcomes], dtype=np.float64)
    ref = np.array([values(o, reference) for o in study.outcomes], dtype=np.float64)
    keep = np.isfinite(cond) & np.isfinite(ref)
    d = cond - ref
    mean, lo, hi = t_interval(d[keep])
    seeds = np.array([o.seed for o in study.outcomes])
    per_seed = tuple(float(d[keep & (seeds == s)].mean()) if (keep & (seeds == s)).any()
                     else math.nan for s in study.config.seeds)
    return Change(controller, condition, reference, metric, int(keep.sum()),
                  float(ref[keep].mean()) if keep.any() else math.nan,
                  float(cond[keep].mean()) if keep.any() else math.nan, mean, lo, hi,
                  per_seed)


def lab_changes(study: PersonalisationStudy) -> list[Change]:
    """Every lab condition against population models, per controller and metric."""
    out = []
    for c in study.config.controllers:
        for cond in study.config.conditions():
            if cond == POPULATION:
                continue
            for metric, _ in LAB_METRICS:
                def val(o: Any, k: str, c: str = c, metric: str = metric) -> float:
                    return float(o.lab[c][k].get(metric, math.nan))
                out.append(_change(study, c, cond, POPULATION, metric, val))
    return out


def day_value(metrics: dict[str, float], metric: str) -> float:
    """A stairs-day metric, with the per-hour rate derived."""
    if metric == "fp_stairs_per_h":
        h = metrics["stairs_h"]
        return metrics["fp_stairs"] / h if h > 0 else math.nan
    return float(metrics[metric])


def day_changes(study: PersonalisationStudy) -> list[Change]:
    """Learned against equal priors on the stairs-heavy day (UMC, population models)."""
    out = []
    for metric, _ in DAY_CHANGES:
        def val(o: Any, k: str, metric: str = metric) -> float:
            return day_value(o.day[k], metric)
        out.append(_change(study, "umc", "learned", "equal", metric, val))
    return out


def _fmt(x: float, f: str = ".2f") -> str:
    return format(x, f) if math.isfinite(x) else "n/a"


def _ci(c: Change, f: str = ".2f") -> str:
    return f"{_fmt(c.change, f)} [{_fmt(c.ci_low, f)}, {_fmt(c.ci_high, f)}]"


def _describe(cond: str) -> str:
    base, _, pri = cond.partition("+")
    kind, _, n = base.partition("-")
    text = {"population": "population models", "map": f"MAP-adapted, {n} demos/motion",
            "own": f"participant-only fit, {n} demos/motion"}[kind]
    return text + (" + learned priors" if pri else "")


def changes_table(changes: list[Change], title: str) -> Table:
    """Long-form table of changes with intervals and per-seed means."""
    rows: list[tuple[Cell, ...]] = [
        (c.controller, c.condition, c.reference, c.metric, c.n, c.mean_reference,
         c.mean_condition, c.change, c.ci_low, c.ci_high,
         " ".join(_fmt(x) for x in c.per_seed)) for c in changes]
    return Table(("controller", "condition", "reference", "metric", "n", "mean_reference",
                  "mean_condition", "change", "ci95_low", "ci95_high", "change_per_seed"),
                 tuple(rows), title=title, float_format=".2f",
                 notes=("Change: condition minus reference, per participant; 95 % Student "
                        "t interval over participants of all seeds.",))


def curve_rows(study: PersonalisationStudy, changes: list[Change]) -> list[Change]:
    """The demonstration-count curve: change in correct decisions (% of lifts) with n
    demonstrations per motion, MAP and participant-only, per controller."""
    index = {(c.controller, c.condition): c for c in changes if c.metric == "correct_pct"}
    out = []
    for ctl in study.config.controllers:
        for n in study.config.demo_counts:
            for cond in (map_condition(n), own_condition(n)):
                if (ctl, cond) in index:
                    out.append(index[(ctl, cond)])
    return out


def curve_figure(study: PersonalisationStudy, changes: list[Change]) -> tuple[bytes, bytes]:
    """Change in correct decisions against demonstrations per motion (PNG, SVG)."""
    fig = new_figure(6.4, 3.8)
    ax = fig.add_subplot(1, 1, 1)
    index = {(c.controller, c.condition): c for c in changes if c.metric == "correct_pct"}
    for k, ctl in enumerate(study.config.controllers):
        colour = controller_colour(ctl, k)
        for method, name, style in (("map", map_condition, "-"), ("own", own_condition, "--")):
            pts = [(n, index[(ctl, name(n))]) for n in study.config.demo_counts
                   if (ctl, name(n)) in index]
            if not pts:
                continue
            x = np.array([n for n, _ in pts], dtype=np.float64) + (0.08 if method == "own"
                                                                    else 0.0) + 0.04 * k
            y = np.array([c.change for _, c in pts])
            err = np.array([[c.change - c.ci_low for _, c in pts],
                            [c.ci_high - c.change for _, c in pts]])
            ax.errorbar(x, y, yerr=np.nan_to_num(err), color=colour, ls=style, marker="o",
                        ms=3.5, capsize=2.5,
                        label=f"{controller_label(ctl)}, "
                        + ("MAP-adapted" if method == "map" else "participant only"))
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("demonstrations per motion")
    ax.set_ylabel("change in correct decisions (pp of lifts)")
    n = len(study.outcomes)
    ax.set_title(f"Personal models against population models, {n} virtual participants, "
                 f"95 % CI", fontsize=8)
    ax.set_xticks(list(study.config.demo_counts))
    ax.legend(fontsize=6.5, loc="best")
    fig.subplots_adjust(left=0.12, right=0.98, top=0.9, bottom=0.13)
    r = render_figure(fig)
    return r.png, r.svg


def participants_table(study: PersonalisationStudy) -> Table:
    """Every participant's lab metrics per controller and condition (long form)."""
    metrics = [m for m, _ in LAB_METRICS]
    rows: list[tuple[Cell, ...]] = []
    for o in study.outcomes:
        for c, conds in o.lab.items():
            for cond, ms in conds.items():
                rows.append((o.seed, o.index + 1, o.participant_seed, c, cond,
                             *[ms.get(m, math.nan) for m in metrics]))
    return Table(("seed", "participant", "participant_seed", "controller", "condition",
                  *metrics), tuple(rows), title="Lab metrics per virtual participant")


def day_table(study: PersonalisationStudy) -> Table:
    """Every participant's stairs-day metrics under equal and learned priors, and the
    learned priors."""
    from controller.evaluation.working_day import DAY_METRICS

    rows: list[tuple[Cell, ...]] = []
    for o in study.outcomes:
        for which, ms in o.day.items():
            rows.append((o.seed, o.index + 1, o.participant_seed, which,
                         *[ms[m] for m in DAY_METRICS],
                         " ".join(f"{v:.4f}" for v in o.priors.values)))
    return Table(("seed", "participant", "participant_seed", "priors", *DAY_METRICS,
                  "learned_priors"), tuple(rows),
                 title="Stairs-heavy day per virtual participant (UMC, population models)")


def analysis_json(study: PersonalisationStudy) -> dict[str, Any]:
    """`personalisation.json`: configuration, changes, curve, priors, timing."""
    lab = lab_changes(study)
    day = day_changes(study)

    cfg = study.config
    priors = np.array([o.priors.values for o in study.outcomes])
    estimates = np.array([o.priors.estimate for o in study.outcomes])
    return json_ready({
        "format": FORMAT_NAME, "format_version": 1,
        "config": {**asdict(cfg), "conditions": list(cfg.conditions())},
        "participants": len(study.outcomes),
        "seconds": study.seconds,
        "utilities_version": study.utilities_version,
        "interval": f"{round(100 * LEVEL)} % Student t over participants",
        "lab_changes": [asdict(c) for c in lab],
        "curve": [asdict(c) for c in curve_rows(study, lab)],
        "day_changes": [asdict(c) for c in day],
        "priors": {"classes": list(CATEGORY_NAMES),
                   "values_mean": priors.mean(axis=0).tolist(),
                   "values_min": priors.min(axis=0).tolist(),
                   "values_max": priors.max(axis=0).tolist(),
                   "estimate_mean": estimates.mean(axis=0).tolist(),
                   "motions": len(study.outcomes[0].priors.sources) if study.outcomes else 0},
        "own_refused": sum(len(o.own_refused) for o in study.outcomes),
    })


def _changes_from(doc: list[dict[str, Any]]) -> list[Change]:
    def num(x: Any) -> float:
        return math.nan if x is None else float(x)

    return [Change(d["controller"], d["condition"], d["reference"], d["metric"], int(d["n"]),
                   num(d["mean_reference"]), num(d["mean_condition"]), num(d["change"]),
                   num(d["ci_low"]), num(d["ci_high"]), tuple(num(x) for x in d["per_seed"]))
            for d in doc]


def section_markdown(doc: dict[str, Any], level: int = 2) -> str:
    """The replication report's section "Personalisation (beyond the paper)", from a
    `personalisation.json` document (`analysis_json`). `level`: heading level."""
    if doc.get("format") != FORMAT_NAME or doc.get("format_version") != 1:
        raise ValueError(f"not an {FORMAT_NAME} document of format_version 1")
    cfg = doc["config"]
    lab = _changes_from(doc["lab_changes"])
    day = _changes_from(doc["day_changes"])
    h = "#" * level
    seeds = ", ".join(str(s) for s in cfg["seeds"])
    pri = doc["priors"]
    lines = [
        f"{h} {SECTION_TITLE}", "",
        f"Virtual evidence for the paper's two proposed improvements, on "
        f"{doc['participants']} virtual participants ({cfg['participants']} per seed, "
        f"seeds {seeds}). Each participant's population models are fitted from the other "
        f"participants' data collections (leave-one-out). Personal models use the "
        f"participant's own demonstrations (MAP adaptation, tau = {cfg['tau']:g}; "
        f"participant-only PPCA fit from {MIN_PARTICIPANT_DEMOS} demonstrations on). "
        f"Learned priors come from a previous stairs-heavy working day (Dirichlet "
        f"pseudo-count {cfg['pseudo_count']:g}, forgetting {cfg['forgetting']:g} per "
        f"motion, projected onto the safe set). Every parameter is the modules' default; "
        f"nothing was tuned. Changes are per participant against population models on "
        f"the same recording, with {doc['interval']} intervals; the numbers after "
        f"'per seed' are each seed's mean change.", "",
        f"{h}# Correct decisions (% of the paper protocol's 20 lifts)", "",
        "| controller | condition | population | condition | change [95 % CI] | "
        "per seed |", "| --- | --- | --- | --- | --- | --- |"]
    for c in lab:
        if c.metric != "correct_pct":
            continue
        lines.append(f"| {controller_label(c.controller)} | {_describe(c.condition)} | "
                     f"{_fmt(c.mean_reference, '.1f')} | {_fmt(c.mean_condition, '.1f')} | "
                     f"{_ci(c)} | {' '.join(_fmt(x, '.1f') for x in c.per_seed)} |")
    lines += ["", f"{h}# False positives in the lab (W + SW per trial)", "",
              "| controller | condition | change [95 % CI] |", "| --- | --- | --- |"]
    for c in lab:
        if c.metric == "fp_total" and not c.condition.startswith(map_condition(0)):
            lines.append(f"| {controller_label(c.controller)} | {_describe(c.condition)} | "
                         f"{_ci(c)} |")
    vals = ", ".join(f"{k} {v:.3f}" for k, v in zip(pri["classes"], pri["values_mean"],
                                                   strict=True))
    lines += ["", f"{h}# Stairs-heavy working day (UMC, population models)", "",
              f"{cfg['day_blocks']} blocks of a stairs bout, a walking bout, a stairs bout "
              f"and one lift cycle ({2 * cfg['day_blocks']} lifts). Learned priors (mean "
              f"over participants, from "
              f"{pri['motions']} confirmed motions): {vals}.", "",
              "| metric | equal priors | learned priors | change [95 % CI] | per seed |",
              "| --- | --- | --- | --- | --- |"]
    labels = dict(DAY_CHANGES)
    for c in day:
        lines.append(f"| {labels.get(c.metric, c.metric)} | {_fmt(c.mean_reference)} | "
                     f"{_fmt(c.mean_condition)} | {_ci(c)} | "
                     f"{' '.join(_fmt(x) for x in c.per_seed)} |")
    lines += ["", "By the safety bound, learned priors can only remove lock decisions, never "
              "add one; what they can change on lifts is which decisions remain. A virtual "
              "cohort is only as good as the simulated population; these are not results "
              "on people.", ""]
    return "\n".join(lines)


def section_from_folder(folder: Path, level: int = 2) -> str:
    """The report section from a study's output folder (its `personalisation.json`);
    what the replication report calls to add the section."""
    path = Path(folder) / "personalisation.json"
    if not path.is_file():
        raise FileNotFoundError(f"no personalisation.json in {folder}; run "
                                "`python -m controller.evaluation.personalisation_report`")
    return section_markdown(json.loads(path.read_text()), level=level)


def readme(study: PersonalisationStudy, doc: dict[str, Any]) -> str:
    """`README.md`: the section plus the list of files and the run time."""
    return (f"# Virtual personalisation study\n\n{section_markdown(doc, level=2)}\n"
            f"Simulated in {study.seconds:.0f} s. Files: `lab_changes.csv/.md`, "
            "`curve.csv/.md`, `curve.png/.svg`, `stairs_day.csv/.md`, `participants.csv`, "
            "`stairs_day_participants.csv`, `personalisation.json`.\n")


def write_outputs(study: PersonalisationStudy, out: Path) -> list[Path]:
    """Every output into `out`; returns the paths written."""
    files = OutputFolder(out)
    lab = lab_changes(study)
    doc = analysis_json(study)
    for stem, table in (
            ("lab_changes", changes_table(lab, "Lab: change against population models")),
            ("curve", changes_table(curve_rows(study, lab),
                                    "Demonstration-count curve: change in correct "
                                    "decisions (% of lifts)")),
            ("stairs_day", changes_table(day_changes(study), "Stairs-heavy day: learned "
                                         "against equal priors (UMC)"))):
        files.put(f"{stem}.csv", table.to_csv())
        files.put(f"{stem}.md", table.to_markdown())
    files.put("participants.csv", participants_table(study).to_csv())
    files.put("stairs_day_participants.csv", day_table(study).to_csv())
    png, svg = curve_figure(study, lab)
    files.put("curve.png", png)
    files.put("curve.svg", svg)
    files.put("personalisation.json", json.dumps(doc, indent=1))
    files.put("README.md", readme(study, doc))
    return files.written



def main(argv: list[str] | None = None) -> int:
    """`python -m controller.evaluation.personalisation_report --out DIR ...`: run the
    study and write its outputs."""
    import argparse
    import os

    from controller.evaluation.personalisation import PersonalisationConfig, simulate_study

    ap = argparse.ArgumentParser(description="virtual personalisation study")
    ap.add_argument("--participants", type=int, default=40)
    ap.add_argument("--seeds", default="1,2,3", help="comma-separated cohort seeds")
    ap.add_argument("--processes", type=int, default=1)
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    try:
        cfg = PersonalisationConfig(participants=args.participants,
                                    seeds=tuple(int(s) for s in args.seeds.split(",")))
    except ValueError as exc:
        ap.error(str(exc))
    load = os.getloadavg()
    study = simulate_study(cfg, processes=args.processes)
    paths = write_outputs(study, Path(args.out))
    print(f"{len(study.outcomes)} participants in {study.seconds:.1f} s "
          f"({args.processes} process(es), load average before "
          f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f}); wrote {len(paths)} files to "
          f"{args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
