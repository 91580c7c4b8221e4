"""The names the browser needs, built from the Python definitions they stand for.

Tick columns, motion models, actions, flag bits, controllers, simulation scripts and
health fields are defined once in Python (`controller.tick_record`, `controller.controllers.spec`,
`backend.schemas.live`, ...). The console's scripts must use the same names, so the
server hands them over as one JavaScript module (`GET /static/vocabulary.js`) and as
JSON (`GET /api/vocabulary`), both built from this model at run time: the browser never
holds a hand-written copy that could fall out of step.

The display labels (what the strip and tables print) are the only words added here;
each is derived from its Python name unless a table below says otherwise.
"""

from __future__ import annotations

import enum
import json
from typing import get_args

from pydantic import BaseModel, Field

from backend.schemas.evidence import SegmentLabel
from backend.schemas.live import STREAM_FIELDS, DatabaseHealth, DeviceHealth, WorkerHealth
from controller.controllers import registry
from controller.evaluation.lifts import CORRECT_ACTION
from controller.evaluation.study import VARIANT_LABELS
from controller.tick_record import (
    CATEGORY_NAMES,
    MODEL_NAMES,
    Action,
    Plausibility,
    TickFlag,
    TickRecord,
)

#: How the state strip names each plausibility failure (short enough for the lab's
#: screen). Every `Plausibility` bit has one; the assertion below keeps it so.
PLAUSIBILITY_LABELS: dict[Plausibility, str] = {
    Plausibility.JUMP: "angle jump",
    Plausibility.VELOCITY: "hip velocity",
    Plausibility.REPEATED: "repeated",
    Plausibility.TIME_BACKWARDS: "time backwards",
    Plausibility.TOO_EARLY: "too early",
    Plausibility.RANGE: "out of range",
    Plausibility.RESYNC: "resync",
    Plausibility.ACCELERATION: "acceleration",
}
assert set(PLAUSIBILITY_LABELS) == {p for p in Plausibility if p}, "a Plausibility bit has no label"



class Named(BaseModel):
    """A name as the API and the database spell it, and as a person reads it."""

    name: str
    label: str


class ModelName(Named):
    """A motion model and the paper's correct first decision in its lift."""

    correct_action: str = Field(description="the `actions` name a lift of it should get")


class ControllerName(Named):
    """A controller the worker can run."""

    needs_models: bool = Field(description="needs a model set and a utility set")
    needs_calibration: bool = Field(
        description="runs only with calibration offsets (standing still first)")
    estimates_intent: bool = Field(
        description="records posteriors: its lifts are judged recognised and correct")
    colour: str | None = Field(description="its colour in figures and pages (#rrggbb); "
                               "null: the page picks one")
    in_plan: bool = Field(description="enters a study's counterbalanced trial plan")
    plan_optional: bool = Field(
        description="planned only when the plan includes the optional controllers")
    idle: bool = Field(description="the resting controller: never locks; the worker "
                       "starts with it and returns to it")
    baseline: bool = Field(
        description="a baseline condition (springs never locked, no exoskeleton): planned "
        "only when a plan asks for baselines, never locks, not compared in the paper's "
        "controller tables; the reference muscle-activity reductions are measured against")
    exoskeleton_worn: bool = Field(
        description="false for the 'no exoskeleton' baseline: its lifts come from the "
        "experimenter's markers, not the device")


class ActionName(Named):
    """One of the paper's actions a1..a4 and the locks it commands."""

    value: int = Field(description="the `action` tick column's value")
    lock_left: bool
    lock_right: bool


class BitName(Named):
    """One bit of a bit-set column (`flags`, `plausibility`)."""

    bit: int


class HealthFields(BaseModel):
    """The field names of each part of `GET /api/health` (and the live status message)."""

    worker: list[str]
    device: list[str]
    database: list[str]


class Vocabulary(BaseModel):
    """`GET /api/vocabulary`: every name the console's scripts use."""

    tick_fields: list[str] = Field(description="every tick column, in stored order")
    stream_fields: list[str] = Field(description="the tick columns the live stream sends")
    models: list[ModelName] = Field(description="the motion models")
    categories: list[Named] = Field(description="the models and the category 'other'")
    segment_labels: list[Named] = Field(description="labels a lift segment may carry")
    actions: list[ActionName]
    tick_flags: list[BitName]
    plausibility: list[BitName]
    controllers: list[ControllerName]
    condition_variants: list[Named] = Field(
        description="how a condition's variant reads after its controller's label: a "
        "condition key is controller+variant (umc+personal)")
    scripts: list[str] = Field(description="the simulated wearer's scripts")
    health: HealthFields


def _spoken(name: str) -> str:
    """`stoop_left` -> `stoop left`, `LOCK_BOTH` -> `lock both`."""
    return name.replace("_", " ").lower()


def _named(names: tuple[str, ...] | list[str]) -> list[Named]:
    return [Named(name=n, label=_spoken(n)) for n in names]


def _bits(flag: type[enum.IntFlag], labels: dict[int, str] | None = None) -> list[BitName]:
    """Every set bit of a flag type, named; labelled from `labels` (by bit) if given."""
    out = []
    for member in flag:
        if not member or member.name is None:
            continue
        label = labels[int(member)] if labels is not None else _spoken(member.name)
        out.append(BitName(name=member.name.lower(), label=label, bit=int(member)))
    return out


def _controller(name: str) -> ControllerName:
    """What a controller declares about itself (`controller.controllers.registry.Registration`)."""
    r = registry.get(name)
    return ControllerName(name=name, label=r.shown, needs_models=r.needs_models,
                          needs_calibration=r.needs_calibration,
                          estimates_intent=r.estimates_intent, colour=r.colour or None,
                          in_plan=r.plan is not None,
                          plan_optional=r.plan is not None and r.plan.optional, idle=r.idle,
                          baseline=r.plan is not None and r.plan.baseline,
                          exoskeleton_worn=r.exoskeleton_worn)


def vocabulary() -> Vocabulary:
    """The vocabulary as the definitions stand now (a controller module may register
    while the server runs, so nothing is cached)."""
    # The script names on first use: `controller.sim.scripts` imports the simulator (SciPy
    # splines built at import), which every server start would otherwise pay for.
    from controller.sim.scripts import SCRIPT_NAMES

    correct: dict[str, Action] = {str(k): a for k, a in CORRECT_ACTION.items()}
    return Vocabulary(
        tick_fields=list(TickRecord.field_names()),
        stream_fields=list(STREAM_FIELDS),
        models=[ModelName(name=m, label=_spoken(m), correct_action=correct[m].name.lower())
                for m in MODEL_NAMES],
        categories=_named(CATEGORY_NAMES),
        segment_labels=_named(list(get_args(SegmentLabel))),
        actions=[ActionName(name=a.name.lower(), label=_spoken(a.name), value=int(a),
                            lock_left=a.locks[0], lock_right=a.locks[1]) for a in Action],
        tick_flags=_bits(TickFlag),
        plausibility=_bits(Plausibility, {int(p): t for p, t in PLAUSIBILITY_LABELS.items()}),
        # The planned controllers in plan rank order, then the others, the idle one last.
        controllers=[_controller(n) for n in registry.display_order()],
        condition_variants=[Named(name=k, label=v) for k, v in VARIANT_LABELS.items()],
        scripts=list(SCRIPT_NAMES),
        health=HealthFields(worker=list(WorkerHealth.model_fields),
                            device=list(DeviceHealth.model_fields),
                            database=list(DatabaseHealth.model_fields)),
    )


def javascript_module() -> str:
    """The vocabulary as an ES module: one frozen object, the default export."""
    data = json.dumps(vocabulary().model_dump(), separators=(",", ":"))
    return (
        "// ExoStudy's vocabulary, generated by the server from its Python definitions\n"
        "// (backend/schemas/vocabulary.py) when asked: do not copy these names.\n"
        f"const VOCABULARY = {data};\n"
        "const freeze = (o) => { Object.values(o).forEach((v) => { "
        "if (v && typeof v === \"object\") freeze(v); }); return Object.freeze(o); };\n"
        "export default freeze(VOCABULARY);\n"
    )
