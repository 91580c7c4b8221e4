"""Questionnaires: the definition format, scoring (SUS test vectors from
docs/questionnaires.md, EUS structure), and the instrument, link and response workflow
through the API."""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any
from uuid import uuid4

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError
from sqlalchemy import insert, update

from backend.db.engine import make_engine
from backend.db.models import ParticipantLink, QuestionnaireInstrument
from backend.questionnaires.catalog import INSTRUMENTS_DIR, built_in_definitions
from backend.questionnaires.definition import ImportedInstrument, InstrumentDefinition
from backend.questionnaires.scoring import AnswerError, score
from tests.databases import AccountTemplates
from tests.module_client import logged_in_client, module_engines


def _definition(key: str) -> InstrumentDefinition:
    return next(d for d in built_in_definitions() if d.key == key)


def _sus(answers: str) -> dict[str, int]:
    return {f"q{i}": int(a) for i, a in enumerate(answers.split(","), start=1)}


SUS_VECTORS = [
    ("4,1,5,2,5,1,4,2,3,1", 85.0),
    ("3,3,3,3,3,3,3,3,3,3", 50.0),
    ("1,5,1,5,1,5,1,5,1,5", 0.0),
    ("5,1,5,1,5,1,5,1,5,1", 100.0),
    ("4,1,5,1,5,1,5,1,5,1", 97.5),
]


# --- scoring -----------------------------------------------------------------------


@pytest.mark.parametrize(("answers", "expected"), SUS_VECTORS)
def test_sus_test_vectors(answers: str, expected: float) -> None:
    assert score(_definition("sus"), _sus(answers)).score == expected


def test_summing_raw_sus_answers_would_fail_the_vectors() -> None:
    # The classic bug: sum of raw answers (times 2.5) ignores reverse items and the
    # 1-based scale. It misses every vector, so the vectors really guard against it.
    for answers, expected in SUS_VECTORS:
        raw = sum(_sus(answers).values())
        assert raw * 2.5 != expected and raw != expected
        assert score(_definition("sus"), _sus(answers)).score == expected


def test_sus_texts_are_the_standard_ones() -> None:
    sus = _definition("sus")
    assert len(sus.items) == 10 and sus.provenance.wording == "standard"
    assert sus.items[0].text == "I think that I would like to use this system frequently."
    assert sus.items[9].text == ("I needed to learn a lot of things before I could get going "
                                 "with this system.")
    assert sus.reverse_scored == ["q2", "q4", "q6", "q8", "q10"]


def test_eus_structure_and_the_project_wording_flag() -> None:
    eus = _definition("eus")
    assert len(eus.items) == 20 and (eus.scale.min, eus.scale.max) == (0, 10)
    assert eus.provenance.wording == "project" and "Maurice" in eus.provenance.note
    assert "NOT the published" in eus.provenance.note
    assert {s.id for s in eus.subscales} == {"usability", "comfort", "support", "intention"}
    best = {it.id: (0 if it.id in eus.reverse_scored else 10) for it in eus.items}
    assert score(eus, best).score == 10.0
    # A mean of 20 integer ratings moves in steps of 0.05, like the paper's 6.35 or 7.95.
    answers = {it.id: 5 for it in eus.items}
    answers["u1"] = 6
    assert score(eus, answers).score == pytest.approx(5.05)
    answers = {it.id: (7 if it.id not in eus.reverse_scored else 3) for it in eus.items}
    answers["u1"], answers["c1"], answers["s1"] = 10, 8, 10  # 147 / 20
    result = score(eus, answers)
    assert result.score == pytest.approx(7.35)
    assert round(result.score / 0.05, 9) == round(result.score / 0.05)


def test_missing_answers_are_rejected_by_default_naming_the_items() -> None:
    answers: dict[str, int | None] = dict(_sus("4,1,5,2,5,1,4,2,3,1"))
    del answers["q3"]
    answers["q7"] = None
    with pytest.raises(AnswerError) as err:
        score(_definition("sus"), answers)
    assert set(err.value.problems) == {"q3", "q7"}


def test_neutral_substitution_when_the_study_chooses_it() -> None:
    data = _definition("sus").model_dump()
    data["missing"] = {"policy": "neutral"}
    lenient = InstrumentDefinition.model_validate(data)
    answers: dict[str, int | None] = dict(_sus("3,3,3,3,3,3,3,3,3,3"))
    del answers["q1"]
    result = score(lenient, answers)
    assert result.score == 50.0 and result.substituted == ("q1",)


@pytest.mark.parametrize(("item", "value", "problem"), [
    ("q1", 6, "outside the scale"), ("q1", 0, "outside the scale"),
    ("q1", 2.5, "whole number"), ("q11", 3, "no such item"),
])
def test_bad_answers_name_the_item(item: str, value: Any, problem: str) -> None:
    answers: dict[str, Any] = dict(_sus("3,3,3,3,3,3,3,3,3,3"))
    answers[item] = value
    with pytest.raises(AnswerError) as err:
        score(_definition("sus"), answers)
    assert problem in err.value.problems[item]


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d.update(reverse_scored=["q2", "q99"]), "reverse_scored: unknown item"),
    (lambda d: d.update(score_range={"min": 0, "max": 40}), "score_range"),
    (lambda d: d["scale"].update(min=5, max=1), "greater than min"),
    (lambda d: d["items"].append({"id": "q1", "text": "again"}), "duplicate item ids"),
    (lambda d: d["subscales"][0]["items"].append("zz"), "subscales.usable.items"),
    (lambda d: d.update(reversed=["q2"]), "Extra inputs"),
    (lambda d: d["provenance"].update(wording="borrowed"), "provenance"),
])
def test_definition_validation_catches_what_would_score_wrongly(
    change: Any, message: str
) -> None:
    data = json.loads((INSTRUMENTS_DIR / "sus.json").read_text())
    change(data)
    with pytest.raises(ValidationError, match=message):
        InstrumentDefinition.model_validate(data)


# --- API ---------------------------------------------------------------------------


@pytest.fixture(scope="module", params=module_engines())
def shared(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory,
           default_sets: tuple[Path, Path], account_templates: AccountTemplates
           ) -> Iterator[TestClient]:
    """One logged-in app per engine for the refusals below, which store nothing; each
    test makes its own study there (`tests/module_client.py`)."""
    server = (request.getfixturevalue("postgres_cluster") if request.param == "postgresql"
              else None)
    with logged_in_client(tmp_path_factory.mktemp("questionnaires"), default_sets,
                          account_templates, server) as c:
        yield c


def _participant_with_conditions(client: TestClient, study: str = "Q") -> int:
    sid = client.post("/api/studies", json={"name": study}).json()["id"]
    pid = int(client.post(f"/api/studies/{sid}/participants", json={"code": "P07"}).json()["id"])
    for label, ctrl in (("A", "umc"), ("B", "pec")):
        client.post(f"/api/participants/{pid}/conditions",
                    json={"label": label, "controller": ctrl})
    return pid


def _own_definition() -> dict[str, Any]:
    return {
        "key": "borg-cr10", "version": "2026.1", "title": "Exertion (Borg CR10)",
        "items": [{"id": "exertion", "text": "How hard was the lifting?"}],
        "scale": {"min": 0, "max": 10, "labels": [{"value": 0, "label": "nothing at all"}]},
        "aggregation": {"method": "sum"}, "score_range": {"min": 0, "max": 10},
        "provenance": {"wording": "study", "source": "our protocol"},
    }


def test_instruments_list_shows_whose_wording(client: TestClient) -> None:
    listing = {i["key"]: i for i in client.get("/api/instruments").json()}
    assert listing["sus"]["wording"] == "standard" and listing["sus"]["built_in"]
    assert listing["eus"]["wording"] == "project"
    assert "own" in listing["eus"]["wording_note"]
    full = client.get("/api/instruments/eus/project-1.0").json()
    assert full["definition"]["provenance"]["wording"] == "project"
    assert client.get("/api/instruments/eus/9.9").status_code == 404


def _study(client: TestClient, name: str = "Own") -> int:
    return int(client.post("/api/studies", json={"name": name}).json()["id"])


def test_import_a_studys_own_definition(client: TestClient) -> None:
    sid = _study(client)
    url = f"/api/studies/{sid}/instruments"
    r = client.post(url, json=_own_definition())
    assert r.status_code == 201 and r.json()["built_in"] is False
    assert r.json()["wording"] == "study" and r.json()["study_id"] == sid
    assert client.post(url, json=_own_definition()).status_code == 409
    broken = _own_definition()
    broken["score_range"] = {"min": 0, "max": 100}
    r = client.post(url, json=broken)
    assert r.status_code == 422 and "score_range" in r.json()["detail"][0]["msg"]
    broken = _own_definition()
    broken["scale"] = {"min": 0}
    r = client.post(url, json=broken)
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "scale", "max"]
    # The study sees it; the built-in list and other studies do not.
    assert "borg-cr10" in {i["key"] for i in client.get(url).json()}
    assert "borg-cr10" not in {i["key"] for i in client.get("/api/instruments").json()}
    other = _study(client, "Other")
    assert "borg-cr10" not in {i["key"] for i in
                               client.get(f"/api/studies/{other}/instruments").json()}
    assert client.get(f"/api/studies/{other}/instruments/borg-cr10/2026.1").status_code == 404
    assert client.get(f"{url}/borg-cr10/2026.1").json()["definition"]["key"] == "borg-cr10"


def test_link_forms_answers_scores_and_single_use(client: TestClient) -> None:
    pid = _participant_with_conditions(client)
    r = client.post(f"/api/participants/{pid}/links", json={"forms": [
        {"instrument_key": "sus", "condition_label": "A"},
        {"instrument_key": "sus", "instrument_version": "1.0", "condition_label": "B"},
        {"instrument_key": "eus", "condition_label": "A"},
    ]})
    assert r.status_code == 201
    link = r.json()
    token = link["token"]
    assert link["url"].endswith(f"/forms/{token}")
    assert link["forms_due"][2]["instrument_version"] == "project-1.0"
    participant = TestClient(client.app)
    view = participant.get(f"/api/participant-forms/{token}")
    assert view.status_code == 200
    text = view.text.lower()
    assert not re.search(r"\b(umc|e-?umc|pec)\b", text) and '"controller"' not in text
    forms = view.json()["forms"]
    assert [f["condition_label"] for f in forms] == ["A", "B", "A"]
    assert forms[2]["provenance"]["wording"] == "project"
    assert len(forms[0]["items"]) == 10 and not forms[0]["submitted"]

    url = f"/api/participant-forms/{token}/responses"
    bad = participant.post(url, json={"form": 0, "answers": {**_sus("4,1,5,2,5,1,4,2,3,1"),
                                                             "q2": 7, "q5": None}})
    assert bad.status_code == 422
    assert {tuple(e["loc"]) for e in bad.json()["detail"]} == {
        ("body", "answers", "q2"), ("body", "answers", "q5")}
    r = participant.post(url, json={"form": 0, "answers": _sus("4,1,5,2,5,1,4,2,3,1")})
    assert r.status_code == 201 and r.json()["forms_remaining"] == 2
    assert participant.post(url, json={"form": 0, "answers": _sus("3,3,3,3,3,3,3,3,3,3")}
                            ).status_code == 409
    assert participant.post(url, json={"form": 5, "answers": {}}).status_code == 422
    participant.post(url, json={"form": 1, "answers": _sus("4,1,5,1,5,1,5,1,5,1")})
    eus = {it["id"]: 7 for it in forms[2]["items"]}  # 16 x 7 + 4 reversed x 3 = 124 / 20
    r = participant.post(url, json={"form": 2, "answers": eus})
    assert r.json() == {"accepted": True, "forms_remaining": 0, "preference_remaining": False,
                        "link_closed": True}
    # Used once: the link is closed.
    assert participant.get(f"/api/participant-forms/{token}").status_code == 410

    responses = client.get(f"/api/participants/{pid}/responses").json()
    got = [(x["instrument_key"], x["instrument_version"], x["condition_label"],
            x["controller"], x["score"]) for x in responses]
    assert got == [("sus", "1.0", "A", "umc", 85.0), ("sus", "1.0", "B", "pec", 97.5),
                   ("eus", "project-1.0", "A", "umc", pytest.approx(6.2))]
    assert responses[0]["subscale_scores"] == {"usable": 84.375, "learnable": 87.5}
    assert responses[0]["answers"]["q1"] == 4
    links = client.get(f"/api/participants/{pid}/links").json()
    assert links[0]["used_at"] is not None and "token" not in links[0]


def test_link_validation(client: TestClient) -> None:
    pid = _participant_with_conditions(client)
    url = f"/api/participants/{pid}/links"
    r = client.post(url, json={"forms": [{"instrument_key": "nasa-tlx"},
                                         {"instrument_key": "sus", "condition_label": "Z"}]})
    assert r.status_code == 422
    assert [e["loc"] for e in r.json()["detail"]] == [
        ["body", "forms", 0, "instrument_key"], ["body", "forms", 1, "condition_label"]]
    r = client.post(url, json={"forms": []})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "forms"]
    twice = {"instrument_key": "sus", "condition_label": "A"}
    assert client.post(url, json={"forms": [twice, twice]}).status_code == 422
    assert client.post("/api/participants/999/links", json={"forms": [twice]}).status_code == 404


def test_an_expired_link_opens_nothing(client: TestClient) -> None:
    pid = _participant_with_conditions(client)
    token = client.post(f"/api/participants/{pid}/links", json={
        "forms": [{"instrument_key": "sus", "condition_label": "A"}]}).json()["token"]
    engine = make_engine(str(client.app.state.settings.database_url))  # type: ignore[attr-defined]
    with engine.begin() as conn:
        conn.execute(update(ParticipantLink).values(
            expires_at=datetime.now(UTC) - timedelta(minutes=1)))
    engine.dispose()
    r = TestClient(client.app).get(f"/api/participant-forms/{token}")
    assert r.status_code == 410 and "expired" in r.json()["detail"]


def test_stored_instrument_versions_are_never_edited(client: TestClient) -> None:
    url = f"/api/studies/{_study(client)}/instruments"
    own = _own_definition()
    client.post(url, json=own)
    changed = copy.deepcopy(own)
    changed["items"][0]["text"] = "How hard was it?"
    assert client.post(url, json=changed).status_code == 409
    changed["version"] = "2026.2"
    assert client.post(url, json=changed).status_code == 201
    versions = [i["version"] for i in client.get(url).json() if i["key"] == "borg-cr10"]
    assert versions == ["2026.1", "2026.2"]


def _phishing_sus() -> dict[str, Any]:
    sus = _definition("sus").model_dump(mode="json")
    sus["version"] = "9.9"
    sus["items"][0]["text"] = "Please type your bank PIN as your answer."
    return sus


def test_one_study_cannot_change_what_another_studys_participants_see(
        client: TestClient) -> None:
    # Issue 23: an experimenter of study X imported "sus 9.9" (asking for a bank PIN,
    # marked standard wording); a link of study Y without a version then served it.
    x = _study(client, "X")
    r = client.post(f"/api/studies/{x}/instruments", json=_phishing_sus())
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "key"]
    assert "built-in" in r.json()["detail"][0]["msg"]
    # Under a key of its own, study X's file is X's alone.
    own = _phishing_sus()
    own["key"] = "sus-x"
    assert client.post(f"/api/studies/{x}/instruments", json=own).status_code == 201
    pid = _participant_with_conditions(client)  # in another study, "Q"
    url = f"/api/participants/{pid}/links"
    r = client.post(url, json={"forms": [{"instrument_key": "sus-x"}]})
    assert r.status_code == 422 and "no instrument sus-x" in r.json()["detail"][0]["msg"]
    r = client.post(url, json={"forms": [{"instrument_key": "sus", "condition_label": "A"}]})
    assert r.status_code == 201 and r.json()["forms_due"][0]["instrument_version"] == "1.0"
    form = TestClient(client.app).get(f"/api/participant-forms/{r.json()['token']}").json()
    assert form["forms"][0]["items"][0]["text"] == (
        "I think that I would like to use this system frequently.")
    keys = {i["key"] for i in client.get(f"/api/participants/{pid}/instruments").json()}
    assert keys == {"sus", "eus"}


def test_a_link_without_a_version_needs_one_version_in_the_study(
        client: TestClient) -> None:
    pid = _participant_with_conditions(client)
    sid = client.get(f"/api/participants/{pid}").json()["study_id"]
    own = _own_definition()
    client.post(f"/api/studies/{sid}/instruments", json=own)
    url = f"/api/participants/{pid}/links"
    r = client.post(url, json={"forms": [{"instrument_key": "borg-cr10"}]})
    assert r.status_code == 201 and r.json()["forms_due"][0]["instrument_version"] == "2026.1"
    own["version"] = "2026.2"
    client.post(f"/api/studies/{sid}/instruments", json=own)
    r = client.post(url, json={"forms": [{"instrument_key": "borg-cr10"}]})
    assert r.status_code == 422 and "name one" in r.json()["detail"][0]["msg"]
    r = client.post(url, json={"forms": [{"instrument_key": "borg-cr10",
                                          "instrument_version": "2026.2"}]})
    assert r.status_code == 201


def test_a_form_is_served_from_the_row_its_link_pinned(client: TestClient) -> None:
    # Two studies may each import the same key and version; each link shows its own.
    pid = _participant_with_conditions(client)
    sid = client.get(f"/api/participants/{pid}").json()["study_id"]
    other = _study(client, "Other")
    theirs = _own_definition()
    theirs["items"][0]["text"] = "Another study's wording"
    assert client.post(f"/api/studies/{other}/instruments", json=theirs).status_code == 201
    assert client.post(f"/api/studies/{sid}/instruments",
                       json=_own_definition()).status_code == 201
    token = client.post(f"/api/participants/{pid}/links", json={"forms": [
        {"instrument_key": "borg-cr10", "instrument_version": "2026.1"}]}).json()["token"]
    participant = TestClient(client.app)
    form = participant.get(f"/api/participant-forms/{token}").json()["forms"][0]
    assert form["items"][0]["text"] == "How hard was the lifting?"
    r = participant.post(f"/api/participant-forms/{token}/responses",
                         json={"form": 0, "answers": {"exertion": 4}})
    assert r.status_code == 201
    assert client.get(f"/api/participants/{pid}/responses").json()[0]["score"] == 4


@pytest.mark.parametrize("value", [True, False, 3.0, "3"])
def test_answers_must_be_integers_not_booleans(shared: TestClient, value: Any) -> None:
    client = shared
    pid = _participant_with_conditions(client, f"Q {uuid4().hex}")
    token = client.post(f"/api/participants/{pid}/links", json={
        "forms": [{"instrument_key": "sus", "condition_label": "A"}]}).json()["token"]
    answers: dict[str, Any] = _sus("3,3,3,3,3,3,3,3,3,3")
    answers["q1"] = value
    r = TestClient(client.app).post(f"/api/participant-forms/{token}/responses",
                                    json={"form": 0, "answers": answers})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"][:3] == ["body", "answers", "q1"]


def _sized(items: int, lo: int, hi: int, labels: list[dict[str, Any]] | None = None
           ) -> dict[str, Any]:
    """A study's own definition with `items` items on a `lo`..`hi` scale (summed)."""
    own = _own_definition()
    own["items"] = [{"id": f"q{i}", "text": f"Item {i}"} for i in range(items)]
    own["scale"] = {"min": lo, "max": hi, "labels": labels or []}
    own["score_range"] = {"min": lo * items, "max": hi * items}
    return own


@pytest.mark.parametrize(("definition", "where", "problem"), [
    (_sized(200, -1000, 1000), ["body", "scale"],
     "-1000..1000 has 2001 points; at most 101 are allowed (for example 0..100)"),
    (_sized(50, 0, 100), ["body"], "the form would show 5050 answer choices (50 items x "
     "101 points); at most 5000: fewer items or a shorter scale"),
    (_sized(5, 1, 7, [{"value": 1, "label": "never"}] * 4000), ["body", "scale", "labels"],
     "List should have at most 101 items after validation, not 4000"),
    (_sized(5, 1, 7, [{"value": 1, "label": "never"}, {"value": 1, "label": "rarely"}]),
     ["body", "scale"], "labels: more than one label for value(s) [1]"),
    (_sized(5, 1, 7, [{"value": 1, "label": "Never"}, {"value": 7, "label": "never "}]),
     ["body", "scale"], "labels: the same words at several values: ['never'] (compared "
     "ignoring case, spacing, invisible characters and character width)"),
    (_sized(5, 1, 7, [{"value": 1, "label": "x" * 201}]), ["body", "scale", "labels", 0,
                                                           "label"],
     "String should have at most 200 characters"),
], ids=["2001-points", "5050-choices", "4000-labels", "two-labels-one-value",
        "same-words-twice", "201-characters"])
def test_an_imported_scale_keeps_its_form_usable(shared: TestClient, definition: dict[str, Any],
                                                 where: list[str | int], problem: str) -> None:
    client = shared
    url = f"/api/studies/{_study(client, f'Own {uuid4().hex}')}/instruments"
    r = client.post(url, json=definition)
    assert r.status_code == 422, r.text[:300]
    found = [(d["loc"], d["msg"].removeprefix("Value error, ")) for d in r.json()["detail"]]
    assert (where, problem) in found, found
    assert client.get(url).json() == [i for i in client.get(url).json() if i["built_in"]]


def _with(definition: dict[str, Any], **changes: Any) -> dict[str, Any]:
    return {**definition, **changes}


#: Labels that read the same (or show nothing), and the refusal each pair gets.
SAME_OR_BLANK_LABELS = [
    (["never", "ne\u200bver"], "labels: the same words at several values: ['never']"),
    (["Never", "\uff2e\uff45\uff56\uff45\uff52"],  # full-width letters
     "labels: the same words at several values: ['never']"),
    (["tr\u00e8s souvent", "tre\u0300s  souvent"],  # composed, decomposed, two spaces
     "labels: the same words at several values: ['tr\u00e8s souvent']"),
    (["\u2060 \u200d", "often"], "labels: the label at value(s) [1] shows no words"),
    (["   ", "often"], "labels: the label at value(s) [1] shows no words"),
]


def test_labels_are_compared_as_a_reader_sees_them(client: TestClient) -> None:
    """Zero-width spaces, full-width letters and decomposed accents once made the same
    words count as different labels; a label of spaces only was accepted."""
    url = f"/api/studies/{_study(client)}/instruments"
    for labels, problem in SAME_OR_BLANK_LABELS:
        definition = _sized(5, 1, 7, [{"value": v, "label": t}
                                      for v, t in zip((1, 7), labels, strict=True)])
        r = client.post(url, json=definition)
        assert r.status_code == 422, (labels, r.text[:300])
        msgs = [d["msg"].removeprefix("Value error, ") for d in r.json()["detail"]]
        assert any(m.startswith(problem) for m in msgs), (labels, msgs)
    assert [i for i in client.get(url).json() if not i["built_in"]] == []


#: Lists beyond the items, and where and how each is refused.
OVERLONG_LISTS: list[tuple[dict[str, Any], list[str | int], str]] = [
    ({"reverse_scored": ["q1"] * 201}, ["body", "reverse_scored"],
     "List should have at most 200 items after validation, not 201"),
    ({"reverse_scored": ["q1", "q2", "q1"]}, ["body"],
     "reverse_scored: listed more than once ['q1']"),
    ({"subscales": [{"id": f"s{i}", "title": "t", "items": ["q1"]} for i in range(51)]},
     ["body", "subscales"], "List should have at most 50 items after validation, not 51"),
    ({"subscales": [{"id": "s", "title": "t", "items": ["q1"] * 201}]},
     ["body", "subscales", 0, "items"],
     "List should have at most 200 items after validation, not 201"),
    ({"subscales": [{"id": "s", "title": "t", "items": ["q1", "q2", "q2"]}]},
     ["body", "subscales", 0], "items: listed more than once ['q2']"),
]


def test_reversed_items_and_subscales_are_bounded_by_the_items(client: TestClient) -> None:
    url = f"/api/studies/{_study(client)}/instruments"
    for changes, where, problem in OVERLONG_LISTS:
        r = client.post(url, json={**_sized(5, 1, 7), **changes})
        assert r.status_code == 422, (where, r.text[:300])
        found = [(d["loc"], d["msg"].removeprefix("Value error, "))
                 for d in r.json()["detail"]]
        assert (where, problem) in found, found
    assert [i for i in client.get(url).json() if not i["built_in"]] == []
    # Each item once in each list, 50 subscales: accepted.
    ok = {**_sized(5, 1, 7), "reverse_scored": ["q0", "q1"], "subscales": [
        {"id": f"s{i}", "title": "t", "items": ["q0", "q1", "q2", "q3", "q4"]}
        for i in range(50)]}
    assert client.post(url, json=ok).status_code == 201, client.post(url, json=ok).text[:300]


def test_the_widest_scale_and_largest_form_allowed_are_imported(client: TestClient) -> None:
    url = f"/api/studies/{_study(client)}/instruments"
    labels = [{"value": 0, "label": "not at all"}, {"value": 100, "label": "extremely"}]
    r = client.post(url, json=_sized(49, 0, 100, labels))
    assert r.status_code == 201, r.text[:300]
    assert [d.key for d in built_in_definitions()] and all(
        ImportedInstrument.model_validate(d.model_dump()) for d in built_in_definitions())


def test_an_instrument_stored_before_the_limits_is_still_served(client: TestClient,
                                                                db_url: str) -> None:
    sid = _study(client)
    wide = _sized(200, -1000, 1000)
    engine = make_engine(db_url)
    with engine.begin() as conn:
        conn.execute(insert(QuestionnaireInstrument).values(
            key=wide["key"], version=wide["version"], title=wide["title"], definition=wide,
            built_in=False, study_id=sid, created_at=datetime.now(UTC)))
    engine.dispose()
    r = client.get(f"/api/studies/{sid}/instruments/{wide['key']}/{wide['version']}")
    assert r.status_code == 200 and r.json()["definition"]["scale"]["min"] == -1000
