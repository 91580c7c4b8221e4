"""Results: the paper's tables and figures of a study, a trial's controller output, the
what-if replay of a trial, and the leave-one-participant-out evaluation of motion models.

Everything here only reads; the computation lives in `backend.analysis.results`,
`backend.analysis.what_if` and `backend.analysis.model_evaluation`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Path, Query
from fastapi.responses import Response

from backend.analysis import model_evaluation as lopo
from backend.analysis import results, what_if
from backend.api.deps import (
    CurrentUser,
    EngineDep,
    ResultsCacheDep,
    RuntimeDep,
    SessionDep,
    SettingsDep,
    SiteDep,
)
from backend.api.errors import (
    AUTH_RESPONSES,
    CONFLICT,
    INVALID,
    NOT_FOUND,
    conflict,
    invalid,
    one_or_404,
)
from backend.api.params import MAX_ID, StudyId
from backend.db.evidence_tables import ModelSetRecord, Trial
from backend.db.models import Study
from backend.schemas.muscle_results import MuscleResultsOut
from backend.schemas.results import ModelEvaluationOut, StudyResultsOut, WhatIfIn, WhatIfOut
from controller.controllers.factory import controller_names

router = APIRouter(tags=["results"], responses={**AUTH_RESPONSES, **NOT_FOUND})

TrialId = Annotated[int, Path(ge=1, le=MAX_ID, description="trial id")]
TableName = Annotated[Literal["performance", "performance_by_kind", "false_positives",
                              "questionnaires", "onset_to_lock", "lifts"],
                      Path(description="which table")]
FigureName = Annotated[Literal["peak_torques", "onset_to_lock"], Path(description="which figure")]
ImageFormat = Annotated[Literal["png", "svg"], Path(description="png or svg")]
_MEDIA = {"png": "image/png", "svg": "image/svg+xml", "csv": "text/csv",
          "md": "text/markdown; charset=utf-8"}


def _study_results(db: SessionDep, runtime: RuntimeDep, engine: EngineDep,
                   cache: ResultsCacheDep, site: SiteDep, study_id: int
                   ) -> results.StudyResults:
    one_or_404(db, Study, study_id, "study")
    runtime.recorder.flush()  # a trial stopped a moment ago has all its ticks stored
    # A member limited to one site sees only that site's participants in the results.
    return cache.get(engine, db, study_id, site)


@router.get("/api/studies/{study_id}/results", response_model=StudyResultsOut)
def study_results(study_id: StudyId, runtime: RuntimeDep, engine: EngineDep,
                  cache: ResultsCacheDep, site: SiteDep, user: CurrentUser,
                  db: SessionDep) -> StudyResultsOut:
    """The paper's tables for the study's completed trials: intent estimation and
    decision performance (UMC/E-UMC), false positives in walking and stair walking,
    questionnaires (unblinded through the condition labels), onset to lock; with the
    ground truth each trial was scored against."""
    return results.results_document(_study_results(db, runtime, engine, cache, site,
                                                   study_id))


@router.get("/api/studies/{study_id}/results/{table}.{fmt}", response_class=Response,
            responses={200: {"content": {"text/csv": {}, "text/markdown": {}},
                             "description": "the table"}})
def study_table(study_id: StudyId, table: TableName,
                fmt: Annotated[Literal["csv", "md"], Path(description="csv or md")],
                runtime: RuntimeDep, engine: EngineDep, cache: ResultsCacheDep,
                site: SiteDep, user: CurrentUser, db: SessionDep) -> Response:
    """One table: CSV in long form (every count), Markdown in the paper's layout."""
    res = _study_results(db, runtime, engine, cache, site, study_id)
    body = res.csv(table) if fmt == "csv" else res.markdown(table)
    return Response(body, media_type=_MEDIA[fmt], headers={
        "Content-Disposition": f'inline; filename="study-{study_id}-{table}.{fmt}"'})


@router.get("/api/studies/{study_id}/figures/{name}.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/svg+xml": {}},
                             "description": "the figure"}})
def study_figure(study_id: StudyId, name: FigureName, fmt: ImageFormat, runtime: RuntimeDep,
                 engine: EngineDep, cache: ResultsCacheDep, site: SiteDep,
                 user: CurrentUser, db: SessionDep) -> Response:
    """Peak exoskeleton torques per lift, or the onset-to-lock histogram."""
    fig = _study_results(db, runtime, engine, cache, site, study_id).figure(name)
    return Response(fig.png if fmt == "png" else fig.svg, media_type=_MEDIA[fmt])


@router.get("/api/trials/{trial_id}/figures/timeline.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/svg+xml": {}},
                             "description": "the five-panel figure"}, **CONFLICT})
def trial_timeline(trial_id: TrialId, fmt: ImageFormat, engine: EngineDep,
                   user: CurrentUser, db: SessionDep) -> Response:
    """The trial's controller output in five panels (hip angles against the trial's
    motion models, actions, posteriors, progress, lock commands)."""
    trial = one_or_404(db, Trial, trial_id, "trial")
    try:
        fig = results.timeline_figure(engine, db, trial)
    except results.ResultsError as exc:
        conflict(exc.field_name, exc.problem)
    return Response(fig.png if fmt == "png" else fig.svg, media_type=_MEDIA[fmt])


@router.post("/api/trials/{trial_id}/what-if", response_model=WhatIfOut,
             responses={**INVALID, **CONFLICT})
def trial_what_if(trial_id: TrialId, body: WhatIfIn, engine: EngineDep, user: CurrentUser,
                  db: SessionDep) -> WhatIfOut:
    """Replay the trial's stored raw hip angles through another controller or settings
    (the live tick code) and return the original's and the replay's metrics side by
    side. The stored trial and its ticks are not changed."""
    trial = one_or_404(db, Trial, trial_id, "trial")
    if body.controller not in controller_names():
        invalid(["body", "controller"], f"unknown controller {body.controller!r}; choose one "
                f"of {', '.join(controller_names())}")
    if trial.run_id is None:
        conflict("status", f"trial {trial.id} has not run")
    try:
        return what_if.what_if(engine, db, trial, body.controller,
                               body.model_set_id, body.utility_set_id, body.rate_hz,
                               body.settings)
    except results.ResultsError as exc:
        # "settings.velocity_threshold" names a place in the body, as a list like every
        # other 422's location (the JSON check at the door reports the same way).
        invalid(["body", *exc.field_name.split(".")], exc.problem)


@router.get("/api/studies/{study_id}/model-evaluation", response_model=ModelEvaluationOut,
            responses=INVALID)
def model_evaluation(
    study_id: StudyId, engine: EngineDep, user: CurrentUser, db: SessionDep,
    model_set_id: Annotated[int, Query(ge=1, le=MAX_ID, description="whose segments")],
    utility_set_id: Annotated[int | None, Query(ge=1, le=MAX_ID)] = None,
    rate_hz: Annotated[float | None, Query(gt=0.0, le=100.0)] = None,
) -> ModelEvaluationOut:
    """Leave-one-participant-out: models fitted without each data-collection
    participant, that participant's segments replayed through the UMC; recognition and
    decision accuracy and confusion matrices."""
    one_or_404(db, Study, study_id, "study")
    ms = one_or_404(db, ModelSetRecord, model_set_id, "model set")
    if ms.study_id != study_id:
        invalid(["query", "model_set_id"], f"model set {ms.id} belongs to another study")
    try:
        return lopo.leave_one_participant_out(engine, db, model_set_id,
                                              utility_set_id, rate_hz)
    except results.ResultsError as exc:
        invalid(["query", exc.field_name], exc.problem)


# Muscle activity (EMG) -----------------------------------------------------------------------
MuscleTable = Annotated[Literal["lifts", "summary", "reductions", "repeated_measures"],
                        Path(description="which muscle-activity table")]
MuscleFigure = Annotated[Literal["muscle_envelopes", "muscle_reduction"],
                         Path(description="which muscle-activity figure")]


def _muscle(db: SessionDep, runtime: RuntimeDep, engine: EngineDep, settings: SettingsDep,
            site: SiteDep, study_id: int) -> Any:
    from backend.emg import muscle_results
    from backend.emg.store import emg_folder

    one_or_404(db, Study, study_id, "study")
    runtime.recorder.flush()
    try:
        return muscle_results.CACHE.get(engine, db, emg_folder(settings), study_id, site)
    except results.ResultsError as exc:
        conflict(exc.field_name, exc.problem)
    except ValueError as exc:  # the processing or statistics refused the data: say why
        conflict("muscle_results", str(exc))


@router.get("/api/studies/{study_id}/muscle-results", responses=CONFLICT,
            response_model=MuscleResultsOut)
def study_muscle_results(study_id: StudyId, runtime: RuntimeDep, engine: EngineDep,
                         settings: SettingsDep, site: SiteDep, user: CurrentUser,
                         db: SessionDep) -> MuscleResultsOut:
    """Muscle activity from the stored EMG: per lift (CSV `lifts`), per controller the
    mean over participants with its 95 % interval, the reduction against each baseline
    and the repeated-measures test, with every processing parameter (`method`) and each
    trial's quality flags."""
    res = _muscle(db, runtime, engine, settings, site, study_id)
    try:
        doc = res.document()
    except ValueError as exc:  # the statistics refused the data: say why, never 500
        conflict("muscle_results", str(exc))
    return MuscleResultsOut.model_validate(doc)


@router.get("/api/studies/{study_id}/muscle-results/{table}.{fmt}", response_class=Response,
            responses={200: {"content": {"text/csv": {}, "text/markdown": {}},
                             "description": "the table"}, **CONFLICT})
def study_muscle_table(study_id: StudyId, table: MuscleTable,
                       fmt: Annotated[Literal["csv", "md"], Path(description="csv or md")],
                       runtime: RuntimeDep, engine: EngineDep, settings: SettingsDep,
                       site: SiteDep, user: CurrentUser, db: SessionDep) -> Response:
    """A muscle-activity table as CSV (the method in `#` lines first); Markdown gives the
    reductions against each baseline whatever the table."""
    res = _muscle(db, runtime, engine, settings, site, study_id)
    try:
        body = res.csv(table) if fmt == "csv" else res.markdown()
    except ValueError as exc:
        conflict("muscle_results", str(exc))
    return Response(body, media_type=_MEDIA[fmt], headers={
        "Content-Disposition": f'inline; filename="study-{study_id}-muscle-{table}.{fmt}"'})


@router.get("/api/studies/{study_id}/muscle-figures/{name}.{fmt}", response_class=Response,
            responses={200: {"content": {"image/png": {}, "image/svg+xml": {}},
                             "description": "the figure"}, **CONFLICT})
def study_muscle_figure(study_id: StudyId, name: MuscleFigure, fmt: ImageFormat,
                        runtime: RuntimeDep, engine: EngineDep, settings: SettingsDep,
                        site: SiteDep, user: CurrentUser, db: SessionDep) -> Response:
    """The envelope over the normalised lift cycle per controller, or the reduction per
    muscle and controller against no exoskeleton (else the first baseline)."""
    try:
        fig = _muscle(db, runtime, engine, settings, site, study_id).figure(name)
    except ValueError as exc:
        conflict("muscle_results", str(exc))
    return Response(fig.png if fmt == "png" else fig.svg, media_type=_MEDIA[fmt])
