"""A virtual cohort's outputs: tables (CSV, Markdown), figures (PNG, SVG), cohort.json.

`analyse` computes the statistics once (`CohortAnalysis`); `write_outputs` writes
everything into a folder; the API serves the same analysis as JSON.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from controller.evaluation import muscle_report
from controller.evaluation.cohort import METRICS, Cohort, MetricSpec, cohort_controllers
from controller.evaluation.cohort_stats import (
    ALPHA,
    POWER_RESAMPLES,
    POWER_SIZES,
    POWER_TARGET,
    Comparison,
    MetricSummary,
    compare,
    summarise,
)
from controller.evaluation.output_folder import OutputFolder, json_ready
from controller.evaluation.rendering import (
    controller_colour,
    new_figure,
    render_figure,
)
from controller.evaluation.study import controller_label
from controller.evaluation.tables import Cell, Table

#: The comparisons the README and the power figure lead with: (metric, a, b).
MAIN_COMPARISONS: tuple[tuple[str, str, str], ...] = (
    ("support_asymmetry_nm", "umc", "pec"),
    ("fp_total", "umc", "eumc"),
    ("fp_total", "umc", "pec"),
    ("correct_pct", "umc", "eumc"),
    ("onset_to_lock_s", "umc", "pec"),
    ("peak_torque_squat_nm", "umc", "pec"),
)
CAVEAT = ("A virtual cohort is only as good as the simulated population: participants "
          "are drawn from the simulator's documented distributions (body size, movement "
          "depth and speed, asymmetry, donning offsets), perform scripted tasks without "
          "fatigue, learning or opinions, and are measured without error. Its power "
          "estimates say how many participants such a population would need, not how "
          "many real people will.")


@dataclass(frozen=True)
class CohortAnalysis:
    """Everything computed from a cohort."""

    summaries: tuple[MetricSummary, ...]
    comparisons: tuple[Comparison, ...]


def _spec(name: str) -> MetricSpec:
    return next(m for m in METRICS if m.name == name)


def analyse(cohort: Cohort, seed: int = 0, resamples: int = POWER_RESAMPLES,
            sizes: tuple[int, ...] = POWER_SIZES) -> CohortAnalysis:
    """Distributions of every metric and paired comparisons of every controller pair
    on every metric both controllers have (deterministic in `seed`)."""
    rng = np.random.default_rng(np.random.SeedSequence([0xC0_40, seed]))
    ctls = cohort.config.controllers
    summaries = []
    for m in METRICS:
        for c in ctls:
            v = cohort.values(c, m.name)
            if np.isfinite(v).any():
                summaries.append(summarise(c, m.name, v, rng))
    comparisons = []
    # Pairs in the order the main comparisons name them, then the rest.
    order = {c: i for i, c in enumerate(cohort_controllers())}
    pairs = [tuple(sorted(p, key=lambda c: order.get(c, 9))) for p in combinations(ctls, 2)]
    for m in METRICS:
        for a, b in pairs:
            xa, xb = cohort.values(a, m.name), cohort.values(b, m.name)
            if (np.isfinite(xa) & np.isfinite(xb)).sum() >= 2:
                comparisons.append(compare(m.name, a, b, xa, xb, rng, sizes, resamples))
    return CohortAnalysis(tuple(summaries), tuple(comparisons))


def _fmt(x: float | None, f: str = ".2f") -> str:
    return "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, f)


def participants_table(cohort: Cohort) -> Table:
    """One row per participant and controller with every metric."""
    rows: list[tuple[Cell, ...]] = []
    for p in cohort.participants:
        for c in cohort.config.controllers:
            rows.append((p.index + 1, p.seed, c,
                         *[p.metrics[c][m.name] for m in METRICS]))
    return Table(("participant", "seed", "controller", *(m.name for m in METRICS)),
                 tuple(rows), title="Metrics per virtual participant")


def summary_table(analysis: CohortAnalysis) -> Table:
    """Each metric per controller: mean with bootstrap 95 % CI, SD, median."""
    rows = [(s.metric, _spec(s.metric).unit, controller_label(s.controller), s.n, s.mean,
             s.ci_low, s.ci_high, s.sd, s.median) for s in analysis.summaries]
    return Table(("metric", "unit", "controller", "n", "mean", "ci95_low", "ci95_high", "sd",
                  "median"), tuple(rows), float_format=".2f",
                 title="Metric distributions (mean, bootstrap 95 % CI)")


def comparisons_table(analysis: CohortAnalysis) -> Table:
    """Each paired comparison: difference with CI, Wilcoxon p, effect size, n for 80 %."""
    rows = []
    for c in analysis.comparisons:
        n80 = c.n_for_power
        rows.append((c.metric, f"{controller_label(c.a)} - {controller_label(c.b)}", c.n,
                     c.nonzero, c.mean_diff, c.ci_low, c.ci_high, c.median_diff, c.statistic,
                     c.p_value, c.rank_biserial,
                     n80 if n80 is not None else f">{max(c.sizes)}"))
    return Table(("metric", "comparison", "n", "nonzero", "mean_diff", "ci95_low",
                  "ci95_high", "median_diff", "wilcoxon_w", "p", "rank_biserial",
                  f"n_for_{round(100 * POWER_TARGET)}pct_power"), tuple(rows),
                 float_format=".3g",
                 title="Paired comparisons (Wilcoxon signed-rank, two-sided)",
                 notes=("Differences are the first controller minus the second, per "
                        "participant. Effect size: matched-pairs rank-biserial "
                        "correlation. Power: probability of p < 0.05 in a study of n "
                        f"participants, from {POWER_RESAMPLES} resampled studies per n.",))


def power_table(analysis: CohortAnalysis) -> Table:
    """Power for every comparison and sample size (long form)."""
    rows = [(c.metric, c.a, c.b, n, p) for c in analysis.comparisons
            for n, p in zip(c.sizes, c.power, strict=True)]
    return Table(("metric", "a", "b", "n", "power"), tuple(rows), float_format=".3f",
                 title="Power by sample size")


def _main(analysis: CohortAnalysis) -> list[Comparison]:
    index = {(c.metric, c.a, c.b): c for c in analysis.comparisons}
    return [index[k] for k in MAIN_COMPARISONS if k in index]


def figures(cohort: Cohort, analysis: CohortAnalysis) -> dict[str, tuple[bytes, bytes]]:
    """`power` and `distributions` as (PNG, SVG) bytes."""
    out: dict[str, tuple[bytes, bytes]] = {}
    fig = new_figure(6.4, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    for c in _main(analysis):
        ax.plot(c.sizes, c.power, marker=".", label=f"{c.metric}: {controller_label(c.a)} "
                f"vs {controller_label(c.b)}")
    ax.axhline(POWER_TARGET, color="0.5", lw=0.8, ls="--")
    ax.set_xlabel("participants (n)")
    ax.set_ylabel(f"power (Wilcoxon, alpha {ALPHA:g})")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"Power by sample size, {len(cohort.participants)} virtual participants")
    ax.legend(fontsize=6.5, loc="lower right")
    fig.subplots_adjust(left=0.1, right=0.98, top=0.92, bottom=0.12)
    r = render_figure(fig)
    out["power"] = (r.png, r.svg)

    shown = [m for m in METRICS if m.name in {"correct_pct", "fp_total", "onset_to_lock_s",
                                                "peak_torque_squat_nm",
                                                "support_asymmetry_nm", "recognised_pct"}]
    fig = new_figure(7.2, 4.6)
    ctls = cohort.config.controllers
    for i, m in enumerate(shown):
        ax = fig.add_subplot(2, 3, i + 1)
        data, labels, colours = [], [], []
        for k, name in enumerate(ctls):
            v = cohort.values(name, m.name)
            v = v[np.isfinite(v)]
            if v.size:
                data.append(v)
                labels.append(controller_label(name))
                colours.append(controller_colour(name, k))
        if data:
            parts = ax.boxplot(data, patch_artist=True, widths=0.6)
            ax.set_xticks(range(1, len(labels) + 1), labels)
            for patch, col in zip(parts["boxes"], colours, strict=True):
                patch.set_facecolor(col)
                patch.set_alpha(0.5)
        ax.set_title(f"{m.name} ({m.unit})", fontsize=7.5)
        ax.tick_params(labelsize=7)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.93, bottom=0.07, hspace=0.4, wspace=0.35)
    r = render_figure(fig)
    out["distributions"] = (r.png, r.svg)
    return out


def analysis_json(cohort: Cohort, analysis: CohortAnalysis) -> dict[str, Any]:
    """`cohort.json`: configuration, population, per-participant metrics, statistics."""
    cfg = cohort.config

    return json_ready({
        "format": "exostudy.cohort", "format_version": 1,
        "config": {**asdict(cfg), "controllers": list(cfg.controllers)},
        "models_version": cohort.models_version,
        "utilities_version": cohort.utilities_version,
        "metrics": [asdict(m) for m in METRICS],
        "participants": [asdict(p) for p in cohort.participants],
        "summaries": [asdict(s) for s in analysis.summaries],
        "comparisons": [{**asdict(c), "n_for_power": c.n_for_power}
                        for c in analysis.comparisons],
        "main_comparisons": [list(k) for k in MAIN_COMPARISONS],
        "alpha": ALPHA, "power_target": POWER_TARGET, "power_resamples": POWER_RESAMPLES,
        "caveat": CAVEAT,
    })


def readme(cohort: Cohort, analysis: CohortAnalysis) -> str:
    """A short Markdown summary: what was simulated, the main comparisons, the caveat."""
    cfg = cohort.config
    lines = ["# Virtual cohort", "",
             f"{len(cohort.participants)} virtual participants (seed {cfg.seed}), "
             f"controllers {', '.join(controller_label(c) for c in cfg.controllers)}, "
             f"script `{cfg.script}` once per controller, "
             + ("the paper's rates" if cfg.rate_hz is None else f"{cfg.rate_hz:g} Hz") + ".",
             "", CAVEAT, "", "## Main comparisons", "",
             "| metric | comparison | mean difference [95 % CI] | p | rank-biserial | "
             "n for 80 % power |", "| --- | --- | --- | --- | --- | --- |"]
    for c in _main(analysis):
        n80 = c.n_for_power
        lines.append(f"| {c.metric} | {controller_label(c.a)} - {controller_label(c.b)} | "
                     f"{_fmt(c.mean_diff)} [{_fmt(c.ci_low)}, {_fmt(c.ci_high)}] | "
                     f"{_fmt(c.p_value, '.2g')} | {_fmt(c.rank_biserial)} | "
                     f"{n80 if n80 is not None else '>' + str(max(c.sizes))} |")
    lines += ["", "Files: `participants.csv` (every metric per participant and controller), "
              "`metrics.csv/.md`, `comparisons.csv/.md`, `power.csv`, `power.png/.svg`, "
              "`distributions.png/.svg`, `cohort.json`.", ""]
    return "\n".join(lines)


def write_outputs(cohort: Cohort, analysis: CohortAnalysis, out: Path) -> list[Path]:
    """Write every output into `out`; returns the paths written."""
    files = OutputFolder(out)
    put = files.put

    put("participants.csv", participants_table(cohort).to_csv())
    for stem, table in (("metrics", summary_table(analysis)),
                        ("comparisons", comparisons_table(analysis))):
        put(f"{stem}.csv", table.to_csv())
        put(f"{stem}.md", table.to_markdown())
    put("power.csv", power_table(analysis).to_csv())
    for stem, (png, svg) in figures(cohort, analysis).items():
        put(f"{stem}.png", png)
        put(f"{stem}.svg", svg)
    put("cohort.json", json.dumps(analysis_json(cohort, analysis), indent=1))
    muscles = muscle_report.write_outputs(cohort, put)  # "" without --emg
    put("README.md", readme(cohort, analysis) + muscles)
    return files.written


def from_json(doc: dict[str, Any]) -> tuple[Cohort, CohortAnalysis]:
    """Inverse of `analysis_json`: the cohort and its analysis from `cohort.json` (the
    console renders tables and figures from the stored document)."""
    from controller.evaluation.cohort import CohortConfig, ParticipantResult
    from controller.evaluation.muscle_activity import ParticipantMuscles

    if doc.get("format") != "exostudy.cohort" or doc.get("format_version") != 1:
        raise ValueError("not an exostudy.cohort document of format_version 1")

    def num(x: Any) -> float:
        return math.nan if x is None else float(x)

    c = doc["config"]
    cfg = CohortConfig(participants=int(c["participants"]), seed=int(c["seed"]),
                       controllers=tuple(c["controllers"]), script=str(c["script"]),
                       rate_hz=None if c["rate_hz"] is None else float(c["rate_hz"]),
                       precompression_pct=float(c["precompression_pct"]),
                       emg=bool(c.get("emg", False)))
    cohort = Cohort(cfg, [ParticipantResult(int(p["index"]), int(p["seed"]), dict(p["body"]),
                                            {k: {m: num(v) for m, v in ms.items()}
                                             for k, ms in p["metrics"].items()},
                                            int(p["calibration_attempts"]),
                                            ParticipantMuscles.from_dict(p["muscles"])
                                            if p.get("muscles") else None)
                          for p in doc["participants"]],
                    str(doc.get("models_version", "")), str(doc.get("utilities_version", "")))
    summaries = tuple(MetricSummary(s["controller"], s["metric"], int(s["n"]),
                                    *(num(s[k]) for k in ("mean", "sd", "median", "ci_low",
                                                          "ci_high")))
                      for s in doc["summaries"])
    comparisons = tuple(Comparison(
        metric=k["metric"], a=k["a"], b=k["b"], n=int(k["n"]), nonzero=int(k["nonzero"]),
        mean_diff=num(k["mean_diff"]), ci_low=num(k["ci_low"]), ci_high=num(k["ci_high"]),
        median_diff=num(k["median_diff"]), statistic=num(k["statistic"]),
        p_value=num(k["p_value"]), rank_biserial=num(k["rank_biserial"]),
        power=tuple(num(p) for p in k["power"]), sizes=tuple(int(n) for n in k["sizes"]))
        for k in doc["comparisons"])
    return cohort, CohortAnalysis(summaries, comparisons)
