"""Results over the API on a trial with known ticks: the paper's tables, CSV and Markdown,
figures, the timeline, and the what-if replay, which must leave the stored trial alone.

The ticks are written straight into a migrated database with the tick recorder (as
the worker's would be), so every expected count follows from the data below:

- a squat (ticks 200-399) recognised at tick 220 and decided correctly (lock both) at
  tick 250;
- a stoop left (500-699) never recognised and decided wrongly (lock both) at 550;
- a 6.4 s walk (750-1389) with one lock signal at 900: one false positive.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select

from backend.analysis import results, tick_queries
from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import ModelSetRecord, Trial, UtilitySetRecord
from backend.db.models import (
    ConditionLabel,
    QuestionnaireInstrument,
    QuestionnaireResponse,
    StudySession,
)
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted, TickBatch
from controller.config import ControllerConfig
from controller.evaluation.columns import TickData
from controller.tick_record import Action, TickRecord

N = 1400


def _bump(k: int, start: int, end: int, peak: float) -> float:
    if not start <= k <= end:
        return 0.0
    return peak * math.sin(math.pi * (k - start) / (end - start)) ** 2


def _ticks() -> list[TickRecord]:
    out = []
    for k in range(N):
        ql = 0.05 + _bump(k, 200, 399, 1.6) + _bump(k, 500, 699, 1.2)
        qr = 0.05 + _bump(k, 200, 399, 1.6) + _bump(k, 500, 699, 0.8)
        if 750 <= k <= 1389:
            ql += 0.3 * math.sin(2 * math.pi * k / 110)
            qr -= 0.3 * math.sin(2 * math.pi * k / 110)
        if 200 <= k <= 399:
            act, lift = "squat", 0
        elif 500 <= k <= 699:
            act, lift = "stoop_left", 1
        elif 750 <= k <= 1389:
            act, lift = "walk", -1
        else:
            act, lift = "stand", -1
        ran = k % 10 == 0
        action = Action.NO_LOCK
        if ran and k in (250, 550, 900):
            action = Action.LOCK_BOTH
        held = any(a <= k < a + 30 for a in (250, 550, 900))
        out.append(TickRecord(
            seq=k, t=k / 100, q_raw_left=ql, q_raw_right=qr, q_left=ql, q_right=qr,
            controller_ran=ran, action=int(action),
            post_squat=0.8 if 220 <= k <= 300 else 0.1,
            post_stoop_left=0.2, post_stoop_right=0.1, post_other=0.1,
            lock_left=held, lock_right=held, torque_left=5.0 if held else 0.0,
            torque_right=4.0 if held else 0.0, truth_activity=act, truth_lift=lift))
    return out


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _setup(client: TestClient, settings: Settings) -> dict[str, int]:
    """A study with one participant, a completed UMC trial with the ticks above, a
    PEC trial without truth columns, and the default model and utility sets."""
    study = _ok(client.post("/api/studies", json={"name": "Results"}), 201)
    part = _ok(client.post(f"/api/studies/{study['id']}/participants",
                           json={"code": "P01"}), 201)
    sess = _ok(client.post(f"/api/participants/{part['id']}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}), 201)
    engine = make_engine(settings.database_url)
    rec = TickRecorder(engine)
    run_umc = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    rec.add(TickBatch.from_records(1, tuple(_ticks())))
    assert rec.flush() == N
    run_pec = rec.run_started(RunStarted(2, "pec", {}, "sim", 1), "sim")
    rec.add(TickBatch.from_records(2, (TickRecord(seq=k, t=k / 100) for k in range(300))))
    assert rec.flush() == 300
    models = json.loads(Path(settings.models_path).read_text())
    util_file = next(Path(settings.utilities_dir).glob("*.json"))
    utilities = json.loads(util_file.read_text())
    with make_session_factory(engine)() as db:
        ms = ModelSetRecord(study_id=study["id"], name="defaults", status="ready",
                            document=models)
        us = UtilitySetRecord(study_id=study["id"], name="defaults", precompression_pct=25,
                              human_source="sim", status="ready", document=utilities)
        db.add_all([ms, us])
        db.flush()
        settings_json = ControllerConfig().to_json()
        umc = Trial(session_id=sess["id"], controller="umc", task="paper-evaluation",
                    planned_order=0, status="completed", run_id=run_umc,
                    model_set_id=ms.id, utility_set_id=us.id,
                    config_snapshot={"controller": "umc", "settings": settings_json})
        pec = Trial(session_id=sess["id"], controller="pec", task="squat-sequence",
                    planned_order=1, status="completed", run_id=run_pec,
                    config_snapshot={"controller": "pec", "settings": settings_json})
        db.add_all([umc, pec])
        db.commit()
        ids = {"study": study["id"], "umc": umc.id, "pec": pec.id, "ms": ms.id, "us": us.id}
    engine.dispose()
    return ids


def test_results_tables_count_the_known_lifts(client: TestClient, settings: Settings) -> None:
    ids = _setup(client, settings)
    doc = _ok(client.get(f"/api/studies/{ids['study']}/results"))
    by_trial = {t["trial_id"]: t for t in doc["trials"]}
    assert by_trial[ids["umc"]]["truth"] == "simulation"
    assert by_trial[ids["umc"]]["lifts"] == 2 and by_trial[ids["umc"]]["gait_trials"] == 1
    assert by_trial[ids["pec"]]["truth"] == "none"
    assert "lifts unknown" in by_trial[ids["pec"]]["truth_note"]
    assert any(str(ids["pec"]) in n for n in doc["notes"])

    perf = doc["tables"]["performance"]
    rows = {(r[0], r[1]): r[2] for r in perf["rows"]}
    assert perf["header"] == ["Metric", "Motion", "P01"]
    assert rows[("Intent estimation", "SQ")] == "1"
    assert rows[("Intent estimation", "AS")] == "0"
    assert rows[("Decision correct", "SQ")] == "1"
    assert rows[("Decision wrong", "AS")] == "1"

    fp = {(r[0], r[1]): r[2] for r in doc["tables"]["false_positives"]["rows"]}
    assert fp[("UMC", "W")] == "1"

    text = client.get(f"/api/studies/{ids['study']}/results/performance.csv").text
    long = list(csv.DictReader(io.StringIO(text)))
    sq = next(r for r in long if r["motion"] == "SQ")
    assert (sq["controller"], sq["lifts"], sq["recognised"], sq["correct"]) == (
        "umc", "1", "1", "1")
    md = client.get(f"/api/studies/{ids['study']}/results/false_positives.md")
    assert md.status_code == 200 and "| UMC | W | 1 |" in md.text
    lifts = list(csv.DictReader(io.StringIO(
        client.get(f"/api/studies/{ids['study']}/results/lifts.csv").text)))
    assert [(r["kind"], r["decision"], r["first_action"]) for r in lifts] == [
        ("squat", "correct", "lock_both"), ("stoop_left", "wrong", "lock_both")]
    assert float(lifts[0]["peak_torque_left_nm"]) == 5.0
    bad = client.get(f"/api/studies/{ids['study']}/results/nonsense.csv")
    assert bad.status_code == 422
    # The tables name participants by their code: a new code is in the next answer (the
    # server's cache of the evaluation is keyed on what it shows).
    pid = _ok(client.get(f"/api/studies/{ids['study']}/participants"))[0]["id"]
    _ok(client.patch(f"/api/participants/{pid}", json={"code": "P99"}))
    again = _ok(client.get(f"/api/studies/{ids['study']}/results"))
    assert again["tables"]["performance"]["header"] == ["Metric", "Motion", "P99"]


def test_a_controllers_conditions_are_tables_of_their_own(
        client: TestClient, settings: Settings) -> None:
    """A plan that runs the UMC on its population models and on the participant's own
    ("umc+personal") is compared condition against condition: the same lifts, decided
    correctly in one and never in the other, are two columns of every table, not one
    pooled column; and the personal condition's questionnaire scores are in the table."""
    ids = _setup(client, settings)
    engine = make_engine(settings.database_url)
    rec = TickRecorder(engine)
    run = rec.run_started(RunStarted(3, "umc", {}, "sim", 1), "sim")
    never = [replace(r, action=int(Action.NO_LOCK), lock_left=False, lock_right=False,
                     torque_left=0.0, torque_right=0.0) for r in _ticks()]
    rec.add(TickBatch.from_records(3, tuple(never)))
    assert rec.flush() == N
    with make_session_factory(engine)() as db:
        first = db.get(Trial, ids["umc"])
        assert first is not None
        sess = db.get(StudySession, first.session_id)
        assert sess is not None
        # Planned first: the tables' order is not the order the trials ran in.
        personal = Trial(session_id=first.session_id, controller="umc",
                         task="paper-evaluation", planned_order=-1, status="completed",
                         run_id=run, model_set_id=ids["ms"], utility_set_id=ids["us"],
                         condition="umc+personal", models="personal",
                         config_snapshot=first.config_snapshot)
        db.add(personal)
        sus = db.scalars(select(QuestionnaireInstrument).where(
            QuestionnaireInstrument.key == "sus")).first()
        assert sus is not None
        for label, key, score in (("A", "umc", 80.0), ("B", "umc+personal", 62.5),
                                  ("C", "springs_free", 40.0)):
            db.add(ConditionLabel(participant_id=sess.participant_id, label=label,
                                  controller=key))
            db.add(QuestionnaireResponse(
                participant_id=sess.participant_id, instrument_id=sus.id,
                instrument_key="sus", instrument_version=sus.version,
                condition_label=label, answers={}, score=score, subscale_scores={}))
        db.commit()
        personal_id = personal.id
    engine.dispose()

    doc = _ok(client.get(f"/api/studies/{ids['study']}/results"))
    conds = {t["trial_id"]: (t["controller"], t["condition"]) for t in doc["trials"]}
    assert conds[ids["umc"]] == ("umc", "umc")
    assert conds[personal_id] == ("umc", "umc+personal")
    perf = doc["tables"]["performance"]
    assert perf["title"].endswith("(UMC/UMC (personal models)/E-UMC)")
    rows = {(r[0], r[1]): r[2] for r in perf["rows"]}
    assert rows[("Intent estimation", "SQ")] == "1/1"  # the same posteriors
    assert rows[("Decision correct", "SQ")] == "1/0"
    assert rows[("Decision missed", "SQ")] == "0/1"
    assert rows[("Decision wrong", "AS")] == "1/0"
    assert rows[("Decision missed", "AS")] == "0/1"
    fp = {(r[0], r[1]): r[2] for r in doc["tables"]["false_positives"]["rows"]}
    assert fp[("UMC", "W")] == "1" and fp[("UMC (personal models)", "W")] == "0"
    long = list(csv.DictReader(io.StringIO(
        client.get(f"/api/studies/{ids['study']}/results/performance.csv").text)))
    sq = {r["controller"]: (r["correct"], r["missed"]) for r in long if r["motion"] == "SQ"}
    assert sq == {"umc": ("1", "0"), "umc+personal": ("0", "1")}
    q = {(r[0], r[1]): r[2] for r in doc["tables"]["questionnaires"]["rows"]}
    # The higher of a participant's scores is marked; a baseline's answer has its row too.
    assert (q[("SUS", "UMC")], q[("SUS", "UMC (personal models)")],
            q[("SUS", "springs free")]) == ("**80**", "62.5", "40")
    onset = [r[0] for r in doc["tables"]["onset_to_lock"]["rows"]]
    assert onset[0] == "UMC" and onset[-1] == "UMC (personal models)"


def test_figures_are_png_and_svg(client: TestClient, settings: Settings) -> None:
    ids = _setup(client, settings)
    png = client.get(f"/api/studies/{ids['study']}/figures/peak_torques.png")
    assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"
    svg = client.get(f"/api/studies/{ids['study']}/figures/onset_to_lock.svg")
    assert svg.status_code == 200 and b"<svg" in svg.content[:2000]
    tl = client.get(f"/api/trials/{ids['umc']}/figures/timeline.png")
    assert tl.status_code == 200 and tl.headers["content-type"] == "image/png"
    assert len(tl.content) > 10_000
    assert client.get("/api/trials/999999/figures/timeline.svg").status_code == 404


def test_a_trial_is_evaluated_and_drawn_from_one_read_with_the_same_results(
        client: TestClient, settings: Settings, monkeypatch: pytest.MonkeyPatch) -> None:
    """The evaluation and the timeline read the fields they use in one query each, and
    give what they give from every column read at once."""
    ids = _setup(client, settings)
    engine = make_engine(settings.database_url)
    queries: list[tuple[str, ...]] = []
    real = tick_queries.columns

    def counted(*args: Any, **kwargs: Any) -> dict[str, np.ndarray]:
        queries.append(tuple(kwargs.get("fields") or ("every field",)))
        return real(*args, **kwargs)

    def every_column(eng: Any, trial: Trial, fields: Any = ()) -> TickData:
        return TickData(real(eng, trial.run_id) if trial.run_id is not None else {})

    monkeypatch.setattr(tick_queries, "columns", counted)
    with make_session_factory(engine)() as db:
        umc = db.get(Trial, ids["umc"])
        assert umc is not None
        res = results.study_results(engine, db, ids["study"])
        timeline = results.timeline_figure(engine, db, umc).svg
        # Both trials (UMC with posteriors, PEC without truth), then the timeline: not
        # one field read on its own.
        assert queries == [results.EVALUATION_FIELDS] * 2 + [results.TIMELINE_FIELDS]
        monkeypatch.setattr(results, "trial_columns", every_column)
        ref = results.study_results(engine, db, ids["study"])
        assert results.timeline_figure(engine, db, umc).svg == timeline
    for name in results.TABLE_NAMES:
        assert res.csv(name) == ref.csv(name), name
    assert results.results_document(res) == results.results_document(ref)
    engine.dispose()


def test_what_if_returns_both_and_leaves_the_trial_alone(client: TestClient,
                                                         settings: Settings) -> None:
    ids = _setup(client, settings)
    before_trial = _ok(client.get(f"/api/trials/{ids['umc']}"))
    before_ticks = client.get(f"/api/trials/{ids['umc']}/ticks.json").content
    before_results = _ok(client.get(f"/api/studies/{ids['study']}/results"))

    r = _ok(client.post(f"/api/trials/{ids['umc']}/what-if",
                        json={"controller": "pec", "settings": {"velocity_threshold": 0.5}}))
    assert r["original"]["controller"] == "umc" and r["replay"]["controller"] == "pec"
    assert (r["original"]["lifts"], r["original"]["recognised"],
            r["original"]["decision_correct"], r["original"]["decision_wrong"],
            r["original"]["false_positive_signals"]) == (2, 1, 1, 1, 1)
    assert r["replay"]["recognised"] is None  # the PEC estimates no intent
    assert r["replay"]["ticks"] == N
    assert r["replay"]["lock_ticks"] > 0  # both lifts flex both hips fast: it locks
    assert r["replay_config"]["settings"]["velocity_threshold"] == 0.5

    umc = _ok(client.post(f"/api/trials/{ids['umc']}/what-if",
                          json={"controller": "umc", "rate_hz": 100}))
    assert umc["replay_config"]["settings"]["umc_rate_hz"] == 100
    assert umc["replay_config"]["model_set_id"] == ids["ms"]
    assert umc["replay"]["lifts"] == 2 and umc["replay"]["recognised"] is not None

    bad = client.post(f"/api/trials/{ids['umc']}/what-if",
                      json={"controller": "umc", "settings": {"no_such": 1}})
    assert bad.status_code == 422 and "no_such" in bad.text
    assert client.post(f"/api/trials/{ids['umc']}/what-if",
                       json={"controller": "nope"}).status_code == 422

    assert _ok(client.get(f"/api/trials/{ids['umc']}")) == before_trial
    assert client.get(f"/api/trials/{ids['umc']}/ticks.json").content == before_ticks
    assert _ok(client.get(f"/api/studies/{ids['study']}/results")) == before_results
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        assert len(list(db.scalars(select(Trial)))) == 2
    engine.dispose()
