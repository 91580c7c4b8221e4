"""Personal model sets, prior sets and their conditions through the API: a plan with a
demonstration block and personal/prior conditions (counterbalanced, blinded), the
personal set fitted from the block as a job with its provenance, priors learned from
confirmed motions inside the safety bound, and priors from outside refused."""

from __future__ import annotations

import json
import threading
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from fastapi.testclient import TestClient
from sqlalchemy import delete, event, update
from sqlalchemy.orm import Session

from backend.core.config import Settings
from backend.db.engine import make_engine, make_session_factory
from backend.db.evidence_tables import ModelSetRecord, Trial, TrialSegment, UtilitySetRecord
from backend.db.personalisation import PriorSetRecord
from backend.live.recorder import TickRecorder
from backend.worker.messages import RunStarted, TickBatch
from controller.evaluation.cohort import trial_recording
from controller.intent.prior_safety import PriorBounds
from controller.intent.segmentation import segment_lifts
from controller.sim.participant import VirtualParticipant
from controller.tick_record import TickRecord
from tests.polling import wait_for

TASKS = ["squat-sequence", "walking"]
STOOP_LEFT_SKEW = [0.05, 0.8, 0.05, 0.1]  # every lift "stoop left": outside the bound


def _ok(r: Any, code: int = 200) -> Any:
    assert r.status_code == code, r.text
    return r.json()


def _setup(client: TestClient, settings: Settings, n: int = 1,
           name: str = "Personal") -> dict[str, Any]:
    study = _ok(client.post("/api/studies", json={"name": name}), 201)
    parts, sessions = [], []
    for i in range(n):
        p = _ok(client.post(f"/api/studies/{study['id']}/participants",
                            json={"code": f"P{i + 1:02d}"}), 201)
        s = _ok(client.post(f"/api/participants/{p['id']}/sessions",
                            json={"kind": "evaluation", "precompression_pct": 25}), 201)
        parts.append(p["id"])
        sessions.append(s["id"])
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        ms = ModelSetRecord(study_id=study["id"], name="population", status="ready",
                            document=json.loads(Path(settings.models_path).read_text()))
        doc = json.loads(next(Path(settings.utilities_dir).glob("*.json")).read_text())
        us = UtilitySetRecord(study_id=study["id"], name="defaults", precompression_pct=25,
                              human_source="sim", status="ready", document=doc)
        db.add_all([ms, us])
        db.commit()
        ids = {"study": study["id"], "participants": parts, "sessions": sessions,
               "ms": ms.id, "us": us.id, "table": np.asarray(doc["utilities_nm2"])}
    engine.dispose()
    return ids


def _record_block(settings: Settings, trial_id: int) -> dict[str, int]:
    """The demonstration block as it would be after the lab ran it: simulated squats
    and stoops stored as the trial's ticks, the lifts marked and labelled."""
    p = VirtualParticipant.from_seed(7)
    recs = [trial_recording(p, 7, s, 100) for s in ("squat-sequence", "stoop-sequence")]
    q = np.concatenate([r.q for r in recs])
    t = np.arange(len(q)) / 100.0
    segs: list[tuple[int, int, int, str]] = []
    offset = 0
    for r in recs:
        assert r.activity is not None
        segs += [(offset + s.start, offset + s.peak, offset + s.end, r.activity[s.peak])
                 for s in segment_lifts(r.t, r.q)]
        offset += len(r.q)
    engine = make_engine(settings.database_url)
    rec = TickRecorder(engine)
    run = rec.run_started(RunStarted(1, "none", {}, "sim", 1), "sim")
    rec.add(TickBatch.from_records(1, (TickRecord(seq=k, t=float(t[k]), q_left=float(q[k, 0]),
                                                  q_right=float(q[k, 1]))
                                       for k in range(len(q)))))
    assert rec.flush() == len(q)
    with make_session_factory(engine)() as db:
        db.execute(update(Trial).where(Trial.id == trial_id).values(
            status="completed", run_id=run, started_at=datetime(2026, 11, 1, 10, tzinfo=UTC)))
        db.add_all([TrialSegment(trial_id=trial_id, start=a, peak=b, end=c, label=lab,
                                 source="manual") for a, b, c, lab in segs])
        db.commit()
    engine.dispose()
    return {lab: sum(s[3] == lab for s in segs) for lab in ("squat", "stoop_left",
                                                             "stoop_right")}


def test_plan_fit_learn_and_condition_snapshot(client: TestClient, settings: Settings) -> None:
    ids = _setup(client, settings, n=3)
    pid, sid = ids["participants"][0], ids["sessions"][0]
    base = {"tasks": TASKS, "include_eumc": False, "model_set_id": ids["ms"],
            "utility_set_id": ids["us"]}

    # A personal condition with nothing to fit it from is refused, naming what to do.
    r = client.post(f"/api/sessions/{sid}/trials/plan",
                    json={**base, "conditions": ["population", "personal"]})
    assert r.status_code == 422 and "demonstration block" in r.text
    # Priors from outside: refused when outside the bound, never projected.
    r = client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "skewed", "method": "import", "utility_set_id": ids["us"],
        "values": STOOP_LEFT_SKEW})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == ["body", "values"]
    assert "stoop_left" in r.json()["detail"][0]["msg"]
    r = client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "nothing yet", "method": "dirichlet", "utility_set_id": ids["us"]})
    assert r.status_code == 422 and "no confirmed motions" in r.text
    equal = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "equal", "method": "equal", "utility_set_id": ids["us"]}), 201)
    assert equal["version"] == 1 and equal["document"]["values"] == [0.25] * 4

    demos = {"squat": 5, "stoop_left": 5, "stoop_right": 5}
    plans = [_ok(client.post(f"/api/sessions/{s}/trials/plan", json={
        **base, "conditions": ["population", "personal"], "demonstrations": demos}), 201)
        for s in ids["sessions"]]
    plan = plans[0]
    block = plan[0]
    assert (block["controller"], block["task"], block["demonstrations"]) == (
        "none", "demonstrations", demos)
    # UMC with population and with personal models, and the PEC, rotated together:
    # each condition leads once in three participants.
    firsts = [p[1]["condition"] for p in plans]
    assert sorted(firsts) == ["pec", "umc", "umc+personal"]
    for p in plans:
        conds = list(dict.fromkeys(t["condition"] for t in p[1:]))
        assert sorted(conds) == ["pec", "umc", "umc+personal"]
        personal = [t for t in p if t["condition"] == "umc+personal"]
        assert all(t["models"] == "personal" and t["model_set_id"] is None for t in personal)
    key = {row["label"]: row["controller"] for row in
           _ok(client.get(f"/api/participants/{pid}/conditions"))}
    assert sorted(key.values()) == ["eumc", "pec", "umc", "umc+personal"] or \
        sorted(key.values()) == ["pec", "umc", "umc+personal"]
    assert len(set(key)) == len(key)  # one letter per condition

    # The personal trial cannot start before the personal set exists (409 naming why).
    personal_trial = next(t for t in plan if t["condition"] == "umc+personal")
    r = client.post(f"/api/trials/{personal_trial['id']}/start", json={})
    assert r.status_code == 409 and "personal" in r.text

    counts = _record_block(settings, block["id"])
    r = client.post(f"/api/participants/{pid}/personal-model-sets", json={
        "name": "too few", "method": "participant-only", "min_per_motion": 6,
        "demonstration_trial_id": block["id"]})
    assert r.status_code == 422 and "stoop_left" in r.text
    fit = _ok(client.post(f"/api/participants/{pid}/personal-model-sets", json={
        "name": "P01 MAP", "method": "map", "population_model_set_id": ids["ms"],
        "demonstration_trial_id": block["id"]}), 202)
    assert (fit["kind"], fit["method"], fit["participant_id"], fit["base_model_set_id"]) == (
        "personal", "map", pid, ids["ms"])
    def finished() -> dict[str, Any]:
        j: dict[str, Any] = client.get(f"/api/jobs/{fit['job_id']}").json()
        return j if j["status"] in ("done", "failed") else {}

    job = wait_for(finished, 120, "the personal fit")
    assert job["status"] == "done", job
    row = _ok(client.get(f"/api/model-sets/{fit['id']}"))
    assert row["status"] == "ready" and row["params"]["counts"] == counts
    doc = _ok(client.get(f"/api/model-sets/{fit['id']}/document"))
    prov = doc["meta"]["personal"]
    assert prov["method"] == "map-mean" and prov["n_participant"] == counts
    assert all(i.startswith("trial-segment:") for i in prov["participant_demonstrations"]
               ["squat"])
    listed = _ok(client.get(f"/api/studies/{ids['study']}/personal-model-sets"))
    assert [m["id"] for m in listed] == [fit["id"]]
    # A personal set is not a population set for everyone.
    s3 = _ok(client.post(f"/api/participants/{pid}/sessions",
                         json={"kind": "evaluation", "precompression_pct": 25}), 201)["id"]
    r = client.post(f"/api/sessions/{s3}/trials/plan", json={**base, "model_set_id": fit["id"]})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "model_set_id"]

    # Priors from the block's confirmed motions: a new version, inside the bound.
    learned = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "from the block", "method": "dirichlet", "utility_set_id": ids["us"]}), 201)
    assert learned["version"] == 2 and learned["params"]["new_motions"] == sum(
        counts.values())
    bounds = PriorBounds.for_table(ids["table"])
    assert bounds.contains(learned["document"]["values"])
    assert learned["document"]["estimate"][3] < 0.25  # lifts only: "other" fell ...
    assert learned["document"]["values"][3] >= 0.25  # ... but not what the controller uses

    # The personal trial's snapshot names the personal set and its provenance; a +priors
    # plan stores the prior set; a prior row altered after it was stored is refused.
    sid2 = _ok(client.post(f"/api/participants/{pid}/sessions",
                           json={"kind": "evaluation", "precompression_pct": 25}), 201)["id"]
    plan2 = _ok(client.post(f"/api/sessions/{sid2}/trials/plan", json={
        **base, "conditions": ["population", "personal+priors"],
        "prior_set_id": learned["id"]}), 201)
    pp = next(t for t in plan2 if t["condition"] == "umc+personal+priors")
    assert pp["prior_set_id"] == learned["id"]
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        doc_row = db.get(PriorSetRecord, learned["id"])
        assert doc_row is not None and doc_row.document is not None
        altered = {**doc_row.document, "values": STOOP_LEFT_SKEW, "roles": [
            "neutral"] * 4}
        db.execute(update(PriorSetRecord).where(PriorSetRecord.id == learned["id"])
                   .values(document=altered))
        db.commit()
    engine.dispose()
    r = client.post(f"/api/trials/{pp['id']}/start", json={})
    assert r.status_code == 409, r.text
    assert "outside the safety bound" in r.text and "stoop_left" in r.text
    assert _ok(client.get(f"/api/trials/{pp['id']}"))["status"] == "planned"


def test_label_shift_priors_from_unconfirmed_use(client: TestClient, settings: Settings) -> None:
    """The EM estimate from a completed UMC walking trial's own ticks (nothing
    confirmed): a prior set inside the bound, with its sources and test in the record."""
    from controller.controllers.umc import UMC
    from controller.decision.utility_function import UtilitySet
    from controller.intent.motion_model import ModelSet
    from controller.runner.replay import records_from_columns, replay_columns

    ids = _setup(client, settings)
    pid, sid = ids["participants"][0], ids["sessions"][0]
    r = client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "em", "method": "label-shift-em", "utility_set_id": ids["us"]})
    assert r.status_code == 422 and "completed UMC or E-UMC trials" in r.text
    p = VirtualParticipant.from_seed(3)
    umc = UMC(ModelSet.load(Path(settings.models_path)),
              UtilitySet.load(next(Path(settings.utilities_dir).glob("*.json"))))
    records = records_from_columns(replay_columns(trial_recording(p, 3, "walking", 0), umc))
    engine = make_engine(settings.database_url)
    rec = TickRecorder(engine)
    run = rec.run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    rec.add(TickBatch.from_records(1, records))
    assert rec.flush() == len(records)
    with make_session_factory(engine)() as db:
        db.add(Trial(session_id=sid, controller="umc", task="walking", planned_order=0,
                     status="completed", run_id=run, model_set_id=ids["ms"],
                     utility_set_id=ids["us"], started_at=datetime(2026, 11, 2, tzinfo=UTC),
                     config_snapshot={"settings": {"priors": [0.25] * 4}}))
        db.commit()
    engine.dispose()
    em = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "em", "method": "label-shift-em", "utility_set_id": ids["us"],
        "window_s": 2.0}), 201)
    doc = em["document"]
    assert doc["method"] == "label-shift-em" and doc["meta"]["converged"]
    assert doc["meta"]["n_samples"] == em["params"]["motions"] == len(doc["sources"]) > 5
    assert PriorBounds.for_table(ids["table"]).contains(doc["values"])
    # Walking is "other": the estimate moves toward it, and the values never below 1/4.
    assert doc["estimate"][3] > 0.25 and doc["values"][3] >= 0.25


def test_a_prior_set_version_taken_meanwhile_is_retried_not_a_500(
        client: TestClient, settings: Settings) -> None:
    """Another request stores the version this one computed, between its count and its
    insert: this one takes the next version (UNIQUE(participant, version) is no 500)."""
    ids = _setup(client, settings)
    pid = ids["participants"][0]
    other = make_engine(settings.database_url)
    taken: list[int] = []

    def meanwhile(session: Any, *_: Any) -> None:
        rows = [o for o in session.new if isinstance(o, PriorSetRecord)]
        if rows and not taken:
            taken.append(rows[0].version)
            with make_session_factory(other)() as db:
                db.add(PriorSetRecord(study_id=ids["study"], participant_id=pid,
                                      version=rows[0].version, name="meanwhile",
                                      method="equal", utility_set_id=ids["us"],
                                      document=None, status="ready"))
                db.commit()

    event.listen(Session, "before_flush", meanwhile)
    try:
        row = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
            "name": "equal", "method": "equal", "utility_set_id": ids["us"]}), 201)
    finally:
        event.remove(Session, "before_flush", meanwhile)
        other.dispose()
    assert taken == [1]
    assert row["version"] == 2 and row["document"]["version"].endswith("-priors-2")


def test_prior_sets_posted_at_once_get_distinct_versions(client: TestClient,
                                                         settings: Settings) -> None:
    ids = _setup(client, settings)
    pid = ids["participants"][0]
    n = 4
    barrier = threading.Barrier(n)

    def post(i: int) -> Any:
        barrier.wait()
        return client.post(f"/api/participants/{pid}/prior-sets", json={
            "name": f"equal {i}", "method": "equal", "utility_set_id": ids["us"]})

    with ThreadPoolExecutor(n) as pool:
        answers = list(pool.map(post, range(n)))
    assert [r.status_code for r in answers] == [201] * n, [r.text for r in answers]
    assert sorted(r.json()["version"] for r in answers) == [1, 2, 3, 4]


def test_forged_prior_documents_are_refusals_and_listed_as_invalid(
        client: TestClient, settings: Settings) -> None:
    """Rows altered into documents of the wrong types: the lists still answer (the row
    marked invalid), a plan naming one is 422, learning on from one is 409."""
    ids = _setup(client, settings)
    pid, sid = ids["participants"][0], ids["sessions"][0]
    made = [_ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": f"equal {i}", "method": "equal", "utility_set_id": ids["us"]}), 201)
        for i in range(4)]
    good = made[0]["document"]
    forged = [{**good, "values": 5}, {**good, "meta": 5}, {**good, "forgetting": None},
              [1, 2, 3]]
    engine = make_engine(settings.database_url)
    with make_session_factory(engine)() as db:
        for row, doc in zip(made, forged, strict=True):
            db.execute(update(PriorSetRecord).where(PriorSetRecord.id == row["id"])
                       .values(document=doc))
        db.commit()
    engine.dispose()
    listed = _ok(client.get(f"/api/participants/{pid}/prior-sets"))
    assert [r["document"] for r in listed] == [None] * 4
    assert ["values" in listed[0]["problem"], "meta" in listed[1]["problem"],
            "forgetting" in listed[2]["problem"], "object" in listed[3]["problem"]] == [
        True] * 4
    assert len(_ok(client.get(f"/api/studies/{ids['study']}/prior-sets"))) == 4
    assert _ok(client.get(f"/api/prior-sets/{made[2]['id']}"))["problem"] is not None
    for row in made:
        r = client.post(f"/api/sessions/{sid}/trials/plan", json={
            "tasks": TASKS, "include_eumc": False, "model_set_id": ids["ms"],
            "utility_set_id": ids["us"], "conditions": ["population", "population+priors"],
            "prior_set_id": row["id"]})
        assert r.status_code == 422, r.text
        assert "not a valid priors document" in r.text
        r = client.post(f"/api/participants/{pid}/prior-sets", json={
            "name": "on", "method": "dirichlet", "utility_set_id": ids["us"],
            "previous_prior_set_id": row["id"]})
        assert r.status_code == 409 and "not a valid priors document" in r.text, r.text
    # The floor: at least the documented one (0.05).
    r = client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "tiny", "method": "equal", "utility_set_id": ids["us"], "floor": 1e-300})
    assert r.status_code == 422 and "floor" in r.text


def test_label_shift_from_a_trial_with_a_zero_prior_names_the_trial(
        client: TestClient, settings: Settings) -> None:
    ids = _setup(client, settings)
    pid, sid = ids["participants"][0], ids["sessions"][0]
    engine = make_engine(settings.database_url)
    run = TickRecorder(engine).run_started(RunStarted(1, "umc", {}, "sim", 1), "sim")
    with make_session_factory(engine)() as db:
        trial = Trial(session_id=sid, controller="umc", task="walking", planned_order=0,
                      status="completed", run_id=run, model_set_id=ids["ms"],
                      utility_set_id=ids["us"], started_at=datetime(2026, 11, 2, tzinfo=UTC),
                      config_snapshot={"settings": {"priors": [0, 0, 0, 1]}})
        db.add(trial)
        db.commit()
        tid = trial.id
    engine.dispose()
    r = client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "em", "method": "label-shift-em", "utility_set_id": ids["us"]})
    assert r.status_code == 409, r.text
    assert f"trial {tid}" in r.text and "[0, 0, 0, 1]" in r.text


def test_trial_start_rechecks_whose_sets_the_trial_names(client: TestClient,
                                                         settings: Settings) -> None:
    """Trial rows altered after planning: another participant's priors under plain
    "umc", another participant's prior set under "+priors", and another study's sets
    are each refused at start (409 naming the mismatch); the trial stays planned."""
    ids = _setup(client, settings, n=2)
    (pid, other), sid = ids["participants"], ids["sessions"][0]
    mine = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        "name": "equal", "method": "equal", "utility_set_id": ids["us"]}), 201)
    theirs = _ok(client.post(f"/api/participants/{other}/prior-sets", json={
        "name": "equal", "method": "equal", "utility_set_id": ids["us"]}), 201)
    plan = _ok(client.post(f"/api/sessions/{sid}/trials/plan", json={
        "tasks": TASKS, "include_eumc": False, "model_set_id": ids["ms"],
        "utility_set_id": ids["us"], "conditions": ["population", "population+priors"],
        "prior_set_id": mine["id"]}), 201)
    plain = next(t for t in plan if t["condition"] == "umc")
    with_priors = next(t for t in plan if t["condition"] == "umc+priors")
    second = _setup(client, settings, name="Another")  # another study's sets
    engine = make_engine(settings.database_url)

    def alter(trial: dict[str, Any], **values: Any) -> None:
        with make_session_factory(engine)() as db:
            db.execute(update(Trial).where(Trial.id == trial["id"]).values(**values))
            db.commit()

    def refused(trial: dict[str, Any], *words: str) -> None:
        r = client.post(f"/api/trials/{trial['id']}/start", json={})
        assert r.status_code == 409, r.text
        assert all(w in r.text for w in words), r.text
        assert _ok(client.get(f"/api/trials/{trial['id']}"))["status"] == "planned"

    alter(plain, prior_set_id=theirs["id"])
    refused(plain, "equal priors", str(theirs["id"]))
    alter(with_priors, prior_set_id=theirs["id"])
    refused(with_priors, "another participant", f"prior set {theirs['id']}")
    alter(with_priors, prior_set_id=mine["id"], model_set_id=second["ms"])
    refused(with_priors, f"model set {second['ms']}", f"study {second['study']}")
    alter(with_priors, model_set_id=ids["ms"], utility_set_id=second["us"])
    refused(with_priors, f"utility set {second['us']}", f"study {second['study']}")
    engine.dispose()


def test_saved_again_or_relabelled_lifts_are_counted_once_with_their_label(
        client: TestClient, settings: Settings) -> None:
    """Saving a trial's segments replaces their rows: a later prior set neither counts
    the same lifts again nor skips a relabelled one; it counts each once, as labelled."""
    ids = _setup(client, settings)
    pid, sid = ids["participants"][0], ids["sessions"][0]
    engine = make_engine(settings.database_url)
    lifts = [(100 * i, 100 * i + 40, 100 * i + 80, "squat") for i in range(6)]

    def save(segs: list[tuple[int, int, int, str]]) -> None:
        """What PUT /api/trials/{id}/segments does: delete the rows, insert new ones."""
        with make_session_factory(engine)() as db:
            db.execute(delete(TrialSegment).where(TrialSegment.trial_id == tid))
            db.add_all([TrialSegment(trial_id=tid, start=a, peak=b, end=c, label=lab,
                                     source="manual") for a, b, c, lab in segs])
            db.commit()

    with make_session_factory(engine)() as db:
        trial = Trial(session_id=sid, controller="pec", task="squat-sequence",
                      planned_order=0, status="completed",
                      started_at=datetime(2026, 11, 2, tzinfo=UTC))
        db.add(trial)
        db.commit()
        tid = trial.id
    save(lifts)
    learn = {"name": "learned", "method": "dirichlet", "utility_set_id": ids["us"],
             "forgetting": 1.0}
    first = _ok(client.post(f"/api/participants/{pid}/prior-sets", json=learn), 201)
    assert first["document"]["counts"] == [6.0, 0.0, 0.0, 0.0]
    save(lifts)  # saved again unchanged: nothing new
    again = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        **learn, "previous_prior_set_id": first["id"]}), 201)
    assert again["params"]["new_motions"] == 0
    assert again["document"]["counts"] == [6.0, 0.0, 0.0, 0.0]
    save([*lifts[:5], (*lifts[5][:3], "stoop_left")])  # one lift relabelled
    relabelled = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        **learn, "previous_prior_set_id": again["id"]}), 201)
    assert relabelled["document"]["counts"] == [5.0, 1.0, 0.0, 0.0]
    assert relabelled["params"]["relabelled"] == [f"trial:{tid}:500-580"]
    assert len(relabelled["document"]["sources"]) == 6
    # A set stored before sources named the motion (segment row ids): counted afresh.
    old_doc = {**first["document"], "sources": [f"trial-segment:{i}" for i in range(6)],
               "meta": {}}
    with make_session_factory(engine)() as db:
        db.execute(update(PriorSetRecord).where(PriorSetRecord.id == first["id"])
                   .values(document=old_doc))
        db.commit()
    recounted = _ok(client.post(f"/api/participants/{pid}/prior-sets", json={
        **learn, "previous_prior_set_id": first["id"]}), 201)
    assert recounted["document"]["counts"] == [5.0, 1.0, 0.0, 0.0]
    assert recounted["params"]["recounted"] is True
    engine.dispose()


def test_unknown_ids_are_404s_naming_them(client: TestClient) -> None:
    body = {"name": "x", "method": "map", "demonstration_trial_id": 1,
            "population_model_set_id": 1}
    prior = {"name": "x", "method": "equal", "utility_set_id": 1}
    asked = {
        ("post", "/api/participants/999999/personal-model-sets", "participant 999999"): body,
        ("get", "/api/participants/999999/personal-model-sets", "participant 999999"): None,
        ("get", "/api/studies/999999/personal-model-sets", "study 999999"): None,
        ("post", "/api/participants/999999/prior-sets", "participant 999999"): prior,
        ("get", "/api/participants/999999/prior-sets", "participant 999999"): None,
        ("get", "/api/studies/999999/prior-sets", "study 999999"): None,
        ("get", "/api/prior-sets/999999", "prior set 999999"): None,
    }
    for (method, url, entity), payload in asked.items():
        r = client.request(method, url, json=payload)
        assert (r.status_code, r.json()["detail"]) == (404, f"{entity} does not exist"), url
