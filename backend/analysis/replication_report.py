"""Writing a replication: `report.html` (rendered from the tables by the Jinja2 template
`templates/replication_report.html.j2`, figures embedded as data URIs, no network access
needed), `figures/*.png|svg`, `replication.json` (every number) and `replication.md`
(the claim table, then the personalisation section). Folders 0700, files 0600.

Sections that their modules give as Markdown (muscle activity, personalisation) reach
the HTML as blocks (`markdown_blocks`: headings, paragraphs, `Table`s) that the
template renders like every other table, never as HTML built from strings.
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from jinja2 import Environment, PackageLoader, StrictUndefined

from backend.analysis.replication_config import Replication
from controller.evaluation.columns import TickData
from controller.evaluation.output_folder import json_ready
from controller.evaluation.paper_claims import (
    PAPER_FALSE_POSITIVES,
    PAPER_PERFORMANCE,
    RULE_TEXT,
    ClaimResult,
    difference_dict,
    verdict_counts,
)
from controller.evaluation.paper_protocol import PAPER_EXTRA
from controller.evaluation.personalisation_report import SECTION_TITLE, section_markdown
from controller.evaluation.rendering import render_figure
from controller.evaluation.study import RecordingEvaluation
from controller.evaluation.tables import Table
from controller.evaluation.timeline import controller_output_figure
from controller.evaluation.verdicts import t_interval
from controller.intent.motion_model import ModelSet
from controller.private_files import make_private_dir, private_folder, write_private

TEMPLATE = "replication_report.html.j2"
#: The report's figure captions, by figure name (others are captioned by their name).
CAPTIONS = {
    "peak_torques": "Peak left and right exoskeleton torque per lift (first seed), PEC, "
                    "UMC, E-UMC (paper figure \"peak torques\").",
    "controller_output": "Controller output, E-UMC, first five asymmetric stoops "
                         "(paper's five-panel figure).",
    "motion_models": "Motion models with 95 % regions (first seed).",
    "utilities": "Utility of each action minus no lock, per lifting motion.",
    "actuator": "Actuator torque against deflection at several precompressions.",
    "chi_square": "Chi-square density, 6 degrees of freedom, D = 7.5.",
    "offsets_both": "UMC minus E-UMC correct decisions against the mean donning offset.",
    "offsets_difference": "The same against the difference of the two hips' offsets.",
    "stairs": "Simulated hip flexion over the stair cycle against the published range.",
    "personalisation_curve": "Personalisation: change in correct decisions against "
                             "demonstrations per motion, MAP-adapted and participant-only "
                             "models, with 95 % intervals.",
}
_PARTICIPANTS = "12345678"


def timeline_figure(trials: Sequence[tuple[TickData, RecordingEvaluation]],
                    models: ModelSet | None) -> tuple[bytes, bytes] | None:
    """The paper's five-panel figure: the first five asymmetric stoops of participant 3
    with the E-UMC (or the first E-UMC participant if there is no third)."""
    eumc = [(c, e) for c, e in trials if e.controller == PAPER_EXTRA]
    if not eumc:
        return None
    cols, ev = next(((c, e) for c, e in eumc if e.participant.endswith("03")), eumc[-1])
    stoops = [o.lift for o in ev.lifts if o.lift.kind != "squat"][:5]
    if not stoops:
        return None
    a, b = max(stoops[0].start - 100, 0), min(stoops[-1].end + 100, len(cols))
    fig = controller_output_figure(cols, a, b, models, [o.lift for o in ev.lifts],
                                   title=f"E-UMC, participant {ev.participant}: first five "
                                   "asymmetric stoops")
    r = render_figure(fig)
    return r.png, r.svg


def _paper_value(c: ClaimResult) -> str:
    paper = "" if not math.isfinite(c.claim.paper) else f"{c.claim.paper:.4g}"
    if c.claim.kind == "ordinal":
        sign = ">" if c.claim.direction > 0 else "<"
        paper = f"{sign} {c.claim.threshold:g}" + (f" (paper {paper})" if paper else "")
    return paper


def claims_markdown(rep: Replication) -> str:
    """The per-claim table as Markdown."""
    lines = ["| claim | source | paper | virtual mean [95 % CI] | verdict | why |",
             "| --- | --- | --- | --- | --- | --- |"]
    for c in rep.claims:
        lines.append(f"| {c.claim.key} | {c.claim.source} | {_paper_value(c)} | "
                     f"{c.interval.text('.3g')} {c.claim.unit} | {c.verdict_text()} | "
                     f"{c.reason} |")
    return "\n".join(lines) + "\n"


def paper_tables() -> list[Table]:
    """The paper's two count tables, transcribed (`controller.evaluation.paper_claims`)."""
    perf = Table(("controller", "metric", "motion", *_PARTICIPANTS),
                 tuple((ctl.upper(), metric, g, *(row.get(p, "/") for p in _PARTICIPANTS))
                       for (ctl, metric, g), row in PAPER_PERFORMANCE.items()),
                 title="Intent estimation and Decision Performance for (E-)UMC (paper, "
                       "transcribed; PEC rows from its text)")
    fp = Table(("controller", "trial", *_PARTICIPANTS),
               tuple((ctl.upper(), g, *(row.get(p, "/") for p in _PARTICIPANTS))
                     for (ctl, g), row in PAPER_FALSE_POSITIVES.items()),
               title="Number of false positive lock signals (paper, transcribed)")
    return [perf, fp]


@dataclass(frozen=True)
class Block:
    """One piece of a Markdown section: a heading (`level`), a paragraph or a table."""

    kind: Literal["heading", "paragraph", "table"]
    text: str = ""
    level: int = 0
    table: Table | None = None


def _row(line: str) -> tuple[str, ...]:
    return tuple(c.strip() for c in line.strip().strip("|").split("|"))


def markdown_blocks(md: str) -> list[Block]:
    """The headings, paragraphs and pipe tables of a Markdown section, in order (the
    subset our section writers produce; a table's second line is its `---` rule)."""
    blocks: list[Block] = []
    para: list[str] = []
    table: list[str] = []

    def flush() -> None:
        if para:
            blocks.append(Block("paragraph", " ".join(para)))
            para.clear()
        if table:
            body = [_row(x) for x in table if not set(x) <= set("|-: ")]
            blocks.append(Block("table", table=Table(body[0], tuple(body[1:]))))
            table.clear()

    for raw in md.splitlines():
        line = raw.strip()
        if not line:
            flush()
        elif line.startswith("|"):
            if para:
                flush()
            table.append(line)
        elif line.startswith("#"):
            flush()
            hashes = len(line) - len(line.lstrip("#"))
            blocks.append(Block("heading", line[hashes:].strip(), level=hashes))
        else:
            if table:
                flush()
            para.append(line)
    flush()
    return blocks


def personalisation_markdown(rep: Replication) -> str:
    """The personalisation section (level-2 heading) with its curve, or "" if the run
    left it out."""
    if not rep.personalisation:
        return ""
    return (section_markdown(rep.personalisation, level=2)
            + f"\n![{CAPTIONS['personalisation_curve']}](figures/personalisation_curve.png)\n")


def _mean_sd(k: dict[str, Any], name: str) -> str:
    v = k.get(name)
    return "" if v is None else f"{v['mean']:.1f} ± {v['sd']:.1f}"


def stairs_table(stairs: dict[str, Any]) -> Table:
    """The simulated stair kinematics beside the published ranges."""
    rows = []
    for kind in ("stairs_up", "stairs_down"):
        k = stairs.get(kind)
        if not k:
            continue
        pub = k["published"]
        rows.append((kind, *(_mean_sd(k, n) for n in ("rom_l", "rom_r", "rom_diff", "peak_l",
                                                       "cadence")),
                     f"{pub['hip_rom_deg'][0]:g}-{pub['hip_rom_deg'][1]:g}",
                     f"{pub['cadence_spm'][0]:g}-{pub['cadence_spm'][1]:g}", pub["source"]))
    return Table(("", "hip ROM left (deg)", "hip ROM right", "|L-R| ROM",
                  "peak flexion above standing", "cadence (steps/min)", "published ROM",
                  "published cadence", "source"), tuple(rows))


def _cell(v: Any, float_format: str) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return format(v, float_format)
    return str(v)


def _how(rep: Replication) -> str:
    cfg = rep.config
    if cfg.from_db:
        return f"{len(rep.seeds)} existing study databases"
    return (f"{len(rep.seeds)} seeds ({cfg.first_seed}..{cfg.first_seed + cfg.seeds - 1}), "
            f"engine '{cfg.engine}', {cfg.participants} participants per seed "
            f"({cfg.eumc} also with the E-UMC), {cfg.data_participants} data-collection "
            "participants per seed")


def _environment() -> Environment:
    env = Environment(loader=PackageLoader("backend.analysis", "templates"),
                      autoescape=True, undefined=StrictUndefined, trim_blocks=True,
                      lstrip_blocks=True)
    env.filters["cell"] = _cell
    return env


def report_html(rep: Replication) -> str:
    """The self-contained HTML report."""
    personal = markdown_blocks(section_markdown(rep.personalisation, level=2)
                               if rep.personalisation else "")
    claims = [{"key": c.claim.key, "statement": c.claim.statement, "source": c.claim.source,
               "paper": _paper_value(c), "virtual": f"{c.interval.text('.3g')} {c.claim.unit}",
               "seeds": ", ".join("n/a" if not math.isfinite(v) else f"{v:.3g}"
                                  for v in c.seeds),
               "verdict": c.verdict_text(), "reason": c.reason,
               "css": c.verdict.value.replace(" ", "-") + (" unstable" if c.unstable else "")}
              for c in rep.claims]
    favoured = [(c, t_interval([s.measures.get(f"umc.stair_favoured.{c}", math.nan)
                                for s in rep.seeds]).text(".2f"))
                for c in ("squat", "stoop_left", "stoop_right", "other")]
    figures = [{"name": name, "caption": CAPTIONS.get(name, name),
                "data": base64.b64encode(png).decode("ascii")}
               for name, (png, _svg) in rep.figures.items()
               if name != "personalisation_curve"]
    curve = rep.figures.get("personalisation_curve")
    curve_figure = None if curve is None else {
        "name": "personalisation_curve", "caption": CAPTIONS["personalisation_curve"],
        "data": base64.b64encode(curve[0]).decode("ascii")}
    return _environment().get_template(TEMPLATE).render(
        how=_how(rep), wall_s=rep.wall_s, phases=rep.phases,
        verdicts=verdict_counts(rep.claims), rule=RULE_TEXT, claims=claims,
        paper_tables=paper_tables(),
        first_tables={k.replace("_", " "): t for k, t in rep.first_tables.items()},
        sections={k.replace("_", " "): markdown_blocks(md)
                  for k, md in rep.sections.items() if md},
        personalisation=personal, personalisation_title=SECTION_TITLE,
        offsets=rep.offsets, stairs=stairs_table(rep.stairs) if rep.stairs else None,
        stair_participants=rep.stairs.get("participants"), favoured=favoured,
        figures=figures, curve=curve_figure, notes=rep.notes)


def _claim_json(c: ClaimResult) -> dict[str, Any]:
    iv = c.interval
    return {"key": c.claim.key, "source": c.claim.source, "statement": c.claim.statement,
            "kind": c.claim.kind, "paper": json_ready(c.claim.paper), "unit": c.claim.unit,
            "interval": json_ready({"n": iv.n, "mean": iv.mean, "low": iv.low,
                                   "high": iv.high, "sd": iv.sd}),
            "seeds": json_ready(list(c.seeds)), "verdict": c.verdict.value,
            "reason": c.reason, "paper_values": list(c.claim.paper_values),
            "margin": json_ready(c.claim.margin),
            "difference": json_ready(difference_dict(c.difference)),
            "halves": None if c.halves is None else [v.value for v in c.halves],
            "unstable": c.unstable}


def write(rep: Replication) -> list[Path]:
    """Write the report, the figures, the JSON and the Markdown claim table: folders
    0700 and files 0600 whatever the umask (the report sits in the private run folder,
    and a copy of it must not be the one thing others can read)."""
    out = rep.config.out
    make_private_dir(out)
    figs = private_folder(out / "figures")
    paths = []
    for name, (png, svg) in rep.figures.items():
        for ext, data in (("png", png), ("svg", svg)):
            p = figs / f"{name}.{ext}"
            write_private(p, data)
            paths.append(p)
    doc = {"config": {k: json_ready(v) for k, v in rep.config.__dict__.items()},
           "wall_s": rep.wall_s, "phases": rep.phases,
           "seeds": [{"label": s.label, "source": s.source, "wall_s": s.wall_s,
                      "measures": json_ready(s.measures)} for s in rep.seeds],
           "claims": [_claim_json(c) for c in rep.claims],
           "checks": json_ready(rep.checks),
           "offsets": json_ready({k: v for k, v in rep.offsets.items()
                                 if k not in ("offset_deg", "gain")}),
           "stairs": json_ready(rep.stairs), "personalisation": rep.personalisation or None,
           "notes": rep.notes}
    for name, body in (("replication.json", json.dumps(doc, indent=1)),
                       ("replication.md", "\n".join(
                           x for x in (claims_markdown(rep), personalisation_markdown(rep))
                           if x)),
                       ("report.html", report_html(rep))):
        p = out / name
        write_private(p, body)
        paths.append(p)
    return paths
